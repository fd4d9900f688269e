/* Minimum distance enforcement (FM §5.4): "if the distance between two agents is smaller than a
 * threshold, we add two symmetrical opposite velocities on them". Done by gathering, so no two
 * threads ever write one agent; each pair is seen from both sides with the same float arithmetic up
 * to sign, so the two velocities are exactly opposite.
 *
 * Per agent: its cell (cx, cy, cz) and where it sits in it; the neighbour cells its d_min ball can
 * reach are, per axis, the cell before (if it is nearer than d_min to the lower face), its own,
 * and the cell after: a box of 1 to 27 cells, usually just its own (d_min is well below the cell,
 * which is the agents' spacing). Each (cy, cz) row of the box is a run of consecutive slots (the
 * hash keeps rows together), so a range of the sorted entries. The agent's own slot comes from the
 * build: the common case costs no hashing at all.
 *
 * The pushes are summed in increasing agent id (hits sorted by id; ids rather than store slots,
 * so the sum does not depend on the store's order, the cell size or how the agents are split over
 * threads or processes). Most agents have no neighbour within d_min and never get that far.
 *
 * Rare cases leave the fast path: two rows' runs sharing slots (hash collisions: then each slot is
 * walked once, on its own), a run wrapping around the table's end (split), more than MDE_BATCH
 * hits (summed a batch of ids at a time, each batch a new walk). */
#include "kernel_mde.h"

#include <assert.h>
#include <math.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

enum {
    MDE_RUNS = 9,    /* rows of the 3 x 3 x 3 box */
    MDE_RANGES = 27, /* at most one per slot */
    MDE_BATCH = 64   /* hits sorted and summed at a time */
};

typedef struct mde_ctx {
    const fm_grid *g;
    const float *px, *py, *pz;
    const int32_t *id;   /* NULL: the store index is the id */
    const fm_grid_quad *quad;
    double reach;        /* d_min in cell units, rounded up */
    float d2min, dmin, push;
} mde_ctx;

typedef struct mde_query {
    int64_t a;
    int32_t ida;
    float x, y, z;
    int nr;
    int32_t rk[2 * MDE_RANGES];
} mde_query;

static inline int32_t id_of(const mde_ctx *c, int64_t j) { return c->id ? c->id[j] : (int32_t)j; }

/* Do runs i and j (n slots from s[.], mod the table) share a slot? */
static int runs_share(const uint32_t *s, const int *n, int runs, uint32_t mask)
{
    for (int i = 0; i < runs; i++)
        for (int j = i + 1; j < runs; j++)
            if (((s[j] - s[i]) & mask) < (uint32_t)n[i] || ((s[i] - s[j]) & mask) < (uint32_t)n[j]) return 1;
    return 0;
}

/* The ranges of sorted entries in the agent's box of cells, each slot once. */
static void plan_ranges(const mde_ctx *c, mde_query *q)
{
    const fm_grid *g = c->g;
    const double sx = fm_grid_scaled(g, q->x), sy = fm_grid_scaled(g, q->y), sz = fm_grid_scaled(g, q->z);
    const int32_t cx = fm_grid_coord(sx), cy = fm_grid_coord(sy), cz = fm_grid_coord(sz);
    int lo[3], hi[3];
    fm_mde_axis_span(sx, cx, c->reach, &lo[0], &hi[0]);
    fm_mde_axis_span(sy, cy, c->reach, &lo[1], &hi[1]);
    fm_mde_axis_span(sz, cz, c->reach, &lo[2], &hi[2]);
    const uint32_t mask = g->mask, table = mask + 1;
    const int n = hi[0] - lo[0] + 1;
    uint32_t s0[MDE_RUNS];
    int len[MDE_RUNS], runs = 0;
    for (int dz = lo[2]; dz <= hi[2]; dz++)
        for (int dy = lo[1]; dy <= hi[1]; dy++, runs++) {
            const uint32_t own = (dy | dz) == 0 ? g->slot[q->a] : fm_grid_slot(g, cx, cy + dy, cz + dz);
            s0[runs] = (own + (uint32_t)lo[0]) & mask, len[runs] = n;
        }
    const int32_t *start = g->start;
    q->nr = 0;
    if (runs == 1 || !runs_share(s0, len, runs, mask)) { /* the usual case: one range a run */
        for (int r = 0; r < runs; r++) {
            const uint32_t b = s0[r], e = b + (uint32_t)n;
            if (e <= table) {
                q->rk[2 * q->nr] = start[b], q->rk[2 * q->nr + 1] = start[e], q->nr++;
            } else { /* wraps around the table's end */
                q->rk[2 * q->nr] = start[b], q->rk[2 * q->nr + 1] = start[table], q->nr++;
                q->rk[2 * q->nr] = start[0], q->rk[2 * q->nr + 1] = start[e - table], q->nr++;
            }
        }
        return;
    }
    uint32_t seen[MDE_RANGES];
    int ns = 0;
    for (int r = 0; r < runs; r++)
        for (int o = 0; o < n; o++) { /* slot by slot, each slot once */
            const uint32_t sl = (s0[r] + (uint32_t)o) & mask;
            int dup = 0;
            for (int j = 0; j < ns; j++) dup |= seen[j] == sl;
            if (dup) continue;
            seen[ns++] = sl;
            q->rk[2 * q->nr] = start[sl], q->rk[2 * q->nr + 1] = start[sl + 1], q->nr++;
        }
}

/* Inserts hit j (id idj) into the sorted batch hit_id/hit of *m entries, dropping the largest id
 * when the batch is full. */
static inline void batch_insert(int32_t *hit_id, int64_t *hit, int *m, int32_t idj, int64_t j)
{
    if (*m == MDE_BATCH && idj > hit_id[*m - 1]) return;
    int at = *m < MDE_BATCH ? (*m)++ : *m - 1;
    while (at > 0 && hit_id[at - 1] > idj) hit_id[at] = hit_id[at - 1], hit[at] = hit[at - 1], at--;
    hit_id[at] = idj, hit[at] = j;
}

/* Lanes of quad e (entries 4 gq .. 4 gq + 3) inside [kb, ke), not the agent and closer than
 * d_min, as bits: the scan's test, 4 entries at once where SSE2 is there. */
#if defined(__SSE2__)
static inline unsigned close_lanes(const mde_ctx *c, const mde_query *q, const fm_grid_quad *e, int32_t gq,
                                   int32_t kb, int32_t ke)
{
    const __m128i k = _mm_add_epi32(_mm_set1_epi32(4 * gq), _mm_setr_epi32(0, 1, 2, 3));
    const __m128i in = _mm_and_si128(_mm_cmpgt_epi32(k, _mm_set1_epi32(kb - 1)), _mm_cmplt_epi32(k, _mm_set1_epi32(ke)));
    const __m128i self = _mm_cmpeq_epi32(_mm_load_si128((const __m128i *)e->i), _mm_set1_epi32((int32_t)q->a));
    const __m128 dx = _mm_sub_ps(_mm_set1_ps(q->x), _mm_load_ps(e->x));
    const __m128 dy = _mm_sub_ps(_mm_set1_ps(q->y), _mm_load_ps(e->y));
    const __m128 dz = _mm_sub_ps(_mm_set1_ps(q->z), _mm_load_ps(e->z));
    const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    const __m128 hit = _mm_and_ps(_mm_cmplt_ps(d2, _mm_set1_ps(c->d2min)), _mm_castsi128_ps(_mm_andnot_si128(self, in)));
    return (unsigned)_mm_movemask_ps(hit);
}
#else
static inline unsigned close_lanes(const mde_ctx *c, const mde_query *q, const fm_grid_quad *e, int32_t gq,
                                   int32_t kb, int32_t ke)
{
    unsigned bits = 0;
    for (int l = 0; l < 4; l++) {
        const int32_t k = 4 * gq + l;
        const float dx = q->x - e->x[l], dy = q->y - e->y[l], dz = q->z - e->z[l];
        bits |= (unsigned)(k >= kb && k < ke && e->i[l] != q->a && dx * dx + dy * dy + dz * dz < c->d2min) << l;
    }
    return bits;
}
#endif

/* Collects, sorted by id, up to MDE_BATCH of the hits (entries closer than d_min, not the agent)
 * with id > after: the smallest such ids. Returns how many hits with id > after there are in all. */
static int64_t collect_hits(const mde_ctx *c, const mde_query *q, int64_t after, int32_t *hit_id, int64_t *hit,
                            int *count)
{
    const fm_grid_quad *quad = c->quad;
    int64_t total = 0;
    int m = 0;
    for (int r = 0; r < q->nr; r++) {
        const int32_t kb = q->rk[2 * r], ke = q->rk[2 * r + 1];
        for (int32_t gq = kb >> 2; 4 * gq < ke; gq++) {
            unsigned bits = close_lanes(c, q, &quad[gq], gq, kb, ke);
            while (bits) { /* rare: a neighbour closer than d_min */
                const int l = __builtin_ctz(bits);
                bits &= bits - 1;
                const int64_t j = quad[gq].i[l];
                const int32_t idj = id_of(c, j);
                if (idj <= after) continue;
                total++;
                batch_insert(hit_id, hit, &m, idj, j);
            }
        }
    }
    *count = m;
    return total;
}

/* Adds the pushes of hits hit[0 .. m-1] (in id order) to out. */
static void add_pushes(const mde_ctx *c, const mde_query *q, const float *const p[3], const int32_t *hit_id,
                       const int64_t *hit, int m, float out[3])
{
    for (int h = 0; h < m; h++) {
        const int64_t j = hit[h];
        const float dx = q->x - p[0][j], dy = q->y - p[1][j], dz = q->z - p[2][j];
        const float d2 = dx * dx + dy * dy + dz * dz;
        if (d2 == 0) { /* coincident: along a direction from the two ids, + for the lower */
            float d[3];
            const int lower = q->ida < hit_id[h];
            fm_mde_coincident_dir(lower ? q->ida : hit_id[h], lower ? hit_id[h] : q->ida, d);
            const float w = lower ? c->push : -c->push;
            out[0] += w * d[0], out[1] += w * d[1], out[2] += w * d[2];
            continue;
        }
        const float dist = sqrtf(d2);
        const float w = c->push * (c->dmin - dist) / (c->dmin * dist);
        out[0] += w * dx, out[1] += w * dy, out[2] += w * dz;
    }
}

/* v_la of one member agent; returns its number of pairs closer than d_min. */
static int64_t mde_agent(const mde_ctx *c, const float *const p[3], int64_t a, float out[3])
{
    mde_query q;
    q.a = a, q.ida = id_of(c, a);
    q.x = c->px[a], q.y = c->py[a], q.z = c->pz[a];
    plan_ranges(c, &q);
    out[0] = out[1] = out[2] = 0;
    int32_t hit_id[MDE_BATCH];
    int64_t hit[MDE_BATCH], pairs = 0, after = INT64_MIN;
    for (;;) {
        int m;
        const int64_t total = collect_hits(c, &q, after, hit_id, hit, &m);
        add_pushes(c, &q, p, hit_id, hit, m, out);
        pairs += m;
        if (total <= m) break;
        after = hit_id[m - 1]; /* the next batch: ids above this one's */
    }
    return pairs;
}

/* d_min in cell units, rounded up: the planned box never misses a cell the float test can reach. */
static double reach_of(const fm_grid *g, float d_min) { return (double)d_min * g->inv_cell * (1.0 + 0x1p-16) + 0x1p-20; }

int64_t fm_kernel_mde_ref(const fm_grid *g, const float *const p[3], const uint8_t *member, const int32_t *id,
                          int64_t begin, int64_t end, float d_min, float push, float *const v_la[3], uint8_t *needed)
{
    assert(!(d_min > g->cell));
    assert(end <= g->n);
    const int active = d_min > 0 && g->count > 0;
    mde_ctx c = {g, p[0], p[1], p[2], id, g->quad, reach_of(g, d_min), d_min * d_min, d_min, push};
    int64_t count = 0;
    for (int64_t a = begin; a < end; a++) {
        fm_mde_prefetch(g, a, end);
        float out[3] = {0, 0, 0};
        int64_t pairs = 0;
        if (active && member[a]) pairs = mde_agent(&c, p, a, out);
        v_la[0][a] = out[0], v_la[1][a] = out[1], v_la[2][a] = out[2];
        needed[a] = pairs > 0;
        count += pairs > 0;
    }
    return count;
}

/* Two passes: the SIMD screen marks the agents with a neighbour closer than d_min in needed[] (almost
 * none of them), then the reference's walk sums the pushes of those alone; the others get 0. */
int64_t fm_kernel_mde(const fm_grid *g, const float *const p[3], const uint8_t *member, const int32_t *id,
                      int64_t begin, int64_t end, float d_min, float push, float *const v_la[3], uint8_t *needed)
{
    fm_mde_screen_fn *screen = FM_SIMD_PICK(fm_mde_screen);
    if (!screen || !(d_min > 0 && g->count > 0))
        return fm_kernel_mde_ref(g, p, member, id, begin, end, d_min, push, v_la, needed);
    assert(!(d_min > g->cell));
    assert(end <= g->n);
    const mde_ctx c = {g, p[0], p[1], p[2], id, g->quad, reach_of(g, d_min), d_min * d_min, d_min, push};
    screen(g, p, member, begin, end, d_min, c.reach, needed);
    int64_t count = 0;
    for (int64_t a = begin; a < end; a++) {
        float out[3] = {0, 0, 0};
        if (needed[a]) needed[a] = mde_agent(&c, p, a, out) > 0;
        v_la[0][a] = out[0], v_la[1][a] = out[1], v_la[2][a] = out[2];
        count += needed[a];
    }
    return count;
}
