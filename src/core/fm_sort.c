/* The stable parallel LSD radix sort of the stores' re-sorts (fm_sort.h). */
#include "fm_sort.h"

#include "fm_internal.h"

#include <string.h>

enum { RADIX_BITS = 11, RADIX = 1 << RADIX_BITS, SORT_MAX_BLOCKS = 8 };

/* One stable counting pass by digit (key >> shift) & (RADIX - 1), over `blocks` agent blocks on
 * as many threads: per-block counts, offsets digit-major and block-minor, then each block
 * scatters its agents in order. The result is that of one block: it does not depend on blocks. */
static void radix_pass(const uint32_t *key, const int32_t *slot, uint32_t *key_to, int32_t *slot_to, int64_t count,
                       int shift, int blocks, int32_t (*hist)[RADIX])
{
#pragma omp parallel for num_threads(blocks) schedule(static, 1)
    for (int b = 0; b < blocks; b++) {
        int32_t *h = hist[b];
        memset(h, 0, sizeof(int32_t) * RADIX);
        for (int64_t a = count * b / blocks; a < count * (b + 1) / blocks; a++) h[(key[a] >> shift) & (RADIX - 1)]++;
    }
    int32_t sum = 0;
    for (int d = 0; d < RADIX; d++)
        for (int b = 0; b < blocks; b++) {
            const int32_t c = hist[b][d];
            hist[b][d] = sum, sum += c;
        }
#pragma omp parallel for num_threads(blocks) schedule(static, 1)
    for (int b = 0; b < blocks; b++) {
        int32_t *h = hist[b];
        for (int64_t a = count * b / blocks; a < count * (b + 1) / blocks; a++) {
            const int32_t to = h[(key[a] >> shift) & (RADIX - 1)]++;
            key_to[to] = key[a], slot_to[to] = slot[a];
        }
    }
}

const int32_t *fm_radix_sort(uint32_t *key, uint32_t *key_tmp, int32_t *slot, int32_t *slot_tmp, int64_t count,
                             int bits, int threads)
{
    int32_t hist[SORT_MAX_BLOCKS][RADIX];
    const int64_t fit = count / 65536 + 1; /* blocks of at least 64 Ki agents */
    const int blocks = (int)FM_MAX(1, FM_MIN(FM_MIN((int64_t)threads, (int64_t)SORT_MAX_BLOCKS), fit));
    for (int64_t a = 0; a < count; a++) slot[a] = (int32_t)a;
    for (int shift = 0; shift < bits; shift += RADIX_BITS) {
        radix_pass(key, slot, key_tmp, slot_tmp, count, shift, blocks, hist);
        uint32_t *kt = key; key = key_tmp, key_tmp = kt;
        int32_t *st = slot; slot = slot_tmp, slot_tmp = st;
    }
    return slot;
}
