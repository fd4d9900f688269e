/* The MDE walk's screen, SIMD (kernel_mde.h): for each member agent, is any other listed agent
 * closer than d_min? FM_W grid entries are tested at once (16 with AVX-512), with the reference's
 * float test (dx * dx + dy * dy) + dz * dz < d_min * d_min, so the answer is its answer bit for bit.
 * Almost every agent has no such neighbour and is done here; fm_kernel_mde sums the pushes of the
 * few others in scalar code, in id order, as its reference twin does. A slot met twice (two rows
 * hashed onto it) is simply tested twice: the screen asks "any", not "how many". Compiled three
 * times (simd.h). */
#include "kernel_mde.h"
#include "simd.h"

/* Entries k0 .. k0 + FM_W - 1 (k0 a multiple of 4 where FM_W >= 4): coordinates and agent index,
 * lane l = entry k0 + l. The quads hold 4 entries as x[4] y[4] z[4] i[4]; wider lanes take FM_W / 4
 * quads and transpose their 128-bit quarters. The grid's quads are padded (FM_GRID_PAD), so the
 * loads past a range's last entry stay inside the array; those lanes are masked off. */
static inline void load_entries(const fm_grid_quad *quad, int32_t k0, fv *x, fv *y, fv *z, iv *i)
{
    const float *e = (const float *)(const void *)(quad + (k0 >> 2));
#if FM_W == 16
    const __m512 q0 = _mm512_loadu_ps(e), q1 = _mm512_loadu_ps(e + 16), q2 = _mm512_loadu_ps(e + 32),
                 q3 = _mm512_loadu_ps(e + 48);
    const __m512 xy01 = _mm512_shuffle_f32x4(q0, q1, _MM_SHUFFLE(1, 0, 1, 0)); /* q0.x q0.y q1.x q1.y */
    const __m512 zi01 = _mm512_shuffle_f32x4(q0, q1, _MM_SHUFFLE(3, 2, 3, 2)); /* q0.z q0.i q1.z q1.i */
    const __m512 xy23 = _mm512_shuffle_f32x4(q2, q3, _MM_SHUFFLE(1, 0, 1, 0));
    const __m512 zi23 = _mm512_shuffle_f32x4(q2, q3, _MM_SHUFFLE(3, 2, 3, 2));
    *x = _mm512_shuffle_f32x4(xy01, xy23, _MM_SHUFFLE(2, 0, 2, 0)); /* q0.x q1.x q2.x q3.x */
    *y = _mm512_shuffle_f32x4(xy01, xy23, _MM_SHUFFLE(3, 1, 3, 1));
    *z = _mm512_shuffle_f32x4(zi01, zi23, _MM_SHUFFLE(2, 0, 2, 0));
    *i = _mm512_castps_si512(_mm512_shuffle_f32x4(zi01, zi23, _MM_SHUFFLE(3, 1, 3, 1)));
#elif FM_W == 8
    const __m256 xy0 = _mm256_loadu_ps(e), zi0 = _mm256_loadu_ps(e + 8);
    const __m256 xy1 = _mm256_loadu_ps(e + 16), zi1 = _mm256_loadu_ps(e + 24);
    *x = _mm256_permute2f128_ps(xy0, xy1, 0x20), *y = _mm256_permute2f128_ps(xy0, xy1, 0x31);
    *z = _mm256_permute2f128_ps(zi0, zi1, 0x20);
    *i = _mm256_castps_si256(_mm256_permute2f128_ps(zi0, zi1, 0x31));
#elif FM_W == 4
    *x = _mm_loadu_ps(e), *y = _mm_loadu_ps(e + 4), *z = _mm_loadu_ps(e + 8);
    *i = _mm_loadu_si128((const __m128i *)(const void *)(e + 12));
#else
    const fm_grid_quad *q = quad + (k0 >> 2);
    *x = q->x[k0 & 3], *y = q->y[k0 & 3], *z = q->z[k0 & 3], *i = q->i[k0 & 3];
    (void)e;
#endif
}

/* Lanes lo .. hi - 1 of FM_W as bits (lo, hi may be past either end). */
static inline unsigned lanes_between(int32_t lo, int32_t hi)
{
    lo = lo < 0 ? 0 : lo, hi = hi > FM_W ? FM_W : hi;
    return lo < hi ? ((1u << hi) - 1) & ~((1u << lo) - 1) : 0u;
}

typedef struct screen_query {
    fv x, y, z, d2min;
    int32_t self;
} screen_query;

/* Does entry range [kb, ke) hold an agent other than q's closer than d_min? */
static inline int range_is_close(const fm_grid_quad *quad, const screen_query *q, int32_t kb, int32_t ke)
{
    for (int32_t k0 = FM_W >= 4 ? kb & ~3 : kb; k0 < ke; k0 += FM_W) {
        fv ex, ey, ez;
        iv ei;
        load_entries(quad, k0, &ex, &ey, &ez, &ei);
        const fv dx = fv_sub(q->x, ex), dy = fv_sub(q->y, ey), dz = fv_sub(q->z, ez);
        const fv d2 = fv_add(fv_add(fv_mul(dx, dx), fv_mul(dy, dy)), fv_mul(dz, dz));
        const unsigned close = fv_mask(fv_lt(d2, q->d2min)) & ~fv_mask(iv_as_mask(iv_eq_mask(ei, q->self)));
        if (close & lanes_between(kb - k0, ke - k0)) return 1;
    }
    return 0;
}

/* The same for the run of n slots from `first` (mod the table): one range, two where it wraps. */
static inline int run_is_close(const fm_grid *g, const screen_query *q, uint32_t first, uint32_t n)
{
    const uint32_t table = g->mask + 1, b = first & g->mask, e = b + n;
    if (e <= table) return range_is_close(g->quad, q, g->start[b], g->start[e]);
    return range_is_close(g->quad, q, g->start[b], g->start[table]) ||
           range_is_close(g->quad, q, g->start[0], g->start[e - table]);
}

/* Agent a: the cells within reach (d_min in cells) of it, as fm_kernel_mde_ref plans them (rows
 * cy - 1 .. cy + 1 and cz - 1 .. cz + 1 where near a face, each a run of 1 to 3 slots along x),
 * tested for a close entry. The usual case is one row, the agent's own (its slot from the build). */
static int agent_is_close(const fm_grid *g, const float *const p[3], int64_t a, double reach, fv d2min)
{
    const float x = p[0][a], y = p[1][a], z = p[2][a];
    const double sx = fm_grid_scaled(g, x), sy = fm_grid_scaled(g, y), sz = fm_grid_scaled(g, z);
    const int32_t cx = fm_grid_coord(sx), cy = fm_grid_coord(sy), cz = fm_grid_coord(sz);
    int lo[3], hi[3];
    fm_mde_axis_span(sx, cx, reach, &lo[0], &hi[0]);
    fm_mde_axis_span(sy, cy, reach, &lo[1], &hi[1]);
    fm_mde_axis_span(sz, cz, reach, &lo[2], &hi[2]);
    const screen_query q = {fv_set1(x), fv_set1(y), fv_set1(z), d2min, (int32_t)a};
    const uint32_t n = (uint32_t)(hi[0] - lo[0] + 1), own = g->slot[a] + (uint32_t)lo[0];
    if ((lo[1] | hi[1] | lo[2] | hi[2]) == 0) return run_is_close(g, &q, own, n);
    for (int dz = lo[2]; dz <= hi[2]; dz++)
        for (int dy = lo[1]; dy <= hi[1]; dy++) {
            const uint32_t first = (dy | dz) == 0 ? own : fm_grid_slot(g, cx, cy + dy, cz + dz) + (uint32_t)lo[0];
            if (run_is_close(g, &q, first, n)) return 1;
        }
    return 0;
}

void FM_SIMD_VARIANT(fm_mde_screen)(const fm_grid *g, const float *const p[3], const uint8_t *member, int64_t begin,
                                    int64_t end, float d_min, double reach, uint8_t *close)
{
    const fv d2min = fv_set1(d_min * d_min);
    for (int64_t a = begin; a < end; a++) {
        fm_mde_prefetch(g, a, end);
        close[a] = member[a] && agent_is_close(g, p, a, reach, d2min);
    }
}
