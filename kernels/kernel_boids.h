/* Boids (Reynolds 1987; SCF "Basic Steering Behaviors"): separation, cohesion and alignment, each
 * with the agent's own perception radius, angle and weight (SCF: "every agent maintains its own
 * attribute list"), and MaxSpeed and MaxForce. Same rules as kernels.h: a pure function over an
 * agent range, no allocation, each agent writes only its own entries, so any split of the range
 * across threads gives the same bits.
 *
 * Every rule weighs a neighbour b smoothly, so that nothing kicks an agent when a neighbour enters or
 * leaves its radius or its view cone (issue 37: hard edges made the rules a source of noise):
 *   distance  k(rho) = (1 - rho^2)^2, rho = |x_b - x_a| / r (the rule's radius): 1 beside the agent,
 *             0 with a zero slope at the radius;
 *   bearing   g = smoothstep over the cosine c between a's velocity and x_b - x_a, from 0 at
 *             cos_half - FM_BOIDS_CONE_BAND to 1 at cos_half + FM_BOIDS_CONE_BAND (an agent at rest,
 *             or an angle of 360 degrees, sees all round: g = 1);
 * and w = g k. Over the neighbours each rule asks for a change of velocity (per second, as
 * Reynolds's steering "desired - velocity"), with W = max(1/4, sum w) (a weighted mean where there are
 * neighbours enough, fading to 0 with the last one instead of jumping):
 *   separation  S sum g s(rho) (x_a - x_b) / |x_a - x_b|,  s(rho) = (1 - rho)^2 (1 + 2 rho)
 *               (away, nearer and more neighbours harder; S per neighbour beside the agent)
 *   cohesion    S sum w (x_b - x_a) / (W r_c)            (toward their centre, S at the radius)
 *   alignment   sum w (v_b - v_a) / W                    (their velocity)
 * where S is the agent's MaxSpeed. The rules are relative to the neighbours, so a flock that moves as
 * one, evenly spaced, feels no alignment and balanced separation and cohesion: they shape the flock
 * without dragging it (Reynolds's MaxSpeed * unit(direction) - v per rule would brake a flock that
 * flies slower than MaxSpeed, and, always of size ~MaxSpeed, hit MaxForce so that the weights stop
 * mattering). The steering force is
 *   F = sum over rules of weight * steer, truncated to |F| <= MaxForce. */
#ifndef FM_KERNEL_BOIDS_H
#define FM_KERNEL_BOIDS_H

#include "grid.h"

#include <math.h>
#include <stdint.h>

enum { FM_BOIDS_SEPARATION = 0, FM_BOIDS_COHESION = 1, FM_BOIDS_ALIGNMENT = 2, FM_BOIDS_RULES = 3 };

/* Per-agent parameters, SoA, indexed by agent. */
typedef struct fm_boids_view {
    const float *radius[FM_BOIDS_RULES];   /* perception radius r = J / sqrt(N) (SCF eq 6) */
    const float *cos_half[FM_BOIDS_RULES]; /* cos(angle / 2); -1 sees all round */
    const float *weight[FM_BOIDS_RULES];
    const float *max_speed, *max_force;
} fm_boids_view;

/* Half the width, in cosine, of the band over which a rule's view cone fades out. */
#define FM_BOIDS_CONE_BAND 0.15f

/* W = max(FM_BOIDS_WEIGHT_FLOOR, sum w): below it a rule fades with its neighbours' weight. */
#define FM_BOIDS_WEIGHT_FLOOR 0.25

/* The bearing weight g of a neighbour whose direction makes cosine c with a's velocity. */
static inline float fm_boids_bearing(float c, float cos_half)
{
    if (cos_half <= -1.0f) return 1.0f;
    const float t = (c - (cos_half - FM_BOIDS_CONE_BAND)) * (0.5f / FM_BOIDS_CONE_BAND);
    if (t <= 0) return 0.0f;
    if (t >= 1) return 1.0f;
    return t * t * (3 - 2 * t);
}

/* Sums over one agent's perceived neighbours (double, so the order they come in barely matters). */
typedef struct fm_boids_sums {
    double rule[FM_BOIDS_RULES][3]; /* separation push, weighted cohesion offsets, weighted velocities */
    double weight[FM_BOIDS_RULES];  /* sum w of cohesion and alignment (separation's is unused) */
} fm_boids_sums;

/* Adds neighbour b (offset d, d2 = |d|^2, velocity vb) to the rules, for an agent heading h (|h| =
 * hlen; 0: at rest, it sees all round); inv_r holds 1 / r of each rule (0 for a rule of radius 0,
 * which sees no one). The weights in float, the sums in double. */
static inline void fm_boids_add(fm_boids_sums *s, const float d[3], float d2, const float vb[3], const float h[3],
                                float hlen, const float inv_r[3], const float cos_half[3])
{
    if (d2 == 0) return;
    const float dist = sqrtf(d2), inv_dist = 1.0f / dist;
    const float c = hlen > 0 ? (h[0] * d[0] + h[1] * d[1] + h[2] * d[2]) * inv_dist / hlen : 1.0f;
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        const float rho = dist * inv_r[r];
        if (inv_r[r] == 0 || !(rho < 1)) continue;
        const float g = hlen > 0 ? fm_boids_bearing(c, cos_half[r]) : 1.0f;
        if (g == 0) continue;
        if (r == FM_BOIDS_SEPARATION) {
            const double push = g * (1 - rho) * (1 - rho) * (1 + 2 * rho) * inv_dist;
            for (int k = 0; k < 3; k++) s->rule[r][k] -= push * d[k];
            continue;
        }
        const float q = 1 - rho * rho;
        const double w = g * q * q;
        for (int k = 0; k < 3; k++) s->rule[r][k] += w * (r == FM_BOIDS_COHESION ? d[k] : vb[k]);
        s->weight[r] += w;
    }
}

/* The steering force of agent a from its sums (see the top of this file). */
void fm_boids_steer(const fm_boids_sums *s, const fm_boids_view *b, int64_t a, const float v[3], float f[3]);

/* For agents a in [begin, end) with phase[a] == phase_sel: f(a) = the steering force from the
 * agents listed in g (built from these p with cell >= every radius; any agent, whatever its phase,
 * is a neighbour if listed); others untouched. No allocation. */
void fm_kernel_boids(const fm_grid *g, const fm_boids_view *b, const float *const p[3], const float *const v[3],
                     const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end, float *const f[3]);

/* The same forces, bit for bit, for the agents listed in g at entries [first, last) (0 <= first <=
 * last <= g->count) with phase[a] == phase_sel: in the grid's order, so that agents of one cell
 * follow each other and walk the same cells while they are in cache (an unsorted store, walked by
 * agent, meets every neighbourhood cold). Each agent writes only its own f entries, so any split of
 * the entries over threads gives the same bits. A selected agent that is not listed is not computed. */
void fm_kernel_boids_listed(const fm_grid *g, const fm_boids_view *b, const float *const v[3], const uint8_t *phase,
                            uint8_t phase_sel, int64_t first, int64_t last, float *const f[3]);

/* The reference twin for tests: the same forces from every pair of the n agents (O(n^2)), every
 * agent a neighbour. */
void fm_kernel_boids_reference(const fm_boids_view *b, const float *const p[3], const float *const v[3],
                               int64_t n, const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end,
                               float *const f[3]);

#endif
