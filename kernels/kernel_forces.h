/* The shape flock's forces besides the boids' and homing's sums (flock_step.c, stage 4: the fuzzy
 * weights of SCF Figure 6, damping, the external fields, MaxForce's bounds, R's factor, and the
 * prioritised combination with homing) FM_W agents at a time in float lanes: the scalar code's
 * operations in its order, lane by lane, so the same bits. The scalar code stays the reference
 * and does the tail (and everything where no SIMD variant is picked). */
#ifndef FM_KERNEL_FORCES_H
#define FM_KERNEL_FORCES_H

#include "simd.h"

#include <stdint.h>

/* A fuzzy curve (flock_fuzzy.h): count points d (increasing), w, and the pieces' slopes. */
typedef struct fm_weight_curve {
    int32_t count;
    const float *d, *w, *slope;
} fm_weight_curve;

typedef struct fm_forces_view {
    fm_weight_curve steer, damp, ext, homing, r_scale;
    int r_over_distance;             /* R's factor over the distance (else over the leader's speed) */
    int tracking;                    /* damping relative to the destination's velocity */
    int fields;                      /* ext holds the fields' acceleration */
    float inv_mass, damping, external_gain;
} fm_forces_view;

/* The agents' arrays (the store's, in slot order). r_scale NULL: R is fixed. */
typedef struct fm_forces_arrays {
    const uint8_t *phase;
    uint8_t sel;                     /* the agents under forces */
    const float *p[3], *v[3], *dest[3], *dest_v[3], *leader[3], *leader_v[3], *max_accel;
    float *steer[3], *ext[3], *acc[3], *w_homing, *r_scale;
} fm_forces_arrays;

/* Stage 4b's first half for whole groups of FM_W agents from begin (other_forces, without the
 * obstacles' push); returns the first agent it did not do. */
int64_t fm_kernel_other_forces(const fm_forces_view *w, const fm_forces_arrays *x, int64_t begin, int64_t end);
/* Its last part (combine_forces: homing first, the boids with what it leaves of MaxForce). */
int64_t fm_kernel_combine_forces(const fm_forces_arrays *x, int64_t begin, int64_t end);

/* Stage 5 for the agents under forces in whole groups of FM_W from begin (move_flying: v' = v + a dt
 * bounded by MaxSpeed, x += (v + v') dt / 2; phase homing = sel + 1 within arrival_radius when it is
 * > 0); returns the first agent it did not do. */
int64_t fm_kernel_move_flying(const fm_forces_arrays *x, float *const p[3], float *const v[3], uint8_t *phase,
                              const float *max_speed, float dt, float arrival_radius, uint8_t homing, int64_t begin,
                              int64_t end);

typedef int64_t fm_other_forces_fn(const fm_forces_view *w, const fm_forces_arrays *x, int64_t begin, int64_t end);
typedef int64_t fm_combine_forces_fn(const fm_forces_arrays *x, int64_t begin, int64_t end);
FM_SIMD_DECLARE(fm_other_forces_fn, fm_kernel_other_forces);
FM_SIMD_DECLARE(fm_combine_forces_fn, fm_kernel_combine_forces);
typedef int64_t fm_move_flying_fn(const fm_forces_arrays *x, float *const p[3], float *const v[3], uint8_t *phase,
                                  const float *max_speed, float dt, float arrival_radius, uint8_t homing, int64_t begin,
                                  int64_t end);
FM_SIMD_DECLARE(fm_move_flying_fn, fm_kernel_move_flying);

#endif
