/* Minimum distance enforcement (FM §5.4): "if the distance between two agents is smaller than a
 * threshold, we add two symmetrical opposite velocities on them". Done by gathering, so no two
 * threads ever write one agent; each pair is seen from both sides with the same float arithmetic up
 * to sign, so the two velocities are exactly opposite.
 *
 * Per agent: its cell (cx, cy, cz); the 9 rows (., cy+dy, cz+dz) are runs of 3 consecutive slots
 * (cells cx-1 .. cx+1), i.e. 9 ranges of the sorted entries (g->quad). When cells are larger than
 * d_min, each run is trimmed to the cells whose box is within reach. A range is tested two quads
 * (8 aligned entries) at a time, branch-free (a range of up to 5 entries costs one fixed step; the
 * lanes outside it are masked), appending the hits' entry numbers to a buffer; the hits then get
 * their square roots 4 at a time, summed in 4 lanes (lane = hit number mod 4), the lanes added in a
 * fixed order. Everything depends only on the grid and the agent, so the result is the same for any
 * thread count, and the scalar fallback (no SSE2, or -DFM_MDE_SCALAR) gives the same bits.
 *
 * Agents in index order are often far apart in the grid, so the work is pipelined: the cell and
 * rows of agent a + 2 (prefetching its slot table entries), the ranges of a + 1 (prefetching their
 * first entries), the scan of a.
 *
 * Rare cases leave the fast path: two rows' runs sharing slots (hash collisions: then each slot is
 * scanned once, on its own), a run wrapping around the table's end (split), coincident pairs (a
 * second pass over the ranges). */
#include "kernel_mde.h"

#include <assert.h>
#include <math.h>

#if defined(__SSE2__) && !defined(FM_MDE_SCALAR)
#include <emmintrin.h>
#define MDE_SSE2 1
#else
#define MDE_SSE2 0
#endif

enum {
    MDE_HITS = 128,    /* hit buffer; flushed when fewer than 8 + 4 entries are left */
    MDE_RANGES = 27    /* at most one per slot of the 27 cells */
};

typedef struct mde_agent {
    float x, y, z;
    int32_t a;
    int32_t m;         /* hits buffered */
    int32_t zeros;     /* hits at distance 0 (the agent itself is never a hit) */
    int64_t pairs;     /* hits at distance > 0 */
    float acc[3][4];   /* v_la so far, per lane (the scalar path; SSE2 keeps them in registers) */
    int32_t hit[MDE_HITS + 4];
} mde_agent;

#if MDE_SSE2
/* lanes of a 4-bit mask, in order, and how many */
static const int32_t lanes16[16][4] = {
    {0, 0, 0, 0}, {0, 0, 0, 0}, {1, 0, 0, 0}, {0, 1, 0, 0}, {2, 0, 0, 0}, {0, 2, 0, 0},
    {1, 2, 0, 0}, {0, 1, 2, 0}, {3, 0, 0, 0}, {0, 3, 0, 0}, {1, 3, 0, 0}, {0, 1, 3, 0},
    {2, 3, 0, 0}, {0, 2, 3, 0}, {1, 2, 3, 0}, {0, 1, 2, 3}};
static const int32_t popc16[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};
#endif

/* Do two of the 9 runs row[r] .. row[r]+2 share a slot? (|r_i - r_j| <= 2 mod the table size) */
static int runs_overlap(const uint32_t s[9], uint32_t mask)
{
#if MDE_SSE2
    const __m128i a = _mm_loadu_si128((const __m128i *)s), b = _mm_loadu_si128((const __m128i *)(s + 4));
    const __m128i c = _mm_set1_epi32((int32_t)s[8]), two = _mm_set1_epi32(2), five = _mm_set1_epi32(5);
    const __m128i m = _mm_set1_epi32((int32_t)mask); /* mask < 2^31: the signed compare is right */
#define MDE_CLOSE(u, v) _mm_cmplt_epi32(_mm_and_si128(_mm_add_epi32(_mm_sub_epi32(u, v), two), m), five)
    __m128i bad = MDE_CLOSE(a, _mm_shuffle_epi32(a, _MM_SHUFFLE(0, 3, 2, 1)));        /* a_i, a_i+1 */
    bad = _mm_or_si128(bad, MDE_CLOSE(a, _mm_shuffle_epi32(a, _MM_SHUFFLE(1, 0, 3, 2)))); /* a_i, a_i+2 */
    bad = _mm_or_si128(bad, MDE_CLOSE(b, _mm_shuffle_epi32(b, _MM_SHUFFLE(0, 3, 2, 1))));
    bad = _mm_or_si128(bad, MDE_CLOSE(b, _mm_shuffle_epi32(b, _MM_SHUFFLE(1, 0, 3, 2))));
    bad = _mm_or_si128(bad, MDE_CLOSE(a, b));                                         /* a_i, b_i+j */
    bad = _mm_or_si128(bad, MDE_CLOSE(a, _mm_shuffle_epi32(b, _MM_SHUFFLE(0, 3, 2, 1))));
    bad = _mm_or_si128(bad, MDE_CLOSE(a, _mm_shuffle_epi32(b, _MM_SHUFFLE(1, 0, 3, 2))));
    bad = _mm_or_si128(bad, MDE_CLOSE(a, _mm_shuffle_epi32(b, _MM_SHUFFLE(2, 1, 0, 3))));
    bad = _mm_or_si128(bad, MDE_CLOSE(a, c));
    bad = _mm_or_si128(bad, MDE_CLOSE(b, c));
#undef MDE_CLOSE
    return _mm_movemask_epi8(bad) != 0;
#else
    int bad = 0;
    for (int i = 1; i < 9; i++)
        for (int j = 0; j < i; j++) bad |= ((s[i] - s[j] + 2) & mask) <= 4;
    return bad;
#endif
}

#define MDE_X(q, k) ((q)[(k) >> 2].x[(k) & 3])
#define MDE_Y(q, k) ((q)[(k) >> 2].y[(k) & 3])
#define MDE_Z(q, k) ((q)[(k) >> 2].z[(k) & 3])

#if MDE_SSE2
typedef struct mde_vec {
    __m128i self; /* the agent's index: its own entry is not a neighbour */
    __m128 x, y, z, d2min, dmin, push, one;
    __m128 vx, vy, vz; /* lane sums */
} mde_vec;

/* Hits hit[0 .. m-1]: push * (1 - dist / d_min) * (x_a - x_b) / dist for d2 > 0, 4 at a time;
 * hits at distance 0 add exactly 0 and are counted. */
static inline void flush_hits(mde_agent *s, mde_vec *v, const fm_grid_quad *q)
{
    const int32_t m = s->m;
    s->hit[m] = s->hit[m + 1] = s->hit[m + 2] = 0; /* tail lanes: any valid entry, masked below */
    const __m128i iota = _mm_setr_epi32(0, 1, 2, 3);
    int32_t zeros = 0;
    for (int32_t j = 0; j < m; j += 4) {
        const int32_t *h = s->hit + j;
        __m128 bx = _mm_setr_ps(MDE_X(q, h[0]), MDE_X(q, h[1]), MDE_X(q, h[2]), MDE_X(q, h[3]));
        __m128 by = _mm_setr_ps(MDE_Y(q, h[0]), MDE_Y(q, h[1]), MDE_Y(q, h[2]), MDE_Y(q, h[3]));
        __m128 bz = _mm_setr_ps(MDE_Z(q, h[0]), MDE_Z(q, h[1]), MDE_Z(q, h[2]), MDE_Z(q, h[3]));
        __m128 dx = _mm_sub_ps(v->x, bx), dy = _mm_sub_ps(v->y, by), dz = _mm_sub_ps(v->z, bz);
        __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
        __m128 valid = _mm_castsi128_ps(_mm_cmplt_epi32(iota, _mm_set1_epi32(m - j)));
        __m128 zero = _mm_cmpeq_ps(d2, _mm_setzero_ps());
        __m128 use = _mm_andnot_ps(zero, valid);
        zeros += popc16[_mm_movemask_ps(_mm_and_ps(zero, valid))];
        __m128 dist = _mm_sqrt_ps(_mm_or_ps(_mm_and_ps(use, d2), _mm_andnot_ps(use, v->one)));
        __m128 w = _mm_div_ps(_mm_mul_ps(v->push, _mm_sub_ps(v->dmin, dist)), _mm_mul_ps(v->dmin, dist));
        w = _mm_and_ps(w, use);
        v->vx = _mm_add_ps(v->vx, _mm_mul_ps(w, dx));
        v->vy = _mm_add_ps(v->vy, _mm_mul_ps(w, dy));
        v->vz = _mm_add_ps(v->vz, _mm_mul_ps(w, dz));
    }
    s->pairs += m - zeros;
    s->zeros += zeros;
    s->m = 0;
}

/* Tests the 4 entries of quad gq, those in [kb, ke) (lanes of kv = 4 gq + lane between kb1 = kb - 1
 * and ke, exclusive); appends the hits (d2 < d2min, not the agent itself) at hit + m; returns
 * the new m. */
static inline int32_t test_quad(int32_t *hit, int32_t m, const mde_vec *v, const fm_grid_quad *q, int32_t gq,
                                __m128i kb1, __m128i ke)
{
    const fm_grid_quad *p = q + gq;
    __m128i kv = _mm_add_epi32(_mm_set1_epi32(4 * gq), _mm_setr_epi32(0, 1, 2, 3));
    __m128i in_range = _mm_and_si128(_mm_cmpgt_epi32(kv, kb1), _mm_cmplt_epi32(kv, ke));
    __m128i self = _mm_cmpeq_epi32(_mm_load_si128((const __m128i *)p->i), v->self);
    __m128 valid = _mm_castsi128_ps(_mm_andnot_si128(self, in_range));
    __m128 dx = _mm_sub_ps(v->x, _mm_load_ps(p->x));
    __m128 dy = _mm_sub_ps(v->y, _mm_load_ps(p->y));
    __m128 dz = _mm_sub_ps(v->z, _mm_load_ps(p->z));
    __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    int bits = _mm_movemask_ps(_mm_and_ps(_mm_cmplt_ps(d2, v->d2min), valid));
    __m128i idx = _mm_add_epi32(_mm_set1_epi32(4 * gq), _mm_loadu_si128((const __m128i *)lanes16[bits]));
    _mm_storeu_si128((__m128i *)(hit + m), idx);
    return m + popc16[bits];
}

/* Entries kb .. ke-1: the quads holding them, two at a time (a range of up to 5 entries, however
 * placed, is one step; the quad array is padded). */
static inline void scan_range(mde_agent *s, mde_vec *v, const fm_grid_quad *q, int32_t kb, int32_t ke)
{
    const __m128i kb1 = _mm_set1_epi32(kb - 1), kev = _mm_set1_epi32(ke);
    int32_t m = s->m, gq = kb >> 2;
    do {
        m = test_quad(s->hit, m, v, q, gq, kb1, kev);
        m = test_quad(s->hit, m, v, q, gq + 1, kb1, kev);
        if (m > MDE_HITS - 8) {
            s->m = m;
            flush_hits(s, v, q);
            m = 0;
        }
        gq += 2;
    } while (4 * gq < ke);
    s->m = m;
}
#else
typedef struct mde_vec {
    float d2min, dmin, push;
} mde_vec;

/* The same arithmetic as the SSE2 path, lane by lane. */
static void flush_hits(mde_agent *s, mde_vec *v, const fm_grid_quad *q)
{
    int32_t zeros = 0;
    for (int32_t j = 0; j < s->m; j++) {
        int32_t k = s->hit[j], lane = j & 3;
        float dx = s->x - MDE_X(q, k), dy = s->y - MDE_Y(q, k), dz = s->z - MDE_Z(q, k);
        float d2 = dx * dx + dy * dy + dz * dz;
        if (d2 == 0) {
            zeros++;
            continue;
        }
        float dist = sqrtf(d2);
        float w = v->push * (v->dmin - dist) / (v->dmin * dist);
        s->acc[0][lane] += w * dx, s->acc[1][lane] += w * dy, s->acc[2][lane] += w * dz;
    }
    s->pairs += s->m - zeros;
    s->zeros += zeros;
    s->m = 0;
}

static void scan_range(mde_agent *s, mde_vec *v, const fm_grid_quad *q, int32_t kb, int32_t ke)
{
    int32_t gq = kb >> 2;
    do {
        for (int32_t k = 4 * gq; k < 4 * gq + 8; k++) {
            if (k < kb || k >= ke || q[k >> 2].i[k & 3] == s->a) continue;
            float dx = s->x - MDE_X(q, k), dy = s->y - MDE_Y(q, k), dz = s->z - MDE_Z(q, k);
            float d2 = dx * dx + dy * dy + dz * dz;
            if (d2 < v->d2min) s->hit[s->m++] = k;
        }
        if (s->m > MDE_HITS - 8) flush_hits(s, v, q);
        gq += 2;
    } while (4 * gq < ke);
}
#endif

/* Second pass for coincident pairs: push along a direction from the two indices. */
static void coincident(mde_agent *s, const fm_grid *g, float push, const int32_t *rk, int nr, float out[3])
{
    const fm_grid_quad *q = g->quad;
    for (int r = 0; r < nr; r++)
        for (int32_t k = rk[2 * r]; k < rk[2 * r + 1]; k++) {
            float dx = s->x - MDE_X(q, k), dy = s->y - MDE_Y(q, k), dz = s->z - MDE_Z(q, k);
            int32_t b = q[k >> 2].i[k & 3];
            if (dx * dx + dy * dy + dz * dz != 0 || b == s->a) continue;
            float d[3];
            int lower = s->a < b;
            fm_mde_coincident_dir(lower ? s->a : b, lower ? b : s->a, d);
            float w = lower ? push : -push;
            out[0] += w * d[0], out[1] += w * d[1], out[2] += w * d[2];
        }
}

/* Per agent, what the pipeline has worked out so far. */
typedef struct mde_plan {
    float x, y, z;
    int member;
    double q[3];          /* scaled coordinates */
    int32_t c[3];         /* cell */
    int rows;             /* rows to walk: 9, or with pruning only those within reach */
    uint32_t row[9];      /* their row hashes */
    uint8_t lo[9], hi[9]; /* with pruning: the part lo .. hi-1 of each run (cells cx-1+lo ..) */
    int overlap;          /* two runs share slots */
    int nr;               /* ranges */
    int32_t rk[2 * MDE_RANGES];
} mde_plan;

typedef struct mde_ctx {
    const fm_grid *g;
    const float *px, *py, *pz;
    const uint8_t *member;
    const int32_t *start;
    const fm_grid_quad *quad;
    uint32_t mask, table;
    double r2;
    int prune, active;
    uint32_t row[9];      /* row hashes for (row_cy, row_cz), kept while consecutive agents share a row */
    int32_t row_cy, row_cz;
    int have_rows, row_overlap;
} mde_ctx;

/* Do runs i and j (slots base + row + lo .. base + row + hi - 1, mod the table) share a slot? */
static int pruned_runs_overlap(const mde_plan *pl, uint32_t mask)
{
    for (int i = 0; i < pl->rows; i++)
        for (int j = i + 1; j < pl->rows; j++) {
            uint32_t a = pl->row[i] + pl->lo[i], b = pl->row[j] + pl->lo[j];
            uint32_t la = (uint32_t)(pl->hi[i] - pl->lo[i]), lb = (uint32_t)(pl->hi[j] - pl->lo[j]);
            if (((b - a) & mask) < la || ((a - b) & mask) < lb) return 1;
        }
    return 0;
}

/* Stage 1 with pruning (cells larger than d_min, the usual case: the cell is at least the agents'
 * spacing): only the rows whose cells come within d_min of the agent, and only their hashes; with
 * one row, typical when d_min is well below the spacing, no overlap test. The rows, runs and their
 * order are those the full 9-row plan would keep after pruning, so the result is the same. */
static inline void plan_cells_pruned(mde_ctx *x, mde_plan *pl)
{
    const fm_grid *g = x->g;
    double gap[3][3]; /* [axis][d + 1]: squared gap to the neighbour cell's box, cell units */
    for (int k = 0; k < 3; k++) {
        double f = pl->q[k] - (double)pl->c[k];
        gap[k][0] = f * f, gap[k][1] = 0, gap[k][2] = (1 - f) * (1 - f);
    }
    if (pl->c[1] != x->row_cy || pl->c[2] != x->row_cz || !x->have_rows) {
        x->row[4] = fm_grid_row(g, pl->c[1], pl->c[2]); /* the agent's own row, reused while it stays */
        x->row_cy = pl->c[1], x->row_cz = pl->c[2], x->have_rows = 1;
    }
    const uint32_t base = (uint32_t)(pl->c[0] - 1);
    int rows = 0;
    for (int dz = 0, r = 0; dz < 3; dz++)
        for (int dy = 0; dy < 3; dy++, r++) {
            double yz = gap[1][dy] + gap[2][dz];
            if (!(yz < x->r2)) continue;
            pl->row[rows] = r == 4 ? x->row[4] : fm_grid_row(g, pl->c[1] + dy - 1, pl->c[2] + dz - 1);
            pl->lo[rows] = !(gap[0][0] + yz < x->r2) ? 1 : 0;
            pl->hi[rows] = !(gap[0][2] + yz < x->r2) ? 2 : 3;
            __builtin_prefetch(x->start + ((base + pl->row[rows] + pl->lo[rows]) & x->mask));
            rows++;
        }
    pl->rows = rows;
    pl->overlap = rows > 1 && pruned_runs_overlap(pl, x->mask);
}

/* Stage 1: the agent's cell and rows; prefetches the slot table entries of the runs. */
static inline void plan_cells(mde_ctx *x, mde_plan *pl, int64_t a)
{
    pl->member = x->member[a] && x->active;
    if (!pl->member) return;
    const fm_grid *g = x->g;
    pl->x = x->px[a], pl->y = x->py[a], pl->z = x->pz[a];
    pl->q[0] = fm_grid_scaled(g, pl->x), pl->q[1] = fm_grid_scaled(g, pl->y), pl->q[2] = fm_grid_scaled(g, pl->z);
    for (int k = 0; k < 3; k++) pl->c[k] = fm_grid_coord(pl->q[k]);
    if (x->prune) {
        plan_cells_pruned(x, pl);
        return;
    }
    if (pl->c[1] != x->row_cy || pl->c[2] != x->row_cz || !x->have_rows) {
        uint32_t hy[3], hz[3];
        for (int d = 0; d < 3; d++)
            hy[d] = (uint32_t)(pl->c[1] + d - 1) * FM_GRID_HY, hz[d] = (uint32_t)(pl->c[2] + d - 1) * FM_GRID_HZ;
        for (int dz = 0, r = 0; dz < 3; dz++)
            for (int dy = 0; dy < 3; dy++, r++) x->row[r] = fm_grid_row_mix(g, hy[dy], hz[dz]);
        x->row_overlap = runs_overlap(x->row, x->mask);
        x->row_cy = pl->c[1], x->row_cz = pl->c[2], x->have_rows = 1;
    }
    const uint32_t base = (uint32_t)(pl->c[0] - 1); /* + row: the slot of the cell cx - 1 */
    pl->rows = 9;
    for (int r = 0; r < 9; r++) {
        pl->row[r] = x->row[r];
        pl->lo[r] = 0, pl->hi[r] = 3;
        __builtin_prefetch(x->start + ((base + x->row[r]) & x->mask));
    }
    pl->overlap = x->row_overlap;
}

/* Stage 2: the ranges of sorted entries to test; prefetches their first positions. */
static inline void plan_ranges(const mde_ctx *x, mde_plan *pl)
{
    if (!pl->member) return;
    const int32_t *start = x->start;
    const uint32_t mask = x->mask, table = x->table;
    const uint32_t base = (uint32_t)(pl->c[0] - 1);
    int32_t *rk = pl->rk;
    uint32_t seen[27];
    int ns = 0, nr = 0;
    for (int r = 0; r < pl->rows; r++) {
        const uint32_t lo = pl->lo[r], hi = pl->hi[r];
        const uint32_t s0 = (base + pl->row[r] + lo) & mask;
        if (!pl->overlap && s0 + (hi - lo) <= table) { /* one range (runs that wrap are rare) */
            rk[2 * nr] = start[s0], rk[2 * nr + 1] = start[s0 + (hi - lo)], nr++;
            continue;
        }
        for (uint32_t o = lo; o < hi; o++) { /* slot by slot, each slot once */
            uint32_t sl = (base + pl->row[r] + o) & mask;
            int dup = 0;
            for (int j = 0; j < ns; j++) dup |= seen[j] == sl;
            if (dup) continue;
            seen[ns++] = sl;
            rk[2 * nr] = start[sl], rk[2 * nr + 1] = start[sl + 1], nr++;
        }
    }
    pl->nr = nr;
    for (int r = 0; r < nr; r++) __builtin_prefetch(x->quad + (rk[2 * r] >> 2));
}

#if MDE_SSE2
/* (l0 + l1) + (l2 + l3), as the scalar path adds its lanes */
static inline float lane_sum(__m128 v)
{
    __m128 t = _mm_add_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 3, 0, 1))); /* l0+l1, ., l2+l3, . */
    return _mm_cvtss_f32(_mm_add_ss(t, _mm_movehl_ps(t, t)));
}
#endif

int64_t fm_kernel_mde(const fm_grid *g, const float *const p[3], const uint8_t *member,
                      int64_t begin, int64_t end, float d_min, float push,
                      float *const v_la[3], uint8_t *needed)
{
    assert(!(d_min > g->cell));
    assert(end <= g->n);
    float *vx = v_la[0], *vy = v_la[1], *vz = v_la[2];
    mde_ctx x;
    x.g = g;
    x.px = p[0], x.py = p[1], x.pz = p[2];
    x.member = member;
    x.start = g->start;
    x.quad = g->quad;
    x.mask = g->mask, x.table = g->mask + 1;
    /* reach in cell units, rounded up: a cell box nearer than this may hold a neighbour */
    const double reach = (double)d_min * g->inv_cell * (1.0 + 0x1p-16) + 0x1p-20;
    x.r2 = reach * reach;
    x.prune = reach < 1; /* else every cell of the 27 is within reach of some point */
    x.active = d_min > 0 && g->count > 0;
    x.row_cy = x.row_cz = 0;
    x.have_rows = x.row_overlap = 0;
    const float d2min = d_min * d_min;
    mde_agent s;
    mde_vec v;
#if MDE_SSE2
    v.d2min = _mm_set1_ps(d2min), v.dmin = _mm_set1_ps(d_min), v.push = _mm_set1_ps(push);
    v.one = _mm_set1_ps(1.0f);
#else
    v.d2min = d2min, v.dmin = d_min, v.push = push;
#endif
    const fm_grid_quad *quad = g->quad;
    int64_t count = 0;

    /* a pipeline: the cells of agent a + 2, the ranges of a + 1, the scan of a */
    mde_plan plan[4];
    if (begin < end) plan_cells(&x, &plan[begin & 3], begin);
    if (begin + 1 < end) plan_cells(&x, &plan[(begin + 1) & 3], begin + 1);
    if (begin < end) plan_ranges(&x, &plan[begin & 3]);
    for (int64_t a = begin; a < end; a++) {
        if (a + 2 < end) plan_cells(&x, &plan[(a + 2) & 3], a + 2);
        if (a + 1 < end) plan_ranges(&x, &plan[(a + 1) & 3]);
        const mde_plan *pl = &plan[a & 3];
        if (!pl->member) {
            vx[a] = vy[a] = vz[a] = 0;
            needed[a] = 0;
            continue;
        }
        s.x = pl->x, s.y = pl->y, s.z = pl->z;
        s.a = (int32_t)a;
        s.m = 0, s.zeros = 0, s.pairs = 0;
#if MDE_SSE2
        v.x = _mm_set1_ps(s.x), v.y = _mm_set1_ps(s.y), v.z = _mm_set1_ps(s.z);
        v.self = _mm_set1_epi32(s.a);
        v.vx = v.vy = v.vz = _mm_setzero_ps();
#else
        for (int k = 0; k < 3; k++)
            for (int l = 0; l < 4; l++) s.acc[k][l] = 0;
#endif
        for (int r = 0; r < pl->nr; r++) scan_range(&s, &v, quad, pl->rk[2 * r], pl->rk[2 * r + 1]);
        if (s.m > 0) flush_hits(&s, &v, quad); /* most agents have no neighbour within d_min */
#if MDE_SSE2
        float out[3] = {lane_sum(v.vx), lane_sum(v.vy), lane_sum(v.vz)};
#else
        float out[3];
        for (int k = 0; k < 3; k++) out[k] = (s.acc[k][0] + s.acc[k][1]) + (s.acc[k][2] + s.acc[k][3]);
#endif
        if (s.zeros > 0) { /* coincident agents */
            coincident(&s, g, push, pl->rk, pl->nr, out);
            s.pairs += s.zeros;
        }
        vx[a] = out[0], vy[a] = out[1], vz[a] = out[2];
        needed[a] = s.pairs > 0;
        count += s.pairs > 0;
    }
    return count;
}
