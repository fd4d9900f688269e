/* Boids steering over the neighbour grid (SCF "Basic Steering Behaviors"); see kernel_boids.h. */
#include "kernel_boids.h"

void fm_boids_steer(const fm_boids_sums *s, const fm_boids_view *b, int64_t a, const float v[3], float f[3])
{
    const double max_speed = b->max_speed[a], max_force = b->max_force[a];
    double force[3] = {0, 0, 0};
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        const double *dir = s->rule[r];
        double len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        if (s->count[r] == 0 || !(len > 0)) continue;
        const double w = b->weight[r][a];
        for (int k = 0; k < 3; k++) force[k] += w * (max_speed * dir[k] / len - v[k]); /* desired - velocity */
    }
    double len = sqrt(force[0] * force[0] + force[1] * force[1] + force[2] * force[2]);
    double scale = len > max_force ? max_force / len : 1.0;
    for (int k = 0; k < 3; k++) f[k] = (float)(force[k] * scale);
}

/* The agent's own perception parameters. */
static void agent_params(const fm_boids_view *b, int64_t a, float r2[3], float cos_half[3], float *r2_max)
{
    *r2_max = 0;
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        r2[r] = b->radius[r][a] * b->radius[r][a];
        cos_half[r] = b->cos_half[r][a];
        if (r2[r] > *r2_max) *r2_max = r2[r];
    }
}

void fm_kernel_boids(const fm_grid *g, const fm_boids_view *b, const float *const p[3], const float *const v[3],
                     const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end, float *const f[3])
{
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        const float x[3] = {p[0][a], p[1][a], p[2][a]}, h[3] = {v[0][a], v[1][a], v[2][a]};
        const float hlen = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        float r2[3], cos_half[3], r2_max;
        agent_params(b, a, r2, cos_half, &r2_max);
        fm_boids_sums sums = {{{0}}, {0}};
        int32_t ranges[2 * FM_GRID_MAX_RANGES];
        const int count = fm_grid_ranges(g, x[0], x[1], x[2], ranges);
        for (int ri = 0; ri < count; ri++) {
            for (int32_t e = ranges[2 * ri]; e < ranges[2 * ri + 1]; e++) {
                const fm_grid_quad *q = &g->quad[e >> 2];
                const int lane = e & 3;
                const int32_t nb = q->i[lane];
                const float d[3] = {q->x[lane] - x[0], q->y[lane] - x[1], q->z[lane] - x[2]};
                const float d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if (nb == a || !(d2 < r2_max)) continue;
                const float vb[3] = {v[0][nb], v[1][nb], v[2][nb]};
                fm_boids_add(&sums, d, d2, vb, h, hlen, r2, cos_half);
            }
        }
        float out[3];
        fm_boids_steer(&sums, b, a, h, out);
        for (int k = 0; k < 3; k++) f[k][a] = out[k];
    }
}

void fm_kernel_boids_reference(const fm_boids_view *b, const float *const p[3], const float *const v[3],
                               int64_t n, const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end,
                               float *const f[3])
{
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        const float h[3] = {v[0][a], v[1][a], v[2][a]};
        const float hlen = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        float r2[3], cos_half[3], r2_max;
        agent_params(b, a, r2, cos_half, &r2_max);
        fm_boids_sums sums = {{{0}}, {0}};
        for (int64_t nb = 0; nb < n; nb++) {
            if (nb == a) continue;
            const float d[3] = {p[0][nb] - p[0][a], p[1][nb] - p[1][a], p[2][nb] - p[2][a]};
            const float vb[3] = {v[0][nb], v[1][nb], v[2][nb]};
            fm_boids_add(&sums, d, d[0] * d[0] + d[1] * d[1] + d[2] * d[2], vb, h, hlen, r2, cos_half);
        }
        float out[3];
        fm_boids_steer(&sums, b, a, h, out);
        for (int k = 0; k < 3; k++) f[k][a] = out[k];
    }
}
