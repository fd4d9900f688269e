/* Phase 1 integration internals shared by the reference and the SIMD variants. */
#ifndef FM_KERNEL_INTEGRATE_H
#define FM_KERNEL_INTEGRATE_H

#include "kernels.h"
#include "simd.h"

/* The sphere switch's SIMD variants (kernel_integrate_simd.c). */
typedef int64_t fm_integrate_sphere_fn(float *const p[3], const float *const v[3], const uint8_t *phase, int64_t begin,
                                       int64_t end, float dt, fm_sphere_view sphere, uint8_t *entered);
FM_SIMD_DECLARE(fm_integrate_sphere_fn, fm_integrate_sphere);

#endif
