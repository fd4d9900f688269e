/* Boids steering over the neighbour grid (SCF "Basic Steering Behaviors"); see kernel_boids.h. */
#include "kernel_boids.h"

#include <string.h>

#if defined(__SSE2__) && !defined(FM_BOIDS_SCALAR)
#include <emmintrin.h>
#define BOIDS_SSE2 1
#else
#define BOIDS_SSE2 0
#endif

void fm_boids_steer(const fm_boids_sums *s, const fm_boids_view *b, int64_t a, const float v[3], float f[3])
{
    const double max_speed = b->max_speed[a], max_force = b->max_force[a];
    double force[3] = {0, 0, 0};
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        const double w = b->weight[r][a], total = s->weight[r], norm = 1.0 / fmax(FM_BOIDS_WEIGHT_FLOOR, total);
        const float *sum = s->rule[r];
        if (r == FM_BOIDS_SEPARATION) {
            for (int k = 0; k < 3; k++) force[k] += w * max_speed * sum[k];
        } else if (r == FM_BOIDS_COHESION) {
            const double radius = b->radius[r][a];
            if (radius > 0)
                for (int k = 0; k < 3; k++) force[k] += w * max_speed * sum[k] * norm / radius;
        } else {
            for (int k = 0; k < 3; k++) force[k] += w * (sum[k] - total * v[k]) * norm; /* see kernel_boids.h */
        }
    }
    double len = sqrt(force[0] * force[0] + force[1] * force[1] + force[2] * force[2]);
    double scale = len > max_force ? max_force / len : 1.0;
    for (int k = 0; k < 3; k++) f[k] = (float)(force[k] * scale);
}

/* Agent a's view of one grid entry k that passed the r2_max test. */
static inline void add_entry(fm_boids_sums *sums, const fm_grid *g, int32_t k, int64_t a, const float x[3],
                             const float *const v[3], const fm_boids_viewer *viewer)
{
    const fm_grid_quad *q = &g->quad[k >> 2];
    const int lane = k & 3;
    const int32_t nb = q->i[lane];
    if (nb == a) return;
    const float d[3] = {q->x[lane] - x[0], q->y[lane] - x[1], q->z[lane] - x[2]};
    const fm_grid_quad *w = g->vel ? &g->vel[k >> 2] : NULL; /* the grid's copy, beside the position */
    const float vb[3] = {w ? w->x[lane] : v[0][nb], w ? w->y[lane] : v[1][nb], w ? w->z[lane] : v[2][nb]};
    fm_boids_add(sums, d, d[0] * d[0] + d[1] * d[1] + d[2] * d[2], vb, viewer);
}

/* The entries [b, e) of the grid within r2_max of x, in entry order, added to the sums. Most
 * candidates of the 27 cells are farther than the widest radius, so they are rejected 4 at a time
 * (SSE2, one aligned quad per test; -DFM_BOIDS_SCALAR or no SSE2 tests them one by one, with the
 * same float arithmetic and so the same hits in the same order). */
static void scan_range(fm_boids_sums *sums, const fm_grid *g, int32_t b, int32_t e, int64_t a, const float x[3],
                       const float *const v[3], const fm_boids_viewer *viewer, float r2_max)
{
#if BOIDS_SSE2
    const __m128 px = _mm_set1_ps(x[0]), py = _mm_set1_ps(x[1]), pz = _mm_set1_ps(x[2]), reach = _mm_set1_ps(r2_max);
    const __m128i lo = _mm_set1_epi32(b - 1), hi = _mm_set1_epi32(e), lanes = _mm_setr_epi32(0, 1, 2, 3);
    for (int32_t qi = b >> 2; qi <= (e - 1) >> 2; qi++) {
        const fm_grid_quad *q = &g->quad[qi];
        const __m128 dx = _mm_sub_ps(_mm_load_ps(q->x), px), dy = _mm_sub_ps(_mm_load_ps(q->y), py);
        const __m128 dz = _mm_sub_ps(_mm_load_ps(q->z), pz);
        const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
        const __m128i k = _mm_add_epi32(_mm_set1_epi32(4 * qi), lanes);
        const __m128i valid = _mm_and_si128(_mm_cmpgt_epi32(k, lo), _mm_cmplt_epi32(k, hi));
        int bits = _mm_movemask_ps(_mm_and_ps(_mm_cmplt_ps(d2, reach), _mm_castsi128_ps(valid)));
        while (bits) {
            const int lane = __builtin_ctz((unsigned)bits);
            bits &= bits - 1;
            add_entry(sums, g, 4 * qi + lane, a, x, v, viewer);
        }
    }
#else
    for (int32_t k = b; k < e; k++) {
        const fm_grid_quad *q = &g->quad[k >> 2];
        const int lane = k & 3;
        const float dx = q->x[lane] - x[0], dy = q->y[lane] - x[1], dz = q->z[lane] - x[2];
        if (dx * dx + dy * dy + dz * dz < r2_max) add_entry(sums, g, k, a, x, v, viewer);
    }
#endif
}

/* Agent a at x heading h: its steering force from the listed agents in the `count` ranges of its
 * 27 cells (fm_grid_ranges), into f. */
static void boids_agent(const fm_grid *g, const fm_boids_view *b, const float *const v[3], int64_t a, const float x[3],
                        const float h[3], const int32_t *ranges, int count, float *const f[3])
{
    fm_boids_viewer viewer;
    float r2_max;
    fm_boids_viewer_init(b, a, h, &viewer, &r2_max);
    fm_boids_sums sums = {{{0}}, {0}};
    for (int ri = 0; ri < count; ri++)
        scan_range(&sums, g, ranges[2 * ri], ranges[2 * ri + 1], a, x, v, &viewer, r2_max);
    float out[3];
    fm_boids_steer(&sums, b, a, h, out);
    for (int k = 0; k < 3; k++) f[k][a] = out[k];
}

void fm_kernel_boids(const fm_grid *g, const fm_boids_view *b, const float *const p[3], const float *const v[3],
                     const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end, float *const f[3])
{
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        const float x[3] = {p[0][a], p[1][a], p[2][a]}, h[3] = {v[0][a], v[1][a], v[2][a]};
        int32_t ranges[2 * FM_GRID_MAX_RANGES];
        const int count = fm_grid_ranges(g, x[0], x[1], x[2], ranges);
        boids_agent(g, b, v, a, x, h, ranges, count, f);
    }
}

void fm_kernel_boids_listed(const fm_grid *g, const fm_boids_view *b, const float *const v[3], const uint8_t *phase,
                            uint8_t phase_sel, int64_t first, int64_t last, float *const f[3])
{
    int32_t ranges[2 * FM_GRID_MAX_RANGES], cell[3] = {0, 0, 0};
    int count = -1; /* the ranges of `cell`, which the agents of one cell, walked in a row, share */
    for (int64_t k = first; k < last; k++) {
        const fm_grid_quad *q = &g->quad[k >> 2];
        const int lane = (int)(k & 3);
        const int32_t a = q->i[lane];
        if (phase[a] != phase_sel) continue;
        const float x[3] = {q->x[lane], q->y[lane], q->z[lane]}; /* the grid's copy: the same floats */
        const int32_t c[3] = {fm_grid_coord(fm_grid_scaled(g, x[0])), fm_grid_coord(fm_grid_scaled(g, x[1])),
                              fm_grid_coord(fm_grid_scaled(g, x[2]))}; /* as fm_grid_ranges places x */
        if (count < 0 || c[0] != cell[0] || c[1] != cell[1] || c[2] != cell[2])
            count = fm_grid_ranges(g, x[0], x[1], x[2], ranges), memcpy(cell, c, sizeof cell);
        const fm_grid_quad *w = g->vel ? &g->vel[k >> 2] : NULL;
        const float h[3] = {w ? w->x[lane] : v[0][a], w ? w->y[lane] : v[1][a], w ? w->z[lane] : v[2][a]};
        boids_agent(g, b, v, a, x, h, ranges, count, f);
    }
}

void fm_kernel_boids_reference(const fm_boids_view *b, const float *const p[3], const float *const v[3],
                               int64_t n, const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end,
                               float *const f[3])
{
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        const float h[3] = {v[0][a], v[1][a], v[2][a]};
        fm_boids_viewer viewer;
        float r2_max;
        fm_boids_viewer_init(b, a, h, &viewer, &r2_max);
        fm_boids_sums sums = {{{0}}, {0}};
        for (int64_t nb = 0; nb < n; nb++) {
            if (nb == a) continue;
            const float d[3] = {p[0][nb] - p[0][a], p[1][nb] - p[1][a], p[2][nb] - p[2][a]};
            const float vb[3] = {v[0][nb], v[1][nb], v[2][nb]};
            fm_boids_add(&sums, d, d[0] * d[0] + d[1] * d[1] + d[2] * d[2], vb, &viewer);
        }
        float out[3];
        fm_boids_steer(&sums, b, a, h, out);
        for (int k = 0; k < 3; k++) f[k][a] = out[k];
    }
}
