/* The shape flock's Kalman homing (SCF eq 9; src/flock/flock_kalman.h) FM_WD agents at a time in
 * double lanes: the same operations in the same order as fm_kalman_covariance_step and
 * fm_kalman_homing, lane by lane, so the same bits. The scalar code stays the reference and does
 * the tail (and everything where no SIMD variant is picked). */
#ifndef FM_KERNEL_KALMAN_H
#define FM_KERNEL_KALMAN_H

#include "simd.h"

#include <stdint.h>

/* The filter's constants as the scalar code rounds them, and the agents' own covariances. */
typedef struct fm_kalman_lanes {
    double dt, gain;               /* gain = 2 / dt^2 */
    double q_pa, q_pb, q_pc;       /* Q's terms: q dt dt dt / 3, q dt dt / 2, q dt */
    double r_pos, r_vel;
    int scale_velocity;
    double k_pp, k_pv;             /* the shared gain, where p is NULL */
    double *p;                     /* NULL, or 3 doubles an agent, advanced here */
    const float *r_scale;          /* with p: each agent's factor of R */
} fm_kalman_lanes;

/* fm_kalman_homing over whole groups of FM_WD agents from begin; returns the first agent it did not
 * do (begin where no SIMD variant is picked). */
int64_t fm_kernel_kalman_homing(const fm_kalman_lanes *k, int64_t begin, int64_t end, const uint8_t *phase,
                                uint8_t phase_sel, const float *const p[3], const float *const v[3],
                                const float *const z_p[3], const float *const z_v[3], const float *weight,
                                const float *max_accel, const float *const u[3], float *const h[3]);
typedef int64_t fm_kalman_homing_fn(const fm_kalman_lanes *k, int64_t begin, int64_t end, const uint8_t *phase,
                                    uint8_t phase_sel, const float *const p[3], const float *const v[3],
                                    const float *const z_p[3], const float *const z_v[3], const float *weight,
                                    const float *max_accel, const float *const u[3], float *const h[3]);
FM_SIMD_DECLARE(fm_kalman_homing_fn, fm_kernel_kalman_homing);

#endif
