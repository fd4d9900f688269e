/* Surface sampling (SCF §3): options, validation, the choice of method, evaluation on a deforming
 * mesh, and the nearest-neighbour uniformity measure. Random sampling and the spatial sort that
 * every method builds on are in sample_random.c, the mosaic and stratified methods in
 * sample_mosaic.c and sample_stratified.c, the correspondence in sample_match.c. */
#include "sample.h"

#include "closest.h"
#include "grid.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

fm_sample_opts fm_default_sample_opts(void)
{
    return (fm_sample_opts){
        .method = FM_SAMPLE_RANDOM,
        .seed = 1,
        .iterations = FM_SAMPLE_MOSAIC_ITERATIONS,
        .manhattan = 0,
        .k = FM_SAMPLE_MOSAIC_K,
        .w = FM_SAMPLE_MOSAIC_W,
        .lambda = FM_SAMPLE_LAMBDA,
        .step = FM_SAMPLE_MOSAIC_STEP,
        .oversample = FM_SAMPLE_OVERSAMPLE,
        .threads = 0,
    };
}

void fm_samples_free(fm_samples *s)
{
    if (!s) return;
    fm_free(s->p);
    fm_free(s->tri);
    fm_free(s->bary);
    *s = (fm_samples){0};
}

/* ------------------------------------------------------------------ geometry */

static double triangle_area(const fm_mesh *m, int64_t t)
{
    const int32_t *f = m->tri + 3 * t;
    const double *a = m->v + 3 * (int64_t)f[0], *b = m->v + 3 * (int64_t)f[1], *c = m->v + 3 * (int64_t)f[2];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    return 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

double fm_mesh_area(const fm_mesh *m)
{
    double sum = 0;
    for (int64_t t = 0; t < m->nt; t++) sum += triangle_area(m, t);
    return sum;
}

/* The point of segment a-b nearest q as the weight of b, in [0, 1]. */
static double segment_param(const double *a, const double *b, const double q[3])
{
    double ab2 = 0, aq = 0;
    for (int k = 0; k < 3; k++) ab2 += (b[k] - a[k]) * (b[k] - a[k]), aq += (q[k] - a[k]) * (b[k] - a[k]);
    double t = ab2 > 0 ? aq / ab2 : 0;
    return t < 0 ? 0 : t > 1 ? 1 : t;
}

void fm_sample_barycentric(const fm_mesh *mesh, int32_t t, const double q[3], double b[3])
{
    const int32_t *f = mesh->tri + 3 * (int64_t)t;
    const double *p0 = mesh->v + 3 * (int64_t)f[0], *p1 = mesh->v + 3 * (int64_t)f[1], *p2 = mesh->v + 3 * (int64_t)f[2];
    double e1[3], e2[3], d[3];
    for (int k = 0; k < 3; k++) e1[k] = p1[k] - p0[k], e2[k] = p2[k] - p0[k], d[k] = q[k] - p0[k];
    double d00 = 0, d01 = 0, d11 = 0, d20 = 0, d21 = 0;
    for (int k = 0; k < 3; k++)
        d00 += e1[k] * e1[k], d01 += e1[k] * e2[k], d11 += e2[k] * e2[k], d20 += d[k] * e1[k], d21 += d[k] * e2[k];
    double den = d00 * d11 - d01 * d01;
    if (den > 1e-24 * d00 * d11) {
        double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
        b[0] = 1.0 - v - w, b[1] = v, b[2] = w;
    } else { /* a sliver: the point on its longest edge */
        double l01 = d00, l02 = d11, l12 = 0;
        for (int k = 0; k < 3; k++) l12 += (p2[k] - p1[k]) * (p2[k] - p1[k]);
        b[0] = b[1] = b[2] = 0;
        if (l01 >= l02 && l01 >= l12) b[1] = segment_param(p0, p1, q), b[0] = 1 - b[1];
        else if (l02 >= l12) b[2] = segment_param(p0, p2, q), b[0] = 1 - b[2];
        else b[2] = segment_param(p1, p2, q), b[1] = 1 - b[2];
    }
    double sum = 0;
    for (int k = 0; k < 3; k++) b[k] = b[k] > 0 ? b[k] : 0, sum += b[k];
    for (int k = 0; k < 3; k++) b[k] = sum > 0 ? b[k] / sum : 1.0 / 3.0;
}

/* ------------------------------------------------------------------ random (area-weighted) */


/* ------------------------------------------------------------------ evaluation */

void fm_samples_eval(const fm_samples *s, const double *mesh_vertices, const int32_t *tri, float *p_out)
{
#pragma omp parallel for num_threads(fm_threads(0)) schedule(static)
    for (int64_t i = 0; i < s->n; i++) {
        const int32_t *f = tri + 3 * (int64_t)s->tri[i];
        const float *b = s->bary + 3 * i;
        for (int k = 0; k < 3; k++)
            p_out[3 * i + k] = (float)((double)b[0] * mesh_vertices[3 * (int64_t)f[0] + k] +
                                       (double)b[1] * mesh_vertices[3 * (int64_t)f[1] + k] +
                                       (double)b[2] * mesh_vertices[3 * (int64_t)f[2] + k]);
    }
}

/* ------------------------------------------------------------------ the entry point */

static fm_status check_option(double value, const char *name, double min, fm_error *err)
{
    if (!(value >= min) || !isfinite(value))
        return fm_fail(err, FM_ERR_INPUT, "sampling option %s must be a finite number >= %g (got %g)", name, min, value);
    return FM_OK;
}

/* opts with zeros replaced by the defaults, validated. */
static fm_status resolve_opts(const fm_sample_opts *in, fm_sample_opts *o, fm_error *err)
{
    fm_sample_opts d = fm_default_sample_opts();
    *o = in ? *in : d;
    if (o->method != FM_SAMPLE_RANDOM && o->method != FM_SAMPLE_MOSAIC && o->method != FM_SAMPLE_STRATIFIED)
        return fm_fail(err, FM_ERR_INPUT, "unknown sampling method %d (0 random, 1 mosaic, 2 stratified)", (int)o->method);
    if (o->iterations < 0)
        return fm_fail(err, FM_ERR_INPUT, "sampling option iterations must be >= 0 (got %d)", o->iterations);
    if (o->threads < 0) return fm_fail(err, FM_ERR_INPUT, "sampling option threads must be >= 0 (got %d)", o->threads);
    fm_status st = check_option(o->k, "k", 0, err);
    if (st == FM_OK) st = check_option(o->w, "w", 0, err);
    if (st == FM_OK) st = check_option(o->lambda, "lambda", 0, err);
    if (st == FM_OK) st = check_option(o->step, "step", 0, err);
    if (st == FM_OK && o->oversample != 0) st = check_option(o->oversample, "oversample", 1, err);
    if (st != FM_OK) return st;
    if (o->k == 0) o->k = d.k;
    if (o->w == 0) o->w = d.w;
    if (o->lambda == 0) o->lambda = d.lambda;
    if (o->step == 0) o->step = d.step;
    if (o->oversample == 0) o->oversample = d.oversample;
    o->threads = fm_threads(o->threads);
    return FM_OK;
}

static fm_status build_ctx(const fm_mesh *mesh, int64_t n, fm_sample_ctx *c, fm_error *err)
{
    fm_status st = fm_closest_check_mesh(mesh, "sampled mesh", 0, err);
    if (st != FM_OK) return st;
    if (n < 1 || n > FM_SAMPLE_MAX)
        return fm_fail(err, FM_ERR_INPUT, "sample count %lld out of range [1, %lld]", (long long)n, (long long)FM_SAMPLE_MAX);
    c->mesh = mesh;
    c->n = n;
    c->cdf = fm_alloc(sizeof(double) * (size_t)mesh->nt);
    if (!c->cdf) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld triangle areas", (long long)mesh->nt);
    double sum = 0;
    for (int64_t t = 0; t < mesh->nt; t++) c->cdf[t] = sum += triangle_area(mesh, t);
    c->area = sum;
    if (!(sum > 0) || !isfinite(sum))
        return fm_fail(err, FM_ERR_INPUT, "the sampled mesh has no surface area (total %g)", sum);
    return FM_OK;
}

/* Triangles and barycentrics of the double points, and positions evaluated from them. */
static fm_status finish(const fm_sample_ctx *c, const double *x, const int32_t *tri, fm_samples *out, fm_error *err)
{
    const int64_t n = c->n;
    out->n = n;
    out->p = fm_alloc(sizeof(float) * 3 * (size_t)n);
    out->bary = fm_alloc(sizeof(float) * 3 * (size_t)n);
    out->tri = fm_alloc(sizeof(int32_t) * (size_t)n);
    if (!out->p || !out->bary || !out->tri)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld samples", (long long)n);
#pragma omp parallel for num_threads(c->threads) schedule(static)
    for (int64_t i = 0; i < n; i++) {
        double b[3];
        fm_sample_barycentric(c->mesh, tri[i], x + 3 * i, b);
        for (int k = 0; k < 3; k++) out->bary[3 * i + k] = (float)b[k];
        out->tri[i] = tri[i];
    }
    fm_samples_eval(out, c->mesh->v, c->mesh->tri, out->p);
    return FM_OK;
}

/* The mesh's area-weighted centroid and its largest vertex distance from it. */
static void mesh_sphere(const fm_sample_ctx *c, double center[3], double *radius)
{
    const fm_mesh *m = c->mesh;
    double sum[3] = {0, 0, 0}, prev = 0;
    for (int64_t t = 0; t < m->nt; t++) {
        const double area = c->cdf[t] - prev;
        prev = c->cdf[t];
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++) sum[k] += area * m->v[3 * (int64_t)m->tri[3 * t + j] + k] / 3;
    }
    for (int k = 0; k < 3; k++) center[k] = sum[k] / c->area;
    *radius = 0;
    for (int64_t i = 0; i < m->nv; i++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (m->v[3 * i + k] - center[k]) * (m->v[3 * i + k] - center[k]);
        *radius = fmax(*radius, sqrt(d2));
    }
}

/* The start of fm_sample_projected: each point of `from`, by its direction from their centroid, on
 * the sphere around the mesh (the centre itself for a point at the centroid). */
static void project_directions(const fm_sample_ctx *c, const float *from, double *x)
{
    double mid[3] = {0, 0, 0}, center[3], radius;
    for (int64_t i = 0; i < c->n; i++)
        for (int k = 0; k < 3; k++) mid[k] += (double)from[3 * i + k] / (double)c->n;
    mesh_sphere(c, center, &radius);
    for (int64_t i = 0; i < c->n; i++) {
        double d[3], len = 0;
        for (int k = 0; k < 3; k++) d[k] = (double)from[3 * i + k] - mid[k], len += d[k] * d[k];
        len = sqrt(len);
        for (int k = 0; k < 3; k++) x[3 * i + k] = center[k] + (len > 0 ? radius * d[k] / len : 0);
    }
}

/* The points of the method opts chose, or (from != NULL) the projection of `from` relaxed by the
 * mosaic, into out. */
static fm_status run_sampler(const char *who, const fm_mesh *mesh, int64_t n, const fm_sample_opts *opts,
                             const float *from, fm_samples *out, fm_error *err)
{
    if (!out) return fm_fail(err, FM_ERR_INPUT, "%s: no output given", who);
    *out = (fm_samples){0};
    if (!mesh) return fm_fail(err, FM_ERR_INPUT, "%s: no mesh given", who);
    for (int64_t i = 0; from && i < 3 * n; i++)
        if (!isfinite(from[i])) return fm_fail(err, FM_ERR_INPUT, "%s: point %lld is not finite", who, (long long)(i / 3));
    fm_sample_ctx c = {0};
    fm_status st = resolve_opts(opts, &c.opts, err);
    c.threads = c.opts.threads;
    if (st == FM_OK) st = build_ctx(mesh, n, &c, err);
    double *x = NULL;
    int32_t *tri = NULL;
    if (st == FM_OK) {
        x = fm_alloc(sizeof(double) * 3 * (size_t)n);
        tri = fm_alloc(sizeof(int32_t) * (size_t)n);
        if (!x || !tri) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld samples", (long long)n);
    }
    if (st == FM_OK) {
        if (from) project_directions(&c, from, x), st = fm_sample_mosaic_from(&c, x, tri, err);
        else if (c.opts.method == FM_SAMPLE_MOSAIC) st = fm_sample_mosaic(&c, x, tri, err);
        else if (c.opts.method == FM_SAMPLE_STRATIFIED) st = fm_sample_stratified(&c, x, tri, err);
        else fm_sample_random_into(&c, x, tri);
    }
    if (st == FM_OK) st = finish(&c, x, tri, out, err);
    if (st != FM_OK) fm_samples_free(out);
    fm_free(x);
    fm_free(tri);
    fm_free(c.cdf);
    return st;
}

fm_status fm_sample_surface(const fm_mesh *mesh, int64_t n, const fm_sample_opts *opts, fm_samples *out,
                            fm_error *err)
{
    return run_sampler("fm_sample_surface", mesh, n, opts, NULL, out, err);
}

fm_status fm_sample_projected(const fm_mesh *mesh, const float *from, int64_t n, const fm_sample_opts *opts,
                              fm_samples *out, fm_error *err)
{
    if (!from) {
        if (out) *out = (fm_samples){0};
        return fm_fail(err, FM_ERR_INPUT, "fm_sample_projected: no points given");
    }
    fm_sample_opts o = opts ? *opts : fm_default_sample_opts();
    o.method = FM_SAMPLE_MOSAIC;
    return run_sampler("fm_sample_projected", mesh, n, &o, from, out, err);
}

/* ------------------------------------------------------------------ uniformity */

static void point_bounds(const float *p, int64_t n, double lo[3], double hi[3])
{
    for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], (double)p[3 * i + k]), hi[k] = fmax(hi[k], (double)p[3 * i + k]);
}

fm_status fm_points_nn_stats(const float *p, int64_t n, int threads, double *mean, double *cv, fm_error *err)
{
    if (n < 2 || !p) return fm_fail(err, FM_ERR_INPUT, "nearest-neighbour statistics need at least 2 points (got %lld)", (long long)n);
    for (int64_t i = 0; i < 3 * n; i++)
        if (!isfinite(p[i])) return fm_fail(err, FM_ERR_INPUT, "point %lld is not finite", (long long)(i / 3));
    threads = fm_threads(threads);
    double lo[3], hi[3], extent = 0;
    point_bounds(p, n, lo, hi);
    for (int k = 0; k < 3; k++) extent = fmax(extent, hi[k] - lo[k]);
    float *xyz[3];
    double *d2 = fm_alloc(sizeof(double) * (size_t)n);
    uint8_t *todo = fm_alloc((size_t)n);
    for (int k = 0; k < 3; k++) xyz[k] = fm_alloc(sizeof(float) * (size_t)n);
    fm_grid g;
    fm_status st = !d2 || !todo || !xyz[0] || !xyz[1] || !xyz[2]
                       ? fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld points", (long long)n)
                       : fm_grid_init(&g, n, err);
    if (st == FM_OK) {
        for (int64_t i = 0; i < n; i++) {
            todo[i] = 1;
            for (int k = 0; k < 3; k++) xyz[k][i] = p[3 * i + k];
        }
        /* a first cell about twice the spacing of n points on a surface in this box; points with
           no neighbour within a cell try again with cells twice as large */
        double cell = extent > 0 ? 2.0 * extent / sqrt((double)n) : 1.0;
        for (int64_t left = n; left > 0; cell *= 2) {
            fm_grid_build(&g, (const float *const *)xyz, NULL, n, (float)cell, threads);
            left = 0;
#pragma omp parallel for num_threads(threads) schedule(static) reduction(+ : left)
            for (int64_t i = 0; i < n; i++) {
                if (!todo[i]) continue;
                const float q[3] = {xyz[0][i], xyz[1][i], xyz[2][i]};
                todo[i] = fm_grid_nearest(&g, q, NULL, i, -1, &d2[i]) < 0 && cell <= 4 * extent;
                left += todo[i];
            }
        }
        double s = 0, s2 = 0;
        for (int64_t i = 0; i < n; i++) s += sqrt(d2[i]);
        double m = s / (double)n;
        for (int64_t i = 0; i < n; i++) s2 += (sqrt(d2[i]) - m) * (sqrt(d2[i]) - m);
        *mean = m;
        *cv = m > 0 ? sqrt(s2 / (double)n) / m : 0.0;
        fm_grid_free(&g);
    }
    for (int k = 0; k < 3; k++) fm_free(xyz[k]);
    fm_free(d2);
    fm_free(todo);
    return st;
}
