/* Surface mosaic sampling (SCF §3, eqs 1-5 and Table I; after Lai, Hu & Martin, "Surface
 * mosaics", 2006).
 *
 * Start: N area-weighted random points. Each iteration (Table I, lines 2-9), for every point i:
 *   U_i  = { j != i : dis_ij < A },  A = k sqrt(M/N)                        (eq 1)
 *   E_ij = exp(-dis_ij^2 / (2 sigma^2)),  sigma = w sqrt(M/N)               (eqs 2-3, see sample.h)
 *   F_i  = sum over U_i of norm(p_i - p_j) E_ij                            (eq 4)
 *   F_i is restricted to the tangent plane (the plane of the triangle p_i lies on), then
 *   p'_i = p_i + delta_t F_i                                               (eq 5)
 * and p'_i is projected orthogonally back onto the mesh: its exact closest point (an Embree
 * rtcPointQuery, closest.h), which also gives the new triangle.
 *
 * Where the paper is vague:
 * - dis_ij is Manhattan (Table I, line 4) or Euclidean, as chosen; the same metric decides who is
 *   in U_i (the paper cuts U by Manhattan distance, which is what Table I's metric gives).
 * - delta_t is not given (Table I prints "sigma t"); we take delta_t = step sqrt(M/N), so the
 *   result does not depend on the model's scale: a point pushed by one close neighbour moves a
 *   quarter of the mean spacing per iteration by default. Steps of 0.5 and more oscillate (the
 *   measurements are in docs/sampling.md).
 * - Points are updated together from the previous iteration's positions (Jacobi, not
 *   Gauss-Seidel), so every point is independent of the others' order and of the thread count:
 *   neighbours are found on the engine's hash grid (grid.h, cells of edge A) and summed in the
 *   grid's order, which does not depend on the thread count either.
 * - Coincident points (dis_ij = 0) have no direction; they are pushed apart along a direction
 *   chosen from their two indices (the MDE kernel's rule), then projected onto the plane. */
#include "sample.h"

#include "closest.h"
#include "grid.h"
#include "kernel_mde.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct mosaic {
    const fm_sample_ctx *c;
    fm_closest *surface;
    fm_grid grid;
    float *xyz[3];        /* float copies of the positions, for the grid */
    double reach;         /* A */
    double inv_2sigma2;   /* 1 / (2 sigma^2) */
    double dt;            /* delta t */
    double slack;         /* absolute slack for the closest-point search radius */
    double scale;         /* largest |coordinate| of the mesh */
    float cell;           /* grid cell: A plus the float rounding of two points */
    int manhattan;
} mosaic;

static double distance_metric(const double d[3], int manhattan)
{
    return manhattan ? fabs(d[0]) + fabs(d[1]) + fabs(d[2]) : sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

/* Eq 4 for point i: the sum over its neighbourhood U_i of norm(p_i - p_j) E_ij. The grid's float
   copies reject the far candidates (most of the 27 cells) before the double arithmetic. Returns
   the candidates examined (the iteration's work, check_work). */
static int64_t repulsion(const mosaic *m, const double *x, int64_t i, double f[3])
{
    int32_t rk[2 * FM_GRID_MAX_RANGES];
    const float q[3] = {m->xyz[0][i], m->xyz[1][i], m->xyz[2][i]};
    const int nr = fm_grid_ranges(&m->grid, q[0], q[1], q[2], rk);
    const double *pi = x + 3 * i;
    const float r2 = m->cell * m->cell;
    int64_t candidates = 0;
    f[0] = f[1] = f[2] = 0;
    for (int r = 0; r < nr; r++)
        for (int32_t k = rk[2 * r]; k < rk[2 * r + 1]; k++) {
            const fm_grid_quad *e = &m->grid.quad[k >> 2];
            const float ex = e->x[k & 3] - q[0], ey = e->y[k & 3] - q[1], ez = e->z[k & 3] - q[2];
            if (ex * ex + ey * ey + ez * ez > r2) continue; /* beyond the cell: dis_ij >= A */
            const int64_t j = e->i[k & 3];
            if (j == i) continue;
            const double *pj = x + 3 * j;
            double d[3] = {pi[0] - pj[0], pi[1] - pj[1], pi[2] - pj[2]};
            double dis = distance_metric(d, m->manhattan);
            if (!(dis < m->reach)) continue;
            double w = exp(-dis * dis * m->inv_2sigma2), len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            if (len > 0) {
                for (int a = 0; a < 3; a++) f[a] += w * d[a] / len;
            } else {
                float u[3];
                int32_t lo = (int32_t)(i < j ? i : j), hi = (int32_t)(i < j ? j : i);
                fm_mde_coincident_dir(lo, hi, u);
                double s = i < j ? w : -w;
                for (int a = 0; a < 3; a++) f[a] += s * (double)u[a];
            }
        }
    for (int r = 0; r < nr; r++) candidates += rk[2 * r + 1] - rk[2 * r];
    return candidates;
}

/* One point's move: eq 5 in the tangent plane, then the orthogonal projection onto the mesh.
   Returns the neighbour candidates it examined. */
static int64_t move_point(const mosaic *m, const double *x, const int32_t *tri, int64_t i, double *x_out, int32_t *tri_out)
{
    double f[3];
    const int64_t candidates = repulsion(m, x, i, f);
    const double *n = fm_closest_face_normal(m->surface, tri[i]);
    double fn = f[0] * n[0] + f[1] * n[1] + f[2] * n[2];
    double step[3], len2 = 0;
    for (int a = 0; a < 3; a++) step[a] = m->dt * (f[a] - fn * n[a]), len2 += step[a] * step[a];
    if (!(len2 > 0)) { /* no neighbour: stays */
        memcpy(x_out + 3 * i, x + 3 * i, 3 * sizeof(double));
        tri_out[i] = tri[i];
        return candidates;
    }
    double q[3] = {x[3 * i] + step[0], x[3 * i + 1] + step[1], x[3 * i + 2] + step[2]};
    int64_t t = -1;
    /* x_i is on the mesh, so the mesh is within |step| of q: the search starts there */
    fm_closest_point(m->surface, q, sqrt(len2) + m->slack, x_out + 3 * i, &t);
    tri_out[i] = (int32_t)t;
    return candidates;
}

/* Reorders the points along a Hilbert curve through their bounding box, so that neighbours on the
   surface are mostly neighbours in memory (the grid walk and the BVH then stay in cache). */
static fm_status sort_spatially(int64_t n, double *x, int32_t *tri, fm_error *err)
{
    fm_keyed *k = malloc(sizeof(fm_keyed) * (size_t)n);
    double *x2 = malloc(sizeof(double) * 3 * (size_t)n);
    int32_t *t2 = malloc(sizeof(int32_t) * (size_t)n);
    if (!k || !x2 || !t2) {
        free(k), free(x2), free(t2);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld mosaic points", (long long)n);
    }
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, extent = 0;
    for (int64_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) lo[a] = fmin(lo[a], x[3 * i + a]), hi[a] = fmax(hi[a], x[3 * i + a]);
    for (int a = 0; a < 3; a++) extent = fmax(extent, hi[a] - lo[a]);
    const double scale = extent > 0 ? (double)((1u << FM_HILBERT_BITS) - 1) / extent : 0;
    for (int64_t i = 0; i < n; i++) k[i] = (fm_keyed){fm_hilbert_key(x + 3 * i, lo, scale), i};
    fm_keyed_sort(k, n);
    for (int64_t i = 0; i < n; i++) {
        memcpy(x2 + 3 * i, x + 3 * k[i].i, 3 * sizeof(double));
        t2[i] = tri[k[i].i];
    }
    memcpy(x, x2, sizeof(double) * 3 * (size_t)n);
    memcpy(tri, t2, sizeof(int32_t) * (size_t)n);
    free(k), free(x2), free(t2);
    return FM_OK;
}

static fm_status mosaic_init(mosaic *m, const fm_sample_ctx *c, fm_error *err)
{
    const double spacing = sqrt(c->area / (double)c->n);
    m->c = c;
    m->reach = c->opts.k * spacing;
    const double sigma = c->opts.w * spacing;
    m->inv_2sigma2 = 1.0 / (2.0 * sigma * sigma);
    m->dt = c->opts.step * spacing;
    m->manhattan = c->opts.manhattan != 0;
    for (int64_t i = 0; i < 3 * c->mesh->nv; i++) m->scale = fmax(m->scale, fabs(c->mesh->v[i]));
    m->slack = 1e-9 * m->scale + 1e-6 * spacing;
    m->surface = fm_closest_build(c->mesh, 1, "sampled mesh", 0, err);
    if (!m->surface) return err ? err->status : FM_ERR_INTERNAL;
    for (int k = 0; k < 3; k++) m->xyz[k] = fm_alloc(sizeof(float) * (size_t)c->n);
    if (!m->xyz[0] || !m->xyz[1] || !m->xyz[2])
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld mosaic points", (long long)c->n);
    return fm_grid_init(&m->grid, c->n, err);
}

static void mosaic_free(mosaic *m)
{
    fm_closest_destroy(m->surface);
    fm_grid_free(&m->grid);
    for (int k = 0; k < 3; k++) fm_free(m->xyz[k]);
}

/* One iteration's work: the neighbour candidates the repulsion examines, every point's 27 grid
 * cells, itself included (so at least n). The count depends on k and on the surface: about 14 k^2
 * a point on a smooth surface, up to n when the neighbourhood A spans the mesh, and more where
 * sheets of the surface lie closer than A. Counted here before the first iteration; the iterations
 * count their own (move_point). */
static int64_t iteration_candidates(const mosaic *m, int64_t n, int threads)
{
    int64_t total = 0;
#pragma omp parallel for num_threads(threads) schedule(static) reduction(+ : total)
    for (int64_t i = 0; i < n; i++) {
        int32_t rk[2 * FM_GRID_MAX_RANGES];
        const int nr = fm_grid_ranges(&m->grid, m->xyz[0][i], m->xyz[1][i], m->xyz[2][i], rk);
        for (int r = 0; r < nr; r++) total += rk[2 * r + 1] - rk[2 * r];
    }
    return total;
}

/* The work bound. The iterations' CPU time is estimated from what they do: the neighbour candidates
 * the repulsion examines, and the points each iteration moves and projects (the grid, the Embree
 * query). Measured with bench_sample (one thread, the project's 2-vCPU VM), a point and iteration
 * take 0.84 us at k 2 (55 candidates), 1.6 at k 4 (208), 4.5 at k 8 (947) and 15.6 at k 16 (3602)
 * on suzanne at 10^4 points, and 12.5 us at k 16 on the 320-triangle sphere at 2000 points, where
 * every point is every other's candidate: 6 ns a candidate and 0.6 us a point bound them all. The
 * iterations may take FM_SAMPLE_MOSAIC_MAX_SECONDS a surface, or what the default iterations take
 * at the default k for n points (with room: MOSAIC_FREE_CANDIDATES a point) if that is more, so
 * that the defaults run at any n the memory check allows, in a time that grows only as n. Past it
 * (k 16 and 10^5 iterations at 2000 points: about 40 minutes a surface) the sampler refuses before
 * its first iteration, with the iterations that would fit. */
#define MOSAIC_CANDIDATE_SECONDS 6e-9
#define MOSAIC_POINT_SECONDS 6e-7
#define MOSAIC_FREE_CANDIDATES 100.0

static double iteration_seconds(double candidates, int64_t n)
{
    return candidates * MOSAIC_CANDIDATE_SECONDS + (double)n * MOSAIC_POINT_SECONDS;
}

static double seconds_limit(int64_t n)
{
    return fmax(FM_SAMPLE_MOSAIC_MAX_SECONDS, FM_SAMPLE_MOSAIC_ITERATIONS * iteration_seconds(MOSAIC_FREE_CANDIDATES * (double)n, n));
}

/* Before iteration it: the time spent (done) and the rest at the rate of `now` candidates an
 * iteration (the first iteration's, counted up front, then the last one's) must stay within the
 * limit. So work past the limit is refused before the first iteration, and a run whose points move
 * into denser neighbourhoods (sheets of the surface nearer each other than A) stops when it would
 * pass the limit, not after. */
static fm_status check_work(const fm_sample_ctx *c, int it, double done, int64_t now, fm_error *err)
{
    const double each = iteration_seconds((double)now, c->n), total = done + each * (c->opts.iterations - it);
    const double limit = seconds_limit(c->n);
    if (total <= limit) return FM_OK;
    const int most = it + (int)fmax(0, floor((limit - done) / each));
    return fm_fail(err, FM_ERR_INPUT, "mosaic sampling: %d iterations over %lld points with k %g would take about %.0f CPU s "
                   "(%.0f neighbour candidates a point and iteration%s), more than the limit of %.0f CPU s; use at most %d "
                   "iterations, or a smaller k (the candidates are the points within about k sqrt(M/N) of each other)",
                   c->opts.iterations, (long long)c->n, c->opts.k, total, (double)now / (double)c->n,
                   it ? " once the points moved" : "", limit, most);
}

static void grid_points(mosaic *m, const fm_sample_ctx *c, const double *x)
{
    for (int64_t i = 0; i < c->n; i++)
        for (int k = 0; k < 3; k++) m->xyz[k][i] = (float)x[3 * i + k];
    fm_grid_build(&m->grid, (const float *const *)m->xyz, NULL, c->n, m->cell, c->threads);
}

/* The relaxation (Table I, lines 2-9), its time bounded by check_work. */
static fm_status relax(mosaic *m, const fm_sample_ctx *c, double *x, int32_t *tri, double *x2, int32_t *tri2, fm_error *err)
{
    /* cells larger than A by the float rounding of both points: a neighbour with dis_ij < A (in
       double) is always in the 27 cells around a point's (float) cell */
    m->cell = (float)(m->reach * (1.0 + 1e-6) + 4.0 * FLT_EPSILON * m->scale);
    double done = 0;
    int64_t now = 0;
    for (int it = 0; it < c->opts.iterations; it++) {
        grid_points(m, c, x);
        if (it == 0) now = iteration_candidates(m, c->n, c->threads);
        fm_status st = fm_build_stage(NULL, NULL, NULL, 0, c->opts.cancel, err);
        if (st == FM_OK) st = check_work(c, it, done, now, err);
        if (st != FM_OK) return st;
        now = 0;
#pragma omp parallel for num_threads(c->threads) schedule(dynamic, 256) reduction(+ : now)
        for (int64_t i = 0; i < c->n; i++) now += move_point(m, x, tri, i, x2, tri2);
        done += iteration_seconds((double)now, c->n);
        memcpy(x, x2, sizeof(double) * 3 * (size_t)c->n);
        memcpy(tri, tri2, sizeof(int32_t) * (size_t)c->n);
    }
    return FM_OK;
}

/* x (3 doubles a point) onto the mesh: each point's closest point and its triangle. */
static void project_points(const mosaic *m, int64_t n, double *x, int32_t *tri, double *x2)
{
#pragma omp parallel for num_threads(m->c->threads) schedule(dynamic, 256)
    for (int64_t i = 0; i < n; i++) {
        int64_t t = -1;
        fm_closest_point(m->surface, x + 3 * i, INFINITY, x2 + 3 * i, &t);
        tri[i] = (int32_t)t;
    }
    memcpy(x, x2, sizeof(double) * 3 * (size_t)n);
}

/* The mosaic from a random start (Table I) or, with `given`, from the points in x projected onto
 * the mesh; the relaxation then moves every point under its own index. */
static fm_status run_mosaic(const fm_sample_ctx *c, double *x, int32_t *tri, int given, fm_error *err)
{
    mosaic m = {0};
    fm_status st = mosaic_init(&m, c, err);
    double *x2 = NULL;
    int32_t *tri2 = NULL;
    if (st == FM_OK) {
        x2 = fm_alloc(sizeof(double) * 3 * (size_t)c->n);
        tri2 = fm_alloc(sizeof(int32_t) * (size_t)c->n);
        if (!x2 || !tri2) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld mosaic points", (long long)c->n);
    }
    if (st == FM_OK && given) project_points(&m, c->n, x, tri, x2);
    else if (st == FM_OK) {
        fm_sample_random_into(c, x, tri); /* Table I starts from random sampling */
        st = sort_spatially(c->n, x, tri, err);
    }
    if (st == FM_OK) st = relax(&m, c, x, tri, x2, tri2, err);
    fm_free(x2);
    fm_free(tri2);
    mosaic_free(&m);
    return st;
}

fm_status fm_sample_mosaic(const fm_sample_ctx *c, double *x, int32_t *tri, fm_error *err)
{
    return run_mosaic(c, x, tri, 0, err);
}

fm_status fm_sample_mosaic_from(const fm_sample_ctx *c, double *x, int32_t *tri, fm_error *err)
{
    return run_mosaic(c, x, tri, 1, err);
}
