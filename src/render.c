/* Preview rendering of tets: orthographic projection, z-buffer, flat Lambert shading, PNG out.
 *
 * The camera looks along view_dir; the image's right axis is normalize(view_dir × up) and its
 * up axis is right × view_dir, so looking along +Y with up +Z puts +X on the right and +Z at
 * the top. The bounds box (the tets' bounding box or opts->bounds) is fitted into the image,
 * keeping the aspect ratio and leaving margin × width/height free on each side. This is a
 * preview, not a renderer of record. */
#define _POSIX_C_SOURCE 200809L
#include "fm_internal.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FM_RENDER_MAX_DIM 16384

static const int fm_tet_faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
static const double fm_object_rgb[3] = {0.72, 0.80, 0.92}; /* light grey-blue */
static const unsigned char fm_background_rgb[3] = {20, 22, 28};
static const double fm_ambient = 0.25;

fm_render_opts fm_default_render_opts(void)
{
    fm_render_opts o;
    memset(&o, 0, sizeof o);
    o.width = 960;
    o.height = 540;
    o.view_dir[1] = 1.0; /* camera on -Y looking at the front */
    o.up[2] = 1.0;
    o.margin = 0.05;
    o.bounds = NULL;
    return o;
}

/* ---------------------------------------------------------------- camera */

typedef struct camera {
    double right[3], up[3], fwd[3]; /* orthonormal image axes and viewing direction */
    double light[3];                /* unit vector towards the light */
    double s_mid, t_mid, scale;     /* bounds centre on the image plane, pixels per unit */
    int width, height;
} camera;

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Normalises v in place; returns its original length. */
static double normalize3(double v[3])
{
    double len = sqrt(dot3(v, v));
    if (len > 0.0 && isfinite(len))
        for (int k = 0; k < 3; k++) v[k] /= len;
    return len;
}

static fm_status camera_axes(const fm_render_opts *o, camera *cam, fm_error *err)
{
    if (o->width < 1 || o->height < 1 || o->width > FM_RENDER_MAX_DIM ||
        o->height > FM_RENDER_MAX_DIM)
        return fm_fail(err, FM_ERR_USAGE, "render: image size %dx%d is outside 1..%d", o->width,
                       o->height, FM_RENDER_MAX_DIM);
    if (!(o->margin >= 0.0 && o->margin < 0.5))
        return fm_fail(err, FM_ERR_USAGE, "render: margin %g is outside [0, 0.5)", o->margin);
    memcpy(cam->fwd, o->view_dir, sizeof cam->fwd);
    double up[3];
    memcpy(up, o->up, sizeof up);
    double lf = normalize3(cam->fwd), lu = normalize3(up);
    if (!(lf > 0.0 && isfinite(lf)) || !(lu > 0.0 && isfinite(lu)))
        return fm_fail(err, FM_ERR_USAGE, "render: view_dir and up must be finite and non-zero");
    cross3(cam->fwd, up, cam->right);
    if (!(normalize3(cam->right) > 1e-9))
        return fm_fail(err, FM_ERR_USAGE, "render: up is parallel to view_dir");
    cross3(cam->right, cam->fwd, cam->up);
    /* From the camera's upper left: towards the camera, up and to the left. */
    for (int k = 0; k < 3; k++)
        cam->light[k] = -1.0 * cam->fwd[k] + 0.6 * cam->up[k] - 0.5 * cam->right[k];
    normalize3(cam->light);
    cam->width = o->width;
    cam->height = o->height;
    return FM_OK;
}

/* Fits the box [lo, hi] into the image. */
static void camera_fit(camera *cam, const double lo[3], const double hi[3], double margin)
{
    double smin = INFINITY, smax = -INFINITY, tmin = INFINITY, tmax = -INFINITY;
    for (int c = 0; c < 8; c++) {
        double p[3] = {(c & 1) ? hi[0] : lo[0], (c & 2) ? hi[1] : lo[1], (c & 4) ? hi[2] : lo[2]};
        double s = dot3(p, cam->right), t = dot3(p, cam->up);
        smin = fmin(smin, s), smax = fmax(smax, s);
        tmin = fmin(tmin, t), tmax = fmax(tmax, t);
    }
    double avail_w = cam->width * (1.0 - 2.0 * margin);
    double avail_h = cam->height * (1.0 - 2.0 * margin);
    double sx = smax > smin ? avail_w / (smax - smin) : INFINITY;
    double sy = tmax > tmin ? avail_h / (tmax - tmin) : INFINITY;
    cam->scale = fmin(sx, sy);
    if (!isfinite(cam->scale)) cam->scale = 1.0; /* a single point: any scale will do */
    cam->s_mid = 0.5 * (smin + smax);
    cam->t_mid = 0.5 * (tmin + tmax);
}

/* World point -> pixel x (right), pixel y (down) and depth (larger is farther). */
static void camera_project(const camera *cam, const float v[3], double out[3])
{
    double p[3] = {v[0], v[1], v[2]};
    out[0] = 0.5 * cam->width + (dot3(p, cam->right) - cam->s_mid) * cam->scale;
    out[1] = 0.5 * cam->height - (dot3(p, cam->up) - cam->t_mid) * cam->scale;
    out[2] = dot3(p, cam->fwd);
}

/* ---------------------------------------------------------------- rasteriser */

typedef struct image {
    int width, height;
    unsigned char *rgb; /* width × height × 3, rows top to bottom */
    float *depth;       /* width × height */
} image;

/* Edge function: > 0 when p is on the inner side of a->b for a triangle with positive area. */
static double edge(const double a[3], const double b[3], const double p[2])
{
    return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
}

/* Top-left fill rule for positive-area triangles in y-down pixel coordinates. */
static int top_left(const double a[3], const double b[3])
{
    double dx = b[0] - a[0], dy = b[1] - a[1];
    return dy < 0.0 || (dy == 0.0 && dx > 0.0);
}

static void raster_triangle(image *img, const double *a, const double *b, const double *c,
                            const unsigned char rgb[3])
{
    for (int k = 0; k < 3; k++)
        if (!isfinite(a[k]) || !isfinite(b[k]) || !isfinite(c[k])) return;
    double pa[2] = {c[0], c[1]};
    double area = edge(a, b, pa);
    if (area < 0.0) { /* make the winding positive */
        const double *tmp = b;
        b = c;
        c = tmp;
        area = -area;
    }
    if (!(area > 0.0)) return; /* degenerate */

    /* Pixels whose centre (x + 0.5, y + 0.5) lies in the triangle's bounding box. */
    double x0 = ceil(fmin(a[0], fmin(b[0], c[0])) - 0.5);
    double x1 = floor(fmax(a[0], fmax(b[0], c[0])) - 0.5);
    double y0 = ceil(fmin(a[1], fmin(b[1], c[1])) - 0.5);
    double y1 = floor(fmax(a[1], fmax(b[1], c[1])) - 0.5);
    x0 = fmax(x0, 0.0), y0 = fmax(y0, 0.0);
    x1 = fmin(x1, img->width - 1.0), y1 = fmin(y1, img->height - 1.0);
    if (x0 > x1 || y0 > y1) return;

    int tl0 = top_left(b, c), tl1 = top_left(c, a), tl2 = top_left(a, b);
    for (int y = (int)y0; y <= (int)y1; y++) {
        for (int x = (int)x0; x <= (int)x1; x++) {
            double p[2] = {x + 0.5, y + 0.5};
            double w0 = edge(b, c, p), w1 = edge(c, a, p), w2 = edge(a, b, p);
            if (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) continue;
            if ((w0 == 0.0 && !tl0) || (w1 == 0.0 && !tl1) || (w2 == 0.0 && !tl2)) continue;
            float z = (float)((w0 * a[2] + w1 * b[2] + w2 * c[2]) / area);
            size_t i = (size_t)y * (size_t)img->width + (size_t)x;
            if (!(z < img->depth[i])) continue;
            img->depth[i] = z;
            memcpy(img->rgb + 3 * i, rgb, 3);
        }
    }
}

/* Flat Lambert shade of the world-space triangle (a, b, c); |n·l| ignores the winding. */
static void shade(const camera *cam, const float *a, const float *b, const float *c,
                  unsigned char rgb[3])
{
    double e1[3], e2[3], n[3];
    for (int k = 0; k < 3; k++) {
        e1[k] = (double)b[k] - a[k];
        e2[k] = (double)c[k] - a[k];
    }
    cross3(e1, e2, n);
    double diffuse = normalize3(n) > 0.0 ? fabs(dot3(n, cam->light)) : 0.0;
    if (!isfinite(diffuse)) diffuse = 0.0;
    double intensity = fm_ambient + (1.0 - fm_ambient) * fmin(diffuse, 1.0);
    for (int k = 0; k < 3; k++)
        rgb[k] = (unsigned char)lround(255.0 * fm_object_rgb[k] * intensity);
}

static void render(const camera *cam, const float *verts, size_t n, image *img)
{
    for (size_t t = 0; t < n; t++) {
        const float *tv = verts + 12 * t;
        double p[4][3];
        for (int v = 0; v < 4; v++) camera_project(cam, tv + 3 * v, p[v]);
        for (int f = 0; f < 4; f++) {
            const int *ix = fm_tet_faces[f];
            unsigned char rgb[3];
            shade(cam, tv + 3 * ix[0], tv + 3 * ix[1], tv + 3 * ix[2], rgb);
            raster_triangle(img, p[ix[0]], p[ix[1]], p[ix[2]], rgb);
        }
    }
}

/* The tets' bounding box over finite vertices; returns 0 if there is none. */
static int tets_bounds(const float *verts, size_t n, double lo[3], double hi[3])
{
    int any = 0;
    for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (size_t i = 0; i < 4 * n; i++) {
        const float *v = verts + 3 * i;
        if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2])) continue;
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], v[k]), hi[k] = fmax(hi[k], v[k]);
        any = 1;
    }
    return any;
}

/* ---------------------------------------------------------------- PNG */

typedef struct png_failure {
    char message[256];
} png_failure;

static void png_error_fn(png_structp png, png_const_charp msg)
{
    png_failure *pf = png_get_error_ptr(png);
    snprintf(pf->message, sizeof pf->message, "%s", msg);
    png_longjmp(png, 1);
}

static void png_warning_fn(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

/* Returns 0 on success, -1 on failure with pf->message set (errno may say more). */
static int write_png(FILE *f, const image *img, png_failure *pf)
{
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, pf, png_error_fn,
                                              png_warning_fn);
    if (!png) {
        snprintf(pf->message, sizeof pf->message, "libpng could not start");
        return -1;
    }
    png_infop info = png_create_info_struct(png);
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        snprintf(pf->message, sizeof pf->message, "libpng could not start");
        return -1;
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return -1;
    }
    png_init_io(png, f);
    png_set_IHDR(png, info, (png_uint_32)img->width, (png_uint_32)img->height, 8,
                 PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                 PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < img->height; y++)
        png_write_row(png, img->rgb + (size_t)y * (size_t)img->width * 3);
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    return 0;
}

/* Writes img to path through path.partial and rename(). */
static fm_status save_png(const image *img, const char *path, fm_error *err)
{
    fm_output_file out;
    fm_status st = fm_output_open(&out, path, err);
    if (st != FM_OK) return st;
    png_failure pf = {""};
    errno = 0;
    if (write_png(out.f, img, &pf) != 0) {
        int e = errno;
        fm_output_discard(&out);
        if (pf.message[0]) return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s", path, pf.message);
        return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s", path, strerror(e ? e : EIO));
    }
    return fm_output_commit(&out, NULL, err);
}

/* ---------------------------------------------------------------- entry point */

fm_status fm_render_tets_png(const float *verts, size_t n, const fm_render_opts *opts,
                             const char *path, fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "render: no output path given");
    if (n > 0 && !verts) return fm_fail(err, FM_ERR_USAGE, "render to '%s': no vertices", path);
    fm_render_opts defaults = fm_default_render_opts();
    const fm_render_opts *o = opts ? opts : &defaults;

    camera cam;
    fm_status s = camera_axes(o, &cam, err);
    if (s != FM_OK) return s;

    double lo[3], hi[3];
    int have_bounds;
    if (o->bounds) {
        for (int k = 0; k < 3; k++) {
            lo[k] = o->bounds[k];
            hi[k] = o->bounds[k + 3];
            if (!isfinite(lo[k]) || !isfinite(hi[k]) || lo[k] > hi[k])
                return fm_fail(err, FM_ERR_USAGE,
                               "render: bounds must be finite [minx miny minz maxx maxy maxz]");
        }
        have_bounds = 1;
    } else {
        have_bounds = tets_bounds(verts, n, lo, hi);
    }

    size_t pixels = (size_t)o->width * (size_t)o->height;
    image img = {o->width, o->height, fm_alloc(3 * pixels), fm_alloc(sizeof(float) * pixels)};
    if (!img.rgb || !img.depth) {
        fm_free(img.rgb);
        fm_free(img.depth);
        return fm_fail(err, FM_ERR_MEMORY, "render to '%s': out of memory for %dx%d", path,
                       o->width, o->height);
    }
    for (size_t i = 0; i < pixels; i++) {
        memcpy(img.rgb + 3 * i, fm_background_rgb, 3);
        img.depth[i] = INFINITY;
    }
    if (have_bounds) {
        camera_fit(&cam, lo, hi, o->margin);
        render(&cam, verts, n, &img);
    }
    s = save_png(&img, path, err);
    fm_free(img.rgb);
    fm_free(img.depth);
    return s;
}
