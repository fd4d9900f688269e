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
#include <string.h>

enum { FM_BOIDS_SEPARATION = 0, FM_BOIDS_COHESION = 1, FM_BOIDS_ALIGNMENT = 2, FM_BOIDS_RULES = 3 };

/* Per-agent parameters, SoA, indexed by agent; and two bounds of the whole flock that set the fixed
 * point of the sums (below). */
typedef struct fm_boids_view {
    const float *radius[FM_BOIDS_RULES];   /* perception radius r = J / sqrt(N) (SCF eq 6) */
    const float *cos_half[FM_BOIDS_RULES]; /* cos(angle / 2); -1 sees all round */
    const float *weight[FM_BOIDS_RULES];
    const float *max_speed, *max_force;
    float reach;                           /* >= every radius (0: taken as 1) */
    float top_speed;                       /* >= every neighbour's speed (0: taken as 1) */
} fm_boids_view;

/* Half the width, in cosine, of the band over which a rule's view cone fades out. */
#define FM_BOIDS_CONE_BAND 0.15f

/* W = max(FM_BOIDS_WEIGHT_FLOOR, sum w): below it a rule fades with its neighbours' weight. */
#define FM_BOIDS_WEIGHT_FLOOR 0.25

/* The sums over an agent's neighbours are exact: each neighbour's term is computed in float, scaled
 * by a power of two and rounded to a 64-bit integer (round to nearest even), and the integers are
 * added. Integer addition is associative, so the sums, and the forces, are the same bits whatever
 * order the neighbours come in: the store's order, the grid's cells, the SIMD lanes that add them,
 * the thread and rank counts. A term as large as its bound (1 for the separation's unit push and the
 * weights, the reach for the cohesion offsets, the top speed for the velocities) is 2^31 units
 * (FM_BOIDS_FIXED_BITS), so a sum holds 2^32 such terms, and its resolution is 2^-31 of the bound
 * (float's own is 2^-24). A term beyond 2^19 times its bound (bad input) is clamped, not undefined. */
#define FM_BOIDS_FIXED_BITS 31
#define FM_BOIDS_FIXED_CLAMP 0x1p50f

/* 2^FM_BOIDS_FIXED_BITS / the power of two above `bound` (2^e with bound < 2^e <= 2 bound; a bound
 * that is <= 0, not finite or outside [2^-90, 2^100): 1), from the float's exponent bits (no libm:
 * every viewer computes it). */
static inline float fm_boids_fixed_scale(float bound)
{
    int e = 1;
    if (bound >= 0x1p-90f && bound < 0x1p100f) {
        uint32_t bits;
        memcpy(&bits, &bound, sizeof bits);
        e = (int)((bits >> 23) & 0xffu) - 126; /* bound = m 2^e, 0.5 <= m < 1 */
    }
    const uint32_t out = (uint32_t)(FM_BOIDS_FIXED_BITS - e + 127) << 23;
    float scale;
    memcpy(&scale, &out, sizeof scale);
    return scale;
}

/* x scaled (a power of two: exact), clamped and rounded to the nearest integer, ties to even: the
 * double's mantissa rounds it when 1.5 * 2^52 is added (|x| < 2^51), the same rounding the SIMD
 * conversions do. NaN counts as the lower clamp, as the SIMD max does. */
static inline int64_t fm_boids_fixed(float x)
{
    x = x > -FM_BOIDS_FIXED_CLAMP ? x : -FM_BOIDS_FIXED_CLAMP;
    x = x < FM_BOIDS_FIXED_CLAMP ? x : FM_BOIDS_FIXED_CLAMP;
    const double y = (double)x + 0x1.8p52;
    int64_t bits;
    memcpy(&bits, &y, sizeof bits);
    return bits - INT64_C(0x4338000000000000);
}

/* Sums over one agent's perceived neighbours, in fixed point (above; unsigned, so that even a
 * clamped overflow wraps instead of being undefined). */
typedef struct fm_boids_sums {
    uint64_t rule[FM_BOIDS_RULES][3]; /* separation's pushes toward the neighbours, weighted cohesion
                                         offsets, weighted velocities */
    uint64_t weight[FM_BOIDS_RULES];  /* sum w of cohesion and alignment (separation's is unused) */
} fm_boids_sums;

/* One agent as it perceives, prepared once for all its neighbours (fm_boids_viewer_init). */
typedef struct fm_boids_viewer {
    float unit[3];                 /* its heading, unit (0 at rest) */
    float inv_r[FM_BOIDS_RULES];   /* 1 / r of each rule; infinite for a radius of 0, which sees no one */
    float lo[FM_BOIDS_RULES];      /* where the cone's band starts, in cosine (below -1: sees all round) */
    float scale[FM_BOIDS_RULES];   /* the fixed point of each rule's vector terms (the weights': unit_scale) */
    float unit_scale;              /* of a term bounded by 1 */
    double inv_scale[FM_BOIDS_RULES], inv_unit_scale; /* their inverses (powers of two: exact) */
} fm_boids_viewer;

/* The fixed point of the view's sums, the same for every agent: set once per walk, before
 * fm_boids_viewer_init, which leaves it. */
static inline void fm_boids_viewer_scales(const fm_boids_view *b, fm_boids_viewer *w)
{
    w->unit_scale = fm_boids_fixed_scale(1.0f);
    w->scale[FM_BOIDS_SEPARATION] = w->unit_scale;
    w->scale[FM_BOIDS_COHESION] = fm_boids_fixed_scale(b->reach);
    w->scale[FM_BOIDS_ALIGNMENT] = fm_boids_fixed_scale(b->top_speed);
    for (int r = 0; r < FM_BOIDS_RULES; r++) w->inv_scale[r] = 1.0 / (double)w->scale[r];
    w->inv_unit_scale = 1.0 / (double)w->unit_scale;
}

/* Agent a heading h (w's scales already set); r2_max = the widest r^2. */
static inline void fm_boids_viewer_init(const fm_boids_view *b, int64_t a, const float h[3], fm_boids_viewer *w,
                                        float *r2_max)
{
    const float hlen = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    for (int k = 0; k < 3; k++) w->unit[k] = hlen > 0 ? h[k] / hlen : 0.0f;
    *r2_max = 0;
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        const float radius = b->radius[r][a], cos_half = b->cos_half[r][a];
        w->inv_r[r] = radius > 0 ? 1.0f / radius : INFINITY;
        w->lo[r] = cos_half <= -1.0f || hlen == 0 ? -3.0f : cos_half - FM_BOIDS_CONE_BAND;
        if (radius * radius > *r2_max) *r2_max = radius * radius;
    }
}

/* Adds neighbour b (offset d, d2 = |d|^2, velocity vb) to the rules of viewer w; the bearing weight g
 * is the smoothstep of t = (c - lo) / (2 band), clamped to [0, 1] (a viewer that sees all round has
 * t >= 1 for any c >= -1). The SIMD walk (kernel_boids_simd.c) does these float operations in this
 * order, lane by lane. */
static inline void fm_boids_add(fm_boids_sums *s, const float d[3], float d2, const float vb[3], const fm_boids_viewer *w)
{
    if (!(d2 > 0)) return; /* itself, or an agent on the same spot */
    const float dist = sqrtf(d2), inv_dist = 1.0f / dist;
    const float c = (w->unit[0] * d[0] + w->unit[1] * d[1] + w->unit[2] * d[2]) * inv_dist;
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        const float rho = dist * w->inv_r[r];
        if (!(rho < 1)) continue;
        float t = (c - w->lo[r]) * (0.5f / FM_BOIDS_CONE_BAND);
        if (!(t > 0)) continue;
        t = t < 1 ? t : 1; /* not fminf: a library call where its NaN rule is kept */
        const float g = t * t * (3 - 2 * t);
        if (r == FM_BOIDS_SEPARATION) {
            const float push = g * (1 - rho) * (1 - rho) * (1 + 2 * rho) * inv_dist;
            for (int k = 0; k < 3; k++) s->rule[r][k] += (uint64_t)fm_boids_fixed(push * d[k] * w->scale[r]);
            continue;
        }
        const float q = 1 - rho * rho;
        const float weight = g * q * q;
        const float *x = r == FM_BOIDS_COHESION ? d : vb;
        for (int k = 0; k < 3; k++) s->rule[r][k] += (uint64_t)fm_boids_fixed(weight * x[k] * w->scale[r]);
        s->weight[r] += (uint64_t)fm_boids_fixed(weight * w->unit_scale);
    }
}

/* The steering force of agent a (viewer w, velocity v) from its sums (see the top of this file),
 * into f[k][a]. */
void fm_boids_steer(const fm_boids_sums *s, const fm_boids_viewer *w, const fm_boids_view *b, int64_t a,
                    const float v[3], float *const f[3]);

/* For agents a in [begin, end) with phase[a] == phase_sel: f(a) = the steering force from the
 * agents listed in g (built from these p with cell >= every radius; any agent, whatever its phase,
 * is a neighbour if listed); others untouched. No allocation. */
void fm_kernel_boids(const fm_grid *g, const fm_boids_view *b, const float *const p[3], const float *const v[3],
                     const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end, float *const f[3]);

/* The same forces, bit for bit, for the agents listed in g at entries [first, last) (0 <= first <=
 * last <= g->count) with phase[a] == phase_sel, from the grid's entry-order copies of positions and
 * velocities (g built by fm_grid_build_moving): in the grid's order, so that agents of one cell follow
 * each other and walk the same cells while they are in cache, FM_W candidates at a time in the SIMD
 * variants (kernel_boids_simd.c; fm_kernel_boids_listed_ref is the scalar twin). Each agent writes
 * only its own f entries, so any split of the entries over threads gives the same bits. A selected
 * agent that is not listed is not computed. */
void fm_kernel_boids_listed(const fm_grid *g, const fm_boids_view *b, const uint8_t *phase, uint8_t phase_sel,
                            int64_t first, int64_t last, float *const f[3]);
void fm_kernel_boids_listed_ref(const fm_grid *g, const fm_boids_view *b, const uint8_t *phase, uint8_t phase_sel,
                                int64_t first, int64_t last, float *const f[3]);
typedef void fm_boids_listed_fn(const fm_grid *g, const fm_boids_view *b, const uint8_t *phase, uint8_t phase_sel,
                                int64_t first, int64_t last, float *const f[3]);

/* The reference twin for tests: the same forces from every pair of the n agents (O(n^2)), every
 * agent a neighbour. */
void fm_kernel_boids_reference(const fm_boids_view *b, const float *const p[3], const float *const v[3],
                               int64_t n, const uint8_t *phase, uint8_t phase_sel, int64_t begin, int64_t end,
                               float *const f[3]);

#endif
