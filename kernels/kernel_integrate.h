/* Phase 1 integration internals shared by the reference and the SIMD variants. */
#ifndef FM_KERNEL_INTEGRATE_H
#define FM_KERNEL_INTEGRATE_H

#include "kernels.h"

int64_t fm_integrate_sphere_base(float *const p[3], const float *const v[3], const uint8_t *phase, int64_t begin,
                                 int64_t end, float dt, fm_sphere_view sphere, uint8_t *entered);
int64_t fm_integrate_sphere_avx2(float *const p[3], const float *const v[3], const uint8_t *phase, int64_t begin,
                                 int64_t end, float dt, fm_sphere_view sphere, uint8_t *entered);
int64_t fm_integrate_sphere_avx512(float *const p[3], const float *const v[3], const uint8_t *phase, int64_t begin,
                                   int64_t end, float dt, fm_sphere_view sphere, uint8_t *entered);

#endif
