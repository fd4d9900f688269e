/* The MDE hash grid and kernel (FM §5.4): the sort's invariants, the kernel against a brute-force
 * O(n^2) reference on uniform, clustered, duplicated, cell-border and hash-colliding point sets,
 * hand-made pairs, non-members, thread-count independence, capacity reuse; then timings at 10^6. */
#define _POSIX_C_SOURCE 200809L
#include "grid.h"
#include "kernel_mde.h"
#include "simd.h"
#include "test_macros.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct pts {
    int64_t n;
    float *p[3];
    uint8_t *member;
} pts;

static pts pts_new(int64_t n)
{
    pts s = {n, {0}, NULL};
    for (int k = 0; k < 3; k++) s.p[k] = fm_alloc(sizeof(float) * (size_t)(n > 0 ? n : 1));
    s.member = fm_alloc((size_t)(n > 0 ? n : 1));
    return s;
}

static void pts_free(pts *s)
{
    for (int k = 0; k < 3; k++) fm_free(s->p[k]);
    fm_free(s->member);
}

/* uniform in [0, side)^3 (shifted by lo), every agent a member */
static void fill_uniform(pts *s, uint64_t *rng, double lo, double side)
{
    for (int64_t a = 0; a < s->n; a++) {
        for (int k = 0; k < 3; k++) s->p[k][a] = (float)(lo + side * test_uniform(rng));
        s->member[a] = 1;
    }
}

static void drop_members(pts *s, uint64_t *rng, double fraction)
{
    for (int64_t a = 0; a < s->n; a++)
        if (test_uniform(rng) < fraction) s->member[a] = 0;
}

/* side of the cube holding n uniform points with `nb` neighbours within d on average */
static double side_for(int64_t n, double nb, double d)
{
    return cbrt((double)n * 4.0 / 3.0 * 3.14159265358979 * d * d * d / nb);
}

/* ------------------------------------------------------------------ reference and checks */

/* The grid's structure: start[] monotone and ending at count; every member listed exactly once,
 * in its own slot; inside a slot increasing index; non-members not listed and slot FM_GRID_NONE. */
static void check_grid(const fm_grid *g, const pts *s)
{
    uint64_t table = (uint64_t)g->mask + 1;
    int64_t members = 0;
    for (int64_t a = 0; a < s->n; a++) members += s->member[a] != 0;
    ENSURE(g->count == members);
    ENSURE(g->start[0] == 0 && g->start[table] == g->count);
    int bad_order = 0, bad_slot = 0, bad_copy = 0;
    uint8_t *listed = calloc((size_t)s->n + 1, 1);
    for (uint64_t sl = 0; sl < table; sl++) {
        if (g->start[sl] > g->start[sl + 1]) bad_order++;
        for (int32_t k = g->start[sl]; k < g->start[sl + 1]; k++) {
            int32_t a = g->quad[k >> 2].i[k & 3];
            if (a < 0 || a >= s->n) { bad_slot++; continue; }
            if (k > g->start[sl] && g->quad[(k - 1) >> 2].i[(k - 1) & 3] >= a) bad_order++;
            if (g->slot[a] != sl || !s->member[a]) bad_slot++;
            const fm_grid_quad *q = &g->quad[k >> 2];
            if (q->x[k & 3] != s->p[0][a] || q->y[k & 3] != s->p[1][a] || q->z[k & 3] != s->p[2][a]) bad_copy++;
            int32_t c0 = fm_grid_coord(fm_grid_scaled(g, s->p[0][a]));
            int32_t c1 = fm_grid_coord(fm_grid_scaled(g, s->p[1][a]));
            int32_t c2 = fm_grid_coord(fm_grid_scaled(g, s->p[2][a]));
            if (fm_grid_slot(g, c0, c1, c2) != sl) bad_slot++;
            listed[a]++;
        }
    }
    int bad_list = 0;
    for (int64_t a = 0; a < s->n; a++) {
        if (listed[a] != (s->member[a] ? 1 : 0)) bad_list++;
        if (!s->member[a] && g->slot[a] != FM_GRID_NONE) bad_list++;
    }
    free(listed);
    ENSURE_MSG(bad_order == 0, "%d order errors", bad_order);
    ENSURE_MSG(bad_slot == 0, "%d slot errors", bad_slot);
    ENSURE_MSG(bad_copy == 0, "%d position copies differ", bad_copy);
    ENSURE_MSG(bad_list == 0, "%d agents listed wrongly", bad_list);
}

/* Brute force: the same float closeness test as the kernel, the push in double. tol[a]: the sum
 * of the magnitudes of a's contributions (for a relative tolerance). */
static void brute_force(const pts *s, float d_min, float push, double *ref, double *mag, uint8_t *needed)
{
    const float d2min = d_min * d_min;
    for (int64_t a = 0; a < s->n; a++) {
        double v[3] = {0, 0, 0}, sum = 0;
        needed[a] = 0;
        if (s->member[a])
            for (int64_t b = 0; b < s->n; b++) {
                if (b == a || !s->member[b]) continue;
                float dx = s->p[0][a] - s->p[0][b], dy = s->p[1][a] - s->p[1][b], dz = s->p[2][a] - s->p[2][b];
                float d2 = dx * dx + dy * dy + dz * dz;
                if (!(d2 < d2min)) continue;
                needed[a] = 1;
                if (d2 > 0) {
                    double e[3] = {(double)s->p[0][a] - s->p[0][b], (double)s->p[1][a] - s->p[1][b],
                                   (double)s->p[2][a] - s->p[2][b]};
                    double dist = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
                    double w = push * (1 - dist / d_min) / dist;
                    for (int k = 0; k < 3; k++) v[k] += w * e[k];
                    sum += push * (1 - dist / d_min);
                } else {
                    float d[3];
                    fm_mde_coincident_dir((int32_t)(a < b ? a : b), (int32_t)(a < b ? b : a), d);
                    double sign = a < b ? 1 : -1;
                    for (int k = 0; k < 3; k++) v[k] += sign * push * d[k];
                    sum += push;
                }
            }
        for (int k = 0; k < 3; k++) ref[3 * a + k] = v[k];
        mag[a] = sum;
    }
}

typedef struct mde_out {
    float *v[3];
    uint8_t *needed;
} mde_out;

static mde_out out_new(int64_t n)
{
    mde_out o;
    for (int k = 0; k < 3; k++) {
        o.v[k] = fm_alloc(sizeof(float) * (size_t)(n > 0 ? n : 1));
        for (int64_t a = 0; a < n; a++) o.v[k][a] = 12345.0f; /* must be overwritten */
    }
    o.needed = fm_alloc((size_t)(n > 0 ? n : 1));
    memset(o.needed, 7, (size_t)n);
    return o;
}

static void out_free(mde_out *o)
{
    for (int k = 0; k < 3; k++) fm_free(o->v[k]);
    fm_free(o->needed);
}

typedef int64_t mde_kernel(const fm_grid *g, const float *const p[3], const uint8_t *member, const int32_t *id,
                           int64_t begin, int64_t end, float d_min, float push, float *const v_la[3], uint8_t *needed);

/* A kernel over [0, n) in blocks of 4093 (odd: ranges off every vector width) on `threads` threads;
 * returns its count. */
static int64_t run_kernel_with(mde_kernel *kernel, const fm_grid *g, const pts *s, float d_min, float push, mde_out *o,
                               int threads)
{
    int64_t count = 0, blocks = (s->n + 4092) / 4093;
    const float *p[3] = {s->p[0], s->p[1], s->p[2]};
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1) reduction(+ : count)
    for (int64_t b = 0; b < blocks; b++) {
        int64_t lo = b * 4093, hi = FM_MIN(s->n, lo + 4093);
        count += kernel(g, p, s->member, NULL, lo, hi, d_min, push, o->v, o->needed);
    }
    return count;
}

static int64_t run_kernel(const fm_grid *g, const pts *s, float d_min, float push, mde_out *o, int threads)
{
    return run_kernel_with(fm_kernel_mde, g, s, d_min, push, o, threads);
}

/* fm_kernel_mde at every SIMD level (its screen FM_W entries at a time, then the sums) against the
 * scalar twin fm_kernel_mde_ref: the same count, v_la and needed, bit for bit. */
static void check_levels_match_ref(const char *what, const fm_grid *g, const pts *s, float d_min, float push)
{
    const fm_simd best = fm_simd_set_level(FM_SIMD_BEST);
    mde_out ref = out_new(s->n), o = out_new(s->n);
    const int64_t c_ref = run_kernel_with(fm_kernel_mde_ref, g, s, d_min, push, &ref, 1);
    for (int level = FM_SIMD_SSE2; level <= (int)best; level++) { /* the scalar level runs the twin itself */
        fm_simd_set_level((fm_simd)level);
        const int64_t c = run_kernel(g, s, d_min, push, &o, 1);
        int64_t differ = 0;
        for (int k = 0; k < 3; k++)
            for (int64_t a = 0; a < s->n; a++) differ += memcmp(&o.v[k][a], &ref.v[k][a], sizeof(float)) != 0;
        for (int64_t a = 0; a < s->n; a++) differ += o.needed[a] != ref.needed[a];
        ENSURE_MSG(c == c_ref && differ == 0, "%s, %s: count %lld against the twin's %lld, %lld values differ", what,
                   fm_simd_name((fm_simd)level), (long long)c, (long long)c_ref, (long long)differ);
    }
    fm_simd_set_level(best);
    out_free(&ref), out_free(&o);
}

/* Rows by position instead of hashed (fm_grid.linear_rows) in the brute-force checks: main runs
 * them both ways. */
static int linear_rows;

/* Builds the grid and runs the kernel on s, checks both against brute force; returns the number
 * of agents that needed a push. */
static int64_t check_against_brute_force(const char *what, const pts *s, float d_min, float cell, float push,
                                         int threads)
{
    const char *quiet = what ? NULL : "";
    if (!what) what = "(quiet)";
    fm_grid g;
    fm_error err;
    ENSURE(fm_grid_init(&g, s->n, &err) == FM_OK);
    g.linear_rows = linear_rows;
    const float *p[3] = {s->p[0], s->p[1], s->p[2]};
    fm_grid_build(&g, p, s->member, s->n, cell, threads);
    check_grid(&g, s);
    mde_out o = out_new(s->n);
    int64_t count = run_kernel(&g, s, d_min, push, &o, threads);
    check_levels_match_ref(what, &g, s, d_min, push);

    double *ref = malloc(sizeof(double) * 3 * (size_t)s->n), *mag = malloc(sizeof(double) * (size_t)s->n);
    uint8_t *needed = malloc((size_t)s->n);
    brute_force(s, d_min, push, ref, mag, needed);
    int64_t ref_count = 0, bad_needed = 0, bad_v = 0, bad_member = 0;
    double worst = 0;
    for (int64_t a = 0; a < s->n; a++) {
        ref_count += needed[a];
        if (o.needed[a] != needed[a]) bad_needed++;
        if (!s->member[a] && (o.v[0][a] != 0 || o.v[1][a] != 0 || o.v[2][a] != 0)) bad_member++;
        double tol = 1e-5 * (mag[a] + push);
        for (int k = 0; k < 3; k++) {
            double e = fabs(o.v[k][a] - ref[3 * a + k]);
            if (!(e <= tol)) bad_v++;
            if (e / (mag[a] + push) > worst) worst = e / (mag[a] + push);
        }
    }
    ENSURE_MSG(count == ref_count, "%s: kernel count %lld, brute force %lld", what, (long long)count,
               (long long)ref_count);
    ENSURE_MSG(bad_needed == 0, "%s: %lld needed flags differ", what, (long long)bad_needed);
    ENSURE_MSG(bad_v == 0, "%s: %lld v_la components off (worst relative %.3g)", what, (long long)bad_v, worst);
    ENSURE_MSG(bad_member == 0, "%s: %lld non-members pushed", what, (long long)bad_member);
    if (quiet == NULL)
        printf("    %-34s n %6lld  cell/d_min %.2f  needed %6lld  worst rel err %.2g\n", what, (long long)s->n,
               (double)(cell / d_min), (long long)ref_count, worst);
    free(ref), free(mag), free(needed);
    out_free(&o);
    fm_grid_free(&g);
    return ref_count;
}

/* ------------------------------------------------------------------ tests */

static void test_hand_made_pairs(void)
{
    /* 0-1: 0.5 apart, inside d_min = 1; 2-3: 1.2 apart; 4-5: exactly d_min apart; 6-7: coincident;
     * 8 a member 0.1 from non-member 9 */
    float x[10] = {0, 0.3f, 10, 11.2f, 20, 21, 30, 30, 40, 40.1f};
    float y[10] = {0, 0.4f, 0, 0, 0, 0, 5, 5, 0, 0};
    float z[10] = {0, 0, 0, 0, 0, 0, -3, -3, 0, 0};
    uint8_t member[10] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 0};
    const float *p[3] = {x, y, z};
    float vx[10], vy[10], vz[10];
    uint8_t needed[10];
    for (int a = 0; a < 10; a++) vx[a] = vy[a] = vz[a] = 99, needed[a] = 99;
    float *v[3] = {vx, vy, vz};
    fm_grid g;
    fm_error err;
    ENSURE(fm_grid_init(&g, 10, &err) == FM_OK);
    fm_grid_build(&g, p, member, 10, 1.0f, 1);
    int64_t count = fm_kernel_mde(&g, p, member, NULL, 0, 10, 1.0f, 2.0f, v, needed);
    ENSURE(count == 4);
    /* magnitude push * (1 - 0.5 / 1) = 1 along (0.6, 0.8, 0), away from the other agent */
    ENSURE_NEAR(vx[0], -0.6, 1e-6);
    ENSURE_NEAR(vy[0], -0.8, 1e-6);
    ENSURE(vz[0] == 0);
    ENSURE(vx[1] == -vx[0] && vy[1] == -vy[0] && vz[1] == -vz[0]); /* exactly opposite */
    ENSURE(needed[0] == 1 && needed[1] == 1);
    for (int a = 2; a < 6; a++) ENSURE(vx[a] == 0 && vy[a] == 0 && vz[a] == 0 && needed[a] == 0);
    /* coincident: magnitude push, opposite */
    ENSURE_NEAR(sqrt(vx[6] * vx[6] + vy[6] * vy[6] + vz[6] * vz[6]), 2.0, 1e-6);
    ENSURE(vx[7] == -vx[6] && vy[7] == -vy[6] && vz[7] == -vz[6]);
    ENSURE(needed[6] == 1 && needed[7] == 1);
    /* a non-member neither gets nor causes a push */
    ENSURE(vx[8] == 0 && vy[8] == 0 && vz[8] == 0 && needed[8] == 0);
    ENSURE(vx[9] == 0 && vy[9] == 0 && vz[9] == 0 && needed[9] == 0);
    ENSURE(g.slot[9] == FM_GRID_NONE);

    /* a sub-range writes only its own agents */
    for (int a = 0; a < 10; a++) vx[a] = 99;
    ENSURE(fm_kernel_mde(&g, p, member, NULL, 1, 2, 1.0f, 2.0f, v, needed) == 1);
    ENSURE(vx[0] == 99 && vx[2] == 99);
    ENSURE_NEAR(vx[1], 0.6, 1e-6);

    /* a larger cell finds the same pairs */
    fm_grid_build(&g, p, member, 10, 3.5f, 1);
    float wx[10], wy[10], wz[10];
    float *w[3] = {wx, wy, wz};
    ENSURE(fm_kernel_mde(&g, p, member, NULL, 0, 10, 1.0f, 2.0f, w, needed) == 4);
    ENSURE_NEAR(wx[0], -0.6, 1e-6);
    ENSURE_NEAR(wy[0], -0.8, 1e-6);
    ENSURE(wx[1] == -wx[0] && wy[1] == -wy[0]);
    ENSURE(wx[2] == 0 && wx[4] == 0 && wx[8] == 0);
    fm_grid_free(&g);
}

static void test_three_in_a_row(void)
{
    /* a at 0, b at 0.25, c at 0.5 on x with d_min 1, push 1: b is pushed equally both ways */
    float x[3] = {0, 0.25f, 0.5f}, y[3] = {0}, z[3] = {0};
    uint8_t member[3] = {1, 1, 1}, needed[3];
    const float *p[3] = {x, y, z};
    float vx[3], vy[3], vz[3];
    float *v[3] = {vx, vy, vz};
    fm_grid g;
    ENSURE(fm_grid_init(&g, 3, NULL) == FM_OK);
    fm_grid_build(&g, p, member, 3, 1.0f, 1);
    ENSURE(fm_kernel_mde(&g, p, member, NULL, 0, 3, 1.0f, 1.0f, v, needed) == 3);
    ENSURE_NEAR(vx[0], -(0.75 + 0.5), 1e-6);
    ENSURE_NEAR(vx[1], 0, 1e-6);
    ENSURE_NEAR(vx[2], 0.75 + 0.5, 1e-6);
    ENSURE(vx[0] == -vx[2]);
    fm_grid_free(&g);
}

static void test_uniform_sets(void)
{
    uint64_t rng = 11;
    pts s = pts_new(4000);
    const float cells[3] = {1.0f, 1.37f, 3.0f};
    for (int c = 0; c < 3; c++) {
        fill_uniform(&s, &rng, -17.0, side_for(s.n, 5, 1.0));
        drop_members(&s, &rng, 0.2);
        int64_t needed = check_against_brute_force("uniform, 20% non-members", &s, 1.0f, cells[c], 1.5f, 2);
        ENSURE(needed > s.n / 2); /* the set is dense enough to test something */
    }
    /* tiny d_min relative to coordinates far from the origin */
    fill_uniform(&s, &rng, 1000.0, side_for(s.n, 5, 0.01));
    drop_members(&s, &rng, 0.1);
    check_against_brute_force("uniform, far from origin", &s, 0.01f, 0.01f, 1.0f, 2);
    pts_free(&s);
}

static void test_clustered_and_duplicates(void)
{
    uint64_t rng = 12;
    pts s = pts_new(3000);
    /* 6 tight clusters (dozens of neighbours each) over a sparse background */
    float cx[6], cy[6], cz[6];
    for (int c = 0; c < 6; c++)
        cx[c] = (float)(40 * test_uniform(&rng)), cy[c] = (float)(40 * test_uniform(&rng)),
        cz[c] = (float)(40 * test_uniform(&rng) - 20);
    for (int64_t a = 0; a < s.n; a++) {
        if (a % 3 == 0) {
            s.p[0][a] = (float)(40 * test_uniform(&rng));
            s.p[1][a] = (float)(40 * test_uniform(&rng));
            s.p[2][a] = (float)(40 * test_uniform(&rng) - 20);
        } else {
            int c = (int)(6 * test_uniform(&rng));
            double g[3];
            for (int k = 0; k < 3; k++)
                g[k] = (test_uniform(&rng) + test_uniform(&rng) + test_uniform(&rng) - 1.5) * 1.2;
            s.p[0][a] = cx[c] + (float)g[0], s.p[1][a] = cy[c] + (float)g[1], s.p[2][a] = cz[c] + (float)g[2];
        }
        s.member[a] = 1;
    }
    drop_members(&s, &rng, 0.15);
    check_against_brute_force("clustered", &s, 1.0f, 1.0f, 1.0f, 2);

    /* exact duplicates: pairs and triples of coincident agents, members and not */
    for (int64_t a = 0; a < s.n; a++)
        if (test_uniform(&rng) < 0.2) {
            int64_t b = (int64_t)(test_uniform(&rng) * (double)s.n);
            for (int k = 0; k < 3; k++) s.p[k][a] = s.p[k][b];
        }
    check_against_brute_force("clustered with duplicates", &s, 1.0f, 1.0f, 1.0f, 2);
    check_against_brute_force("clustered with duplicates", &s, 0.5f, 1.25f, 1.0f, 1);
    pts_free(&s);

    /* a dense ball: ~400 neighbours each (the hit buffer fills several times per agent), with
     * groups of coincident agents */
    pts d = pts_new(600);
    for (int64_t a = 0; a < d.n; a++) {
        for (int k = 0; k < 3; k++) d.p[k][a] = (float)(5 + 0.8 * test_uniform(&rng));
        d.member[a] = a % 11 != 0;
        if (a % 7 == 3)
            for (int k = 0; k < 3; k++) d.p[k][a] = d.p[k][a - 3];
    }
    int64_t needed = check_against_brute_force("dense ball", &d, 1.0f, 1.0f, 1.0f, 2);
    ENSURE(needed == 600 - 55);
    pts_free(&d);
}

/* The engine's case: most agents have no neighbour within d_min (the SIMD screen answers alone),
 * cells several times d_min (the walk trims the rows), and pairs placed about d_min apart, one float
 * either side of it, so that the screen's float test must give the twin's answer at the edge. */
static void test_sparse_near_misses(void)
{
    uint64_t rng = 19;
    const float d_min = 0.2f;
    pts s = pts_new(4000);
    fill_uniform(&s, &rng, -3.0, side_for(s.n, 0.3, d_min));
    drop_members(&s, &rng, 0.05);
    for (int64_t a = 0; a + 1 < s.n; a += 8) { /* agent a + 1 at d_min from a, give or take a float */
        float u[3], len = 0;
        for (int k = 0; k < 3; k++) u[k] = (float)(2 * test_uniform(&rng) - 1), len += u[k] * u[k];
        const float scale = d_min / sqrtf(len) * (a % 24 == 0 ? 1 - 0x1p-23f : a % 24 == 8 ? 1 : 1 + 0x1p-23f);
        for (int k = 0; k < 3; k++) s.p[k][a + 1] = s.p[k][a] + u[k] * scale;
    }
    const int64_t in_cells = check_against_brute_force("sparse, near misses, cell 7.5 d_min", &s, d_min, 1.5f, 1.0f, 2);
    const int64_t in_dmin = check_against_brute_force("sparse, near misses, cell d_min", &s, d_min, d_min, 1.0f, 1);
    ENSURE(in_cells == in_dmin);
    ENSURE_MSG(in_cells > s.n / 20 && in_cells < s.n / 2, "%lld of %lld agents pushed: both paths tested",
               (long long)in_cells, (long long)s.n);
    pts_free(&s);
}

static void test_cell_borders(void)
{
    /* coordinates on (and one float either side of) the grid's cell borders k * cell * (1 + 2^-20),
     * on the nominal multiples k * cell, and on half cells; negative ones too */
    uint64_t rng = 13;
    const float cell = 0.75f;
    pts s = pts_new(3000);
    for (int64_t a = 0; a < s.n; a++) {
        for (int k = 0; k < 3; k++) {
            int m = (int)(24 * test_uniform(&rng)) - 12;
            double u = test_uniform(&rng);
            float x;
            if (u < 0.3) x = (float)(m * (double)cell * (1.0 + 0x1p-20));
            else if (u < 0.5) x = (float)m * cell;
            else if (u < 0.7) x = (float)m * cell * 0.5f;
            else x = (float)((m + test_uniform(&rng)) * cell);
            double w = test_uniform(&rng);
            if (w < 0.2) x = nextafterf(x, INFINITY);
            else if (w < 0.4) x = nextafterf(x, -INFINITY);
            s.p[k][a] = x;
        }
        s.member[a] = test_uniform(&rng) < 0.9;
    }
    check_against_brute_force("cell borders, d_min = cell", &s, cell, cell, 1.0f, 2);
    check_against_brute_force("cell borders, d_min = cell / 2", &s, cell * 0.5f, cell, 1.0f, 2);
    check_against_brute_force("cell borders, d_min = 3/4 cell", &s, cell * 0.75f, cell, 1.0f, 2);
    pts_free(&s);
}

/* Few agents in small clusters far apart, in a tiny table: the 27 cells around an agent often
 * share slots (a neighbour's slot reached through two cells would be counted twice), and runs of 3
 * slots wrap around the table's end. The test checks that both situations do occur with a true
 * neighbour involved, and that the kernel still matches brute force. */
static void test_hash_collisions(void)
{
    uint64_t rng = 14;
    int64_t risky = 0, wrapped = 0, needed = 0, pruned = 0;
    for (int round = 0; round < 40; round++) {
        pts s = pts_new(30); /* capacity 30: a table of 64 slots */
        for (int64_t a = 0; a < s.n; a += 3) {
            float c[3];
            for (int k = 0; k < 3; k++) c[k] = (float)(2000 * test_uniform(&rng) - 1000);
            for (int64_t b = a; b < a + 3; b++) {
                for (int k = 0; k < 3; k++) s.p[k][b] = c[k] + (float)(1.4 * test_uniform(&rng) - 0.7);
                s.member[b] = 1;
            }
        }
        s.member[round % 30] = 0;
        fm_grid g;
        ENSURE(fm_grid_init(&g, s.n, NULL) == FM_OK);
        ENSURE(g.mask == 63);
        const float *p[3] = {s.p[0], s.p[1], s.p[2]};
        fm_grid_build(&g, p, s.member, s.n, 1.0f, 1);
        for (int64_t a = 0; a < s.n; a++) {
            int32_t c[3], cb[3];
            for (int k = 0; k < 3; k++) c[k] = fm_grid_coord(fm_grid_scaled(&g, s.p[k][a]));
            for (int64_t b = 0; b < s.n; b++) {
                float dx = s.p[0][a] - s.p[0][b], dy = s.p[1][a] - s.p[1][b], dz = s.p[2][a] - s.p[2][b];
                if (b == a || !s.member[a] || !s.member[b] || !(dx * dx + dy * dy + dz * dz < 1.0f)) continue;
                for (int k = 0; k < 3; k++) cb[k] = fm_grid_coord(fm_grid_scaled(&g, s.p[k][b]));
                uint32_t sb = fm_grid_slot(&g, cb[0], cb[1], cb[2]);
                int reach = 0;
                for (int j = 0; j < 27; j++)
                    reach += fm_grid_slot(&g, c[0] + j % 3 - 1, c[1] + j / 3 % 3 - 1, c[2] + j / 9 - 1) == sb;
                risky += reach > 1;
                wrapped += fm_grid_slot(&g, c[0] - 1, cb[1], cb[2]) > g.mask - 2;
            }
        }
        fm_grid_free(&g);
        needed += check_against_brute_force(round == 0 ? "tiny table, shared slots, wraps" : NULL, &s, 1.0f,
                                            1.0f, 1.0f, 1);
        /* the same with cells larger than d_min: the pruned walk, its runs sharing slots too */
        pruned += check_against_brute_force(round == 0 ? "tiny table, pruned rows" : NULL, &s, 0.6f, 1.0f, 1.0f, 1);
        pts_free(&s);
    }
    printf("    neighbours reachable through 2+ of the 27 cells: %lld, in wrapping runs: %lld\n",
           (long long)risky, (long long)wrapped);
    ENSURE(risky > 0);
    ENSURE(wrapped > 0);
    ENSURE(needed > 200);
    ENSURE(pruned > 50);
}

static void test_threads_bitwise(void)
{
    uint64_t rng = 15;
    pts s = pts_new(200000);
    fill_uniform(&s, &rng, -50.0, side_for(s.n, 5, 1.0));
    drop_members(&s, &rng, 0.1);
    for (int64_t a = 0; a < s.n; a += 97) /* some duplicates */
        for (int k = 0; k < 3; k++) s.p[k][a] = s.p[k][(a * 7919) % s.n];
    const float *p[3] = {s.p[0], s.p[1], s.p[2]};
    fm_grid g1, g2;
    ENSURE(fm_grid_init(&g1, s.n, NULL) == FM_OK);
    ENSURE(fm_grid_init(&g2, s.n, NULL) == FM_OK);
    mde_out o1 = out_new(s.n), o2 = out_new(s.n);
    fm_grid_build(&g1, p, s.member, s.n, 1.0f, 1);
    int64_t c1 = run_kernel(&g1, &s, 1.0f, 1.0f, &o1, 1);
    const int counts[3] = {2, 3, 8};
    for (int t = 0; t < 3; t++) {
        fm_grid_build(&g2, p, s.member, s.n, 1.0f, counts[t]);
        int64_t c2 = run_kernel(&g2, &s, 1.0f, 1.0f, &o2, counts[t]);
        size_t table = (size_t)g1.mask + 1;
        ENSURE(g1.count == g2.count);
        ENSURE(memcmp(g1.start, g2.start, sizeof(int32_t) * (table + 1)) == 0);
        ENSURE(memcmp(g1.quad, g2.quad, sizeof(fm_grid_quad) * (size_t)(g1.count / 4)) == 0);
        for (int64_t k = g1.count & ~INT64_C(3); k < g1.count; k++) {
            const fm_grid_quad *q1 = &g1.quad[k >> 2], *q2 = &g2.quad[k >> 2];
            ENSURE(q1->x[k & 3] == q2->x[k & 3] && q1->i[k & 3] == q2->i[k & 3]);
        }
        ENSURE(memcmp(g1.slot, g2.slot, sizeof(uint32_t) * (size_t)s.n) == 0);
        ENSURE(c1 == c2);
        for (int k = 0; k < 3; k++) ENSURE(memcmp(o1.v[k], o2.v[k], sizeof(float) * (size_t)s.n) == 0);
        ENSURE(memcmp(o1.needed, o2.needed, (size_t)s.n) == 0);
    }
    ENSURE(c1 > s.n / 2);
    check_grid(&g2, &s);
    /* to compare builds (SSE2 against -DFM_MDE_SCALAR): both must print the same */
    uint64_t sum = 1469598103934665603ull;
    for (int k = 0; k < 3; k++)
        for (int64_t a = 0; a < s.n; a++) {
            uint32_t bits;
            memcpy(&bits, &o1.v[k][a], sizeof bits);
            sum = (sum ^ bits) * 1099511628211ull;
        }
    printf("    v_la checksum %016llx (%lld agents pushed)\n", (unsigned long long)sum, (long long)c1);
    out_free(&o1), out_free(&o2);
    fm_grid_free(&g1), fm_grid_free(&g2);
    pts_free(&s);
}

static void test_capacity_reuse(void)
{
    uint64_t rng = 16;
    pts s = pts_new(5000);
    fill_uniform(&s, &rng, 0.0, side_for(s.n, 5, 1.0));
    drop_members(&s, &rng, 0.1);
    const float *p[3] = {s.p[0], s.p[1], s.p[2]};
    fm_grid g;
    ENSURE(fm_grid_init(&g, s.n, NULL) == FM_OK);
    void *ptrs[6] = {g.start, g.quad, g.slot, g.hist, g.tmp, g.tmp_slot};
    uint32_t mask = g.mask;
    mde_out o = out_new(s.n), o2 = out_new(s.n);
    fm_grid_build(&g, p, s.member, s.n, 1.0f, 2);
    int64_t c_full = run_kernel(&g, &s, 1.0f, 1.0f, &o, 2);

    /* a smaller build with another cell: agents past n are no longer listed */
    pts small = s;
    small.n = 1200;
    fm_grid_build(&g, p, s.member, small.n, 2.0f, 2);
    check_grid(&g, &small);
    for (int64_t a = small.n; a < s.n; a++) ENSURE(g.slot[a] == FM_GRID_NONE);
    int64_t c_small = run_kernel(&g, &small, 1.0f, 1.0f, &o2, 2);
    ENSURE(c_small < c_full);

    /* the full build again gives the first build's result bit for bit */
    fm_grid_build(&g, p, s.member, s.n, 1.0f, 1);
    check_grid(&g, &s);
    ENSURE(run_kernel(&g, &s, 1.0f, 1.0f, &o2, 1) == c_full);
    for (int k = 0; k < 3; k++) ENSURE(memcmp(o.v[k], o2.v[k], sizeof(float) * (size_t)s.n) == 0);
    void *after[6] = {g.start, g.quad, g.slot, g.hist, g.tmp, g.tmp_slot};
    ENSURE(memcmp(ptrs, after, sizeof ptrs) == 0);
    ENSURE(g.mask == mask && g.capacity == s.n);

    /* an empty build */
    fm_grid_build(&g, p, s.member, 0, 1.0f, 2);
    ENSURE(g.count == 0 && g.start[(size_t)g.mask + 1] == 0);
    fm_grid_free(&g);
    ENSURE(g.start == NULL && g.quad == NULL);
    fm_grid_free(&g); /* twice is harmless */
    ENSURE(fm_grid_init(&g, -1, NULL) == FM_ERR_INPUT);
    out_free(&o), out_free(&o2);
    check_against_brute_force("capacity reuse set", &s, 1.0f, 1.0f, 1.0f, 2);
    pts_free(&s);
}

/* ------------------------------------------------------------------ timing */

/* Reorders agents: by = 1 by x only (slabs across the x axis, as the engine's launch order by
 * projection on the path), by = 2 by cell (z, y, x) (a spatially coherent order). */
typedef struct sort_item {
    double key;
    float x, y, z;
} sort_item;

static int cmp_item(const void *a, const void *b)
{
    double x = ((const sort_item *)a)->key, y = ((const sort_item *)b)->key;
    return (x > y) - (x < y);
}

static void reorder(pts *s, int by)
{
    sort_item *it = malloc(sizeof(sort_item) * (size_t)s->n);
    for (int64_t a = 0; a < s->n; a++) {
        double c[3];
        for (int k = 0; k < 3; k++) c[k] = floor(s->p[k][a]);
        double key = by == 1 ? s->p[0][a] : ((c[2] * 1024 + c[1]) * 1024 + c[0]) * 1048576.0 + (double)a;
        it[a] = (sort_item){key, s->p[0][a], s->p[1][a], s->p[2][a]};
    }
    qsort(it, (size_t)s->n, sizeof(sort_item), cmp_item);
    for (int64_t a = 0; a < s->n; a++) s->p[0][a] = it[a].x, s->p[1][a] = it[a].y, s->p[2][a] = it[a].z;
    free(it);
}

/* Mean number of members within d_min of a member, by a plain walk of the 27 cells (slots
 * deduplicated). */
static double mean_neighbours(const fm_grid *g, const pts *s, float d_min)
{
    int64_t pairs = 0, members = 0;
    const float d2min = d_min * d_min;
    for (int64_t a = 0; a < s->n; a++) {
        if (!s->member[a]) continue;
        members++;
        int32_t c[3];
        for (int k = 0; k < 3; k++) c[k] = fm_grid_coord(fm_grid_scaled(g, s->p[k][a]));
        uint32_t seen[27];
        for (int j = 0; j < 27; j++) {
            uint32_t sl = fm_grid_slot(g, c[0] + j % 3 - 1, c[1] + j / 3 % 3 - 1, c[2] + j / 9 - 1);
            int dup = 0;
            for (int i = 0; i < j; i++) dup |= seen[i] == sl;
            seen[j] = sl;
            if (dup) continue;
            for (int32_t k = g->start[sl]; k < g->start[sl + 1]; k++) {
                const fm_grid_quad *q = &g->quad[k >> 2];
                float dx = s->p[0][a] - q->x[k & 3], dy = s->p[1][a] - q->y[k & 3], dz = s->p[2][a] - q->z[k & 3];
                pairs += q->i[k & 3] != a && dx * dx + dy * dy + dz * dz < d2min;
            }
        }
    }
    return members ? (double)pairs / (double)members : 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double cpu_seconds(void) /* all threads of the process */
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ns per agent for the build and the kernel at 10^6 uniform agents, d_min = cell = 1, ~5 neighbours
 * within d_min: wall clock (median and best of `reps`) and CPU time of all threads (median; on a
 * shared machine the wall clock of 2 threads says little, CPU time / threads is the ideal wall). */
static void bench(void)
{
    const int64_t n = 1000000;
    const int reps = 5;
    const float d_min = 1.0f;
    uint64_t rng = 17;
    pts s = pts_new(n);
    fill_uniform(&s, &rng, 0.0, side_for(n, 5, d_min));
    const float *p[3] = {s.p[0], s.p[1], s.p[2]};
    fm_grid g;
    ENSURE(fm_grid_init(&g, n, NULL) == FM_OK);
    mde_out o = out_new(n);
    fm_grid_build(&g, p, s.member, n, d_min, 2);
    printf("    timing: n = %lld uniform in a cube of side %.1f, d_min = cell = 1: %.2f neighbours within d_min\n",
           (long long)n, side_for(n, 5, d_min), mean_neighbours(&g, &s, d_min));
    printf("    ns/agent (%d runs)         build: wall median (best)  cpu | kernel: wall median (best)  cpu\n",
           reps);
    const char *orders[3] = {"random order", "slab order (by x)", "cell order"};
    for (int order = 0; order < 3; order++) {
        if (order > 0) reorder(&s, order);
        for (int threads = 1; threads <= 2; threads++) {
            double tb[16], tk[16], cb[16], ck[16];
            for (int r = 0; r < reps; r++) {
                double t0 = fm_seconds(), c0 = cpu_seconds();
                fm_grid_build(&g, p, s.member, n, d_min, threads);
                double t1 = fm_seconds(), c1 = cpu_seconds();
                run_kernel(&g, &s, d_min, 1.0f, &o, threads);
                double t2 = fm_seconds(), c2 = cpu_seconds();
                tb[r] = (t1 - t0) * 1e9 / (double)n, tk[r] = (t2 - t1) * 1e9 / (double)n;
                cb[r] = (c1 - c0) * 1e9 / (double)n, ck[r] = (c2 - c1) * 1e9 / (double)n;
            }
            qsort(tb, reps, sizeof(double), cmp_double), qsort(tk, reps, sizeof(double), cmp_double);
            qsort(cb, reps, sizeof(double), cmp_double), qsort(ck, reps, sizeof(double), cmp_double);
            printf("    %-18s %d thread%s        %6.1f (%6.1f) %6.1f |        %6.1f (%6.1f) %6.1f\n", orders[order],
                   threads, threads > 1 ? "s" : " ", tb[reps / 2], tb[0], cb[reps / 2], tk[reps / 2], tk[0],
                   ck[reps / 2]);
        }
    }
    out_free(&o);
    fm_grid_free(&g);
    pts_free(&s);
}

/* MDE sums by id, not in the grid's order: hashed rows and rows by position (which list the
 * agents in other orders, with other slot collisions) give the same bits, and so do cells of
 * other sizes. */
static void test_layout_does_not_change_v_la(void)
{
    uint64_t rng = 23;
    pts s = pts_new(6000);
    fill_uniform(&s, &rng, -3.0, side_for(s.n, 6, 1.0));
    drop_members(&s, &rng, 0.1);
    for (int64_t a = 0; a < 300; a += 3) /* triples on top of each other: coincident pairs, 3+ hits */
        for (int k = 0; k < 3; k++) s.p[k][a + 1] = s.p[k][a + 2] = s.p[k][a];
    const float *p[3] = {s.p[0], s.p[1], s.p[2]};
    mde_out o[3] = {out_new(s.n), out_new(s.n), out_new(s.n)};
    const float cell[3] = {1.0f, 1.0f, 2.5f};
    for (int v = 0; v < 3; v++) {
        fm_grid g;
        ENSURE(fm_grid_init(&g, s.n, NULL) == FM_OK);
        g.linear_rows = v == 1;
        fm_grid_build(&g, p, s.member, s.n, cell[v], 2);
        run_kernel(&g, &s, 1.0f, 1.5f, &o[v], 2);
        fm_grid_free(&g);
    }
    int64_t pushed = 0;
    for (int64_t a = 0; a < s.n; a++) pushed += o[0].needed[a];
    ENSURE(pushed > s.n / 2);
    for (int v = 1; v < 3; v++) {
        for (int k = 0; k < 3; k++)
            ENSURE_MSG(memcmp(o[0].v[k], o[v].v[k], sizeof(float) * (size_t)s.n) == 0, "layout %d changed v_la", v);
        ENSURE(memcmp(o[0].needed, o[v].needed, (size_t)s.n) == 0);
    }
    for (int v = 0; v < 3; v++) out_free(&o[v]);
    pts_free(&s);
}

/* Fitted rows (FM_GRID_ROWS_FITTED): the cells of the listed agents' box, and one around it, get
 * distinct slots while the box fits the table, wherever the box lies (here far from the origin, so
 * the wrap is exercised); a box too large for the table still gives every axis its bits and builds
 * a grid that lists every agent once (check_grid); fm_grid_placement fits the same rows. */
static void test_fitted_rows(void)
{
    uint64_t rng = 41;
    pts s = pts_new(4000);
    fill_uniform(&s, &rng, 1000.25, 5.5); /* cells 1000 .. 1005 on every axis, 1000 cells from the origin */
    drop_members(&s, &rng, 0.1);
    for (int k = 0; k < 3; k++) s.p[0][k] = 1000.5f + 40.0f * (float)k, s.member[k] = 1; /* x: cells 1000 .. 1080 */
    const float *p[3] = {s.p[0], s.p[1], s.p[2]};
    fm_grid g;
    ENSURE(fm_grid_init(&g, s.n, NULL) == FM_OK);
    g.linear_rows = FM_GRID_ROWS_FITTED;
    const fm_grid before = fm_grid_placement(&g, p, s.member, s.n, 1.0f, 1);
    fm_grid_build(&g, p, s.member, s.n, 1.0f, 2);
    check_grid(&g, &s);
    ENSURE_MSG(before.shift_y == g.shift_y && before.shift_z == g.shift_z, "placement (%d, %d), build (%d, %d)",
               before.shift_y, before.shift_z, g.shift_y, g.shift_z);
    ENSURE_MSG(g.shift_y == 7 && g.shift_z == 7 + 3, "shifts %d %d: x spans 83 cells with its margin (7 bits), y 8 (3)",
               g.shift_y, g.shift_z);
    /* every cell of the box and its margin: a distinct slot */
    const int32_t lo[3] = {999, 999, 999}, hi[3] = {1081, 1006, 1006};
    const int64_t cells = (int64_t)(hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
    uint8_t *seen = calloc((size_t)g.mask + 1, 1);
    int64_t shared = 0;
    for (int32_t z = lo[2]; z <= hi[2]; z++)
        for (int32_t y = lo[1]; y <= hi[1]; y++)
            for (int32_t x = lo[0]; x <= hi[0]; x++) shared += seen[fm_grid_slot(&g, x, y, z)]++ > 0;
    ENSURE_MSG(shared == 0, "%lld of %lld cells share a slot", (long long)shared, (long long)cells);
    free(seen);
    /* a box wider than the table: the bits are shared out, the grid still lists everyone once */
    s.p[1][5] = 1e7f, s.p[2][6] = -1e7f, s.member[5] = s.member[6] = 1;
    fm_grid_build(&g, p, s.member, s.n, 1.0f, 1);
    check_grid(&g, &s);
    ENSURE(g.shift_z <= g.log2_table && g.shift_y <= g.shift_z && g.shift_y > 0);
    fm_grid_free(&g);
    pts_free(&s);
}

int main(void)
{
    RUN_TEST(test_hand_made_pairs);
    RUN_TEST(test_three_in_a_row);
    RUN_TEST(test_uniform_sets);
    RUN_TEST(test_clustered_and_duplicates);
    RUN_TEST(test_sparse_near_misses);
    RUN_TEST(test_cell_borders);
    RUN_TEST(test_hash_collisions);
    RUN_TEST(test_threads_bitwise);
    RUN_TEST(test_capacity_reuse);
    RUN_TEST(test_layout_does_not_change_v_la);
    RUN_TEST(test_fitted_rows);
    for (linear_rows = FM_GRID_ROWS_THIRDS; linear_rows <= FM_GRID_ROWS_FITTED; linear_rows++) {
        /* the brute-force checks again, rows by position */
        RUN_TEST(test_uniform_sets);
        RUN_TEST(test_clustered_and_duplicates);
        RUN_TEST(test_sparse_near_misses);
        RUN_TEST(test_cell_borders);
    }
#if defined(__SANITIZE_ADDRESS__)
    printf("    (timings skipped under AddressSanitizer)\n");
    (void)bench;
#else
    if (getenv("FM_TEST_BENCH")) bench(); /* timings only on request: FM_TEST_BENCH=1 (bench/ holds the benchmarks) */
#endif
    return test_result();
}
