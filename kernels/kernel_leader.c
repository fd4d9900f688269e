/* The leaders' SIMD variant, picked at run time (kernel_leader.h). */
#include "kernel_leader.h"

int64_t fm_kernel_leaders(const fm_leader_view *w, const uint8_t *phase, uint8_t skip, const float *const start[3],
                          const float *const dest[3], float *const leader[3], float *const leader_v[3], int64_t begin,
                          int64_t end, int64_t *left, int64_t *left_count)
{
    fm_leaders_fn *variant = FM_SIMD_PICK(fm_kernel_leaders);
    *left_count = 0;
    return variant ? variant(w, phase, skip, start, dest, leader, leader_v, begin, end, left, left_count) : begin;
}
