/* Agent-to-sample correspondence (SCF §3, "Point Correspondence Establishment").
 *
 * The paper obtains coherent correspondences between overlapping consecutive shapes "by
 * spherically projecting source positions on the first shape onto the surface of the second
 * shape". We match by that projection: both point sets are projected onto unit spheres around
 * their own centroids, and agents take the samples whose directions are nearest theirs. An exact
 * assignment (n^3) is out of reach for 10^6 agents, so:
 *   1. both sets are sorted along a 3D Hilbert curve through their unit directions (Skilling,
 *      "Programming the Hilbert curve", 2004; 21 bits per axis), which keeps nearby directions
 *      nearby in the order, and matched rank to rank;
 *   2. a few passes over the agents in curve order let each agent swap samples with the next
 *      MATCH_WINDOW agents along the curve whenever that lowers the pair's summed squared
 *      direction distance |u_a - v_s|^2; every swap lowers the total, so the passes converge.
 * Everything is sequential and depends only on the input, never on threads. */
#include "sample.h"
#include "grid.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { MATCH_WINDOW = 8, MATCH_PASSES = 4, UNCROSS_ROUNDS = 32 };

/* The layouts whose neighbours uncrossing compares (fm_match_uncross): eq 11's offsets at these
 * blends w, (1 - w) x + w y, the source's (w = 0) and three on the way. */
static const double UNCROSS_BLENDS[] = {0.0, 0.25, 0.5, 0.75};
enum { UNCROSS_LAYOUTS = sizeof UNCROSS_BLENDS / sizeof UNCROSS_BLENDS[0] };

/* Unit directions from the centroid (0 for a point at the centroid) and their curve order. */
static void directions(const float *p, int64_t n, double *u, fm_keyed *order)
{
    double c[3] = {0, 0, 0};
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) c[k] += (double)p[3 * i + k];
    for (int k = 0; k < 3; k++) c[k] /= (double)n;
    const double lo[3] = {-1, -1, -1}, scale = 0.5 * (double)((1u << FM_HILBERT_BITS) - 1);
    for (int64_t i = 0; i < n; i++) {
        double d[3], len = 0;
        for (int k = 0; k < 3; k++) d[k] = (double)p[3 * i + k] - c[k], len += d[k] * d[k];
        len = sqrt(len);
        for (int k = 0; k < 3; k++) u[3 * i + k] = len > 0 ? d[k] / len : 0.0;
        order[i] = (fm_keyed){fm_hilbert_key(u + 3 * i, lo, scale), i};
    }
    fm_keyed_sort(order, n);
}

static double dir_cost(const double *u, const double *v)
{
    double d0 = u[0] - v[0], d1 = u[1] - v[1], d2 = u[2] - v[2];
    return d0 * d0 + d1 * d1 + d2 * d2;
}

static void improve_by_swaps(const double *ua, const double *us, const fm_keyed *agents, int64_t n, int64_t *out)
{
    for (int pass = 0; pass < MATCH_PASSES; pass++) {
        int64_t swaps = 0;
        for (int64_t r = 0; r < n; r++) {
            const int64_t a = agents[r].i;
            for (int64_t w = 1; w <= MATCH_WINDOW && r + w < n; w++) {
                const int64_t b = agents[r + w].i;
                const double *pa = ua + 3 * a, *pb = ua + 3 * b, *sa = us + 3 * out[a], *sb = us + 3 * out[b];
                if (dir_cost(pa, sb) + dir_cost(pb, sa) < dir_cost(pa, sa) + dir_cost(pb, sb)) {
                    int64_t t = out[a];
                    out[a] = out[b], out[b] = t, swaps++;
                }
            }
        }
        if (swaps == 0) break;
    }
}

static fm_status match_spherical(const float *agents, const float *samples, int64_t n, int64_t *out, fm_error *err)
{
    double *ua = malloc(sizeof(double) * 3 * (size_t)n), *us = malloc(sizeof(double) * 3 * (size_t)n);
    fm_keyed *ra = malloc(sizeof(fm_keyed) * (size_t)n), *rs = malloc(sizeof(fm_keyed) * (size_t)n);
    fm_status st = FM_OK;
    if (!ua || !us || !ra || !rs) {
        st = fm_fail(err, FM_ERR_MEMORY, "out of memory matching %lld agents", (long long)n);
    } else {
        directions(agents, n, ua, ra);
        directions(samples, n, us, rs);
        for (int64_t r = 0; r < n; r++) out[ra[r].i] = rs[r].i;
        improve_by_swaps(ua, us, ra, n, out);
    }
    free(ua), free(us), free(ra), free(rs);
    return st;
}

/* Points less their centroid, in double; returns the largest extent of their bounding box. */
static double centred(const float *p, int64_t n, double *x)
{
    double c[3] = {0, 0, 0}, lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) c[k] += (double)p[3 * i + k];
    for (int k = 0; k < 3; k++) c[k] /= (double)n;
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            x[3 * i + k] = (double)p[3 * i + k] - c[k];
            lo[k] = fmin(lo[k], x[3 * i + k]), hi[k] = fmax(hi[k], x[3 * i + k]);
        }
    return fmax(fmax(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
}

/* Swapping a's and b's samples lowers |x_a - y_a|^2 + |x_b - y_b|^2 by exactly -2 (x_a - x_b) . (y_a - y_b). */
static int uncross_pair(const double *x, const double *y, int64_t a, int64_t b, int64_t *match)
{
    const double *xa = x + 3 * a, *xb = x + 3 * b, *ya = y + 3 * match[a], *yb = y + 3 * match[b];
    const double turn = (xa[0] - xb[0]) * (ya[0] - yb[0]) + (xa[1] - xb[1]) * (ya[1] - yb[1]) + (xa[2] - xb[2]) * (ya[2] - yb[2]);
    if (!(turn < 0)) return 0;
    const int64_t t = match[a];
    match[a] = match[b], match[b] = t;
    return 1;
}

/* One pass of uncrossing: every agent a with todo[a] (all where todo is NULL), in index order,
 * against every other in its grid cell's 27; a swapped pair is marked in changed. Returns the swaps. */
static int64_t uncross_pass(const fm_grid *g, const float *const z[3], const double *x, const double *y, int64_t n,
                            const uint8_t *todo, uint8_t *changed, int64_t *match)
{
    int64_t swaps = 0;
    for (int64_t a = 0; a < n; a++) {
        if (todo && !todo[a] && !changed[a]) continue;
        int32_t rk[2 * FM_GRID_MAX_RANGES];
        const int ranges = fm_grid_ranges(g, z[0][a], z[1][a], z[2][a], rk);
        for (int r = 0; r < ranges; r++)
            for (int32_t e = rk[2 * r]; e < rk[2 * r + 1]; e++) {
                const int64_t b = g->quad[e >> 2].i[e & 3];
                if (b != a && uncross_pair(x, y, a, b, match)) swaps++, changed[a] = changed[b] = 1;
            }
    }
    return swaps;
}

/* The layout at blend w of the current match into z, and its grid (cells of `cell`). */
static void blended_grid(fm_grid *g, const double *x, const double *y, const int64_t *match, int64_t n, double w,
                         float cell, float *const z[3])
{
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) z[k][i] = (float)((1 - w) * x[3 * i + k] + w * y[3 * match[i] + k]);
    fm_grid_build(g, (const float *const *)z, NULL, n, cell, 1);
}

fm_status fm_match_uncross(const float *agents, const float *samples, int64_t n, int64_t *match, fm_error *err)
{
    if (n < 2) return FM_OK;
    double *x = malloc(sizeof(double) * 3 * (size_t)n), *y = malloc(sizeof(double) * 3 * (size_t)n);
    float *z[3] = {malloc(sizeof(float) * (size_t)n), malloc(sizeof(float) * (size_t)n), malloc(sizeof(float) * (size_t)n)};
    uint8_t *todo = calloc((size_t)n, 1), *changed = calloc((size_t)n, 1);
    fm_grid g = {0};
    fm_status st = !x || !y || !z[0] || !z[1] || !z[2] || !todo || !changed
                       ? fm_fail(err, FM_ERR_MEMORY, "out of memory uncrossing %lld agents", (long long)n)
                       : fm_grid_init(&g, n, err);
    if (st == FM_OK) {
        const double extent = centred(agents, n, x);
        centred(samples, n, y);
        /* cells of about four spacings of n points on a surface in this box: pairs that are not
         * next to each other but close enough to cross are compared too */
        const float cell = extent > 0 ? (float)(4.0 * extent / sqrt((double)n)) : 1.0f;
        /* only a pair with an agent whose destination changed can have turned crossing: after the
         * first round (every agent), each round looks at those of the round before */
        for (int round = 0; round < UNCROSS_ROUNDS; round++) {
            int64_t swaps = 0;
            for (int l = 0; l < UNCROSS_LAYOUTS; l++) {
                blended_grid(&g, x, y, match, n, UNCROSS_BLENDS[l], cell, z);
                swaps += uncross_pass(&g, (const float *const *)z, x, y, n, round ? todo : NULL, changed, match);
            }
            if (swaps == 0) break;
            uint8_t *t = todo;
            todo = changed, changed = t;
            memset(changed, 0, (size_t)n);
        }
    }
    fm_grid_free(&g);
    free(x), free(y), free(z[0]), free(z[1]), free(z[2]), free(todo), free(changed);
    return st;
}

/* Fisher-Yates from a splitmix64 stream; the modulo bias (< n / 2^64) does not matter here. */
static void match_random(int64_t n, uint64_t seed, int64_t *out)
{
    uint64_t s = seed;
    for (int64_t i = 0; i < n; i++) out[i] = i;
    for (int64_t i = n - 1; i > 0; i--) {
        int64_t j = (int64_t)(fm_splitmix64(&s) % (uint64_t)(i + 1)), t = out[i];
        out[i] = out[j], out[j] = t;
    }
}

static fm_status check_points(const float *p, int64_t n, const char *what, fm_error *err)
{
    if (!p) return fm_fail(err, FM_ERR_INPUT, "fm_match_agents: no %s positions given", what);
    for (int64_t i = 0; i < 3 * n; i++)
        if (!isfinite(p[i])) return fm_fail(err, FM_ERR_INPUT, "fm_match_agents: %s %lld is not finite", what, (long long)(i / 3));
    return FM_OK;
}

fm_status fm_match_agents(const float *agents, const float *samples, int64_t n, fm_match_method m, uint64_t seed,
                          int64_t *out, fm_error *err)
{
    if (n < 0) return fm_fail(err, FM_ERR_INPUT, "fm_match_agents: negative count %lld", (long long)n);
    if (m != FM_MATCH_RANDOM && m != FM_MATCH_SPHERICAL)
        return fm_fail(err, FM_ERR_INPUT, "unknown matching method %d (0 random, 1 spherical)", (int)m);
    if (n == 0) return FM_OK;
    if (!out) return fm_fail(err, FM_ERR_INPUT, "fm_match_agents: no output given");
    if (m == FM_MATCH_RANDOM) {
        match_random(n, seed, out);
        return FM_OK;
    }
    fm_status st = check_points(agents, n, "agent", err);
    if (st == FM_OK) st = check_points(samples, n, "sample", err);
    return st == FM_OK ? match_spherical(agents, samples, n, out, err) : st;
}
