/* The stable parallel LSD radix sort the stores' spatial re-sorts share (the tetra morph's,
 * morph_resort.c, and the shape flock's, flock_resort.c). */
#ifndef FM_SORT_H
#define FM_SORT_H

#include <stdint.h>

/* Slots 0 .. count - 1 sorted by key[slot] (its low `bits` bits), equal keys in slot order: key,
 * key_tmp, slot and slot_tmp hold count entries each (key is overwritten). Counting passes of 11 bits
 * over at most `threads` blocks of agents (8 at most, each of at least 64 Ki agents); the order does
 * not depend on the thread count. Returns the slots in sorted order (slot or slot_tmp). */
const int32_t *fm_radix_sort(uint32_t *key, uint32_t *key_tmp, int32_t *slot, int32_t *slot_tmp, int64_t count,
                             int bits, int threads);

#endif
