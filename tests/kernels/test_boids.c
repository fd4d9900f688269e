/* Boids (SCF "Basic Steering Behaviors"): the grid kernel equals its O(n^2) reference twin on
 * random, clustered and coincident agents with per-agent radii, angles and weights; a neighbour
 * outside a rule's perception angle or radius is ignored; each rule steers the way it should;
 * MaxForce bounds the result. */
#include "kernel_boids.h"
#include "simd.h"
#include "test_macros.h"

#include <stdlib.h>
#include <string.h>

enum { MAX_AGENTS = 4000 };

static const double PI = 3.14159265358979323846;

typedef struct flock {
    int64_t n;
    float *p[3], *v[3], *f[3], *ref[3];
    float *radius[3], *cos_half[3], *weight[3], *max_speed, *max_force;
    uint8_t *phase;
} flock;

static float *floats(int64_t n) { return calloc((size_t)n, sizeof(float)); }

static flock make_flock(int64_t n)
{
    flock f = {.n = n, .max_speed = floats(n), .max_force = floats(n), .phase = calloc((size_t)n, 1)};
    for (int k = 0; k < 3; k++) {
        f.p[k] = floats(n), f.v[k] = floats(n), f.f[k] = floats(n), f.ref[k] = floats(n);
        f.radius[k] = floats(n), f.cos_half[k] = floats(n), f.weight[k] = floats(n);
    }
    return f;
}

static void free_flock(flock *f)
{
    for (int k = 0; k < 3; k++) {
        free(f->p[k]), free(f->v[k]), free(f->f[k]), free(f->ref[k]);
        free(f->radius[k]), free(f->cos_half[k]), free(f->weight[k]);
    }
    free(f->max_speed), free(f->max_force), free(f->phase);
}

static fm_boids_view view(const flock *f)
{
    fm_boids_view b = {.max_speed = f->max_speed, .max_force = f->max_force};
    for (int r = 0; r < 3; r++) b.radius[r] = f->radius[r], b.cos_half[r] = f->cos_half[r], b.weight[r] = f->weight[r];
    return b;
}

/* The grid kernel's forces into f->f (cell = the largest radius), the reference's into f->ref. */
static void run_both(flock *f)
{
    float cell = 0;
    for (int r = 0; r < 3; r++)
        for (int64_t a = 0; a < f->n; a++) cell = fmaxf(cell, f->radius[r][a]);
    fm_grid g;
    memset(&g, 0, sizeof g);
    ENSURE(fm_grid_init(&g, f->n, NULL) == FM_OK);
    uint8_t *member = malloc((size_t)f->n);
    memset(member, 1, (size_t)f->n);
    fm_grid_build(&g, (const float *const *)f->p, member, f->n, cell, 2);
    fm_boids_view b = view(f);
    fm_kernel_boids(&g, &b, (const float *const *)f->p, (const float *const *)f->v, f->phase, 1, 0, f->n, f->f);
    fm_kernel_boids_reference(&b, (const float *const *)f->p, (const float *const *)f->v, f->n, f->phase, 1, 0, f->n, f->ref);
    /* with the grid's copy of the velocities (the flock's build): the same forces, bit for bit */
    ENSURE(fm_grid_init_velocities(&g, NULL) == FM_OK);
    fm_grid_build_moving(&g, (const float *const *)f->p, (const float *const *)f->v, member, f->n, cell, 2);
    float *copy[3];
    for (int k = 0; k < 3; k++) copy[k] = calloc((size_t)f->n, sizeof(float));
    fm_kernel_boids(&g, &b, (const float *const *)f->p, (const float *const *)f->v, f->phase, 1, 0, f->n, copy);
    for (int k = 0; k < 3; k++) {
        for (int64_t a = 0; a < f->n; a++)
            if (f->phase[a] != 1) copy[k][a] = f->f[k][a]; /* untouched by the kernel */
        ENSURE_MSG(memcmp(copy[k], f->f[k], sizeof(float) * (size_t)f->n) == 0, "velocity copy changed force axis %d", k);
    }
    /* in the grid's order, split at an odd entry: the same forces, bit for bit */
    for (int k = 0; k < 3; k++)
        for (int64_t a = 0; a < f->n; a++) copy[k][a] = f->phase[a] == 1 ? NAN : f->f[k][a];
    const int64_t split = g.count / 3 + 1;
    fm_kernel_boids_listed(&g, &b, f->phase, 1, split, g.count, copy);
    fm_kernel_boids_listed(&g, &b, f->phase, 1, 0, split, copy);
    for (int k = 0; k < 3; k++) {
        ENSURE_MSG(memcmp(copy[k], f->f[k], sizeof(float) * (size_t)f->n) == 0, "grid order changed force axis %d", k);
        free(copy[k]);
    }
    fm_grid_free(&g);
    free(member);
}

/* n agents in a box of side `box` (a few share positions), random velocities and parameters. */
static flock random_flock(int64_t n, float box, uint64_t seed)
{
    flock f = make_flock(n);
    for (int64_t a = 0; a < n; a++) {
        for (int k = 0; k < 3; k++) {
            f.p[k][a] = (float)(box * test_uniform(&seed));
            f.v[k][a] = (float)(4 * test_uniform(&seed) - 2);
        }
        if (a % 97 == 5) /* coincident with the previous agent */
            for (int k = 0; k < 3; k++) f.p[k][a] = f.p[k][a - 1];
        if (a % 89 == 3) f.v[0][a] = f.v[1][a] = f.v[2][a] = 0; /* at rest: sees all round */
        for (int r = 0; r < 3; r++) {
            f.radius[r][a] = (float)(0.3 + 0.7 * test_uniform(&seed));
            f.cos_half[r][a] = (float)cos(PI * test_uniform(&seed)); /* angles 0 .. 360 degrees */
            f.weight[r][a] = (float)(0.5 + test_uniform(&seed));
        }
        if (a % 83 == 7) f.radius[FM_BOIDS_COHESION][a] = 0; /* no cohesion: the steering skips its term */
        f.max_speed[a] = (float)(5 + 5 * test_uniform(&seed));
        f.max_force[a] = a % 3 == 0 ? 1e9f : (float)(2 + 10 * test_uniform(&seed)); /* some never truncate */
        f.phase[a] = a % 11 == 0 ? 3 : 1; /* a few in another phase: not computed, still neighbours */
    }
    return f;
}

static void test_kernel_equals_reference(void)
{
    const float boxes[3] = {10.0f, 3.0f, 0.5f}; /* sparse, dense, everybody within reach of everybody */
    for (int trial = 0; trial < 3; trial++) {
        flock f = random_flock(MAX_AGENTS, boxes[trial], 100 + (uint64_t)trial);
        for (int64_t a = 0; a < f.n; a++) f.f[0][a] = f.ref[0][a] = -12345; /* untouched sentinel */
        run_both(&f);
        double worst = 0;
        int64_t nonzero = 0, untouched_ok = 1;
        for (int64_t a = 0; a < f.n; a++) {
            if (f.phase[a] != 1) {
                untouched_ok &= f.f[0][a] == -12345 && f.ref[0][a] == -12345;
                continue;
            }
            double scale = 1 + fabs(f.ref[0][a]) + fabs(f.ref[1][a]) + fabs(f.ref[2][a]);
            for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(f.f[k][a] - f.ref[k][a]) / scale);
            nonzero += f.ref[0][a] != 0 || f.ref[1][a] != 0 || f.ref[2][a] != 0;
        }
        ENSURE_MSG(worst < 1e-5, "box %g: kernel and reference differ by %g (relative)", boxes[trial], worst);
        ENSURE_MSG(nonzero > f.n / 2, "box %g: only %lld agents felt a force", boxes[trial], (long long)nonzero);
        ENSURE(untouched_ok);
        free_flock(&f);
    }
}

/* Agent 0 at the origin heading +x; agent 1 somewhere; one rule on at a time. */
static flock pair(const float other[3], int rule, float radius, float angle_deg)
{
    flock f = make_flock(2);
    f.v[0][0] = 1;
    for (int k = 0; k < 3; k++) f.p[k][1] = other[k];
    f.v[1][1] = 3; /* agent 1 heads +y */
    for (int a = 0; a < 2; a++) {
        for (int r = 0; r < 3; r++) f.radius[r][a] = radius, f.cos_half[r][a] = (float)cos(angle_deg * PI / 360);
        f.weight[rule][a] = 1;
        f.max_speed[a] = 10, f.max_force[a] = 1e9f;
        f.phase[a] = 1;
    }
    return f;
}

static float force_on_0(const float other[3], int rule, float radius, float angle_deg, float out[3])
{
    flock f = pair(other, rule, radius, angle_deg);
    run_both(&f);
    for (int k = 0; k < 3; k++) {
        out[k] = f.f[k][0];
        ENSURE(f.f[k][0] == f.ref[k][0]);
    }
    free_flock(&f);
    return sqrtf(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
}

static void test_neighbours_outside_the_angle_are_ignored(void)
{
    const float front[3] = {0.5f, 0.1f, 0}, behind[3] = {-0.5f, 0.1f, 0}, side[3] = {0, 0.5f, 0};
    float out[3];
    for (int rule = 0; rule < 3; rule++) {
        ENSURE_MSG(force_on_0(front, rule, 1, 120, out) > 0, "rule %d: a neighbour ahead is not seen", rule);
        ENSURE_MSG(force_on_0(behind, rule, 1, 120, out) == 0, "rule %d: a neighbour behind is seen with 120 degrees", rule);
        ENSURE_MSG(force_on_0(side, rule, 1, 120, out) == 0, "rule %d: a neighbour at 90 degrees is seen with 120", rule);
        ENSURE_MSG(force_on_0(side, rule, 1, 200, out) > 0, "rule %d: a neighbour at 90 degrees is not seen with 200", rule);
        ENSURE_MSG(force_on_0(behind, rule, 1, 360, out) > 0, "rule %d: 360 degrees does not see behind", rule);
    }
}

static void test_neighbours_outside_the_radius_are_ignored(void)
{
    const float near[3] = {0.99f, 0, 0}, far[3] = {1.01f, 0, 0};
    float out[3];
    for (int rule = 0; rule < 3; rule++) {
        ENSURE_MSG(force_on_0(near, rule, 1, 360, out) > 0, "rule %d: a neighbour inside the radius is not seen", rule);
        ENSURE_MSG(force_on_0(far, rule, 1, 360, out) == 0, "rule %d: a neighbour beyond the radius is seen", rule);
    }
}

/* Separation steers away, cohesion toward, alignment to the neighbour's velocity (kernel_boids.h):
 * v = (1, 0, 0), MaxSpeed S = 10, the neighbour at distance 1 inside radius 2 (rho = 1/2, w = 9/16 above
 * the floor 1/4, so cohesion and alignment are the plain offset and velocity difference) with
 * velocity (0, 3, 0). */
static void test_each_rule_steers_its_way(void)
{
    const float other[3] = {0.6f, 0.8f, 0};
    float out[3];
    force_on_0(other, FM_BOIDS_SEPARATION, 2, 360, out); /* S s(1/2) (x_a - x_b) / |d|, s(1/2) = 1/4 * 2 */
    ENSURE_NEAR(out[0], -3, 1e-5);
    ENSURE_NEAR(out[1], -4, 1e-5);
    ENSURE_NEAR(out[2], 0, 1e-6);
    force_on_0(other, FM_BOIDS_COHESION, 2, 360, out); /* S (x_b - x_a) / r */
    ENSURE_NEAR(out[0], 3, 1e-5);
    ENSURE_NEAR(out[1], 4, 1e-5);
    force_on_0(other, FM_BOIDS_ALIGNMENT, 2, 360, out); /* v_b - v_a */
    ENSURE_NEAR(out[0], -1, 1e-5);
    ENSURE_NEAR(out[1], 3, 1e-5);
}

/* Issue 37: no rule kicks. Walked in 40 small steps into a rule's radius (distance 2.2 to 1.8 of
 * radius 2) and into its view cone (120 degrees: bearings with cosines 0.25 to 0.75 across cos_half
 * 1/2), a neighbour changes the force by less than a quarter of its full size per step, where the
 * hard-edged rules jumped by all of it at once; outside it adds nothing. */
static void test_rules_fade_at_the_edges(void)
{
    float out[3];
    for (int rule = 0; rule < 3; rule++) {
        const float mid[3] = {0.6f, 0.8f, 0}, full = force_on_0(mid, rule, 2, 360, out);
        float jump_r = 0, jump_c = 0, last_r = 0, last_c = 0;
        for (int i = 0; i <= 40; i++) {
            const float d = 2.2f - 0.01f * (float)i, at[3] = {0.6f * d, 0.8f * d, 0};
            const float c = 0.25f + 0.0125f * (float)i, side[3] = {c, sqrtf(1 - c * c), 0};
            const float fr = force_on_0(at, rule, 2, 360, out), fc = force_on_0(side, rule, 2, 120, out);
            if (i == 0) ENSURE_MSG(fr == 0 && fc == 0, "rule %d: a neighbour outside is felt (%g, %g)", rule, fr, fc);
            if (i > 0) jump_r = fmaxf(jump_r, fabsf(fr - last_r)), jump_c = fmaxf(jump_c, fabsf(fc - last_c));
            last_r = fr, last_c = fc;
        }
        ENSURE_MSG(last_r > 0 && last_c > 0.5f * full, "rule %d: the walk ends at %g, %g of %g", rule, last_r, last_c, full);
        ENSURE_MSG(jump_r < 0.25f * full && jump_c < 0.25f * full, "rule %d: steps of %g (radius) and %g (cone) against %g",
                   rule, jump_r, jump_c, full);
    }
}

/* A flock that moves as one, evenly spaced, feels no rule: an agent in the middle of a cubic
 * lattice of neighbours, all with its velocity, gets no force (Reynolds's MaxSpeed * unit - v
 * would brake it). */
static void test_uniform_flock_feels_nothing(void)
{
    flock f = make_flock(27);
    for (int a = 0; a < 27; a++) {
        f.p[0][a] = (float)(a % 3), f.p[1][a] = (float)(a / 3 % 3), f.p[2][a] = (float)(a / 9);
        f.v[0][a] = 4, f.v[1][a] = 1;
        for (int r = 0; r < 3; r++) f.radius[r][a] = 1.9f, f.cos_half[r][a] = -1, f.weight[r][a] = 1;
        f.max_speed[a] = 10, f.max_force[a] = 1e9f, f.phase[a] = 1;
    }
    run_both(&f);
    for (int k = 0; k < 3; k++) ENSURE_NEAR(f.f[k][13], 0, 1e-4); /* agent 13 is the centre */
    ENSURE(fabsf(f.f[0][0]) > 1); /* a corner is pushed */
    free_flock(&f);
}

static void test_max_force_bounds_the_steering(void)
{
    flock f = random_flock(1000, 2.0f, 7);
    run_both(&f);
    int64_t truncated = 0;
    for (int64_t a = 0; a < f.n; a++) {
        if (f.phase[a] != 1) continue;
        float len = sqrtf(f.f[0][a] * f.f[0][a] + f.f[1][a] * f.f[1][a] + f.f[2][a] * f.f[2][a]);
        ENSURE_MSG(len <= f.max_force[a] * (1 + 1e-6f), "agent %lld: |F| %g > MaxForce %g", (long long)a, len, f.max_force[a]);
        truncated += len >= f.max_force[a] * (1 - 1e-6f);
    }
    ENSURE_MSG(truncated > 100, "only %lld agents reached MaxForce: the bound is not exercised", (long long)truncated);
    free_flock(&f);
}


/* The listed walk (grid order, FM_W candidates at a time) of flock f into out, at the current SIMD
 * level, with a grid of edge `cell`. */
static void listed(const flock *f, float cell, float *const out[3])
{
    fm_grid g;
    memset(&g, 0, sizeof g);
    ENSURE(fm_grid_init(&g, f->n, NULL) == FM_OK && fm_grid_init_velocities(&g, NULL) == FM_OK);
    fm_grid_build_moving(&g, (const float *const *)f->p, (const float *const *)f->v, NULL, f->n, cell, 2);
    fm_boids_view b = view(f);
    b.reach = 1.0f, b.top_speed = 3.5f;
    for (int k = 0; k < 3; k++)
        for (int64_t a = 0; a < f->n; a++) out[k][a] = -12345;
    fm_kernel_boids_listed(&g, &b, f->phase, 1, 0, g.count, out);
    fm_grid_free(&g);
}

static int same_floats(const float *a, const float *b, int64_t n) { return memcmp(a, b, sizeof(float) * (size_t)n) == 0; }

/* Every SIMD level's walk gives the scalar twin's bits, whatever the grid's cell (a wider cell
 * brings more candidates, which the radius test drops: the same neighbours). */
static void simd_levels_agree(float box);

static void test_every_simd_level_gives_the_same_bits(void)
{
    for (int dense = 0; dense < 2; dense++) simd_levels_agree(dense ? 3.0f : 12.0f);
}

/* In a box of side 3 every cell's neighbourhood holds far more than the walk's run of candidates
 * (kernel_boids_simd.c: RUN_MAX, 512), so it scans the grid's ranges; in one of side 12 (about 60
 * candidates a cell) it gathers each cell's run. */
static void simd_levels_agree(float box)
{
    flock f = random_flock(MAX_AGENTS, box, 41);
    float *want[3], *got[3];
    for (int k = 0; k < 3; k++) want[k] = floats(f.n), got[k] = floats(f.n);
    const fm_simd best = fm_simd_set_level(FM_SIMD_BEST);
    fm_simd_set_level(FM_SIMD_SCALAR);
    listed(&f, 1.0f, want);
    int levels = 0;
    for (int level = FM_SIMD_SCALAR; level <= (int)best; level++) {
        fm_simd_set_level((fm_simd)level);
        for (int wide = 0; wide < 2; wide++) {
            listed(&f, wide ? 1.7f : 1.0f, got);
            for (int k = 0; k < 3; k++)
                ENSURE_MSG(same_floats(got[k], want[k], f.n), "box %g, level %s, cell %s: force axis %d differs", box,
                           fm_simd_name((fm_simd)level), wide ? "1.7" : "1", k);
        }
        levels++;
    }
    fm_simd_set_level(best);
    ENSURE(levels >= 2); /* scalar and at least SSE2 */
    for (int k = 0; k < 3; k++) free(want[k]), free(got[k]);
    free_flock(&f);
}

/* The sums are exact: the same agents stored in another order feel the same forces, bit for bit
 * (what lets the store be sorted in space and split over ranks). */
static void test_agents_order_does_not_change_the_bits(void)
{
    flock f = random_flock(MAX_AGENTS, 3.0f, 43), g = make_flock(MAX_AGENTS);
    int64_t *to = malloc(sizeof(int64_t) * (size_t)f.n);
    for (int64_t a = 0; a < f.n; a++) to[a] = a;
    uint64_t seed = 5;
    for (int64_t a = f.n - 1; a > 0; a--) { /* Fisher-Yates */
        const int64_t b = (int64_t)(test_uniform(&seed) * (double)(a + 1)) % (a + 1), t = to[a];
        to[a] = to[b], to[b] = t;
    }
    for (int64_t a = 0; a < f.n; a++) {
        const int64_t b = to[a];
        for (int k = 0; k < 3; k++) {
            g.p[k][b] = f.p[k][a], g.v[k][b] = f.v[k][a];
            g.radius[k][b] = f.radius[k][a], g.cos_half[k][b] = f.cos_half[k][a], g.weight[k][b] = f.weight[k][a];
        }
        g.max_speed[b] = f.max_speed[a], g.max_force[b] = f.max_force[a], g.phase[b] = f.phase[a];
    }
    listed(&f, 1.0f, f.f);
    listed(&g, 1.0f, g.f);
    int64_t differ = 0, felt = 0;
    for (int64_t a = 0; a < f.n; a++)
        for (int k = 0; k < 3; k++) {
            differ += memcmp(&f.f[k][a], &g.f[k][to[a]], sizeof(float)) != 0;
            felt += f.phase[a] == 1 && k == 0 && f.f[0][a] != 0;
        }
    ENSURE_MSG(differ == 0, "%lld force components changed with the agents' order", (long long)differ);
    ENSURE(felt > f.n / 2);
    free(to);
    free_flock(&f), free_flock(&g);
}

/* The fixed point: a term's bound is 2^31 units, rounding to nearest with ties to even, clamped, NaN
 * to the lower clamp. */
static void test_fixed_point_rounds_and_clamps(void)
{
    ENSURE(fm_boids_fixed_scale(1.0f) == 0x1p30f);    /* 1 = 2^0: 2^31 / 2^1 */
    ENSURE(fm_boids_fixed_scale(0.75f) == 0x1p31f);   /* 0.75 < 2^0 */
    ENSURE(fm_boids_fixed_scale(3.5f) == 0x1p29f);    /* 3.5 < 2^2 */
    ENSURE(fm_boids_fixed_scale(0.0f) == 0x1p30f && fm_boids_fixed_scale(NAN) == 0x1p30f);
    ENSURE(fm_boids_fixed(2.5f) == 2 && fm_boids_fixed(3.5f) == 4 && fm_boids_fixed(-2.5f) == -2);
    ENSURE(fm_boids_fixed(0.49999997f) == 0 && fm_boids_fixed(-7.75f) == -8);
    ENSURE(fm_boids_fixed(0x1p40f) == INT64_C(1) << 40);
    ENSURE(fm_boids_fixed(1e30f) == INT64_C(1) << 50 && fm_boids_fixed(-1e30f) == -(INT64_C(1) << 50));
    ENSURE(fm_boids_fixed(NAN) == -(INT64_C(1) << 50));
}

int main(void)
{
    RUN_TEST(test_kernel_equals_reference);
    RUN_TEST(test_neighbours_outside_the_angle_are_ignored);
    RUN_TEST(test_neighbours_outside_the_radius_are_ignored);
    RUN_TEST(test_each_rule_steers_its_way);
    RUN_TEST(test_rules_fade_at_the_edges);
    RUN_TEST(test_uniform_flock_feels_nothing);
    RUN_TEST(test_max_force_bounds_the_steering);
    RUN_TEST(test_every_simd_level_gives_the_same_bits);
    RUN_TEST(test_agents_order_does_not_change_the_bits);
    RUN_TEST(test_fixed_point_rounds_and_clamps);
    return test_result();
}
