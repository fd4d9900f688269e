/* The global path (FM §5.1): a curve from C_S through the user's control points to C_T,
 * resampled to m + 2 key points Q_0 = C_S .. Q_{m+1} = C_T evenly spaced by arc length; with
 * obstacles, rerouted round them first where it crosses them (path_route.c, issue 38). */
#include "morph.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { CURVE_SAMPLES_PER_SEGMENT = 64 };

static double dist3(const double *a, const double *b)
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* Uniform Catmull-Rom between p1 and p2 at s in [0, 1]. */
static void catmull_rom(const double *p0, const double *p1, const double *p2, const double *p3,
                        double s, double *out)
{
    double s2 = s * s, s3 = s2 * s;
    for (int k = 0; k < 3; k++)
        out[k] = 0.5 * (2 * p1[k] + (-p0[k] + p2[k]) * s + (2 * p0[k] - 5 * p1[k] + 4 * p2[k] - p3[k]) * s2 +
                        (-p0[k] + 3 * p1[k] - 3 * p2[k] + p3[k]) * s3);
}

/* Dense polyline of the curve through `ctrl` (count points). Returns its point count. */
static int64_t densify(const double *ctrl, int count, fm_curve curve, double *dense)
{
    if (curve == FM_CURVE_POLYLINE || count < 3) {
        memcpy(dense, ctrl, sizeof(double) * 3 * (size_t)count);
        return count;
    }
    int64_t w = 0;
    for (int i = 0; i + 1 < count; i++) {
        const double *p0 = ctrl + 3 * (i > 0 ? i - 1 : 0), *p1 = ctrl + 3 * i, *p2 = ctrl + 3 * (i + 1);
        const double *p3 = ctrl + 3 * (i + 2 < count ? i + 2 : count - 1);
        for (int s = 0; s < CURVE_SAMPLES_PER_SEGMENT; s++)
            catmull_rom(p0, p1, p2, p3, (double)s / CURVE_SAMPLES_PER_SEGMENT, dense + 3 * w++);
    }
    memcpy(dense + 3 * w++, ctrl + 3 * (count - 1), 3 * sizeof(double));
    return w;
}

/* Resamples a polyline to `count` points evenly spaced by arc length, ends kept exactly. */
static void resample(const double *pts, int64_t n, double total, int32_t count, double *out)
{
    int64_t seg = 0;
    double seg_start = 0;
    for (int32_t j = 0; j < count; j++) {
        double target = total * j / (count - 1);
        while (seg + 2 < n && seg_start + dist3(pts + 3 * seg, pts + 3 * (seg + 1)) < target)
            seg_start += dist3(pts + 3 * seg, pts + 3 * (seg + 1)), seg++;
        double len = dist3(pts + 3 * seg, pts + 3 * (seg + 1));
        double s = len > 0 ? (target - seg_start) / len : 0;
        s = s < 0 ? 0 : s > 1 ? 1 : s;
        for (int k = 0; k < 3; k++) out[3 * j + k] = pts[3 * seg + k] + s * (pts[3 * (seg + 1) + k] - pts[3 * seg + k]);
    }
    memcpy(out + 3 * (count - 1), pts + 3 * (n - 1), 3 * sizeof(double));
}

fm_status fm_path_build_routed(const fm_scene_def *def, const double cs[3], const double ct[3], fm_path_route *route,
                               fm_path *out, fm_error *err)
{
    int count = def->path_point_count + 2;
    double *ctrl = malloc(sizeof(double) * 3 * (size_t)count);
    double *dense = malloc(sizeof(double) * 3 * ((size_t)count * CURVE_SAMPLES_PER_SEGMENT + 1));
    out->count = def->path_key_points + 2;
    out->q = NULL;
    if (!ctrl || !dense) {
        free(ctrl), free(dense);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory building the path");
    }
    memcpy(ctrl, cs, 3 * sizeof(double));
    memcpy(ctrl + 3 * (count - 1), ct, 3 * sizeof(double));
    memcpy(ctrl + 3, def->path_points, sizeof(double) * 3 * (size_t)def->path_point_count);
    int64_t n = densify(ctrl, count, def->path_curve, dense);
    fm_status st = route ? fm_path_route_dense(route, &dense, &n, err) : FM_OK;
    double total = 0;
    for (int64_t i = 0; i + 1 < n; i++) total += dist3(dense + 3 * i, dense + 3 * (i + 1));
    /* the key points resolve the way round: one per r_soft, but at most twice the scene's (eq 3's
       nearest key point costs O(m) an agent-step) */
    if (st == FM_OK && route && route->routed && route->r_soft > 0)
        out->count = (int32_t)fmax(out->count, fmin(ceil(total / route->r_soft) + 1, 2.0 * out->count));
    if (st == FM_OK && !(total > 0))
        st = fm_fail(err, FM_ERR_INPUT, "the path has fewer than two distinct points (zero length): the source "
                     "and target centroids coincide and no path point lies apart from them");
    if (st == FM_OK && !(out->q = malloc(sizeof(double) * 3 * (size_t)out->count)))
        st = fm_fail(err, FM_ERR_MEMORY, "out of memory building the path");
    if (st == FM_OK) resample(dense, n, total, out->count, out->q);
    free(ctrl);
    free(dense);
    if (st != FM_OK) fm_path_free(out);
    return st;
}

fm_status fm_path_build(const fm_scene_def *def, const double cs[3], const double ct[3], fm_path *out, fm_error *err)
{
    return fm_path_build_routed(def, cs, ct, NULL, out, err);
}

void fm_path_free(fm_path *path)
{
    free(path->q);
    path->q = NULL;
    path->count = 0;
}
