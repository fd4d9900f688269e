/* Minimum distance enforcement (FM §5.4) over the hash grid of grid.h. Same rules as
 * kernels.h: a pure function over an agent range, no allocation, each agent writes only its own
 * entries, so any split of the range across threads gives the same bits. */
#ifndef FM_KERNEL_MDE_H
#define FM_KERNEL_MDE_H

#include "grid.h"
#include "simd.h"

#include <stdint.h>

/* MDE by gathering: for each agent a in [begin, end) with member[a],
 *
 *     v_la(a) = sum over members b != a with |x_a - x_b| < d_min, in increasing id(b), of
 *               push * (1 - |x_a - x_b| / d_min) * unit(x_a - x_b)
 *
 * where "|x_a - x_b| < d_min" is the float test dx*dx + dy*dy + dz*dz < d_min*d_min, the sum is
 * taken in float from 0 in that order, and id(b) = id[b] (id NULL: b itself). A pair whose
 * dx*dx + dy*dy + dz*dz is 0 (coincident) gets magnitude `push` along fm_mde_coincident_dir of the
 * two ids, + for the lower id and - for the higher. Every pair thus gets equal and opposite
 * contributions (bit for bit), and the sums depend only on the agents' ids and positions: not on
 * the store's order, the grid's cell or the split of the range. Writes (does not add) v_la, zero
 * for agents with no close neighbour or not members, and needed[a] = 1 if the agent had at least
 * one pair closer than d_min, else 0. Returns how many agents of the range needed it. d_min <= 0
 * turns MDE off (all zero).
 *
 * Requires g built from these p and member with cell >= d_min, and end <= the build's n. Walks the
 * cells of the 27 around each agent that its d_min ball reaches (usually its own alone), visiting
 * a slot once even when hashing maps two of the cells to it. No allocation. */
int64_t fm_kernel_mde(const fm_grid *g, const float *const p[3], const uint8_t *member, const int32_t *id,
                      int64_t begin, int64_t end, float d_min, float push,
                      float *const v_la[3], uint8_t *needed);
/* The scalar reference twin, which fm_kernel_mde runs at the scalar SIMD level: the same result, bit
 * for bit, at every level (test_grid). It walks and sums every agent in one pass, testing 4 entries
 * at a time where SSE2 is there. */
int64_t fm_kernel_mde_ref(const fm_grid *g, const float *const p[3], const uint8_t *member, const int32_t *id,
                          int64_t begin, int64_t end, float d_min, float push,
                          float *const v_la[3], uint8_t *needed);

/* fm_kernel_mde's first pass at the SSE2, AVX2 and AVX-512 levels (kernel_mde_simd.c): close[a] = 1
 * for each agent a in [begin, end) with member[a] that has another listed agent b with the kernel's
 * float test dx*dx + dy*dy + dz*dz < d_min*d_min, else 0; FM_W entries at a time. reach is d_min in
 * cell units, rounded up, as the kernel plans with it. The kernel then sums the pushes of those
 * agents alone, in scalar code. */
typedef void fm_mde_screen_fn(const fm_grid *g, const float *const p[3], const uint8_t *member, int64_t begin,
                              int64_t end, float d_min, double reach, uint8_t *close);
FM_SIMD_DECLARE(fm_mde_screen_fn, fm_mde_screen);

/* The direction a coincident pair (ids lo < hi) is pushed along: + for lo, - for hi. One of the 26
 * directions of {-1,0,1}^3 \ {0}, chosen by a hash of the ids, normalized. */
static inline void fm_mde_coincident_dir(int32_t lo, int32_t hi, float d[3])
{
    uint64_t h = (uint64_t)(uint32_t)lo * 0x9E3779B97F4A7C15ull ^ (uint64_t)(uint32_t)hi * 0xC2B2AE3D27D4EB4Full;
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    int c = (int)((h >> 32) % 26);
    if (c >= 13) c++; /* skip (0,0,0) */
    int dx = c % 3 - 1, dy = c / 3 % 3 - 1, dz = c / 9 - 1;
    int nz = (dx != 0) + (dy != 0) + (dz != 0);
    float s = nz == 1 ? 1.0f : nz == 2 ? 0.70710678f : 0.57735027f;
    d[0] = (float)dx * s, d[1] = (float)dy * s, d[2] = (float)dz * s;
}

/* -1, 0 or 1 cells either side along one axis: those whose face is nearer than reach. */
static inline void fm_mde_axis_span(double q, int32_t cell, double reach, int *lo, int *hi)
{
    const double f = q - (double)cell;
    *lo = f < reach ? -1 : 0;
    *hi = 1 - f < reach ? 1 : 0;
    if (!(f == f)) *lo = -1, *hi = 1; /* NaN: everything (such agents sit in the clamp cell) */
}

/* The walk's prefetches for agent a: the slot table entry of the agent 32 further on, then the first
 * entries of the one 16 on (the store is in the grid's order, so they are the next agents' too). */
static inline void fm_mde_prefetch(const fm_grid *g, int64_t a, int64_t end)
{
    enum { AHEAD = 32 };
    const uint32_t *slot = g->slot;
    if (a + AHEAD < end && slot[a + AHEAD] != FM_GRID_NONE) __builtin_prefetch(g->start + slot[a + AHEAD]);
    if (a + AHEAD / 2 < end && slot[a + AHEAD / 2] != FM_GRID_NONE)
        __builtin_prefetch(g->quad + (g->start[slot[a + AHEAD / 2]] >> 2));
}

#endif
