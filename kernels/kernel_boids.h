/* Boids (Reynolds 1987; SCF "Basic Steering Behaviors"): separation, cohesion and alignment, each
 * with the agent's own perception radius, angle and weight (SCF: "every agent maintains its own
 * attribute list"), and MaxSpeed and MaxForce. Same rules as kernels.h: a pure function over an
 * agent range, no allocation, each agent writes only its own entries, so any split of the range
 * across threads gives the same bits.
 *
 * Agent a perceives b for a rule when |x_b - x_a| < r (the rule's radius) and b lies inside the
 * rule's cone: the angle between a's velocity and x_b - x_a is at most half the rule's angle (an
 * agent at rest, or an angle of 360 degrees, sees all round). Over the perceived neighbours, each
 * rule asks for a change of velocity (per second, as Reynolds's steering "desired - velocity"):
 *   separation  S r_s * mean (x_a - x_b) / |x_a - x_b|^2   (away, nearer neighbours harder: S
 *                                                         from one at the radius)
 *   cohesion    S * mean (x_b - x_a) / r_c                (toward their centre, S at the radius)
 *   alignment   mean v_b - v_a                            (their velocity)
 * for a rule with at least one neighbour (else 0). The rules are relative to the neighbours, so a
 * flock that moves as one, evenly spaced, feels none of them: they shape the flock without
 * dragging it (Reynolds's MaxSpeed * unit(direction) - v per rule would brake a flock that flies
 * slower than MaxSpeed, and, always of size ~MaxSpeed, hit MaxForce so that the weights stop
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

/* The perception test, shared by the kernel and its reference so both pick the same neighbours:
 * d2 = |x_b - x_a|^2 (float, dx*dx + dy*dy + dz*dz), hd = v_a . (x_b - x_a), hlen_dist =
 * |v_a| sqrtf(d2). */
static inline int fm_boids_sees(float d2, float hd, float hlen_dist, float hlen, float r2, float cos_half)
{
    if (!(d2 < r2) || d2 == 0) return 0;
    return cos_half <= -1.0f || hlen == 0 || hd >= cos_half * hlen_dist;
}

/* Sums over one agent's perceived neighbours (double, so the order they come in barely matters). */
typedef struct fm_boids_sums {
    double rule[FM_BOIDS_RULES][3]; /* separation sum, cohesion offset sum, alignment velocity sum */
    int32_t count[FM_BOIDS_RULES];
} fm_boids_sums;

/* Adds neighbour b (offset d, d2 = |d|^2, velocity vb) to the rules that perceive it. */
static inline void fm_boids_add(fm_boids_sums *s, const float d[3], float d2, const float vb[3], const float h[3],
                                float hlen, const float r2[3], const float cos_half[3])
{
    const float hd = h[0] * d[0] + h[1] * d[1] + h[2] * d[2], hlen_dist = hlen * sqrtf(d2);
    if (fm_boids_sees(d2, hd, hlen_dist, hlen, r2[FM_BOIDS_SEPARATION], cos_half[FM_BOIDS_SEPARATION])) {
        const double inv_d2 = 1.0 / d2;
        for (int k = 0; k < 3; k++) s->rule[FM_BOIDS_SEPARATION][k] -= d[k] * inv_d2;
        s->count[FM_BOIDS_SEPARATION]++;
    }
    if (fm_boids_sees(d2, hd, hlen_dist, hlen, r2[FM_BOIDS_COHESION], cos_half[FM_BOIDS_COHESION])) {
        for (int k = 0; k < 3; k++) s->rule[FM_BOIDS_COHESION][k] += d[k];
        s->count[FM_BOIDS_COHESION]++;
    }
    if (fm_boids_sees(d2, hd, hlen_dist, hlen, r2[FM_BOIDS_ALIGNMENT], cos_half[FM_BOIDS_ALIGNMENT])) {
        for (int k = 0; k < 3; k++) s->rule[FM_BOIDS_ALIGNMENT][k] += vb[k];
        s->count[FM_BOIDS_ALIGNMENT]++;
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
