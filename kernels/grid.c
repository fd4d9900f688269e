/* The MDE hash grid: a deterministic two-level counting sort of agents by slot.
 *
 * Pass 1 (parallel over agent blocks): each member's slot, and per-block counts of coarse buckets
 *         (a bucket is `fine` consecutive slots; counts fit in L1/L2, unlike per-slot histograms).
 * Offsets: bucket by bucket, block by block, so block t's agents of a bucket follow block t-1's.
 * Pass 2 (parallel over agent blocks): each block scatters its members, in index order, to its
 *         part of their bucket in tmp: tmp is grouped by bucket and in index order inside one.
 * Pass 3 (parallel over buckets): a counting sort of one bucket's agents by slot, stable, inside
 *         the bucket's own part of start[] and quad[] (cache resident).
 * Every write position follows from counts alone, so the result is the same for any thread count. */
#include "grid.h"

#include <assert.h>
#include <math.h>
#include <string.h>

static void grid_zero(fm_grid *g)
{
    *g = (fm_grid){0};
}

/* The table for up to `agents` agents: the next power of two >= 2 agents slots (at least 64). A
 * build sizes it for the agents it may list, not the capacity, so a build over few agents (most of
 * them still waiting) costs little; a larger table never needs more than init allocated. */
static void size_table(fm_grid *g, int64_t agents)
{
    int log2_table = 6;
    while ((INT64_C(1) << log2_table) < 2 * agents) log2_table++;
    int64_t table = INT64_C(1) << log2_table;
    /* slots per coarse bucket: 2048 (8 KB of counts), more for huge tables so that buckets stay
     * <= 4096 (pass 2 then scatters to at most 4096 streams) */
    int log2_fine = 11;
    while (log2_fine < log2_table && (table >> log2_fine) > 4096) log2_fine++;
    if (log2_fine > log2_table) log2_fine = log2_table;
    g->mask = (uint32_t)(table - 1);
    g->log2_table = log2_table;
    g->shift_y = (log2_table + 1) / 3, g->shift_z = 2 * g->shift_y;
    g->log2_fine = log2_fine;
    g->coarse = (int32_t)(table >> log2_fine);
}

fm_status fm_grid_init(fm_grid *g, int64_t capacity, fm_error *err)
{
    return fm_grid_init_table(g, capacity, 0, err);
}

fm_status fm_grid_init_table(fm_grid *g, int64_t capacity, int64_t table_agents, fm_error *err)
{
    grid_zero(g);
    if (capacity < 0 || capacity > FM_GRID_MAX_CAPACITY || table_agents < 0 || table_agents > FM_GRID_MAX_CAPACITY)
        return fm_fail(err, FM_ERR_INPUT, "grid capacity %lld out of range [0, %lld]", (long long)FM_MAX(capacity, table_agents),
                       (long long)FM_GRID_MAX_CAPACITY);
    g->table_agents = table_agents;
    size_table(g, FM_MAX(capacity, table_agents));
    const int64_t table = (int64_t)g->mask + 1;
    g->capacity = capacity;
    size_t cap = (size_t)(capacity > 0 ? capacity : 1);
    g->start = fm_alloc(sizeof(int32_t) * (size_t)(table + 1));
    g->quad = fm_alloc(sizeof(fm_grid_quad) * ((cap + FM_GRID_PAD + 3) / 4));
    g->slot = fm_alloc(sizeof(uint32_t) * cap);
    g->hist = fm_alloc(sizeof(int32_t) * (size_t)FM_GRID_MAX_BLOCKS * (size_t)g->coarse);
    g->tmp = fm_alloc(sizeof(fm_grid_rec) * cap);
    g->tmp_slot = fm_alloc(sizeof(uint32_t) * cap);
    if (!g->start || !g->quad || !g->slot || !g->hist || !g->tmp || !g->tmp_slot) {
        fm_grid_free(g);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for a grid of %lld agents", (long long)capacity);
    }
    for (int64_t a = 0; a < capacity; a++) g->slot[a] = FM_GRID_NONE;
    return FM_OK;
}

fm_status fm_grid_init_velocities(fm_grid *g, fm_error *err)
{
    const size_t cap = (size_t)(g->capacity > 0 ? g->capacity : 1);
    int ok = (g->tmp_vel = fm_alloc(sizeof(float) * 3 * cap)) != NULL;
    for (int c = 0; c < 6; c++) {
        ok = ok && (g->soa[c] = fm_alloc(sizeof(float) * (cap + FM_GRID_SOA_PAD))) != NULL;
        if (ok) memset(g->soa[c] + cap, 0, sizeof(float) * FM_GRID_SOA_PAD); /* tails a walk may load */
    }
    if (!ok) return fm_fail(err, FM_ERR_MEMORY, "out of memory for a grid of %lld agents", (long long)g->capacity);
    return FM_OK;
}

void fm_grid_free(fm_grid *g)
{
    for (int c = 0; c < 6; c++) fm_free(g->soa[c]);
    fm_free(g->tmp_vel);
    fm_free(g->start);
    fm_free(g->quad);
    fm_free(g->slot);
    fm_free(g->hist);
    fm_free(g->tmp);
    fm_free(g->tmp_slot);
    grid_zero(g);
}

/* Slots of agents [lo, hi): members get theirs, the others FM_GRID_NONE; h counts coarse buckets. */
static void slots_block(const fm_grid *g, const float *px, const float *py, const float *pz,
                        const uint8_t *member, int64_t lo, int64_t hi, uint32_t *slot, int32_t *h)
{
    const fm_grid gl = *g; /* locals: the stores below cannot alias them */
    const int log2_fine = gl.log2_fine;
    for (int64_t a = lo; a < hi; a++) {
        uint32_t s = fm_grid_slot_of(&gl, px[a], py[a], pz[a]);
        if (!member || member[a]) {
            slot[a] = s;
            h[s >> log2_fine]++;
        } else {
            slot[a] = FM_GRID_NONE;
        }
    }
}

/* Bits to count `span` cells: the least b with 2^b >= span (span >= 1). */
static int bits_for(double span)
{
    int b = 0;
    while (b < 40 && (double)(INT64_C(1) << b) < span) b++;
    return b;
}

/* FM_GRID_ROWS_FITTED: shift_y and shift_z from the box of the listed agents (grid.h); the table's
 * bits go to the widest axes first where the box does not fit. */
static void fit_rows(fm_grid *g, const float *const p[3], const uint8_t *member, int64_t n, int threads)
{
    float lo0 = INFINITY, lo1 = INFINITY, lo2 = INFINITY, hi0 = -INFINITY, hi1 = -INFINITY, hi2 = -INFINITY;
    const float *px = p[0], *py = p[1], *pz = p[2];
#pragma omp parallel for num_threads(threads) schedule(static) reduction(min : lo0, lo1, lo2) reduction(max : hi0, hi1, hi2)
    for (int64_t a = 0; a < n; a++) { /* branch-free, so that it vectorizes; NaN compares false: skipped */
        const int in = !member || member[a];
        const float x = px[a], y = py[a], z = pz[a];
        lo0 = in && x < lo0 ? x : lo0, lo1 = in && y < lo1 ? y : lo1, lo2 = in && z < lo2 ? z : lo2;
        hi0 = in && x > hi0 ? x : hi0, hi1 = in && y > hi1 ? y : hi1, hi2 = in && z > hi2 ? z : hi2;
    }
    const float lo[3] = {lo0, lo1, lo2}, hi[3] = {hi0, hi1, hi2};
    int bits[3] = {0, 0, 0};
    for (int k = 0; k < 3; k++)
        if (lo[k] <= hi[k]) /* cells from one before the box's first to one after its last */
            bits[k] = bits_for((double)fm_grid_coord(fm_grid_scaled(g, hi[k])) - fm_grid_coord(fm_grid_scaled(g, lo[k])) + 3);
    while (bits[0] + bits[1] + bits[2] > g->log2_table) {
        int widest = bits[1] > bits[0] ? 1 : 0;
        widest = bits[2] > bits[widest] ? 2 : widest;
        bits[widest]--;
    }
    g->shift_y = bits[0], g->shift_z = bits[0] + bits[1];
}

/* Linear rows 8 slots or more apart, planes 8 rows apart and 8 planes in the table: two of a
 * neighbourhood's 9 runs of 3 slots (rows cy - 1 .. cy + 1, cz - 1 .. cz + 1) are then at least 8
 * slots apart, never wrapping onto each other, so fm_grid_ranges need not compare them. */
static int runs_apart(const fm_grid *g)
{
    return g->linear_rows && g->shift_y >= 3 && g->shift_z >= g->shift_y + 3 && g->log2_table >= g->shift_z + 3;
}

/* The table and scale a build over `agents` agents with edge `cell` uses; p and member (with fitted
 * rows) the agents it lists. */
static void set_placement(fm_grid *g, const float *const p[3], const uint8_t *member, int64_t agents, float cell,
                          int threads)
{
    g->cell = cell;
    g->inv_cell = 1.0 / ((double)cell * (1.0 + 0x1p-20));
    size_table(g, g->table_agents > 0 ? g->table_agents : agents);
    if (g->linear_rows == FM_GRID_ROWS_FITTED) fit_rows(g, p, member, agents, threads);
    g->runs_apart = runs_apart(g);
}

fm_grid fm_grid_placement(const fm_grid *g, const float *const p[3], const uint8_t *member, int64_t agents, float cell,
                          int threads)
{
    fm_grid out = *g;
    for (int c = 0; c < 6; c++) out.soa[c] = NULL;
    out.start = NULL, out.quad = NULL, out.slot = NULL, out.tmp_vel = NULL, out.hist = NULL, out.tmp = NULL,
    out.tmp_slot = NULL;
    set_placement(&out, p, member, agents, cell, threads);
    return out;
}

void fm_grid_build(fm_grid *g, const float *const p[3], const uint8_t *member, int64_t n, float cell,
                   int threads)
{
    fm_grid_build_moving(g, p, NULL, member, n, cell, threads);
}

void fm_grid_build_moving(fm_grid *g, const float *const p[3], const float *const v[3], const uint8_t *member,
                          int64_t n, float cell, int threads)
{
    assert(!v || g->soa[0]);
    assert(n >= 0 && n <= g->capacity);
    assert(cell > 0);
    if (threads < 1) threads = 1;
    set_placement(g, p, member, n, cell, threads);

    const int32_t coarse = g->coarse;
    const int log2_fine = g->log2_fine;
    const int64_t fine = INT64_C(1) << log2_fine;
    /* agent blocks: at most one per thread, and not tiny */
    int64_t nblocks = (n + 16383) / 16384;
    if (nblocks > threads) nblocks = threads;
    if (nblocks > FM_GRID_MAX_BLOCKS) nblocks = FM_GRID_MAX_BLOCKS;
    if (nblocks < 1) nblocks = 1;
    const int nthreads = (int)nblocks;
    const float *px = p[0], *py = p[1], *pz = p[2];
    uint32_t *slot = g->slot;
    int32_t *hist = g->hist;

    /* pass 1: slots and per-block bucket counts */
#pragma omp parallel for num_threads(nthreads) schedule(static, 1)
    for (int64_t t = 0; t < nblocks; t++) {
        int64_t lo = n * t / nblocks, hi = n * (t + 1) / nblocks;
        int32_t *h = hist + t * coarse;
        for (int32_t c = 0; c < coarse; c++) h[c] = 0;
        slots_block(g, px, py, pz, member, lo, hi, slot, h);
    }
    for (int64_t a = n; a < g->n; a++) slot[a] = FM_GRID_NONE; /* a larger previous build's tail */
    g->n = n;

    /* offsets: bucket-major, block-minor; hist becomes each block's first position per bucket */
    int32_t run = 0;
    for (int32_t c = 0; c < coarse; c++)
        for (int64_t t = 0; t < nblocks; t++) {
            int32_t k = hist[t * coarse + c];
            hist[t * coarse + c] = run;
            run += k;
        }
    const int32_t total = run;
    g->count = total;

    /* pass 2: scatter to buckets, each block in index order */
    fm_grid_rec *tmp = g->tmp;
    uint32_t *tmp_slot = g->tmp_slot;
    float *tmp_vel = g->tmp_vel;
#pragma omp parallel for num_threads(nthreads) schedule(static, 1)
    for (int64_t t = 0; t < nblocks; t++) {
        int64_t lo = n * t / nblocks, hi = n * (t + 1) / nblocks;
        int32_t *h = hist + t * coarse;
        for (int64_t a = lo; a < hi; a++) {
            uint32_t s = slot[a];
            if (s == FM_GRID_NONE) continue;
            int32_t k = h[s >> log2_fine]++;
            tmp[k] = (fm_grid_rec){px[a], py[a], pz[a], (int32_t)a};
            tmp_slot[k] = s;
            if (v) tmp_vel[3 * k] = v[0][a], tmp_vel[3 * k + 1] = v[1][a], tmp_vel[3 * k + 2] = v[2][a];
        }
    }
    /* after pass 2 the last block's offsets are the bucket ends */
    const int32_t *ends = hist + (nblocks - 1) * coarse;

    /* pass 3: per bucket, a stable counting sort by slot inside its part of start[] and the
     * sorted arrays */
    int32_t *start = g->start;
    fm_grid_quad *quad = g->quad;
    start[0] = 0;
    int nthreads3 = threads;
    if (nthreads3 > coarse) nthreads3 = coarse;
    if (total < 16384) nthreads3 = 1;
#pragma omp parallel for num_threads(nthreads3) schedule(static)
    for (int32_t c = 0; c < coarse; c++) {
        const int32_t kb = c > 0 ? ends[c - 1] : 0, ke = ends[c];
        const int64_t s0 = (int64_t)c << log2_fine;
        int32_t *cnt = start + s0 + 1; /* cnt[j]: slot s0 + j; start[s0] is the bucket before's */
        for (int64_t j = 0; j < fine; j++) cnt[j] = 0;
        for (int32_t k = kb; k < ke; k++) cnt[tmp_slot[k] - s0]++;
        int32_t pos = kb;
        for (int64_t j = 0; j < fine; j++) {
            int32_t k = cnt[j];
            cnt[j] = pos;
            pos += k;
        }
        for (int32_t k = kb; k < ke; k++) {
            int32_t d = cnt[tmp_slot[k] - s0]++;
            fm_grid_quad *q = &quad[d >> 2];
            q->x[d & 3] = tmp[k].x, q->y[d & 3] = tmp[k].y, q->z[d & 3] = tmp[k].z, q->i[d & 3] = tmp[k].i;
            if (v) {
                float *const *c = g->soa;
                c[0][d] = tmp[k].x, c[1][d] = tmp[k].y, c[2][d] = tmp[k].z;
                c[3][d] = tmp_vel[3 * k], c[4][d] = tmp_vel[3 * k + 1], c[5][d] = tmp_vel[3 * k + 2];
            }
        }
        /* now cnt[j] = end of slot s0 + j = start of slot s0 + j + 1 */
    }
}

/* Do two of the runs base[r] .. base[r] + 2 share a slot? */
static int runs_share_slots(const uint32_t base[9], uint32_t mask)
{
    for (int r = 1; r < 9; r++)
        for (int q = 0; q < r; q++)
            if (((base[r] - base[q] + 2) & mask) <= 4) return 1;
    return 0;
}

int fm_grid_ranges(const fm_grid *g, float x, float y, float z, int32_t rk[2 * FM_GRID_MAX_RANGES])
{
    const int32_t cx = fm_grid_coord(fm_grid_scaled(g, x)), cy = fm_grid_coord(fm_grid_scaled(g, y)),
                  cz = fm_grid_coord(fm_grid_scaled(g, z));
    uint32_t base[9];
    for (int dz = -1, r = 0; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++, r++) base[r] = ((uint32_t)(cx - 1) + fm_grid_row(g, cy + dy, cz + dz)) & g->mask;
    int nr = 0;
    if (g->runs_apart || !runs_share_slots(base, g->mask)) { /* the usual case: 9 runs of 3 slots, split at a wrap */
        for (int r = 0; r < 9; r++) {
            const uint32_t s0 = base[r], s3 = s0 + 3;
            if (s3 <= g->mask + 1) {
                rk[2 * nr] = g->start[s0], rk[2 * nr + 1] = g->start[s3], nr++;
            } else {
                rk[2 * nr] = g->start[s0], rk[2 * nr + 1] = g->start[g->mask + 1], nr++;
                rk[2 * nr] = g->start[0], rk[2 * nr + 1] = g->start[s3 - (g->mask + 1)], nr++;
            }
        }
        return nr;
    }
    uint32_t seen[FM_GRID_MAX_RANGES];
    int ns = 0;
    for (int r = 0; r < 9; r++) {
        for (uint32_t o = 0; o < 3; o++) {
            const uint32_t s = (base[r] + o) & g->mask;
            int dup = 0;
            for (int j = 0; j < ns; j++) dup |= seen[j] == s;
            if (dup) continue;
            seen[ns++] = s;
            rk[2 * nr] = g->start[s], rk[2 * nr + 1] = g->start[s + 1], nr++;
        }
    }
    return nr;
}

int64_t fm_grid_nearest(const fm_grid *g, const float q[3], const uint8_t *alive, int64_t self, int64_t skip,
                        double *d2)
{
    int32_t rk[2 * FM_GRID_MAX_RANGES];
    const int nr = fm_grid_ranges(g, q[0], q[1], q[2], rk);
    const double reach2 = (double)g->cell * (double)g->cell;
    double best = INFINITY;
    int64_t who = -1;
    for (int r = 0; r < nr; r++)
        for (int32_t k = rk[2 * r]; k < rk[2 * r + 1]; k++) {
            const fm_grid_quad *e = &g->quad[k >> 2];
            const int64_t j = e->i[k & 3];
            if (j == self || j == skip || (alive && !alive[j])) continue;
            double dx = (double)e->x[k & 3] - q[0], dy = (double)e->y[k & 3] - q[1], dz = (double)e->z[k & 3] - q[2];
            double dd = dx * dx + dy * dy + dz * dz;
            if (dd < best || (dd == best && j < who)) best = dd, who = j;
        }
    if (!(best <= reach2)) who = -1, best = INFINITY;
    *d2 = best;
    return who;
}
