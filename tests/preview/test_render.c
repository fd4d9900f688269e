/* The preview renderer (src/preview/render.c) and its video writer (src/preview/video.c): render small scenes
 * whose projection is known and check where the pixels land, that a tet shadows the ground, that
 * the bytes do not depend on the thread count, that points become spheres, that obstacles are drawn
 * and cast and take shadows; then `flockmorph render` to MP4 through ffmpeg, counted back with
 * ffprobe, and its errors; and the shot (issue 14): the camera that follows the flock, the old
 * camera under --camera animation, and the obstacles beside the cache. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "export.h"
#include "test_macros.h"

#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>

#ifndef FM_TEST_TMP
#error "FM_TEST_TMP must name a scratch directory"
#endif

/* ---------------------------------------------------------------- images */

typedef struct rgb_image {
    int width, height;
    unsigned char *rgb;
} rgb_image;

static const unsigned char *pixel(const rgb_image *im, int x, int y)
{
    return im->rgb + 3 * ((size_t)y * (size_t)im->width + (size_t)x);
}

static int brightness(const rgb_image *im, int x, int y)
{
    const unsigned char *p = pixel(im, x, y);
    return p[0] + p[1] + p[2];
}

/* Renders tets (points = 0) or points, coloured as c says (NULL: by index), into a new image; rgb
 * is NULL on failure. */
static rgb_image render_coloured(const float *data, size_t n, int points, const fm_render_colours *c,
                                 const fm_render_opts *o)
{
    rgb_image im = {o->width, o->height, malloc(3 * (size_t)o->width * (size_t)o->height)};
    fm_error err = {0};
    fm_renderer *r = fm_renderer_create(o, &err);
    ENSURE_MSG(r != NULL, "create: %s", err.message);
    fm_status st = FM_ERR_INTERNAL;
    if (r && im.rgb && c)
        st = points ? fm_renderer_draw_points_coloured(r, data, n, c, im.rgb, &err)
                    : fm_renderer_draw_tets_coloured(r, data, n, c, im.rgb, &err);
    else if (r && im.rgb)
        st = points ? fm_renderer_draw_points(r, data, n, im.rgb, &err)
                    : fm_renderer_draw_tets(r, data, n, im.rgb, &err);
    ENSURE_MSG(st == FM_OK, "draw: status %d: %s", (int)st, err.message);
    fm_renderer_destroy(r);
    if (st != FM_OK) free(im.rgb), im.rgb = NULL;
    return im;
}

static rgb_image render(const float *data, size_t n, int points, const fm_render_opts *o)
{
    return render_coloured(data, n, points, NULL, o);
}

/* Reads an 8-bit RGB PNG (anything else fails); 0 on success. */
static int read_png(const char *path, rgb_image *out)
{
    memset(out, 0, sizeof *out);
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path)) return 1;
    if (img.format != PNG_FORMAT_RGB) return png_image_free(&img), 2;
    out->rgb = malloc(PNG_IMAGE_SIZE(img));
    if (!out->rgb || !png_image_finish_read(&img, NULL, out->rgb, 0, NULL)) {
        png_image_free(&img);
        free(out->rgb);
        out->rgb = NULL;
        return 3;
    }
    out->width = (int)img.width;
    out->height = (int)img.height;
    return 0;
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static char *tmp_path(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s/render_%s", FM_TEST_TMP, name);
    return buf;
}

/* Foreground = any pixel that differs from the top-left corner (the scenes leave it empty). */
typedef struct coverage {
    long fg;
    int x0, x1, y0, y1; /* foreground bounding box (inclusive) */
} coverage;

static int is_fg(const rgb_image *im, int x, int y)
{
    return memcmp(pixel(im, x, y), pixel(im, 0, 0), 3) != 0;
}

static coverage cover(const rgb_image *im)
{
    coverage c = {0, im->width, -1, im->height, -1};
    for (int y = 0; y < im->height; y++)
        for (int x = 0; x < im->width; x++) {
            if (!is_fg(im, x, y)) continue;
            c.fg++;
            if (x < c.x0) c.x0 = x;
            if (x > c.x1) c.x1 = x;
            if (y < c.y0) c.y0 = y;
            if (y > c.y1) c.y1 = y;
        }
    return c;
}

/* ---------------------------------------------------------------- scenes */

/* A tet whose back face (v0 v1 v2) lies in the plane y = y0 as the triangle
 * (cx - w, cz - h), (cx + w, cz - h), (cx, cz + h) in (x, z), with the apex v3 sticking out
 * towards -Y (towards the front camera) over the triangle's centroid. Positive volume. */
static void make_tet(float *t, double cx, double y0, double cz, double w, double h, double depth)
{
    const double v[4][3] = {{cx - w, y0, cz - h},
                            {cx + w, y0, cz - h},
                            {cx, y0, cz + h},
                            {cx, y0 - depth, cz - h / 3.0}};
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++) t[3 * i + k] = (float)v[i][k];
}

static const double unit_box[6] = {-1, -1, -1, 1, 1, 1};

/* Orthographic front view (along +Y, up +Z), no ground, fitted to the box [-1, 1]^3. */
static fm_render_opts front_opts(void)
{
    fm_render_opts o = fm_default_render_opts();
    ENSURE(fm_render_set_view(&o, "front", NULL) == FM_OK);
    o.ground = 0;
    o.bounds = unit_box;
    return o;
}

/* Pixels per world unit once the box [-1, 1]^3, which spans 2 x 2 on the front view's image
 * plane, is fitted into W x H with margin m. */
static double box_scale(const fm_render_opts *o, double plane_w, double plane_h)
{
    double sx = o->width * (1.0 - 2.0 * o->margin) / plane_w;
    double sy = o->height * (1.0 - 2.0 * o->margin) / plane_h;
    return sx < sy ? sx : sy;
}
static double px_of(const fm_render_opts *o, double s) { return 0.5 * o->width + s * box_scale(o, 2, 2); }
static double py_of(const fm_render_opts *o, double t) { return 0.5 * o->height - t * box_scale(o, 2, 2); }

/* ---------------------------------------------------------------- options */

static void test_defaults_and_views(void)
{
    fm_render_opts o = fm_default_render_opts();
    ENSURE(o.width == 960 && o.height == 540);
    ENSURE(o.perspective == 1 && o.ground == 1 && o.samples == 1 && o.bounds == NULL);
    ENSURE(o.world_up[0] == 0 && o.world_up[1] == 0 && o.world_up[2] == 1);
    ENSURE(o.view_dir[1] > 0 && o.view_dir[2] < 0); /* persp: from the front, above */
    ENSURE_NEAR(o.margin, 0.05, 1e-15);
    fm_error err = {0};
    ENSURE(fm_render_set_view(&o, "top", &err) == FM_OK);
    ENSURE(o.perspective == 0 && o.view_dir[2] == -1 && o.up[1] == 1);
    ENSURE(fm_render_set_view(&o, "side", &err) == FM_OK && o.view_dir[0] == -1);
    ENSURE(fm_render_set_view(&o, "front", &err) == FM_OK && o.view_dir[1] == 1);
    ENSURE(fm_render_set_view(&o, "diagonal", &err) == FM_ERR_USAGE);
    ENSURE_MSG(strstr(err.message, "diagonal") && strstr(err.message, "persp"), "%s", err.message);
}

/* ---------------------------------------------------------------- where pixels land */

/* One tet in the right half of the fixed box, seen from the front: its pixels lie inside its
 * projected bounding box and fill the silhouette (the back triangle, half that box). */
static void test_front_view_inside_projected_box(void)
{
    fm_render_opts o = front_opts();
    float tet[12];
    make_tet(tet, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4); /* x in [0.3, 0.9], z in [-0.5, 0.5] */
    rgb_image im = render(tet, 1, 0, &o);
    if (!im.rgb) return;
    coverage c = cover(&im);
    double bx0 = px_of(&o, 0.3), bx1 = px_of(&o, 0.9), by0 = py_of(&o, 0.5), by1 = py_of(&o, -0.5);
    /* Pixel centres (x + 0.5) inside the box, and the box reached, to a pixel. */
    ENSURE_MSG(c.fg > 0 && c.x0 + 0.5 >= bx0 - 1 && c.x1 + 0.5 <= bx1 + 1 && c.y0 + 0.5 >= by0 - 1 &&
                   c.y1 + 0.5 <= by1 + 1,
               "foreground [%d, %d] x [%d, %d] outside [%.1f, %.1f] x [%.1f, %.1f]", c.x0, c.x1,
               c.y0, c.y1, bx0, bx1, by0, by1);
    ENSURE_MSG(c.x0 + 0.5 <= bx0 + 1 && c.x1 + 0.5 >= bx1 - 1 && c.y0 + 0.5 <= by0 + 1 &&
                   c.y1 + 0.5 >= by1 - 1,
               "foreground [%d, %d] x [%d, %d] does not reach [%.1f, %.1f] x [%.1f, %.1f]", c.x0,
               c.x1, c.y0, c.y1, bx0, bx1, by0, by1);
    double area = 0.5 * (bx1 - bx0) * (by1 - by0);
    ENSURE_MSG(fabs((double)c.fg - area) < 0.015 * area, "%ld foreground pixels, expected %.0f",
               c.fg, area);
    ENSURE_MSG(c.x0 >= im.width / 2, "+X is not on the right: foreground from x = %d", c.x0);
    free(im.rgb);
}

/* Perspective, fitted to a cube (the 6 tets of its Kuhn triangulation, so its silhouette is the
 * projection of its bounding box): it spans the image minus the margins along the limiting axis,
 * centred, and stays inside the margins on the other. */
static size_t kuhn_block(float *out, int cells);

static void test_perspective_fit(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.ground = 0;
    float cube[6 * 12 + 12];
    size_t n = kuhn_block(cube, 1);
    for (size_t i = 0; i < 12 * n; i++) cube[i] = 2.0f * cube[i] + (i % 3 == 2 ? -7.0f : 5.0f);
    rgb_image im = render(cube, n, 0, &o);
    if (!im.rgb) return;
    coverage c = cover(&im);
    double mx = o.margin * o.width, my = o.margin * o.height;
    ENSURE_MSG(c.fg > 1000, "only %ld foreground pixels", c.fg);
    ENSURE_MSG(c.x0 >= mx - 1 && c.x1 <= o.width - mx && c.y0 >= my - 1 && c.y1 <= o.height - my,
               "foreground [%d, %d] x [%d, %d] crosses the margins", c.x0, c.x1, c.y0, c.y1);
    ENSURE_NEAR(c.y0 + 0.5, my, 1.5);
    ENSURE_NEAR(c.y1 + 0.5, o.height - my, 1.5);
    ENSURE_NEAR(0.5 * (c.x0 + c.x1 + 1), 0.5 * o.width, 1.5);
    free(im.rgb);
}

/* Agent i takes colour i / (n - 1) of the gradient: agent 0 blue, the last agent coral. */
static void test_gradient_over_agents(void)
{
    fm_render_opts o = front_opts();
    float tets[24];
    make_tet(tets, -0.5, 0.0, 0.0, 0.3, 0.5, 0.4);
    make_tet(tets + 12, 0.5, 0.0, 0.0, 0.3, 0.5, 0.4);
    rgb_image im = render(tets, 2, 0, &o);
    if (!im.rgb) return;
    long left = 0, right = 0, wrong = 0;
    for (int y = 0; y < im.height; y++)
        for (int x = 0; x < im.width; x++) {
            if (!is_fg(&im, x, y)) continue;
            const unsigned char *p = pixel(&im, x, y);
            int blue = p[2] > p[0] + 20, coral = p[0] > p[2] + 20;
            if (x < im.width / 2) left++, wrong += !blue;
            else right++, wrong += !coral;
        }
    ENSURE_MSG(left > 1000 && right > 1000, "left %ld, right %ld pixels", left, right);
    ENSURE_MSG(wrong == 0, "%ld pixels have the other end's colour", wrong);
    free(im.rgb);
}

/* ---------------------------------------------------------------- colours */

/* Two tets side by side, the left one agent 0. */
static void two_tets(float tets[24])
{
    make_tet(tets, -0.5, 0.0, 0.0, 0.3, 0.5, 0.4);
    make_tet(tets + 12, 0.5, 0.0, 0.0, 0.3, 0.5, 0.4);
}

static int same_image(const rgb_image *a, const rgb_image *b)
{
    return a->rgb && b->rgb && a->width == b->width && a->height == b->height &&
           memcmp(a->rgb, b->rgb, 3 * (size_t)a->width * (size_t)a->height) == 0;
}

/* Relative luminance of an sRGB colour. */
static double luminance(const float srgb[3])
{
    double y = 0.0;
    const double w[3] = {0.2126, 0.7152, 0.0722};
    for (int k = 0; k < 3; k++) {
        double c = srgb[k];
        y += w[k] * (c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
    }
    return y;
}

/* The colormap is viridis: matplotlib's first and last entries at the ends, clamped outside, its
 * lightness rising all the way (a sequential map); the phase palette has four distinct colours. */
static void test_colormap_and_palette(void)
{
    float c[3], d[3];
    fm_render_colormap(0.0, c);
    ENSURE_NEAR(c[0], 0.267004, 1e-6);
    ENSURE_NEAR(c[1], 0.004874, 1e-6);
    ENSURE_NEAR(c[2], 0.329415, 1e-6);
    fm_render_colormap(1.0, c);
    ENSURE_NEAR(c[0], 0.993248, 1e-6);
    ENSURE_NEAR(c[1], 0.906157, 1e-6);
    ENSURE_NEAR(c[2], 0.143936, 1e-6);
    fm_render_colormap(0.5, c); /* matplotlib's entry 128 of 256 */
    ENSURE_NEAR(c[0], 0.127568, 2e-3);
    ENSURE_NEAR(c[1], 0.566949, 2e-3);
    ENSURE_NEAR(c[2], 0.550556, 2e-3);
    fm_render_colormap(7.0, d);
    fm_render_colormap(1.0, c);
    ENSURE(memcmp(c, d, sizeof c) == 0);
    double last = -1.0;
    for (int i = 0; i <= 256; i++) {
        fm_render_colormap(i / 256.0, c);
        ENSURE_MSG(luminance(c) > last, "lightness falls at u = %d / 256", i);
        last = luminance(c);
    }
    float phase[5][3];
    for (unsigned p = 0; p < 5; p++) fm_render_phase_colour(p, phase[p]);
    for (int a = 0; a < 5; a++)
        for (int b = a + 1; b < 5; b++) {
            double dist = fabs(phase[a][0] - phase[b][0]) + fabs(phase[a][1] - phase[b][1]) +
                          fabs(phase[a][2] - phase[b][2]);
            ENSURE_MSG(dist > 0.3, "phase colours %d and %d are alike", a, b);
        }
    fm_render_phase_colour(200, c);
    ENSURE(memcmp(c, phase[4], sizeof c) == 0); /* every unknown phase is the same grey */
}

/* FM_COLOUR_VALUE: lo takes the map's first colour and hi its last (the same bytes as giving those
 * colours as FM_COLOUR_RGB), values outside are clamped, and NaN is the palette's grey. */
static void test_values_on_the_map(void)
{
    fm_render_opts o = front_opts();
    o.width = 240, o.height = 160;
    float tets[24], ends[6], grey[6];
    two_tets(tets);
    fm_render_colormap(0.0, ends), fm_render_colormap(1.0, ends + 3);
    const float slow_fast[2] = {2.0f, 10.0f}, outside[2] = {-50.0f, 1e6f}, nan_fast[2] = {NAN, 10.0f};
    fm_render_colours value = {FM_COLOUR_VALUE, slow_fast, 2.0, 10.0, NULL};
    fm_render_colours given = {FM_COLOUR_RGB, NULL, 0.0, 0.0, ends};
    rgb_image v = render_coloured(tets, 2, 0, &value, &o), g = render_coloured(tets, 2, 0, &given, &o);
    ENSURE_MSG(same_image(&v, &g), "values at lo and hi are not the map's ends");
    value.values = outside;
    rgb_image clamped = render_coloured(tets, 2, 0, &value, &o);
    ENSURE_MSG(same_image(&v, &clamped), "values outside the range are not clamped to its ends");
    value.values = nan_fast;
    fm_render_phase_colour(99, grey), memcpy(grey + 3, ends + 3, 3 * sizeof(float));
    given.rgb = grey;
    rgb_image nan = render_coloured(tets, 2, 0, &value, &o), nan_given = render_coloured(tets, 2, 0, &given, &o);
    ENSURE_MSG(same_image(&nan, &nan_given), "a NaN value is not grey");
    /* And the ends look like viridis: dark violet on the left, yellow on the right. */
    long left = 0, right = 0, wrong = 0;
    for (int y = 0; v.rgb && y < v.height; y++)
        for (int x = 0; x < v.width; x++) {
            if (!is_fg(&v, x, y)) continue;
            const unsigned char *p = pixel(&v, x, y);
            if (x < v.width / 2) left++, wrong += !(p[2] > p[1] + 20 && p[0] > p[1]);
            else right++, wrong += !(p[0] > p[2] + 40 && p[1] > p[2] + 40);
        }
    ENSURE_MSG(left > 500 && right > 500 && wrong == 0, "left %ld, right %ld, %ld of another colour", left,
               right, wrong);
    free(v.rgb), free(g.rgb), free(clamped.rgb), free(nan.rgb), free(nan_given.rgb);
}

/* Colours that cannot be used are usage errors, and nothing is drawn. */
static void test_bad_colours(void)
{
    fm_render_opts o = front_opts();
    o.width = 32, o.height = 32;
    float tets[24];
    two_tets(tets);
    const float values[2] = {1, 2};
    const fm_render_colours bad[] = {{(fm_render_colour_mode)7, NULL, 0, 0, NULL},
                                     {FM_COLOUR_VALUE, NULL, 0, 1, NULL},
                                     {FM_COLOUR_VALUE, values, 1, 1, NULL},
                                     {FM_COLOUR_VALUE, values, 2, 1, NULL},
                                     {FM_COLOUR_VALUE, values, NAN, 1, NULL},
                                     {FM_COLOUR_VALUE, values, 0, INFINITY, NULL},
                                     {FM_COLOUR_RGB, values, 0, 1, NULL}};
    fm_error err = {0};
    fm_renderer *r = fm_renderer_create(&o, &err);
    unsigned char rgb[3 * 32 * 32];
    for (size_t i = 0; r && i < sizeof bad / sizeof bad[0]; i++) {
        fm_status st = fm_renderer_draw_tets_coloured(r, tets, 2, &bad[i], rgb, &err);
        ENSURE_MSG(st == FM_ERR_USAGE && strstr(err.message, "colour"), "case %zu: status %d: %s", i, (int)st,
                   err.message);
        ENSURE(fm_renderer_draw_points_coloured(r, tets, 2, &bad[i], rgb, &err) == FM_ERR_USAGE);
    }
    /* No agents: no values needed. */
    const fm_render_colours none = {FM_COLOUR_VALUE, NULL, 0, 1, NULL};
    ENSURE(r && fm_renderer_draw_tets_coloured(r, NULL, 0, &none, rgb, &err) == FM_OK);
    fm_renderer_destroy(r);
}

/* ---------------------------------------------------------------- shadows */

/* Light from straight above, camera looking down at 45 degrees from the front (orthographic): a
 * tet hovering over the middle of the box darkens the ground right under it, which the camera
 * sees below the tet, while the ground elsewhere stays lit (and is the same with no tet). */
static void test_shadow_on_ground(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.perspective = 0;
    o.view_dir[0] = 0, o.view_dir[1] = 1, o.view_dir[2] = -1;
    o.up[0] = 0, o.up[1] = 0, o.up[2] = 1;
    o.light_dir[2] = 1;
    o.bounds = unit_box;
    o.width = 400, o.height = 300;
    float tet[12];
    make_tet(tet, 0.0, 0.1, 0.5, 0.2, 0.2, 0.2); /* x in [-0.2, 0.2], y in [-0.1, 0.1], z ~ 0.5 */
    rgb_image im = render(tet, 1, 0, &o), bare = render(NULL, 0, 0, &o);
    if (!im.rgb || !bare.rgb) return free(im.rgb), free(bare.rgb);
    /* Image plane: s = x, t = (y + z) / sqrt 2; the box spans 2 x 2 sqrt 2 of it. The ground lies
     * at z = -1 (a hair below). */
    double scale = box_scale(&o, 2.0, 2.0 * sqrt(2.0)), r2 = sqrt(0.5);
    int sx = (int)(0.5 * o.width), sy = (int)(0.5 * o.height + r2 * scale);  /* under the tet */
    int fx = (int)(0.5 * o.width + 0.7 * scale);                            /* x = 0.7: far */
    int tet_y = (int)(0.5 * o.height - 0.5 * r2 * scale);                   /* the tet itself */
    ENSURE_MSG(is_fg(&im, sx, tet_y), "the tet is not at (%d, %d)", sx, tet_y);
    int under = brightness(&im, sx, sy), far = brightness(&im, fx, sy), lit = brightness(&bare, sx, sy);
    ENSURE_MSG(is_fg(&im, sx, sy) && is_fg(&im, fx, sy), "(%d, %d) or (%d, %d) is not ground", sx,
               sy, fx, sy);
    ENSURE_MSG(under < 0.7 * far, "ground under the tet (%d) is not darker than far from it (%d)",
               under, far);
    ENSURE_MSG(lit == far, "without the tet the ground there is %d, elsewhere %d", lit, far);
    const unsigned char *p = pixel(&im, sx, sy);
    ENSURE_MSG(abs(p[0] - p[1]) < 8 && abs(p[1] - p[2]) < 8, "the shadow (%d %d %d) is not grey ground",
               p[0], p[1], p[2]);
    free(im.rgb);
    free(bare.rgb);
}

/* ---------------------------------------------------------------- obstacles */

/* The obstacle colour, light warm grey, shaded: red over green over blue, but by little (every
 * agent colour that has red > green > blue, amber and coral, has far more red than blue), which
 * neither the bluish ground and background nor the neutral grey of unknown values have. */
static int is_obstacle_colour(const unsigned char *p)
{
    return p[0] > p[1] && p[1] > p[2] && p[0] - p[2] <= p[0] / 4 + 2;
}

static long obstacle_pixels(const rgb_image *im)
{
    long n = 0;
    for (int y = 0; y < im->height; y++)
        for (int x = 0; x < im->width; x++) n += is_obstacle_colour(pixel(im, x, y));
    return n;
}

/* The plate |x|, |y| <= 0.3 at z = 0.5, two triangles. */
static const float plate_verts[] = {-0.3f, -0.3f, 0.5f, 0.3f, -0.3f, 0.5f, 0.3f, 0.3f, 0.5f, -0.3f, 0.3f, 0.5f};
static const uint32_t plate_tris[] = {0, 1, 2, 0, 2, 3};

/* Renders tets with the plate as the obstacles (plate = 0: without). */
static rgb_image render_with_plate(const float *tets, size_t n, int plate, const fm_render_opts *o)
{
    rgb_image im = {o->width, o->height, malloc(3 * (size_t)o->width * (size_t)o->height)};
    fm_error err = {0};
    fm_renderer *r = fm_renderer_create(o, &err);
    fm_status st = r && im.rgb ? FM_OK : FM_ERR_INTERNAL;
    if (st == FM_OK && plate) st = fm_renderer_set_obstacles(r, plate_verts, 4, plate_tris, 2, &err);
    if (st == FM_OK) st = fm_renderer_draw_tets(r, tets, n, im.rgb, &err);
    ENSURE_MSG(st == FM_OK, "status %d: %s", (int)st, err.message);
    fm_renderer_destroy(r);
    if (st != FM_OK) free(im.rgb), im.rgb = NULL;
    return im;
}

/* The view of test_shadow_on_ground with the light straight above: the plate is drawn in the
 * obstacle colour, its shadow darkens the ground under it, and a tet above it shadows the plate. */
static void test_obstacles_drawn_with_shadows(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.perspective = 0;
    o.view_dir[0] = 0, o.view_dir[1] = 1, o.view_dir[2] = -1;
    o.light_dir[2] = 1;
    o.bounds = unit_box;
    o.width = 400, o.height = 300;
    float tet[12];
    make_tet(tet, 0.0, 0.1, 0.8, 0.15, 0.1, 0.2); /* over the plate's centre, clear of it */
    rgb_image bare = render_with_plate(NULL, 0, 0, &o), plate = render_with_plate(NULL, 0, 1, &o);
    rgb_image shaded = render_with_plate(tet, 1, 1, &o);
    if (!bare.rgb || !plate.rgb || !shaded.rgb) return free(bare.rgb), free(plate.rgb), free(shaded.rgb);
    /* Image plane: s = x, t = (y + z) / sqrt 2, as in test_shadow_on_ground. */
    double scale = box_scale(&o, 2.0, 2.0 * sqrt(2.0)), r2 = sqrt(0.5);
    int cx = (int)(0.5 * o.width), plate_y = (int)(0.5 * o.height - 0.5 * r2 * scale);
    int ground_y = (int)(0.5 * o.height + r2 * scale), far_x = (int)(0.5 * o.width + 0.7 * scale);
    const unsigned char *p = pixel(&plate, cx, plate_y);
    ENSURE_MSG(is_obstacle_colour(p), "the plate's centre is (%d %d %d)", p[0], p[1], p[2]);
    ENSURE_MSG(obstacle_pixels(&bare) == 0, "%ld obstacle-coloured pixels without obstacles", obstacle_pixels(&bare));
    int under = brightness(&plate, cx, ground_y), far = brightness(&plate, far_x, ground_y);
    ENSURE_MSG(under < 0.7 * far, "the ground under the plate (%d) is not darker than far from it (%d)", under, far);
    ENSURE_MSG(brightness(&bare, cx, ground_y) == far, "without the plate the ground under it is lit differently");
    int lit = brightness(&plate, cx, plate_y), dark = brightness(&shaded, cx, plate_y);
    ENSURE_MSG(dark < 0.7 * lit && is_obstacle_colour(pixel(&shaded, cx, plate_y)),
               "the tet's shadow on the plate (%d) is not darker than the lit plate (%d)", dark, lit);
    /* the same bytes with 1 and 2 threads */
    o.threads = 1;
    rgb_image one = render_with_plate(tet, 1, 1, &o);
    o.threads = 2;
    rgb_image two = render_with_plate(tet, 1, 1, &o);
    ENSURE(one.rgb && two.rgb && memcmp(one.rgb, two.rgb, 3 * (size_t)o.width * (size_t)o.height) == 0);
    free(one.rgb), free(two.rgb);
    free(bare.rgb), free(plate.rgb), free(shaded.rgb);
}

static void test_obstacle_and_bounds_errors(void)
{
    fm_error err = {0};
    fm_renderer *r = fm_renderer_create(NULL, &err);
    ENSURE(r != NULL);
    if (!r) return;
    const uint32_t bad_index[] = {0, 1, 4};
    float nan_verts[12];
    memcpy(nan_verts, plate_verts, sizeof nan_verts);
    nan_verts[4] = NAN;
    ENSURE(fm_renderer_set_obstacles(r, plate_verts, 4, bad_index, 1, &err) == FM_ERR_USAGE);
    ENSURE_MSG(strstr(err.message, "vertex 4 of 4"), "%s", err.message);
    ENSURE(fm_renderer_set_obstacles(r, nan_verts, 4, plate_tris, 2, &err) == FM_ERR_USAGE);
    ENSURE(fm_renderer_set_obstacles(r, NULL, 4, plate_tris, 2, &err) == FM_ERR_USAGE);
    ENSURE(fm_renderer_set_obstacles(NULL, plate_verts, 4, plate_tris, 2, &err) == FM_ERR_USAGE);
    ENSURE(fm_renderer_set_obstacles(r, plate_verts, 4, plate_tris, 2, &err) == FM_OK);
    ENSURE(fm_renderer_set_obstacles(r, NULL, 0, NULL, 0, &err) == FM_OK); /* removed */
    const double inverted[6] = {1, 0, 0, 0, 1, 1}, nan_box[6] = {0, 0, 0, NAN, 1, 1};
    ENSURE(fm_renderer_set_bounds(r, inverted, &err) == FM_ERR_USAGE);
    ENSURE(fm_renderer_set_bounds(r, nan_box, &err) == FM_ERR_USAGE);
    ENSURE(fm_renderer_set_bounds(r, unit_box, &err) == FM_OK);
    ENSURE(fm_renderer_set_bounds(r, NULL, &err) == FM_OK);
    fm_renderer_destroy(r);
}

/* ---------------------------------------------------------------- threads */

/* A block of cubes, each split into the 6 tets of its Kuhn triangulation, so neighbouring tets
 * share faces exactly (ties for the BVH), plus a duplicate of every 7th tet. */
static size_t kuhn_block(float *out, int cells)
{
    static const int path[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    size_t n = 0;
    for (int cz = 0; cz < cells; cz++)
        for (int cy = 0; cy < cells; cy++)
            for (int cx = 0; cx < cells; cx++)
                for (int p = 0; p < 6; p++) {
                    int v[3] = {cx, cy, cz};
                    float *t = out + 12 * n++;
                    for (int k = 0; k < 3; k++) t[k] = (float)v[k];
                    for (int step = 0; step < 3; step++) { /* walk the cube's diagonal, one axis a step */
                        v[path[p][step]]++;
                        for (int k = 0; k < 3; k++) t[3 * (step + 1) + k] = (float)v[k];
                    }
                    if (n % 7 == 0) memcpy(out + 12 * n, t, 12 * sizeof(float)), n++;
                }
    return n;
}

static void test_same_bytes_for_any_thread_count(void)
{
    enum { CELLS = 6 };
    float *tets = malloc(sizeof(float) * 12 * 7 * CELLS * CELLS * CELLS);
    if (!tets) return;
    size_t n = kuhn_block(tets, CELLS);
    fm_render_opts o = fm_default_render_opts();
    o.width = 320, o.height = 200, o.samples = 2;
    /* By index, and by a value that varies from tet to tet (what --color speed draws). */
    float *values = malloc(sizeof(float) * n);
    for (size_t i = 0; values && i < n; i++) values[i] = (float)sin(0.37 * (double)i) * 3.0f;
    const fm_render_colours by_value = {FM_COLOUR_VALUE, values, -2.0, 2.5, NULL};
    for (int mode = 0; mode < 2 && values; mode++) {
        rgb_image im[3];
        for (int i = 0; i < 3; i++) {
            o.threads = i + 1;
            im[i] = render_coloured(tets, n, 0, mode ? &by_value : NULL, &o);
        }
        if (im[0].rgb && im[1].rgb && im[2].rgb) {
            coverage c = cover(&im[0]);
            ENSURE_MSG(c.fg > 320 * 200 / 4, "only %ld pixels drawn", c.fg);
            size_t bytes = 3 * 320 * 200;
            ENSURE_MSG(memcmp(im[0].rgb, im[1].rgb, bytes) == 0, "mode %d: 1 and 2 threads differ", mode);
            ENSURE_MSG(memcmp(im[0].rgb, im[2].rgb, bytes) == 0, "mode %d: 1 and 3 threads differ", mode);
        }
        for (int i = 0; i < 3; i++) free(im[i].rgb);
    }
    free(values);
    free(tets);
}

/* ---------------------------------------------------------------- points */

/* Three points of radius 0.1 seen from the front: three discs of radius 0.1 x scale pixels at the
 * projected centres, and nothing else. */
static void test_points_are_spheres(void)
{
    fm_render_opts o = front_opts();
    o.width = 400, o.height = 400;
    o.point_radius = 0.1;
    const float pts[9] = {-0.5f, 0.0f, 0.5f, 0.5f, 0.3f, 0.5f, 0.0f, -0.2f, -0.5f};
    rgb_image im = render(pts, 3, 1, &o);
    if (!im.rgb) return;
    double rpx = 0.1 * box_scale(&o, 2, 2);
    long inside[3] = {0, 0, 0}, stray = 0;
    for (int y = 0; y < im.height; y++)
        for (int x = 0; x < im.width; x++) {
            if (!is_fg(&im, x, y)) continue;
            int which = -1;
            for (int i = 0; i < 3; i++) {
                double dx = x + 0.5 - px_of(&o, pts[3 * i]), dy = y + 0.5 - py_of(&o, pts[3 * i + 2]);
                if (sqrt(dx * dx + dy * dy) <= rpx + 1.0) which = i;
            }
            if (which < 0) stray++;
            else inside[which]++;
        }
    double disc = 3.14159265358979 * rpx * rpx;
    ENSURE_MSG(stray == 0, "%ld pixels outside the discs", stray);
    for (int i = 0; i < 3; i++)
        ENSURE_MSG(fabs((double)inside[i] - disc) < 0.05 * disc, "disc %d: %ld pixels, expected %.0f",
                   i, inside[i], disc);
    /* Lit from the upper left: the disc's upper-left part is brighter than its lower right. */
    int cx = (int)px_of(&o, pts[0]), cy = (int)py_of(&o, pts[2]), d = (int)(0.5 * rpx);
    ENSURE(brightness(&im, cx - d, cy - d) > brightness(&im, cx + d, cy + d) + 30);
    free(im.rgb);
}

/* 0.45 x the median nearest-neighbour distance: on a 3D lattice, a plane lattice and a line. */
static void test_point_radius(void)
{
    enum { SIDE = 12 };
    float *p = malloc(sizeof(float) * 3 * SIDE * SIDE * SIDE);
    if (!p) return;
    size_t n = 0;
    for (int i = 0; i < SIDE * SIDE * SIDE; i++, n++) {
        p[3 * n] = 0.5f * (float)(i % SIDE) + 3.0f;
        p[3 * n + 1] = 0.5f * (float)(i / SIDE % SIDE);
        p[3 * n + 2] = 0.5f * (float)(i / (SIDE * SIDE)) - 7.0f;
    }
    ENSURE_NEAR(fm_render_point_radius(p, n), 0.225, 1e-6);
    for (size_t i = 0; i < n; i++) p[3 * i + 2] = 0.0f, p[3 * i + 1] *= 0.25f; /* a 12 x 12 plane */
    ENSURE_NEAR(fm_render_point_radius(p, SIDE * SIDE), 0.45 * 0.125, 1e-6);
    p[0] = NAN; /* ignored */
    ENSURE_NEAR(fm_render_point_radius(p, SIDE), 0.225, 1e-6); /* a line of spacing 0.5 */
    const float two[6] = {0, 0, 0, 2, 0, 0};
    ENSURE_NEAR(fm_render_point_radius(two, 2), 0.9, 1e-6);
    ENSURE_NEAR(fm_render_point_radius(two, 1), 1.0, 0.0);
    free(p);
}

/* ---------------------------------------------------------------- robustness and PNG */

/* NaN and infinite tets are skipped, degenerate ones draw nothing, and no geometry at all gives
 * the background. */
static void test_nan_degenerate_and_empty(void)
{
    fm_render_opts o = front_opts();
    o.width = 200, o.height = 120;
    float scene[36];
    make_tet(scene, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4);
    for (int k = 0; k < 12; k++) scene[12 + k] = NAN;
    for (int k = 0; k < 12; k++) scene[24 + k] = 0.25f; /* four equal vertices */
    scene[12 + 4] = INFINITY;
    rgb_image all = render(scene, 3, 0, &o), first = render(scene, 1, 0, &o);
    if (all.rgb && first.rgb)
        ENSURE_MSG(memcmp(all.rgb, first.rgb, 3 * 200 * 120) == 0,
                   "the NaN and the degenerate tet changed the picture");
    free(all.rgb), free(first.rgb);
    o.bounds = NULL;
    o.ground = 1;
    rgb_image none = render(scene + 12, 1, 0, &o);
    if (none.rgb) ENSURE_MSG(cover(&none).fg == 0, "only a NaN tet, yet something was drawn");
    free(none.rgb);
    rgb_image empty = render(NULL, 0, 1, &o);
    if (empty.rgb) ENSURE(cover(&empty).fg == 0 && brightness(&empty, 0, 0) < 3 * 80);
    free(empty.rgb);
}

/* fm_render_tets_png writes what the renderer drew, as an 8-bit RGB PNG, through .partial. */
static void test_png_matches_buffer(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.width = 160, o.height = 90;
    float tet[12];
    make_tet(tet, 0.0, 0.0, 0.0, 0.3, 0.5, 0.4);
    char path[512], partial[600];
    tmp_path(path, sizeof path, "tet.png");
    snprintf(partial, sizeof partial, "%s.partial", path);
    remove(path);
    fm_error err = {0};
    ENSURE_MSG(fm_render_tets_png(tet, 1, &o, path, &err) == FM_OK, "%s", err.message);
    ENSURE(!file_exists(partial));
    rgb_image png, drawn = render(tet, 1, 0, &o);
    int rc = read_png(path, &png);
    ENSURE_MSG(rc == 0, "cannot read %s back (%d)", path, rc);
    if (rc == 0 && drawn.rgb) {
        ENSURE(png.width == 160 && png.height == 90);
        ENSURE_MSG(cover(&png).fg > 500, "the PNG is nearly empty");
        ENSURE_MSG(memcmp(png.rgb, drawn.rgb, 3 * 160 * 90) == 0, "the PNG differs from the drawing");
    }
    free(png.rgb), free(drawn.rgb);
    const float pts[3] = {0, 0, 0};
    tmp_path(path, sizeof path, "point.png");
    ENSURE_MSG(fm_render_points_png(pts, 1, &o, path, &err) == FM_OK, "%s", err.message);
    rc = read_png(path, &png);
    ENSURE(rc == 0 && cover(&png).fg > 500);
    free(png.rgb);
}

static void test_errors(void)
{
    float tet[12];
    make_tet(tet, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4);
    fm_render_opts o = fm_default_render_opts();
    char path[512], partial[600];
    tmp_path(path, sizeof path, "no_such_dir/out.png");
    snprintf(partial, sizeof partial, "%s.partial", path);
    fm_error err = {0};
    fm_status s = fm_render_tets_png(tet, 1, &o, path, &err);
    ENSURE_MSG(s == FM_ERR_IO && strstr(err.message, path) && strstr(err.message, "No such file"),
               "status %d: %s", (int)s, err.message);
    ENSURE(!file_exists(path) && !file_exists(partial));

    tmp_path(path, sizeof path, "badopts.png");
    remove(path);
    enum { BAD = 9 };
    fm_render_opts bad[BAD];
    for (int i = 0; i < BAD; i++) bad[i] = o;
    const double inverted[6] = {0, 0, 0, -1, 1, 1};
    bad[0].width = 0;
    bad[1].up[0] = bad[1].view_dir[0], bad[1].up[1] = bad[1].view_dir[1], bad[1].up[2] = bad[1].view_dir[2];
    bad[2].margin = 0.5;
    bad[3].view_dir[0] = bad[3].view_dir[1] = bad[3].view_dir[2] = 0.0;
    bad[4].fov_deg = 0.0;
    bad[5].samples = 9;
    bad[6].point_radius = -1.0;
    bad[7].bounds = inverted;
    bad[8].light_dir[0] = NAN;
    for (int i = 0; i < BAD; i++) {
        s = fm_render_tets_png(tet, 1, &bad[i], path, &err);
        ENSURE_MSG(s == FM_ERR_USAGE, "bad option set %d: status %d", i, (int)s);
        ENSURE(!file_exists(path));
        ENSURE(fm_renderer_create(&bad[i], &err) == NULL);
    }
    ENSURE(fm_write_png(NULL, 4, 4, path, &err) == FM_ERR_USAGE && !file_exists(path));
    fm_renderer *r = fm_renderer_create(&o, &err);
    ENSURE(r != NULL);
    unsigned char px[3];
    ENSURE(fm_renderer_draw_tets(r, NULL, 5, px, &err) == FM_ERR_USAGE);
    ENSURE(fm_renderer_draw_points(r, tet, 1, NULL, &err) == FM_ERR_USAGE);
    fm_renderer_destroy(r);
    ENSURE(fm_video_open(path, 65, 48, 24, &err) == NULL && err.status == FM_ERR_USAGE);
    ENSURE(fm_video_open(path, 64, 48, 0, &err) == NULL && err.status == FM_ERR_USAGE);
}

/* ---------------------------------------------------------------- the CLI: MP4 and its errors */

#define FRAMES 10
#define AGENTS 12

static char g_err[1 << 14]; /* the last command's stderr */

/* Runs `[ENV] flockmorph ARGS`; returns its exit status (-1 if it did not exit normally). */
static int cli(const char *env, const char *args)
{
    char err_path[512], cmd[4096];
    tmp_path(err_path, sizeof err_path, "stderr.txt");
    snprintf(cmd, sizeof cmd, "%s '%s' %s >/dev/null 2>'%s'", env, FM_CLI, args, err_path);
    int status = system(cmd);
    g_err[0] = 0;
    FILE *f = fopen(err_path, "rb");
    if (f) g_err[fread(g_err, 1, sizeof g_err - 1, f)] = 0, fclose(f);
    return status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

#define ENSURE_EXIT(env, args, code)                                                            \
    do {                                                                                        \
        int rc_ = cli(env, args);                                                               \
        ENSURE_MSG(rc_ == (code), "flockmorph %s: exit %d, expected %d\nstderr: %s", (args), rc_, \
                   (code), g_err);                                                              \
    } while (0)

/* A cache of AGENTS tets in a row drifting up by 0.1 per frame, at 24 frames per second. */
static int write_cache(const char *path)
{
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(path, AGENTS, 24.0, 1, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return -1;
    float tets[12 * AGENTS];
    for (int f = 0; f < FRAMES; f++) {
        for (int a = 0; a < AGENTS; a++) make_tet(tets + 12 * a, a - 6.0, 0.0, 0.1 * f, 0.4, 0.4, 0.5);
        ENSURE(fm_cache_writer_add_frame(w, tets, &err) == FM_OK);
    }
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    return 0;
}

/* Video frames that ffprobe decodes from the file; -1 if it cannot tell. */
static long probe_frames(const char *path)
{
    char cmd[1024], line[64] = "";
    snprintf(cmd, sizeof cmd,
             "ffprobe -v error -count_frames -select_streams v:0 -show_entries stream=nb_read_frames "
             "-of csv=p=0 '%s' 2>/dev/null", path);
    FILE *p = popen(cmd, "r");
    if (!p) return -1;
    char *got = fgets(line, sizeof line, p);
    int status = pclose(p);
    return got && status == 0 ? strtol(line, NULL, 10) : -1;
}

/* The colour tags ffprobe reads from the video stream: "range,space,transfer,primaries". */
static void probe_colour(const char *path, char *out, size_t size)
{
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "ffprobe -v error -select_streams v:0 -show_entries "
             "stream=color_range,color_space,color_transfer,color_primaries -of csv=p=0 '%s' 2>/dev/null", path);
    FILE *p = popen(cmd, "r");
    out[0] = 0;
    if (p && fgets(out, (int)size, p)) out[strcspn(out, "\n")] = 0;
    if (p) pclose(p);
}

/* The MP4's top-level boxes in file order (4 letters each, space-separated), from their headers:
 * a 32-bit big-endian size and the type, the size 1 meaning a 64-bit size follows. */
static void top_level_boxes(const char *path, char *out, size_t size)
{
    FILE *f = fopen(path, "rb");
    unsigned char h[16];
    out[0] = 0;
    for (long at = 0; f && fseek(f, at, SEEK_SET) == 0 && fread(h, 1, 16, f) >= 8 && strlen(out) + 6 < size;) {
        uint64_t len = (uint64_t)h[0] << 24 | (uint64_t)h[1] << 16 | (uint64_t)h[2] << 8 | h[3];
        if (len == 1) {
            len = 0;
            for (int k = 8; k < 16; k++) len = len << 8 | h[k];
        }
        snprintf(out + strlen(out), size - strlen(out), "%s%.4s", out[0] ? " " : "", (const char *)h + 4);
        if (len < 8) break;
        at += (long)len;
    }
    if (f) fclose(f);
}

static void test_cli_mp4(void)
{
    char cache[512], out[512], partial[600], args[2048];
    tmp_path(cache, sizeof cache, "drift.fmc");
    tmp_path(out, sizeof out, "drift.mp4");
    snprintf(partial, sizeof partial, "%s.partial", out);
    if (write_cache(cache)) return;
    remove(out);
    snprintf(args, sizeof args, "render '%s' -o '%s' --frames 2:6 --size 64x48", cache, out);
    ENSURE_EXIT("", args, 0);
    ENSURE_MSG(probe_frames(out) == 5, "ffprobe counts %ld frames, 5 asked for", probe_frames(out));
    ENSURE(!file_exists(partial));
    /* tagged BT.709, TV range, and the index (moov) before the frames (mdat): plays while it loads */
    char tags[256], boxes[256];
    probe_colour(out, tags, sizeof tags);
    ENSURE_MSG(!strcmp(tags, "tv,bt709,bt709,bt709"), "colour tags '%s'", tags);
    top_level_boxes(out, boxes, sizeof boxes);
    const char *moov = strstr(boxes, "moov"), *mdat = strstr(boxes, "mdat");
    ENSURE_MSG(moov && mdat && moov < mdat, "top-level boxes '%s': moov is not before mdat", boxes);
    snprintf(args, sizeof args, "render '%s' -o '%s' --size 64x48 --view front --fps 12", cache, out);
    ENSURE_EXIT("", args, 0);
    ENSURE_MSG(probe_frames(out) == FRAMES, "all frames: ffprobe counts %ld", probe_frames(out));
    snprintf(args, sizeof args, "render '%s' -o '%s' --frames -3: --size 64x48", cache, out);
    ENSURE_EXIT("", args, 0);
    ENSURE_MSG(probe_frames(out) == 3, "the last 3: ffprobe counts %ld", probe_frames(out));
    /* A directory that does not exist: an I/O error before anything is rendered. */
    tmp_path(out, sizeof out, "no_such_dir/drift.mp4");
    snprintf(args, sizeof args, "render '%s' -o '%s' --size 64x48", cache, out);
    ENSURE_EXIT("", args, 3);
    ENSURE_MSG(strstr(g_err, "No such file") != NULL, "%s", g_err);
}

/* ffmpeg missing (PATH holds an empty directory) or failing (a stand-in that prints and exits 1):
 * exit 3, a message that names ffmpeg and quotes what it said, and no file. */
static void test_cli_mp4_without_ffmpeg(void)
{
    char cache[512], out[512], partial[600], args[2048], dir[512], env[1024], fake[600];
    tmp_path(cache, sizeof cache, "drift.fmc");
    tmp_path(out, sizeof out, "noffmpeg.mp4");
    snprintf(partial, sizeof partial, "%s.partial", out);
    tmp_path(dir, sizeof dir, "empty_bin");
    mkdir(dir, 0777);
    remove(out);
    snprintf(args, sizeof args, "render '%s' -o '%s' --size 64x48", cache, out);
    snprintf(env, sizeof env, "PATH='%s'", dir);
    ENSURE_EXIT(env, args, 3);
    ENSURE_MSG(strstr(g_err, "ffmpeg") && strstr(g_err, "not installed"), "%s", g_err);
    ENSURE(!file_exists(out) && !file_exists(partial));

    tmp_path(dir, sizeof dir, "broken_bin");
    mkdir(dir, 0777);
    snprintf(fake, sizeof fake, "%s/ffmpeg", dir);
    FILE *f = fopen(fake, "w");
    ENSURE(f != NULL);
    if (!f) return;
    fputs("#!/bin/sh\necho 'Unknown encoder libx264 (stand-in)' >&2\nexit 1\n", f);
    fclose(f);
    chmod(fake, 0755);
    snprintf(env, sizeof env, "PATH='%s:/usr/bin:/bin'", dir);
    ENSURE_EXIT(env, args, 3);
    ENSURE_MSG(strstr(g_err, "ffmpeg") && strstr(g_err, "Unknown encoder libx264 (stand-in)"),
               "%s", g_err);
    ENSURE(!file_exists(out) && !file_exists(partial));
}

/* A disk that fills while ffmpeg writes (a file-size limit of 2 KiB that ffmpeg inherits): ffmpeg
 * logs the failed write and still exits 0, with an MP4 that has no index (issue 42). The render
 * must fail (exit 3, saying the file is incomplete) and leave no file, under either name. */
static void test_cli_mp4_disk_full(void)
{
    char cache[512], out[512], partial[600], args[2048];
    tmp_path(cache, sizeof cache, "drift.fmc");
    tmp_path(out, sizeof out, "full.mp4");
    snprintf(partial, sizeof partial, "%s.partial", out);
    remove(out);
    snprintf(args, sizeof args, "render '%s' -o '%s' --size 256x192", cache, out);
    ENSURE_EXIT("ulimit -f 2;", args, 3);
    ENSURE_MSG(strstr(g_err, out) && strstr(g_err, "incomplete"), "%s", g_err);
    ENSURE(!file_exists(out) && !file_exists(partial));
}

static void test_cli_usage_errors(void)
{
    char cache[512], out[512], args[2048];
    tmp_path(cache, sizeof cache, "drift.fmc");
    static const struct {
        const char *out, *opts, *says;
    } cases[] = {{"x.gif", "", ".png or .mp4"},
                 {"x.mp4", "--frame 3", "--frames"},
                 {"x.mp4", "--size 65x48", "even"},
                 {"x.png", "--frames 1:2", "--frame K"},
                 {"x.mp4", "--frames 6:2", "empty"},
                 {"x.mp4", "--frames 2:99", "has 10 frames"},
                 {"x.mp4", "--frames a:b", "--frames"},
                 {"x.mp4", "--fps -1", "--fps"},
                 {"x.png", "--view diagonal", "persp"},
                 {"x.png", "--samples 0", "--samples"},
                 {"x.png", "--radius 0", "--radius"},
                 {"x.png", "--color foo", "--color is speed, phase or id, not 'foo'"},
                 {"x.png", "--color-range 3:1", "--color-range wants LO:HI"},
                 {"x.png", "--color-range 1:1", "--color-range wants LO:HI"},
                 {"x.png", "--color-range a:2", "--color-range wants LO:HI"},
                 {"x.png", "--color-range 2", "--color-range wants LO:HI"},
                 {"x.png", "--color-range 0:inf", "--color-range wants LO:HI"},
                 {"x.png", "--color-range 0:1x", "--color-range wants LO:HI"},
                 {"x.png", "--color id --color-range 0:1", "--color-range 0:1 sets the scale of --color speed"},
                 {"x.png", "--color phase", "--color phase"}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        tmp_path(out, sizeof out, cases[i].out);
        remove(out);
        snprintf(args, sizeof args, "render '%s' -o '%s' %s", cache, out, cases[i].opts);
        ENSURE_EXIT("", args, 1);
        ENSURE_MSG(strstr(g_err, cases[i].says), "%s: '%s' not in: %s", cases[i].opts, cases[i].says, g_err);
        ENSURE(!file_exists(out));
    }
}

/* The CLI's PNG: the default perspective view with the ground, camera fitted to all frames. */
static void test_cli_png(void)
{
    char cache[512], out[512], args[2048];
    tmp_path(cache, sizeof cache, "drift.fmc");
    tmp_path(out, sizeof out, "drift.png");
    remove(out);
    snprintf(args, sizeof args, "render '%s' -o '%s' --frame 0 --size 200x120 --threads 2", cache, out);
    ENSURE_EXIT("", args, 0);
    rgb_image im;
    ENSURE(read_png(out, &im) == 0 && im.width == 200 && im.height == 120);
    if (im.rgb) ENSURE_MSG(cover(&im).fg > 200 * 120 / 4, "the ground and tets cover too little");
    free(im.rgb);
}

/* ---------------------------------------------------------------- the CLI: the shot (issue 14) */

#define TRAVEL_FRAMES 48
#define TRAVEL_DIR FM_TEST_TMP "/render_shot"

/* A flock of 8 tets in a 2 x 2 x 2 block that travels from x = -20 to x = 20 at 24 frames per
 * second, in a directory of its own (an obstacles.ply there is drawn with it). */
static int write_travel_cache(const char *path)
{
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(path, 8, 24.0, 1, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return -1;
    float tets[12 * 8];
    for (int f = 0; f < TRAVEL_FRAMES; f++) {
        double x = -20.0 + 40.0 * f / (TRAVEL_FRAMES - 1);
        for (int a = 0; a < 8; a++)
            make_tet(tets + 12 * a, x + 0.8 * (a & 1), 0.8 * (a >> 1 & 1), 0.8 * (a >> 2 & 1), 0.4, 0.4, 0.5);
        ENSURE(fm_cache_writer_add_frame(w, tets, &err) == FM_OK);
    }
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    return 0;
}

/* Renders `flockmorph render CACHE -o TRAVEL_DIR/NAME OPTS` and reads the PNG back (rgb NULL if
 * it failed). */
static rgb_image cli_png(const char *cache, const char *name, const char *opts)
{
    char out[512], args[2048];
    snprintf(out, sizeof out, "%s/%s", TRAVEL_DIR, name);
    remove(out);
    snprintf(args, sizeof args, "render '%s' -o '%s' %s", cache, out, opts);
    ENSURE_EXIT("", args, 0);
    rgb_image im = {0, 0, NULL};
    ENSURE_MSG(read_png(out, &im) == 0, "cannot read %s", out);
    return im;
}

static long box_area(const coverage *c) { return c->fg ? (long)(c->x1 - c->x0 + 1) * (c->y1 - c->y0 + 1) : 0; }

/* The camera follows the flock: at the first frame and half-way, the flock (without the ground)
 * fills a far larger part of the picture than under --camera animation, which sees the whole
 * 40-unit trip, and sits in the middle of it. */
static void test_cli_camera_frames_the_shot(void)
{
    char cache[512];
    mkdir(TRAVEL_DIR, 0777);
    snprintf(cache, sizeof cache, "%s/travel.fmc", TRAVEL_DIR);
    if (write_travel_cache(cache)) return;
    for (int k = 0; k < 2; k++) {
        const char *frame = k ? "--frame 24" : "--frame 0";
        char opts[256];
        snprintf(opts, sizeof opts, "%s --size 200x120 --no-ground --camera frame", frame);
        rgb_image near = cli_png(cache, "near.png", opts);
        snprintf(opts, sizeof opts, "%s --size 200x120 --no-ground --camera animation", frame);
        rgb_image far = cli_png(cache, "far.png", opts);
        if (near.rgb && far.rgb) {
            coverage n = cover(&near), f = cover(&far);
            ENSURE_MSG(box_area(&n) > 8 * box_area(&f), "%s: the flock's box covers %ld pixels following it, %ld "
                       "fitted to the animation", frame, box_area(&n), box_area(&f));
            ENSURE_MSG(n.y1 - n.y0 + 1 > 120 / 2, "%s: the flock is %d of 120 pixels tall", frame, n.y1 - n.y0 + 1);
            double mx = 0.5 * (n.x0 + n.x1) / 200.0, my = 0.5 * (n.y0 + n.y1) / 120.0;
            ENSURE_MSG(fabs(mx - 0.5) < 0.1 && fabs(my - 0.5) < 0.1, "%s: the flock's centre is at (%.2f, %.2f) of "
                       "the picture", frame, mx, my);
        }
        free(near.rgb), free(far.rgb);
    }
}

/* --camera animation is the camera of before: the same bytes as the C API's renderer fitted to
 * the bounds of every frame (what render did), coloured by index as --color id. */
static void test_cli_camera_animation_is_the_old_camera(void)
{
    char cache[512];
    snprintf(cache, sizeof cache, "%s/travel.fmc", TRAVEL_DIR);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(cache, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    float tets[12 * 8], frame5[12 * 8];
    double b[6] = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
    for (uint32_t f = 0; f < fm_cache_frames(r); f++) {
        ENSURE(fm_cache_read_frame(r, f, tets, &err) == FM_OK);
        if (f == 5) memcpy(frame5, tets, sizeof tets);
        for (int i = 0; i < 12 * 8; i++) b[i % 3] = fmin(b[i % 3], tets[i]), b[3 + i % 3] = fmax(b[3 + i % 3], tets[i]);
    }
    fm_cache_close(r);
    fm_render_opts o = fm_default_render_opts();
    o.width = 200, o.height = 120, o.bounds = b;
    rgb_image old = render(frame5, 8, 0, &o);
    rgb_image now = cli_png(cache, "animation.png", "--frame 5 --size 200x120 --camera animation --color id");
    ENSURE(old.rgb && now.rgb && memcmp(old.rgb, now.rgb, 3 * 200 * 120) == 0);
    free(old.rgb), free(now.rgb);
}

/* The default camera frames the whole shot: without obstacles it is --camera animation's, the
 * same bytes at the first and the last frame's time; with an obstacle near the path (the cube
 * below, beside the cache) it widens to take it in, where animation's does not. */
static void write_cube_ply(const char *path);

/* Obstacle-coloured pixels in the outermost rows and columns. */
static long obstacle_pixels_on_edge(const rgb_image *im)
{
    long n = 0;
    for (int y = 0; y < im->height; y++)
        for (int x = 0; x < im->width; x++)
            if (x == 0 || y == 0 || x == im->width - 1 || y == im->height - 1) n += is_obstacle_colour(pixel(im, x, y));
    return n;
}

static void test_cli_default_camera_is_the_shot(void)
{
    char cache[512], beside[512];
    snprintf(cache, sizeof cache, "%s/travel.fmc", TRAVEL_DIR);
    snprintf(beside, sizeof beside, "%s/obstacles.ply", TRAVEL_DIR);
    remove(beside);
    for (int k = 0; k < 2; k++) {
        const char *frame = k ? "--frame -1 --size 200x120" : "--frame 0 --size 200x120";
        char opts[256];
        rgb_image shot = cli_png(cache, "shot.png", frame);
        snprintf(opts, sizeof opts, "%s --camera animation", frame);
        rgb_image whole = cli_png(cache, "whole.png", opts);
        snprintf(opts, sizeof opts, "%s --camera frame", frame);
        rgb_image follow = cli_png(cache, "follow.png", opts);
        ENSURE_MSG(shot.rgb && whole.rgb && !memcmp(shot.rgb, whole.rgb, 3 * 200 * 120), "%s: the default camera is "
                   "not the one fitted to every frame", frame);
        ENSURE_MSG(shot.rgb && follow.rgb && memcmp(shot.rgb, follow.rgb, 3 * 200 * 120), "%s: the default camera "
                   "follows the flock", frame);
        free(shot.rgb), free(whole.rgb), free(follow.rgb);
    }
    write_cube_ply(beside);
    const char *side = "--frame 24 --size 200x120 --view side --no-ground --color id";
    char opts[256];
    rgb_image shot = cli_png(cache, "shot.png", side);
    snprintf(opts, sizeof opts, "%s --camera animation", side);
    rgb_image whole = cli_png(cache, "whole.png", opts);
    if (shot.rgb && whole.rgb) {
        ENSURE_MSG(obstacle_pixels(&shot) > 0, "the shot's camera leaves out the cube near the path");
        ENSURE_MSG(obstacle_pixels_on_edge(&shot) == 0, "the shot's camera cuts the cube near the path (%ld "
                   "pixels of it on the picture's edge)", obstacle_pixels_on_edge(&shot));
        ENSURE_MSG(obstacle_pixels_on_edge(&whole) > 0, "the agents' camera alone takes in the cube: the test "
                   "shows nothing");
    }
    free(shot.rgb), free(whole.rgb);
    remove(beside);
}

/* --burn-in writes the scene's name, the frame and its time into a box at the bottom left: the
 * picture is the same outside it, white text inside; another frame says another thing; the name
 * comes from stats.json beside the cache (a longer one, a wider line). */
static void burnt_box(const rgb_image *plain, const rgb_image *burnt, coverage *changed, long *white)
{
    *changed = (coverage){0, plain->width, -1, plain->height, -1};
    *white = 0;
    for (int y = 0; y < plain->height; y++)
        for (int x = 0; x < plain->width; x++) {
            const unsigned char *a = pixel(plain, x, y), *b = pixel(burnt, x, y);
            if (!memcmp(a, b, 3)) continue;
            changed->fg++;
            changed->x0 = x < changed->x0 ? x : changed->x0, changed->x1 = x > changed->x1 ? x : changed->x1;
            changed->y0 = y < changed->y0 ? y : changed->y0, changed->y1 = y > changed->y1 ? y : changed->y1;
            *white += b[0] == 255 && b[1] == 255 && b[2] == 255;
        }
}

static void test_cli_burn_in(void)
{
    char cache[512], stats[512];
    snprintf(cache, sizeof cache, "%s/travel.fmc", TRAVEL_DIR);
    snprintf(stats, sizeof stats, "%s/stats.json", TRAVEL_DIR);
    remove(stats);
    coverage box[3];
    long white[3];
    for (int k = 0; k < 3; k++) {
        FILE *f = k == 2 ? fopen(stats, "w") : NULL;
        if (f) fputs("{\"scene\": \"scenes/a_rather_long_scene_name/scene.json\"}\n", f), fclose(f);
        const char *frame = k == 1 ? "--frame 17 --size 320x180" : "--frame 5 --size 320x180";
        char opts[256];
        rgb_image plain = cli_png(cache, "plain.png", frame);
        snprintf(opts, sizeof opts, "%s --burn-in", frame);
        rgb_image burnt = cli_png(cache, "burnt.png", opts);
        if (plain.rgb && burnt.rgb) burnt_box(&plain, &burnt, &box[k], &white[k]);
        free(plain.rgb), free(burnt.rgb);
        if (!plain.rgb || !burnt.rgb) return;
        ENSURE_MSG(box[k].x0 < 10 && box[k].y1 > 170 && box[k].y0 > 150 && white[k] > 100, "%s: the burn-in changes "
                   "x %d..%d, y %d..%d, %ld white pixels: not a line of text at the bottom left", frame, box[k].x0,
                   box[k].x1, box[k].y0, box[k].y1, white[k]);
    }
    remove(stats);
    ENSURE_MSG(box[1].x1 > box[0].x1, "frame 17's line (to x %d) is no longer than frame 5's (to x %d)", box[1].x1, box[0].x1);
    ENSURE_MSG(box[2].x1 > box[0].x1 + 60, "the scene named in stats.json (line to x %d) is not in the line (travel's "
               "folder: to x %d)", box[2].x1, box[0].x1);
}

/* A cube |x + 20| <= 2, 1.5 <= y <= 3, |z| <= 2 behind the flock's start. */
static void write_cube_ply(const char *path)
{
    double v[8 * 3];
    for (int i = 0; i < 8; i++)
        v[3 * i] = i & 1 ? -18 : -22, v[3 * i + 1] = i & 2 ? 3 : 1.5, v[3 * i + 2] = i & 4 ? 2 : -2;
    static const int32_t tri[] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                  2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    const fm_ply_mesh cube = {"cube", v, 8, tri, 12};
    fm_error err = {0};
    ENSURE_MSG(fm_export_ply_meshes(&cube, 1, NULL, path, &err) == FM_OK, "%s", err.message);
}

/* obstacles.ply beside the cache is drawn in the obstacle colour (seen from the front it fills
 * the picture behind the flock); --no-obstacles leaves it out; --obstacles FILE draws another
 * file; a missing one is an input error that names it; the bytes do not depend on the threads. */
static void test_cli_obstacles(void)
{
    char cache[512], beside[512], other[512], args[2048];
    snprintf(cache, sizeof cache, "%s/travel.fmc", TRAVEL_DIR);
    snprintf(beside, sizeof beside, "%s/obstacles.ply", TRAVEL_DIR);
    tmp_path(other, sizeof other, "cube.ply");
    write_cube_ply(beside);
    write_cube_ply(other);
    const char *front = "--frame 0 --size 200x120 --view front --no-ground --color id --camera frame";
    char opts[1024];
    rgb_image with = cli_png(cache, "with.png", front);
    snprintf(opts, sizeof opts, "%s --no-obstacles", front);
    rgb_image without = cli_png(cache, "without.png", opts);
    snprintf(opts, sizeof opts, "%s --obstacles '%s' --threads 1", front, other);
    rgb_image named = cli_png(cache, "named.png", opts);
    snprintf(opts, sizeof opts, "%s --threads 2", front);
    rgb_image two = cli_png(cache, "two.png", opts);
    if (with.rgb && without.rgb) {
        ENSURE_MSG(obstacle_pixels(&with) > 200 * 120 / 3, "%ld obstacle pixels", obstacle_pixels(&with));
        ENSURE_MSG(is_obstacle_colour(pixel(&with, 3, 3)), "the corner is (%d %d %d), not the cube behind",
                   pixel(&with, 3, 3)[0], pixel(&with, 3, 3)[1], pixel(&with, 3, 3)[2]);
        ENSURE_MSG(obstacle_pixels(&without) == 0, "--no-obstacles: %ld obstacle pixels", obstacle_pixels(&without));
        ENSURE(cover(&without).fg > 0); /* the flock is there */
    }
    ENSURE(with.rgb && named.rgb && memcmp(with.rgb, named.rgb, 3 * 200 * 120) == 0);
    ENSURE(with.rgb && two.rgb && memcmp(with.rgb, two.rgb, 3 * 200 * 120) == 0);
    free(with.rgb), free(without.rgb), free(named.rgb), free(two.rgb);

    snprintf(args, sizeof args, "render '%s' -o '%s/x.png' --obstacles '%s/no_such.ply'", cache, TRAVEL_DIR, TRAVEL_DIR);
    ENSURE_EXIT("", args, 2);
    ENSURE_MSG(strstr(g_err, "--obstacles") && strstr(g_err, "no_such.ply") && strstr(g_err, "No such file"), "%s", g_err);
    snprintf(args, sizeof args, "render '%s' -o '%s/x.png' --obstacles '%s' --no-obstacles", cache, TRAVEL_DIR, other);
    ENSURE_EXIT("", args, 1);
    snprintf(args, sizeof args, "render '%s' -o '%s/x.png' --camera orbit", cache, TRAVEL_DIR);
    ENSURE_EXIT("", args, 1);
    ENSURE_MSG(strstr(g_err, "--camera is shot, frame or animation, not 'orbit'"), "%s", g_err);
    FILE *f = fopen(beside, "w"); /* beside the cache but not a mesh: refused, with the way out */
    if (f) fputs("not a mesh\n", f), fclose(f);
    snprintf(args, sizeof args, "render '%s' -o '%s/x.png'", cache, TRAVEL_DIR);
    ENSURE_EXIT("", args, 2);
    ENSURE_MSG(strstr(g_err, "obstacles.ply") && strstr(g_err, "--no-obstacles"), "%s", g_err);
    remove(beside);
    ENSURE_EXIT("", args, 0); /* none beside the cache: silently fine */
}

int main(void)
{
    RUN_TEST(test_defaults_and_views);
    RUN_TEST(test_front_view_inside_projected_box);
    RUN_TEST(test_perspective_fit);
    RUN_TEST(test_gradient_over_agents);
    RUN_TEST(test_colormap_and_palette);
    RUN_TEST(test_values_on_the_map);
    RUN_TEST(test_bad_colours);
    RUN_TEST(test_shadow_on_ground);
    RUN_TEST(test_obstacles_drawn_with_shadows);
    RUN_TEST(test_obstacle_and_bounds_errors);
    RUN_TEST(test_same_bytes_for_any_thread_count);
    RUN_TEST(test_points_are_spheres);
    RUN_TEST(test_point_radius);
    RUN_TEST(test_nan_degenerate_and_empty);
    RUN_TEST(test_png_matches_buffer);
    RUN_TEST(test_errors);
    RUN_TEST(test_cli_mp4);
    RUN_TEST(test_cli_mp4_without_ffmpeg);
    RUN_TEST(test_cli_mp4_disk_full);
    RUN_TEST(test_cli_usage_errors);
    RUN_TEST(test_cli_png);
    RUN_TEST(test_cli_camera_frames_the_shot);
    RUN_TEST(test_cli_camera_animation_is_the_old_camera);
    RUN_TEST(test_cli_default_camera_is_the_shot);
    RUN_TEST(test_cli_burn_in);
    RUN_TEST(test_cli_obstacles);
    return test_result();
}
