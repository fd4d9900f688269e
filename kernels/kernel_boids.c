/* Boids steering over the neighbour grid (SCF "Basic Steering Behaviors"); see kernel_boids.h. The
 * scalar walks and the dispatch; the SIMD walk is in kernel_boids_simd.c. */
#include "kernel_boids.h"
#include "simd.h"

/* A fixed-point sum back in the units of its terms (1 / scale, a power of two, is exact: the same
 * bits as dividing by it, at a multiplication's cost; the inverses are the viewer's, once per walk). */
static double unfixed(uint64_t sum, double inv_scale) { return (double)(int64_t)sum * inv_scale; }

void fm_boids_steer(const fm_boids_sums *s, const fm_boids_viewer *w, const fm_boids_view *b, int64_t a,
                    const float v[3], float *const f[3])
{
    const double max_speed = b->max_speed[a], max_force = b->max_force[a], inv_unit = w->inv_unit_scale;
    double force[3] = {0, 0, 0};
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        const double weight = b->weight[r][a], total = unfixed(s->weight[r], inv_unit);
        const double norm = 1.0 / fmax(FM_BOIDS_WEIGHT_FLOOR, total), inv_scale = w->inv_scale[r];
        double sum[3];
        for (int k = 0; k < 3; k++) sum[k] = unfixed(s->rule[r][k], inv_scale);
        if (r == FM_BOIDS_SEPARATION) {
            for (int k = 0; k < 3; k++) force[k] -= weight * max_speed * sum[k]; /* away from them */
        } else if (r == FM_BOIDS_COHESION) {
            const double radius = b->radius[r][a];
            if (radius > 0)
                for (int k = 0; k < 3; k++) force[k] += weight * max_speed * sum[k] * norm / radius;
        } else {
            for (int k = 0; k < 3; k++) force[k] += weight * (sum[k] - total * v[k]) * norm; /* see kernel_boids.h */
        }
    }
    double len = sqrt(force[0] * force[0] + force[1] * force[1] + force[2] * force[2]);
    double scale = len > max_force ? max_force / len : 1.0;
    for (int k = 0; k < 3; k++) f[k][a] = (float)(force[k] * scale);
}

/* Agent a at x heading h (viewer w, its scales set): its steering force from the listed agents in
 * the `count` ranges of its 27 cells (fm_grid_ranges), into f; neighbour k's position from the
 * grid's quads, its velocity from v by agent, or with v NULL from the grid's entry-order copy (any
 * order of the neighbours gives the same sums). */
static void boids_agent(const fm_grid *g, const fm_boids_view *b, const float *const v[3], int64_t a, const float x[3],
                        const float h[3], const int32_t *ranges, int count, fm_boids_viewer *w, float *const f[3])
{
    float r2_max;
    fm_boids_viewer_init(b, a, h, w, &r2_max);
    fm_boids_sums sums = {{{0}}, {0}};
    for (int ri = 0; ri < count; ri++)
        for (int32_t k = ranges[2 * ri]; k < ranges[2 * ri + 1]; k++) {
            const fm_grid_quad *q = &g->quad[k >> 2];
            const int lane = k & 3;
            const float d[3] = {q->x[lane] - x[0], q->y[lane] - x[1], q->z[lane] - x[2]};
            const float d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if (!(d2 < r2_max)) continue;
            const int32_t nb = q->i[lane];
            const float vb[3] = {v ? v[0][nb] : g->soa[3][k], v ? v[1][nb] : g->soa[4][k], v ? v[2][nb] : g->soa[5][k]};
            fm_boids_add(&sums, d, d2, vb, w);
        }
    fm_boids_steer(&sums, w, b, a, h, f);
}

void fm_kernel_boids(const fm_grid *g, const fm_boids_view *b, const float *const p[3], const float *const v[3],
                     const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end, float *const f[3])
{
    fm_boids_viewer viewer;
    fm_boids_viewer_scales(b, &viewer);
    int32_t ranges[2 * FM_GRID_MAX_RANGES];
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        const float x[3] = {p[0][a], p[1][a], p[2][a]}, h[3] = {v[0][a], v[1][a], v[2][a]};
        const int count = fm_grid_ranges(g, x[0], x[1], x[2], ranges);
        boids_agent(g, b, v, a, x, h, ranges, count, &viewer, f);
    }
}

void fm_kernel_boids_listed_ref(const fm_grid *g, const fm_boids_view *b, const uint8_t *phase, uint8_t phase_sel,
                                int64_t first, int64_t last, float *const f[3])
{
    fm_boids_viewer viewer;
    fm_boids_viewer_scales(b, &viewer);
    int32_t ranges[2 * FM_GRID_MAX_RANGES];
    for (int64_t k = first; k < last; k++) {
        const int32_t a = g->quad[k >> 2].i[k & 3];
        if (phase[a] != phase_sel) continue;
        const float *const *c = (const float *const *)g->soa; /* x, y, z, vx, vy, vz by entry */
        const float x[3] = {c[0][k], c[1][k], c[2][k]}, h[3] = {c[3][k], c[4][k], c[5][k]};
        const int count = fm_grid_ranges(g, x[0], x[1], x[2], ranges);
        boids_agent(g, b, NULL, a, x, h, ranges, count, &viewer, f);
    }
}

FM_SIMD_DECLARE(fm_boids_listed_fn, fm_kernel_boids_listed);

void fm_kernel_boids_listed(const fm_grid *g, const fm_boids_view *b, const uint8_t *phase, uint8_t phase_sel,
                            int64_t first, int64_t last, float *const f[3])
{
    fm_boids_listed_fn *variant = FM_SIMD_PICK(fm_kernel_boids_listed);
    (variant ? variant : fm_kernel_boids_listed_ref)(g, b, phase, phase_sel, first, last, f);
}

void fm_kernel_boids_reference(const fm_boids_view *b, const float *const p[3], const float *const v[3],
                               int64_t n, const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end,
                               float *const f[3])
{
    fm_boids_viewer viewer;
    fm_boids_viewer_scales(b, &viewer);
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        const float h[3] = {v[0][a], v[1][a], v[2][a]};
        float r2_max;
        fm_boids_viewer_init(b, a, h, &viewer, &r2_max);
        fm_boids_sums sums = {{{0}}, {0}};
        for (int64_t nb = 0; nb < n; nb++) {
            const float d[3] = {p[0][nb] - p[0][a], p[1][nb] - p[1][a], p[2][nb] - p[2][a]};
            const float vb[3] = {v[0][nb], v[1][nb], v[2][nb]};
            fm_boids_add(&sums, d, d[0] * d[0] + d[1] * d[1] + d[2] * d[2], vb, &viewer);
        }
        fm_boids_steer(&sums, &viewer, b, a, h, f);
    }
}
