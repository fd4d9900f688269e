/* The shape flock's agents' frames from their velocities. The scalar function is the reference;
 * fm_kernel_orient_along (kernel_orient_simd.c) computes a block of agents in double lanes. */
#ifndef FM_KERNEL_ORIENT_H
#define FM_KERNEL_ORIENT_H

#include "simd.h"

#include <stdint.h>

void fm_flock_update_orientation(float *q, const float v[3]);

/* fm_flock_update_orientation(q + 4 a, v(a)) for the agents a in [begin, end) with phase[a] != skip:
 * the same bits, the usual case FM_WD agents at a time. */
void fm_kernel_orient_along(float *q, const float *const v[3], const uint8_t *phase, uint8_t skip, int64_t begin,
                            int64_t end);
typedef void fm_orient_along_fn(float *q, const float *const v[3], const uint8_t *phase, uint8_t skip, int64_t begin,
                                int64_t end);
FM_SIMD_DECLARE(fm_orient_along_fn, fm_kernel_orient_along);

#endif
