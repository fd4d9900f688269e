/* The shape flock's store sorted in space (issue 40), as the tetra morph's is (morph_resort.c).
 *
 * The boids pass walks the agents in the neighbour grid's order, and each gathers its parameters
 * (radius, angle and weight per rule, MaxSpeed, MaxForce) and its neighbours by slot; in id order,
 * which is no order in space, every one of those is a cache miss. Every resort_every steps (one
 * process) the slots are sorted by the slot of their cell in the grid as the next build lays it out
 * (fm_grid_placement, the flock's cell), bound agents (not in the grid) last: that build then lists
 * the agents in store order, and the walk reads the store, the parameters and the grid's entries
 * almost in sequence. The sort is fm_radix_sort on (key, slot): stable, the same order for any
 * thread count. Every carried per-slot array moves with its agent (fm_flock_state_move_slots, as on
 * P ranks), the parameters and id[] among them; slot_by_id is its inverse, through which the
 * frames, the measures' block sums and the checkpoints read the store in id order. */
#include "flock.h"
#include "fm_sort.h"

#include <stdlib.h>
#include <string.h>

int fm_flock_resort_interval(fm_error *err)
{
    /* a debugging and measuring switch (docs/performance.md): 0 keeps the store in id order */
    const char *e = getenv("FM_FLOCK_RESORT");
    if (!e || !*e) return FM_FLOCK_RESORT_INTERVAL;
    char *end = NULL;
    const long k = strtol(e, &end, 10);
    if (*end == '\0' && k >= 0 && k <= 1000000) return (int)k;
    fm_fail(err, FM_ERR_INPUT, "FM_FLOCK_RESORT=%s: the shape flock's re-sort interval must be a whole number of steps "
            "from 0 (off) to 1000000 (docs/performance.md)", e);
    return -1;
}

/* Keys by grid slot: the slot of the agent's cell for an agent in the grid (flying or homing),
 * 2^log2_table (after every slot) for a bound one; returns the key's bit count. */
static int slot_keys(const fm_flock_model *m, fm_flock_state *s, uint32_t *key)
{
    fm_flock_mark_members(s); /* the agents the next build lists, whose box it fits its rows to */
    const fm_grid g = fm_grid_placement(&s->grid, (const float *const *)s->p, s->member, s->slots, fm_flock_cell(m),
                                        s->threads);
    const uint32_t bound = 1u << g.log2_table;
    const float *px = s->p[0], *py = s->p[1], *pz = s->p[2];
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->slots; a++)
        key[a] = s->phase[a] == FM_PHASE_ARRIVED ? bound : fm_grid_slot_of(&g, px[a], py[a], pz[a]);
    return g.log2_table + 1;
}

/* slot_by_id from id[] after the slots moved. */
static void index_slots(fm_flock_state *s)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->slots; a++) s->slot_by_id[s->id[a]] = (int32_t)a;
}

void fm_flock_state_resort(const fm_flock_model *m, fm_flock_state *s)
{
    if (s->dist || !s->slot_by_id || s->slots == 0) return;
    /* the keys and the sort's slots in the moves' scratch (24 bytes a slot: 4 words of the 6) */
    uint32_t *key = s->scratch, *key_tmp = key + s->cap;
    int32_t *slot = (int32_t *)(key_tmp + s->cap), *slot_tmp = slot + s->cap;
    const int bits = slot_keys(m, s, key);
    const int32_t *order = fm_radix_sort(key, key_tmp, slot, slot_tmp, s->slots, bits, s->threads);
    memcpy(s->move_from, order, sizeof(int32_t) * (size_t)s->slots); /* the moves reuse the scratch */
    fm_flock_state_move_slots(s, s->move_from, s->slots);
    index_slots(s);
    s->sorted = 1;
    s->grid_current = 0; /* a frame's grid lists the old slots */
}

/* Agent k to slot k, from its slot in slot_by_id, which is left as it was. */
static void move_to_id_order(fm_flock_state *s)
{
    memcpy(s->move_from, s->slot_by_id, sizeof(int32_t) * (size_t)s->slots);
    fm_flock_state_move_slots(s, s->move_from, s->slots);
}

/* Back in id order for good (a checkpoint's load): the order is the identity. */
void fm_flock_state_in_id_order(fm_flock_state *s)
{
    if (!s->sorted) return;
    move_to_id_order(s);
    index_slots(s);
    s->sorted = 0;
    s->grid_current = 0;
}

int fm_flock_state_id_order_begin(fm_flock_state *s)
{
    if (!s->sorted) return 0;
    move_to_id_order(s);
    s->sorted = 0;
    return 1;
}

/* Every agent back to its slot in slot_by_id (agent k is in slot k): new slot slot_by_id[k] from k. */
void fm_flock_state_id_order_end(fm_flock_state *s, int begun)
{
    if (!begun) return;
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t k = 0; k < s->slots; k++) s->move_from[s->slot_by_id[k]] = (int32_t)k;
    fm_flock_state_move_slots(s, s->move_from, s->slots);
    s->sorted = 1; /* the grid, if current, lists these slots again */
}
