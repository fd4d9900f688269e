/* The Kalman homing's SIMD variant, picked at run time (kernel_kalman.h). */
#include "kernel_kalman.h"

int64_t fm_kernel_kalman_homing(const fm_kalman_lanes *k, int64_t begin, int64_t end, const uint8_t *phase,
                                uint8_t phase_sel, const float *const p[3], const float *const v[3],
                                const float *const z_p[3], const float *const z_v[3], const float *weight,
                                const float *max_accel, const float *const u[3], float *const h[3])
{
    fm_kalman_homing_fn *variant = FM_SIMD_PICK(fm_kernel_kalman_homing);
    return variant ? variant(k, begin, end, phase, phase_sel, p, v, z_p, z_v, weight, max_accel, u, h) : begin;
}
