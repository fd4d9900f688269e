/* The preview renderer: Embree 3 ray casting of a frame's tets (4 triangles each) or points
 * (spheres) and of static obstacle triangles (fm_renderer_set_obstacles), Lambert shading with one key light and hard shadows, a ground plane under the bounds,
 * a colour per agent (render_colour.c: by index, by value or given), sRGB output. docs/render.md
 * describes it.
 *
 * Camera. The image's right axis is normalize(view_dir x up) and its up axis right x view_dir, so
 * looking along +Y with up +Z puts +X on the right and +Z at the top. A point p lands on the image
 * plane at (s, t) = (p.right, p.up) (orthographic) or (q.right, q.up) / q.fwd with q = p - eye
 * (perspective, the eye at the bounds' centre pulled back until the bounding sphere fills fov_deg).
 * The bounds' eight corners are fitted into the image, keeping the aspect ratio and leaving
 * margin x width/height free on each side; pixel (x, y) is the plane point
 * (s_mid + (x - W/2) / scale, t_mid - (y - H/2) / scale).
 *
 * Determinism. Each pixel is computed by one thread from fixed rays, and the BVH is built on one
 * Embree thread ("threads=1"), so ties between coincident faces (neighbouring tets share faces)
 * are broken the same way whatever the thread count: the image bytes do not depend on it. */
#define _POSIX_C_SOURCE 200809L
#include "render.h"

#include <embree3/rtcore.h>

#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FM_RENDER_MAX_SAMPLES 8
#define FM_RENDER_PI 3.14159265358979323846

/* Colours in sRGB (converted to linear light once). */
static const double fm_background_srgb[3] = {0.118, 0.129, 0.157};
static const double fm_ground_srgb[3] = {0.62, 0.62, 0.64};
/* Obstacles: a light warm grey, lighter and warmer than the ground and the grey of unknown values,
 * and far from every agent colour (the index gradient, viridis, the phase palette). */
static const double fm_obstacle_srgb[3] = {0.84, 0.80, 0.74};
static const double fm_ambient = 0.28; /* linear light that reaches surfaces in shadow */
static const double fm_key = 0.85;     /* the key light's strength */

/* ---------------------------------------------------------------- small vector helpers */

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

/* Normalises v in place; returns its original length (v is left alone when that is 0 or not finite). */
static double normalize3(double v[3])
{
    double len = sqrt(dot3(v, v));
    if (len > 0.0 && isfinite(len))
        for (int k = 0; k < 3; k++) v[k] /= len;
    return len;
}

static int finite_nonzero3(const double v[3])
{
    double len = sqrt(dot3(v, v));
    return isfinite(len) && len > 0.0;
}

/* ---------------------------------------------------------------- colour */

/* edge[v] = the linear value at which the 8-bit sRGB code reaches v (edge[0] = -inf), so that
 * encoding is a search instead of a pow() per channel. */
static void srgb_edges(float edge[256])
{
    edge[0] = -INFINITY;
    for (int v = 1; v < 256; v++) edge[v] = (float)fm_srgb_to_linear((v - 0.5) / 255.0);
}

static unsigned char srgb_encode(const float edge[256], float linear)
{
    int lo = 0; /* largest v with edge[v] <= linear; NaN stays 0 */
    for (int step = 128; step > 0; step >>= 1)
        if (edge[lo + step] <= linear) lo += step;
    return (unsigned char)lo;
}

static void linear_colour(const double srgb[3], float out[3])
{
    for (int k = 0; k < 3; k++) out[k] = (float)fm_srgb_to_linear(srgb[k]);
}

/* ---------------------------------------------------------------- options and views */

fm_render_opts fm_default_render_opts(void)
{
    fm_render_opts o;
    memset(&o, 0, sizeof o);
    o.width = 960;
    o.height = 540;
    o.fov_deg = 40.0;
    o.margin = 0.05;
    o.bounds = NULL;
    o.world_up[2] = 1.0;
    o.ground = 1;
    o.point_radius = 0.0;
    o.samples = 1;
    o.threads = 0;
    fm_render_set_view(&o, "persp", NULL);
    return o;
}

typedef struct named_view {
    const char *name;
    double dir[3], up[3];
    int perspective;
} named_view;

/* "persp" looks from the front left, above: the classic 3/4 view of a scene standing on +Z. */
static const named_view fm_views[] = {{"persp", {0.5, 1.0, -0.4}, {0, 0, 1}, 1},
                                      {"front", {0, 1, 0}, {0, 0, 1}, 0},
                                      {"top", {0, 0, -1}, {0, 1, 0}, 0},
                                      {"side", {-1, 0, 0}, {0, 0, 1}, 0}};

fm_status fm_render_set_view(fm_render_opts *opts, const char *name, fm_error *err)
{
    for (size_t i = 0; i < sizeof fm_views / sizeof fm_views[0]; i++) {
        if (!name || strcmp(name, fm_views[i].name) != 0) continue;
        memcpy(opts->view_dir, fm_views[i].dir, sizeof opts->view_dir);
        memcpy(opts->up, fm_views[i].up, sizeof opts->up);
        opts->perspective = fm_views[i].perspective;
        return FM_OK;
    }
    return fm_fail(err, FM_ERR_USAGE, "render: view is persp, front, top or side, not '%s'",
                   name ? name : "(null)");
}

static fm_status check_opts(const fm_render_opts *o, fm_error *err)
{
    if (o->width < 1 || o->height < 1 || o->width > FM_RENDER_MAX_DIM ||
        o->height > FM_RENDER_MAX_DIM)
        return fm_fail(err, FM_ERR_USAGE, "render: image size %dx%d is outside 1..%d", o->width,
                       o->height, FM_RENDER_MAX_DIM);
    if (!(o->margin >= 0.0 && o->margin < 0.5))
        return fm_fail(err, FM_ERR_USAGE, "render: margin %g is outside [0, 0.5)", o->margin);
    if (!finite_nonzero3(o->view_dir) || !finite_nonzero3(o->up) || !finite_nonzero3(o->world_up))
        return fm_fail(err, FM_ERR_USAGE,
                       "render: view_dir, up and world_up must be finite and non-zero");
    if (!isfinite(dot3(o->light_dir, o->light_dir)))
        return fm_fail(err, FM_ERR_USAGE, "render: light_dir must be finite");
    double f[3], u[3], r[3];
    memcpy(f, o->view_dir, sizeof f), memcpy(u, o->up, sizeof u);
    normalize3(f), normalize3(u);
    cross3(f, u, r);
    if (!(sqrt(dot3(r, r)) > 1e-9))
        return fm_fail(err, FM_ERR_USAGE, "render: up is parallel to view_dir");
    if (o->perspective && !(o->fov_deg >= 1.0 && o->fov_deg <= 170.0))
        return fm_fail(err, FM_ERR_USAGE, "render: fov_deg %g is outside [1, 170]", o->fov_deg);
    if (!(o->point_radius >= 0.0 && isfinite(o->point_radius)))
        return fm_fail(err, FM_ERR_USAGE, "render: point radius %g is not a finite value >= 0",
                       o->point_radius);
    if (o->samples < 1 || o->samples > FM_RENDER_MAX_SAMPLES)
        return fm_fail(err, FM_ERR_USAGE, "render: samples %d is outside 1..%d", o->samples,
                       FM_RENDER_MAX_SAMPLES);
    if (o->bounds)
        for (int k = 0; k < 3; k++)
            if (!isfinite(o->bounds[k]) || !isfinite(o->bounds[k + 3]) ||
                o->bounds[k] > o->bounds[k + 3])
                return fm_fail(err, FM_ERR_USAGE,
                               "render: bounds must be finite [minx miny minz maxx maxy maxz]");
    return FM_OK;
}

/* ---------------------------------------------------------------- the renderer */

/* Static triangles drawn with every frame (fm_renderer_set_obstacles): the renderer's own copy. */
typedef struct obstacle_mesh {
    float *verts;      /* nv x 3 */
    uint32_t *tris;    /* nt x 3 */
    size_t nv, nt;
    double lo[3], hi[3];
} obstacle_mesh;

struct fm_renderer {
    fm_render_opts o;      /* o.bounds points at bounds below (or is NULL) */
    double bounds[6];
    RTCDevice device;
    char embree_error[256];
    float srgb_edge[256];
    float background[3], ground_albedo[3], obstacle_albedo[3]; /* linear */
    fm_colour_tables colours;
    obstacle_mesh obstacles;
};

static void on_embree_error(void *user, enum RTCError code, const char *str)
{
    fm_renderer *r = user;
    if (!r->embree_error[0])
        snprintf(r->embree_error, sizeof r->embree_error, "Embree error %d: %s", (int)code,
                 str ? str : "");
}

static fm_status renderer_create(const fm_render_opts *opts, fm_renderer **out, fm_error *err)
{
    *out = NULL;
    fm_render_opts defaults = fm_default_render_opts();
    const fm_render_opts *o = opts ? opts : &defaults;
    fm_status st = check_opts(o, err);
    if (st != FM_OK) return st;
    fm_renderer *r = calloc(1, sizeof *r);
    if (!r) return fm_fail(err, FM_ERR_MEMORY, "render: out of memory");
    r->o = *o;
    if (o->bounds) {
        memcpy(r->bounds, o->bounds, sizeof r->bounds);
        r->o.bounds = r->bounds;
    }
    /* One build thread: see the determinism note at the top. */
    r->device = rtcNewDevice("threads=1");
    if (!r->device) {
        free(r);
        const enum RTCError e = rtcGetDeviceError(NULL); /* reading it clears it */
        return fm_library_start_failed(err, "render: Embree's device", (int)e, e == RTC_ERROR_OUT_OF_MEMORY);
    }
    rtcSetDeviceErrorFunction(r->device, on_embree_error, r);
    srgb_edges(r->srgb_edge);
    linear_colour(fm_background_srgb, r->background);
    linear_colour(fm_ground_srgb, r->ground_albedo);
    linear_colour(fm_obstacle_srgb, r->obstacle_albedo);
    fm_colour_tables_init(&r->colours);
    *out = r;
    return FM_OK;
}

fm_renderer *fm_renderer_create(const fm_render_opts *opts, fm_error *err)
{
    fm_renderer *r;
    renderer_create(opts, &r, err);
    return r;
}

static void obstacles_free(obstacle_mesh *m)
{
    free(m->verts);
    free(m->tris);
    memset(m, 0, sizeof *m);
}

void fm_renderer_destroy(fm_renderer *r)
{
    if (!r) return;
    obstacles_free(&r->obstacles);
    rtcReleaseDevice(r->device);
    free(r);
}

fm_status fm_renderer_set_bounds(fm_renderer *r, const double *bounds, fm_error *err)
{
    if (!r) return fm_fail(err, FM_ERR_USAGE, "render: no renderer given");
    fm_render_opts o = r->o;
    o.bounds = bounds;
    fm_status st = check_opts(&o, err);
    if (st != FM_OK) return st;
    if (bounds) memcpy(r->bounds, bounds, sizeof r->bounds);
    r->o.bounds = bounds ? r->bounds : NULL;
    return FM_OK;
}

/* Every vertex finite (and within Embree's reach), every corner a vertex. */
static fm_status check_obstacles(const float *verts, size_t nv, const uint32_t *tris, size_t nt,
                                 fm_error *err)
{
    if (nt > 0 && (!verts || !tris))
        return fm_fail(err, FM_ERR_USAGE, "render: obstacles without vertices or triangles");
    if (nv > UINT32_MAX || nt > UINT32_MAX)
        return fm_fail(err, FM_ERR_USAGE, "render: %zu obstacle vertices and %zu triangles are more "
                       "than Embree can hold", nv, nt);
    for (size_t i = 0; i < nv; i++)
        if (!fm_render_coords_ok(verts + 3 * i, 3))
            return fm_fail(err, FM_ERR_USAGE, "render: obstacle vertex %zu is not finite", i);
    for (size_t i = 0; i < 3 * nt; i++)
        if (tris[i] >= nv)
            return fm_fail(err, FM_ERR_USAGE, "render: obstacle triangle %zu names vertex %u of %zu",
                           i / 3, (unsigned)tris[i], nv);
    return FM_OK;
}

fm_status fm_renderer_set_obstacles(fm_renderer *r, const float *verts, size_t nv,
                                    const uint32_t *tris, size_t nt, fm_error *err)
{
    if (!r) return fm_fail(err, FM_ERR_USAGE, "render: no renderer given");
    fm_status st = check_obstacles(verts, nv, tris, nt, err);
    if (st != FM_OK) return st;
    obstacles_free(&r->obstacles);
    if (nt == 0) return FM_OK;
    obstacle_mesh *m = &r->obstacles;
    m->verts = malloc(3 * sizeof(float) * (nv ? nv : 1));
    m->tris = malloc(3 * sizeof(uint32_t) * nt);
    if (!m->verts || !m->tris) {
        obstacles_free(m);
        return fm_fail(err, FM_ERR_MEMORY, "render: out of memory for %zu obstacle triangles", nt);
    }
    memcpy(m->verts, verts, 3 * sizeof(float) * nv);
    memcpy(m->tris, tris, 3 * sizeof(uint32_t) * nt);
    m->nv = nv, m->nt = nt;
    for (int k = 0; k < 3; k++) m->lo[k] = INFINITY, m->hi[k] = -INFINITY;
    for (size_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++)
            m->lo[k] = fmin(m->lo[k], verts[3 * i + k]), m->hi[k] = fmax(m->hi[k], verts[3 * i + k]);
    return FM_OK;
}

/* ---------------------------------------------------------------- camera, ground and light */

typedef struct view {
    double right[3], up[3], fwd[3];
    double eye[3];            /* perspective: the eye; orthographic: origin of the ray through (0, 0) */
    int perspective;
    double s_mid, t_mid, scale; /* image-plane centre and pixels per image-plane unit */
    int width, height, samples;
    double light[3];          /* unit vector towards the key light */
    double eps;               /* offset of shadow rays off a surface, world units */
    /* ground: the plane w.x = height, drawn over [lo1, hi1] x [lo2, hi2] in the (g1, g2) basis */
    int ground;
    double w[3], g1[3], g2[3], level, lo1, hi1, lo2, hi2;
} view;

static void box_corner(const double lo[3], const double hi[3], int c, double p[3])
{
    p[0] = (c & 1) ? hi[0] : lo[0];
    p[1] = (c & 2) ? hi[1] : lo[1];
    p[2] = (c & 4) ? hi[2] : lo[2];
}

/* World point -> image-plane (s, t). */
static void project(const view *v, const double p[3], double *s, double *t)
{
    if (!v->perspective) {
        *s = dot3(p, v->right), *t = dot3(p, v->up);
        return;
    }
    double q[3] = {p[0] - v->eye[0], p[1] - v->eye[1], p[2] - v->eye[2]};
    double depth = dot3(q, v->fwd);
    *s = dot3(q, v->right) / depth, *t = dot3(q, v->up) / depth;
}

/* Axes, eye and the fit of the box [lo, hi] into the image. */
static void view_camera(const fm_render_opts *o, const double lo[3], const double hi[3], view *v)
{
    memcpy(v->fwd, o->view_dir, sizeof v->fwd);
    double up[3];
    memcpy(up, o->up, sizeof up);
    normalize3(v->fwd), normalize3(up);
    cross3(v->fwd, up, v->right);
    normalize3(v->right);
    cross3(v->right, v->fwd, v->up);
    v->perspective = o->perspective;
    v->width = o->width, v->height = o->height, v->samples = o->samples;

    double c[3], radius = 0.0;
    for (int k = 0; k < 3; k++) {
        c[k] = 0.5 * (lo[k] + hi[k]);
        radius += 0.25 * (hi[k] - lo[k]) * (hi[k] - lo[k]);
    }
    radius = sqrt(radius);
    if (!(radius > 0.0)) radius = 1.0; /* a single point: any size will do */
    /* Perspective: far enough that the bounding sphere fills fov_deg. Orthographic: the rays start
     * well in front of the bounds and the ground (which reaches 2 radii out). */
    double back = o->perspective ? radius / sin(o->fov_deg * (FM_RENDER_PI / 360.0)) : 4.0 * radius;
    for (int k = 0; k < 3; k++) v->eye[k] = c[k] - back * v->fwd[k];
    if (!v->perspective) {
        double along = dot3(v->eye, v->fwd); /* keep only the depth: (s, t) are added per ray */
        for (int k = 0; k < 3; k++) v->eye[k] = along * v->fwd[k];
    }

    double smin = INFINITY, smax = -INFINITY, tmin = INFINITY, tmax = -INFINITY;
    for (int i = 0; i < 8; i++) {
        double p[3], s, t;
        box_corner(lo, hi, i, p);
        project(v, p, &s, &t);
        smin = fmin(smin, s), smax = fmax(smax, s);
        tmin = fmin(tmin, t), tmax = fmax(tmax, t);
    }
    double avail_w = o->width * (1.0 - 2.0 * o->margin);
    double avail_h = o->height * (1.0 - 2.0 * o->margin);
    double sx = smax > smin ? avail_w / (smax - smin) : INFINITY;
    double sy = tmax > tmin ? avail_h / (tmax - tmin) : INFINITY;
    v->scale = fmin(sx, sy);
    if (!isfinite(v->scale)) v->scale = o->perspective ? 1.0 : avail_h / (2.0 * radius);
    v->s_mid = 0.5 * (smin + smax);
    v->t_mid = 0.5 * (tmin + tmax);
    v->eps = 1e-4 * radius;
}

/* A unit vector across w (for the ground's basis and the light's horizontal part). */
static void perpendicular(const double w[3], const double hint[3], double out[3])
{
    double d = dot3(hint, w);
    for (int k = 0; k < 3; k++) out[k] = hint[k] - d * w[k];
    if (normalize3(out) > 1e-6) return;
    const double x[3] = {1, 0, 0}, y[3] = {0, 1, 0};
    const double *axis = fabs(w[0]) < 0.9 ? x : y;
    d = dot3(axis, w);
    for (int k = 0; k < 3; k++) out[k] = axis[k] - d * w[k];
    normalize3(out);
}

/* Widens the ground's rectangle to reach under the obstacles' box, so that an obstacle the camera
 * sees beside the framed box stands on the ground rather than beyond its edge. */
static void ground_under_obstacles(const obstacle_mesh *ob, view *v)
{
    if (!ob->nt) return;
    for (int i = 0; i < 8; i++) {
        double p[3];
        box_corner(ob->lo, ob->hi, i, p);
        double a = dot3(p, v->g1), b = dot3(p, v->g2);
        v->lo1 = fmin(v->lo1, a), v->hi1 = fmax(v->hi1, a);
        v->lo2 = fmin(v->lo2, b), v->hi2 = fmax(v->hi2, b);
    }
}

/* The ground: a rectangle just under the box, wider than it by 0.3 x its largest extent on each
 * side and reaching under the obstacles. The key light: opts' light_dir, or else high above (about
 * 60 degrees), from the left and a little from the camera's side, so shadows fall to the right and
 * away from the camera. */
static void view_ground_and_light(const fm_render_opts *o, const double lo[3], const double hi[3],
                                  const obstacle_mesh *ob, view *v)
{
    memcpy(v->w, o->world_up, sizeof v->w);
    normalize3(v->w);
    perpendicular(v->w, v->right, v->g1);
    cross3(v->w, v->g1, v->g2);
    double hmin = INFINITY, hmax = -INFINITY;
    v->lo1 = v->lo2 = INFINITY, v->hi1 = v->hi2 = -INFINITY;
    for (int i = 0; i < 8; i++) {
        double p[3];
        box_corner(lo, hi, i, p);
        double h = dot3(p, v->w), a = dot3(p, v->g1), b = dot3(p, v->g2);
        hmin = fmin(hmin, h), hmax = fmax(hmax, h);
        v->lo1 = fmin(v->lo1, a), v->hi1 = fmax(v->hi1, a);
        v->lo2 = fmin(v->lo2, b), v->hi2 = fmax(v->hi2, b);
    }
    double extent = fmax(fmax(v->hi1 - v->lo1, v->hi2 - v->lo2), hmax - hmin);
    double pad = extent > 0.0 ? 0.3 * extent : 1.0;
    v->lo1 -= pad, v->hi1 += pad, v->lo2 -= pad, v->hi2 += pad;
    ground_under_obstacles(ob, v);
    /* A hair under the lowest point, so faces resting on the bounds' floor never tie with it. */
    v->level = hmin - 1e-3 * pad;
    v->ground = o->ground;

    memcpy(v->light, o->light_dir, sizeof v->light);
    if (normalize3(v->light) > 0.0) return;
    double across[3]; /* the image's right axis, levelled */
    perpendicular(v->w, v->right, across);
    for (int k = 0; k < 3; k++) v->light[k] = 1.6 * v->w[k] - 0.9 * across[k] - 0.3 * v->fwd[k];
    normalize3(v->light);
}

/* The ray through image point (x, y) in pixels (continuous, y down). */
static void camera_ray(const view *v, double x, double y, float org[3], float dir[3])
{
    double s = v->s_mid + (x - 0.5 * v->width) / v->scale;
    double t = v->t_mid - (y - 0.5 * v->height) / v->scale;
    double o[3], d[3];
    for (int k = 0; k < 3; k++) {
        if (v->perspective) {
            o[k] = v->eye[k];
            d[k] = v->fwd[k] + s * v->right[k] + t * v->up[k];
        } else {
            o[k] = v->eye[k] + s * v->right[k] + t * v->up[k];
            d[k] = v->fwd[k];
        }
    }
    normalize3(d);
    for (int k = 0; k < 3; k++) org[k] = (float)o[k], dir[k] = (float)d[k];
}

/* ---------------------------------------------------------------- the frame's Embree scene */

typedef struct frame_scene {
    RTCScene scene;    /* NULL when nothing finite is drawn */
    unsigned obstacle_geom; /* the obstacles' geometry ID in scene, RTC_INVALID_GEOMETRY_ID if none */
    uint32_t *agent;   /* agent of each kept tet or point */
    float *colour;     /* n x 3: each agent's colour, linear */
    size_t n;          /* agents in the frame */
    int tets;          /* 1: primitive p is face p % 4 of kept tet p / 4; 0: primitive p is kept point p */
    int have_bounds;   /* lo, hi hold the kept geometry's bounds */
    double lo[3], hi[3];
} frame_scene;

static void frame_scene_free(frame_scene *sc)
{
    if (sc->scene) rtcReleaseScene(sc->scene);
    free(sc->agent);
    free(sc->colour);
    memset(sc, 0, sizeof *sc);
}

static void grow_bounds(frame_scene *sc, const float *p, double pad)
{
    for (int k = 0; k < 3; k++) {
        sc->lo[k] = fmin(sc->lo[k], p[k] - pad);
        sc->hi[k] = fmax(sc->hi[k], p[k] + pad);
    }
    sc->have_bounds = 1;
}

/* Keeps the agents whose `floats` coordinates are finite; fills sc->agent, returns how many. */
static size_t keep_finite(const float *data, size_t n, int floats, frame_scene *sc)
{
    size_t kept = 0;
    for (size_t i = 0; i < n; i++)
        if (fm_render_coords_ok(data + (size_t)floats * i, floats)) sc->agent[kept++] = (uint32_t)i;
    return kept;
}

static fm_status embree_status(fm_renderer *r, fm_error *err)
{
    enum RTCError e = rtcGetDeviceError(r->device);
    if (e == RTC_ERROR_NONE && !r->embree_error[0]) return FM_OK;
    fm_status st = e == RTC_ERROR_OUT_OF_MEMORY ? FM_ERR_MEMORY : FM_ERR_INTERNAL;
    fm_fail(err, st, "render: %s", r->embree_error[0] ? r->embree_error : "Embree failed");
    r->embree_error[0] = 0;
    return st;
}

/* The obstacles as a triangle geometry, copied into Embree's buffers (a few thousand triangles
 * per frame: cheaper than keeping Embree's padding rules for shared buffers); NULL on failure. */
static RTCGeometry obstacle_geometry(fm_renderer *r)
{
    const obstacle_mesh *m = &r->obstacles;
    RTCGeometry g = rtcNewGeometry(r->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g) return NULL;
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                        3 * sizeof(float), m->nv);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           3 * sizeof(unsigned), m->nt);
    if (!vb || !ib) return rtcReleaseGeometry(g), NULL;
    memcpy(vb, m->verts, 3 * sizeof(float) * m->nv);
    memcpy(ib, m->tris, 3 * sizeof(unsigned) * m->nt);
    return g;
}

/* Commits g (the agents, or NULL when none is finite) and the obstacles as the frame's scene,
 * and releases the caller's reference to g. sc->scene stays NULL when there is neither. */
static fm_status commit_scene(fm_renderer *r, RTCGeometry g, frame_scene *sc, fm_error *err)
{
    sc->obstacle_geom = RTC_INVALID_GEOMETRY_ID;
    RTCGeometry obstacles = r->obstacles.nt ? obstacle_geometry(r) : NULL;
    if (r->obstacles.nt && !obstacles) {
        if (g) rtcReleaseGeometry(g);
        fm_status st = embree_status(r, err);
        return st != FM_OK ? st : fm_fail(err, FM_ERR_MEMORY, "render: out of memory for the obstacles");
    }
    if (g || obstacles) sc->scene = rtcNewScene(r->device);
    if (sc->scene) {
        /* Watertight traversal: rays do not slip through the shared edges of neighbouring faces. */
        rtcSetSceneFlags(sc->scene, RTC_SCENE_FLAG_ROBUST);
        if (g) rtcCommitGeometry(g), rtcAttachGeometry(sc->scene, g);
        if (obstacles) rtcCommitGeometry(obstacles), sc->obstacle_geom = rtcAttachGeometry(sc->scene, obstacles);
        rtcCommitScene(sc->scene);
    }
    if (g) rtcReleaseGeometry(g);
    if (obstacles) rtcReleaseGeometry(obstacles);
    return embree_status(r, err);
}

/* The scene's agent list and each agent's colour, as c says (NULL: by index). */
static fm_status start_scene(const fm_renderer *r, size_t n, int tets, const fm_render_colours *c,
                             frame_scene *sc, fm_error *err)
{
    memset(sc, 0, sizeof *sc);
    sc->obstacle_geom = RTC_INVALID_GEOMETRY_ID; /* 0 is a valid ID */
    sc->n = n, sc->tets = tets;
    for (int k = 0; k < 3; k++) sc->lo[k] = INFINITY, sc->hi[k] = -INFINITY;
    if ((uint64_t)n * 4 > UINT32_MAX)
        return fm_fail(err, FM_ERR_USAGE, "render: %zu agents are more than Embree can hold", n);
    sc->agent = malloc(sizeof(uint32_t) * (n ? n : 1));
    sc->colour = malloc(3 * sizeof(float) * (n ? n : 1));
    if (!sc->agent || !sc->colour)
        return fm_fail(err, FM_ERR_MEMORY, "render: out of memory for %zu agents", n);
    fm_agent_colours(&r->colours, c, n, sc->colour);
    return FM_OK;
}

static fm_status build_tets(fm_renderer *r, const float *verts, size_t n,
                            const fm_render_colours *c, frame_scene *sc, fm_error *err)
{
    static const unsigned faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    fm_status st = start_scene(r, n, 1, c, sc, err);
    if (st != FM_OK) return st;
    size_t kept = keep_finite(verts, n, 12, sc);
    if (kept == 0) return commit_scene(r, NULL, sc, err);
    RTCGeometry g = rtcNewGeometry(r->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g) return embree_status(r, err);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                        3 * sizeof(float), 4 * kept);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           3 * sizeof(unsigned), 4 * kept);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        return fm_fail(err, FM_ERR_MEMORY, "render: out of memory for %zu tets", kept);
    }
    for (size_t t = 0; t < kept; t++) {
        const float *tv = verts + 12 * (size_t)sc->agent[t];
        memcpy(vb + 12 * t, tv, 12 * sizeof(float));
        for (int c = 0; c < 4; c++) grow_bounds(sc, tv + 3 * c, 0.0);
        for (int f = 0; f < 4; f++)
            for (int c = 0; c < 3; c++) ib[3 * (4 * t + f) + c] = (unsigned)(4 * t) + faces[f][c];
    }
    return commit_scene(r, g, sc, err);
}

static fm_status build_points(fm_renderer *r, const float *pos, size_t n,
                              const fm_render_colours *c, frame_scene *sc, fm_error *err)
{
    fm_status st = start_scene(r, n, 0, c, sc, err);
    if (st != FM_OK) return st;
    size_t kept = keep_finite(pos, n, 3, sc);
    if (kept == 0) return commit_scene(r, NULL, sc, err);
    float radius = (float)(r->o.point_radius > 0.0 ? r->o.point_radius
                                                   : fm_render_point_radius(pos, n));
    RTCGeometry g = rtcNewGeometry(r->device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    if (!g) return embree_status(r, err);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                        4 * sizeof(float), kept);
    if (!vb) {
        rtcReleaseGeometry(g);
        return fm_fail(err, FM_ERR_MEMORY, "render: out of memory for %zu points", kept);
    }
    for (size_t i = 0; i < kept; i++) {
        const float *p = pos + 3 * (size_t)sc->agent[i];
        memcpy(vb + 4 * i, p, 3 * sizeof(float));
        vb[4 * i + 3] = radius;
        grow_bounds(sc, p, radius);
    }
    return commit_scene(r, g, sc, err);
}

/* ---------------------------------------------------------------- tracing and shading */

typedef struct surface {
    double p[3], n[3]; /* hit point, unit normal facing the ray's origin */
    float albedo[3];
} surface;

/* Distance along the ray to the ground rectangle, +inf if it misses. */
static double ground_hit(const view *v, const double org[3], const double dir[3])
{
    double denom = dot3(v->w, dir);
    if (!v->ground || fabs(denom) < 1e-12) return INFINITY;
    double t = (v->level - dot3(v->w, org)) / denom;
    if (!(t > 0.0)) return INFINITY;
    double q[3] = {org[0] + t * dir[0], org[1] + t * dir[1], org[2] + t * dir[2]};
    double a = dot3(q, v->g1), b = dot3(q, v->g2);
    return a >= v->lo1 && a <= v->hi1 && b >= v->lo2 && b <= v->hi2 ? t : INFINITY;
}

/* The nearest surface along the ray: a tet face, a sphere or the ground. 0 if none. */
static int trace(const fm_renderer *r, const view *v, const frame_scene *sc, const float org[3],
                 const float dir[3], surface *hit)
{
    double t_obj = INFINITY, n[3] = {0, 0, 0};
    uint32_t agent = 0;
    int obstacle = 0;
    if (sc->scene) {
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        struct RTCRayHit rh;
        memset(&rh, 0, sizeof rh);
        rh.ray.org_x = org[0], rh.ray.org_y = org[1], rh.ray.org_z = org[2];
        rh.ray.dir_x = dir[0], rh.ray.dir_y = dir[1], rh.ray.dir_z = dir[2];
        rh.ray.tnear = 0.0f, rh.ray.tfar = INFINITY, rh.ray.mask = UINT32_MAX;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(sc->scene, &ctx, &rh);
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
            t_obj = rh.ray.tfar;
            n[0] = rh.hit.Ng_x, n[1] = rh.hit.Ng_y, n[2] = rh.hit.Ng_z;
            obstacle = rh.hit.geomID == sc->obstacle_geom;
            if (!obstacle) agent = sc->agent[sc->tets ? rh.hit.primID / 4 : rh.hit.primID];
        }
    }
    double o[3] = {org[0], org[1], org[2]}, d[3] = {dir[0], dir[1], dir[2]};
    double t_gnd = ground_hit(v, o, d);
    if (t_obj == INFINITY && t_gnd == INFINITY) return 0;
    if (t_obj <= t_gnd) {
        memcpy(hit->albedo, obstacle ? r->obstacle_albedo : sc->colour + 3 * (size_t)agent,
               sizeof hit->albedo);
    } else {
        memcpy(n, v->w, sizeof n);
        memcpy(hit->albedo, r->ground_albedo, sizeof hit->albedo);
    }
    double t = fmin(t_obj, t_gnd);
    if (normalize3(n) == 0.0) memcpy(n, v->w, sizeof n); /* a zero-area face: any normal */
    if (dot3(n, d) > 0.0)                                 /* shade the side the ray sees */
        for (int k = 0; k < 3; k++) n[k] = -n[k];
    for (int k = 0; k < 3; k++) hit->p[k] = o[k] + t * d[k], hit->n[k] = n[k];
    return 1;
}

/* 1 if something lies between the surface and the key light. */
static int in_shadow(const view *v, const frame_scene *sc, const surface *s)
{
    if (!sc->scene) return 0;
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay ray;
    memset(&ray, 0, sizeof ray);
    ray.org_x = (float)(s->p[0] + v->eps * s->n[0]);
    ray.org_y = (float)(s->p[1] + v->eps * s->n[1]);
    ray.org_z = (float)(s->p[2] + v->eps * s->n[2]);
    ray.dir_x = (float)v->light[0], ray.dir_y = (float)v->light[1], ray.dir_z = (float)v->light[2];
    ray.tnear = (float)v->eps, ray.tfar = INFINITY, ray.mask = UINT32_MAX;
    rtcOccluded1(sc->scene, &ctx, &ray);
    return ray.tfar < 0.0f; /* Embree sets tfar to -inf on a hit */
}

/* Linear radiance seen along one camera ray. */
static void shade_ray(const fm_renderer *r, const view *v, const frame_scene *sc, double x,
                      double y, float out[3])
{
    float org[3], dir[3];
    camera_ray(v, x, y, org, dir);
    surface s;
    if (!trace(r, v, sc, org, dir, &s)) {
        memcpy(out, r->background, 3 * sizeof(float));
        return;
    }
    double lambert = dot3(s.n, v->light);
    double light = fm_ambient;
    if (lambert > 0.0 && !in_shadow(v, sc, &s)) light += fm_key * lambert;
    for (int k = 0; k < 3; k++) out[k] = (float)(s.albedo[k] * light);
}

/* One pixel: the mean of samples x samples rays on a regular grid inside it. */
static void shade_pixel(const fm_renderer *r, const view *v, const frame_scene *sc, int px,
                        int py, unsigned char rgb[3])
{
    int m = v->samples;
    float sum[3] = {0, 0, 0};
    for (int j = 0; j < m; j++)
        for (int i = 0; i < m; i++) {
            float c[3];
            shade_ray(r, v, sc, px + (i + 0.5) / m, py + (j + 0.5) / m, c);
            for (int k = 0; k < 3; k++) sum[k] += c[k];
        }
    for (int k = 0; k < 3; k++) rgb[k] = srgb_encode(r->srgb_edge, sum[k] / (float)(m * m));
}

static void fill_background(const fm_renderer *r, unsigned char *rgb)
{
    unsigned char bg[3];
    for (int k = 0; k < 3; k++) bg[k] = srgb_encode(r->srgb_edge, r->background[k]);
    size_t pixels = (size_t)r->o.width * (size_t)r->o.height;
    for (size_t i = 0; i < pixels; i++) memcpy(rgb + 3 * i, bg, 3);
}

static fm_status draw(fm_renderer *r, frame_scene *sc, unsigned char *rgb, fm_error *err)
{
    const fm_render_opts *o = &r->o;
    double lo[3], hi[3];
    if (o->bounds) {
        memcpy(lo, o->bounds, sizeof lo), memcpy(hi, o->bounds + 3, sizeof hi);
    } else if (sc->have_bounds) {
        memcpy(lo, sc->lo, sizeof lo), memcpy(hi, sc->hi, sizeof hi);
    } else if (r->obstacles.nt) { /* no agents: the obstacles alone */
        memcpy(lo, r->obstacles.lo, sizeof lo), memcpy(hi, r->obstacles.hi, sizeof hi);
    } else { /* nothing to fit: an empty picture */
        fill_background(r, rgb);
        frame_scene_free(sc);
        return FM_OK;
    }
    view v;
    view_camera(o, lo, hi, &v);
    view_ground_and_light(o, lo, hi, &r->obstacles, &v);
    int threads = fm_threads(o->threads);
    const fm_renderer *cr = r;
#pragma omp parallel for schedule(dynamic, 2) num_threads(threads)
    for (int y = 0; y < o->height; y++)
        for (int x = 0; x < o->width; x++)
            shade_pixel(cr, &v, sc, x, y, rgb + 3 * ((size_t)y * (size_t)o->width + (size_t)x));
    frame_scene_free(sc);
    return embree_status(r, err);
}

static fm_status check_draw_args(const fm_renderer *r, const void *data, size_t n,
                                 const fm_render_colours *c, const unsigned char *rgb,
                                 fm_error *err)
{
    if (!r) return fm_fail(err, FM_ERR_USAGE, "render: no renderer given");
    if (n > 0 && !data) return fm_fail(err, FM_ERR_USAGE, "render: no coordinates given");
    if (!rgb) return fm_fail(err, FM_ERR_USAGE, "render: no image buffer given");
    return fm_check_colours(c, n, err);
}

fm_status fm_renderer_draw_tets_coloured(fm_renderer *r, const float *verts, size_t n,
                                         const fm_render_colours *c, unsigned char *rgb,
                                         fm_error *err)
{
    fm_status st = check_draw_args(r, verts, n, c, rgb, err);
    frame_scene sc;
    if (st == FM_OK && (st = build_tets(r, verts, n, c, &sc, err)) != FM_OK) frame_scene_free(&sc);
    return st == FM_OK ? draw(r, &sc, rgb, err) : st;
}

fm_status fm_renderer_draw_points_coloured(fm_renderer *r, const float *positions, size_t n,
                                           const fm_render_colours *c, unsigned char *rgb,
                                           fm_error *err)
{
    fm_status st = check_draw_args(r, positions, n, c, rgb, err);
    frame_scene sc;
    if (st == FM_OK && (st = build_points(r, positions, n, c, &sc, err)) != FM_OK)
        frame_scene_free(&sc);
    return st == FM_OK ? draw(r, &sc, rgb, err) : st;
}

fm_status fm_renderer_draw_tets(fm_renderer *r, const float *verts, size_t n, unsigned char *rgb,
                                fm_error *err)
{
    return fm_renderer_draw_tets_coloured(r, verts, n, NULL, rgb, err);
}

fm_status fm_renderer_draw_points(fm_renderer *r, const float *positions, size_t n,
                                  unsigned char *rgb, fm_error *err)
{
    return fm_renderer_draw_points_coloured(r, positions, n, NULL, rgb, err);
}

/* ---------------------------------------------------------------- one-call forms */

typedef fm_status (*draw_fn)(fm_renderer *, const float *, size_t, unsigned char *, fm_error *);

static fm_status render_png(draw_fn draw_frame, const float *data, size_t n,
                            const fm_render_opts *opts, const char *path, fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "render: no output path given");
    fm_renderer *r;
    fm_status st = renderer_create(opts, &r, err);
    if (st != FM_OK) return st;
    size_t bytes = 3 * (size_t)r->o.width * (size_t)r->o.height;
    unsigned char *rgb = malloc(bytes);
    st = rgb ? FM_OK
             : fm_fail(err, FM_ERR_MEMORY, "render to '%s': out of memory for %dx%d",
                                 path, r->o.width, r->o.height);
    if (st == FM_OK) st = draw_frame(r, data, n, rgb, err);
    if (st == FM_OK) st = fm_write_png(rgb, r->o.width, r->o.height, path, err);
    free(rgb);
    fm_renderer_destroy(r);
    return st;
}

fm_status fm_render_tets_png(const float *verts, size_t n, const fm_render_opts *opts,
                             const char *path, fm_error *err)
{
    return render_png(fm_renderer_draw_tets, verts, n, opts, path, err);
}

fm_status fm_render_points_png(const float *positions, size_t n, const fm_render_opts *opts,
                               const char *path, fm_error *err)
{
    return render_png(fm_renderer_draw_points, positions, n, opts, path, err);
}
