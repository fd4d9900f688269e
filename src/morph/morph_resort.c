/* Spatial re-sort of the agent store (the throughput issue's locality lever).
 *
 * Agents are launched in D1 order (FM eq 4), which is spatially coherent in the source but not after
 * a few seconds of flight; the MDE neighbour walk (kernel_mde.c), the field and distance-grid
 * samples then touch memory at random. Every FM_RESORT_INTERVAL steps the active range is sorted by
 * position, so agents close in space are close in memory. With MDE the key is the slot of the
 * agent's cell in the MDE grid as the next build lays it out (grid.h: rows by position), so that
 * build lists the agents in store order and the MDE walk reads the grid's table and entries in
 * step with the store instead of hopping between rows (issue 40). A flock translating as a whole
 * keeps that order (a translation by whole cells adds a constant to every slot), which a Morton
 * order does not. Without MDE the key is the Morton code of the position on a 1024^3 lattice over
 * the scene bounds. Agents that arrived since the last sort go first and leave the active range.
 * The sort is a stable LSD radix sort on (key, slot), so the order, like everything else in the
 * step, does not depend on the thread count; no result depends on the store's order (MDE sums by
 * id), so neither key changes a cache. Every per-slot array moves with its agent; id[] says who is
 * where. */
#include "fm_sort.h"
#include "morph.h"

#include <assert.h>
#include <string.h>

enum { MORTON_BITS = 10 };
#define ARRIVED_KEY 0u
#define FLIGHT_KEY (1u << (3 * MORTON_BITS))

/* Spreads the low 10 bits of x to every third bit. */
static uint32_t spread3(uint32_t x)
{
    x &= 0x3ffu;
    x = (x | (x << 16)) & 0x030000ffu;
    x = (x | (x << 8)) & 0x0300f00fu;
    x = (x | (x << 4)) & 0x030c30c3u;
    x = (x | (x << 2)) & 0x09249249u;
    return x;
}

static uint32_t lattice(float x, double lo, double scale)
{
    double q = ((double)x - lo) * scale;
    if (!(q > 0)) return 0; /* NaN too */
    return q >= (1 << MORTON_BITS) - 1 ? (1u << MORTON_BITS) - 1 : (uint32_t)q;
}

/* Morton keys on the scene lattice; returns the key's bit count. */
static int morton_keys(const fm_morph_model *m, const fm_morph_state *s, uint32_t *key)
{
    double scale[3];
    for (int k = 0; k < 3; k++) {
        double extent = m->scene_hi[k] - m->scene_lo[k];
        scale[k] = extent > 0 ? (double)(1 << MORTON_BITS) / extent : 0;
    }
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->active_end; a++) {
        if (s->phase[a] == FM_PHASE_ARRIVED) {
            key[a] = ARRIVED_KEY;
            continue;
        }
        uint32_t x = lattice(s->p[0][a], m->scene_lo[0], scale[0]);
        uint32_t y = lattice(s->p[1][a], m->scene_lo[1], scale[1]);
        uint32_t z = lattice(s->p[2][a], m->scene_lo[2], scale[2]);
        key[a] = FLIGHT_KEY | spread3(x) | spread3(y) << 1 | spread3(z) << 2;
    }
    return 3 * MORTON_BITS + 1;
}

/* Keys by MDE grid slot: 0 for an arrival, 1 + the slot of its cell for an agent in flight (the
 * table of the next build, over about the agents active now); returns the key's bit count. */
static int slot_keys(const fm_morph_model *m, const fm_morph_state *s, uint32_t *key)
{
    const fm_grid g = fm_grid_placement(&s->grid, NULL, NULL, s->active_end, fm_morph_mde_cell(m), 1);
    const float *px = s->p[0], *py = s->p[1], *pz = s->p[2];
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->active_end; a++)
        key[a] = s->phase[a] == FM_PHASE_ARRIVED ? ARRIVED_KEY : 1 + fm_grid_slot_of(&g, px[a], py[a], pz[a]);
    return g.log2_table + 1;
}

/* Stable LSD radix sort of slots 0..count-1 by their keys of `bits` bits (fm_sort.h); returns the
 * slots in sorted order (in one of the two halves of s->sort_slots). */
static const int32_t *radix_sort(fm_morph_state *s, int64_t count, int bits)
{
    return fm_radix_sort(s->sort_keys, s->sort_keys + s->capacity, s->sort_slots, s->sort_slots + s->capacity, count,
                         bits, s->threads);
}

/* array[k] = old array[order[k]] for k < count, through the scratch buffer. */
static void permute(void *array, size_t size, const int32_t *order, int64_t count, void *scratch, int threads)
{
    unsigned char *a = array, *t = scratch;
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int64_t k = 0; k < count; k++) {
        switch (size) { /* fixed sizes let the compiler emit single moves */
        case 1: t[k] = a[order[k]]; break;
        case 4: memcpy(t + 4 * k, a + 4 * (size_t)order[k], 4); break;
        case 8: memcpy(t + 8 * k, a + 8 * (size_t)order[k], 8); break;
        default: memcpy(t + size * (size_t)k, a + size * (size_t)order[k], size);
        }
    }
    fm_copy_parallel(array, scratch, size * (size_t)count, threads);
}

void fm_morph_state_resort(const fm_morph_model *m, fm_morph_state *s)
{
    const int64_t count = s->active_end;
    if (count == 0) return;
    const int bits = m->def.d_min > 0 && s->grid_ready ? slot_keys(m, s, s->sort_keys) : morton_keys(m, s, s->sort_keys);
    const int32_t *order = radix_sort(s, count, bits);
    void *tmp = s->sort_scratch;
    for (int k = 0; k < 3; k++) {
        permute(s->p[k], sizeof(float), order, count, tmp, s->threads);
        permute(s->v[k], sizeof(float), order, count, tmp, s->threads);
        permute(s->p2[k], sizeof(float), order, count, tmp, s->threads);
    }
    for (int j = 0; j < 12; j++) permute(s->rest_rel[j], sizeof(float), order, count, tmp, s->threads);
    permute(s->rest_radius, sizeof(float), order, count, tmp, s->threads);
    permute(s->id, sizeof(int32_t), order, count, tmp, s->threads);
    permute(s->phase, 1, order, count, tmp, s->threads);
    permute(s->target, sizeof(int64_t), order, count, tmp, s->threads);
    permute(s->t2, sizeof(float), order, count, tmp, s->threads);
    permute(s->tf, sizeof(float), order, count, tmp, s->threads);
    permute(s->morph, sizeof(float) * FM_MORPH_FLOATS, order, count, tmp, s->threads);
    permute(s->perm, 1, order, count, tmp, s->threads);
    permute(s->morph_safe, 1, order, count, tmp, s->threads);
    if (m->detour_time > 0) { /* issue 38's detour clock: only scenes that take detours carry it */
        permute(s->detour_best, sizeof(float), order, count, tmp, s->threads);
        permute(s->detour_since, sizeof(float), order, count, tmp, s->threads);
        permute(s->detour_on, 1, order, count, tmp, s->threads);
    }
    int64_t arrived = 0;
    while (arrived < count && s->phase[arrived] == FM_PHASE_ARRIVED) arrived++;
    s->active_begin = arrived;
    s->sorted_end = s->active_end;
}
