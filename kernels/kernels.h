/* The step's hot loops: pure functions over structure-of-arrays data, one agent range each.
 * No allocation, no I/O, no globals; every agent writes only its own entries, so any split of
 * the range across threads gives the same bits. */
#ifndef FM_KERNELS_H
#define FM_KERNELS_H

#include "kernel_sdf.h"

#include <stdint.h>

/* The phases the kernels act on. The kernels include no engine header, so they name the phases
 * here; the engine checks them against its own fm_phase (morph_step.c, _Static_assert). */
enum fm_kernel_phase { FM_KERNEL_FLYING = 1, FM_KERNEL_HOMING = 2, FM_KERNEL_ARRIVED = 3 };

/* Key points Q_i and unit directions f_i of the global path (FM eq 3), SoA. */
typedef struct fm_path_view {
    const float *q[3];
    const float *f[3];
    int32_t count;
    float half_width;   /* path width / 2; 0 = no width constraint */
    float attraction;   /* pull speed per unit of distance beyond half_width, 1/s */
} fm_path_view;

typedef struct fm_sphere_view {
    float c[3];
    float r;
} fm_sphere_view;

/* FM eq 3 weighted by omega1 (eq 6): v = omega1 * speed0 * f_i, i = the nearest key point, for
 * agents in phase 1; the last key point Q_{m+1} = C_T has no f, agents nearest it head for C_T.
 * With a path width (FM §5.1), an agent farther than half_width from the path segment at its
 * nearest key point also gets attraction * (excess distance) toward the path.
 * Other agents' velocities are left untouched. */
void fm_kernel_global_velocity(const fm_path_view *path, const float *const p[3],
                               const uint8_t *phase, int64_t begin, int64_t end, float speed,
                               float *const v[3]);
/* Its scalar reference twin (the SIMD variants match it bit for bit). */
void fm_kernel_global_velocity_ref(const fm_path_view *path, const float *const p[3],
                                   const uint8_t *phase, int64_t begin, int64_t end, float speed,
                                   float *const v[3]);

/* Phase 1 integration x += v dt, then the phase switch test (FM §5.5): entered[i] = 1 if a flying
 * agent is now inside the target's bounding sphere, or, when target_sdf is not NULL (beyond the
 * paper, §8), closer to the target than switch_distance by the target's own signed distance.
 * Returns how many entered. */
int64_t fm_kernel_integrate_flying(float *const p[3], const float *const v[3], const uint8_t *phase,
                                   int64_t begin, int64_t end, float dt, fm_sphere_view sphere,
                                   const fm_sdf_view *target_sdf, float switch_distance,
                                   uint8_t *entered);
int64_t fm_kernel_integrate_flying_ref(float *const p[3], const float *const v[3], const uint8_t *phase,
                                       int64_t begin, int64_t end, float dt, fm_sphere_view sphere,
                                       const fm_sdf_view *target_sdf, float switch_distance,
                                       uint8_t *entered);

/* Phase 2 (FM eq 9): straight flight at speed0 from p2 to the target centroid, evaluated in closed
 * form at `time` so no error accumulates; agents whose flight time tf has passed arrive. Returns
 * how many arrived in this call.
 * The switch blend (issue 38, beyond the paper): over the first T_b = min(blend, tf) seconds the
 * velocity turns from the phase-1 velocity V_1 to V_e with a smoothstep weight, then the agent flies
 * straight at V_e = (P_X' - P_X - T_b V_1 / 2) / (tf - T_b / 2), which lands it on its target at
 * t2 + tf as eq 9 does (|V_e| is speed0 to within O(T_b / tf)); heading and speed are continuous.
 * Then v[] must hold V_1 (the velocity of the switch step) all through phase 2 and is left as it
 * is. blend = 0 is the paper's hard switch, and v[] is V_2.
 * A moving target (issue 38): target NULL, and tgt_c holds each slot's own target centroid at the
 * step's end (the three kernels here alike), so the flight chases it and lands on it where it is. */
int64_t fm_kernel_homing(float *const p[3], float *const v[3], uint8_t *phase,
                         const int64_t *target, const float *const tgt_c[3],
                         const float *const p2[3], const float *t2, const float *tf,
                         int64_t begin, int64_t end, double time, double blend);

/* Phase 2 with obstacle avoidance (beyond the paper, §8): the straight flight of eq 9 becomes a
 * steered one. Velocity: speed0 toward the target centroid (the avoidance kernel may then bend it);
 * move: x += v dt, arriving when the target is within one step. Returns arrivals.
 * The switch blend: until t2 + blend, the aim replaces only the share dt / (time left of the blend)
 * of the last step's velocity v[], so v turns from V_1 to the aim linearly over the blend. `time`
 * is the step's start. */
void fm_kernel_homing_aim(const float *const p[3], float *const v[3], const uint8_t *phase,
                          const int64_t *target, const float *const tgt_c[3], const float *t2,
                          int64_t begin, int64_t end, float speed0, double time, float dt, double blend);
int64_t fm_kernel_homing_steered(float *const p[3], const float *const v[3], uint8_t *phase,
                                 const int64_t *target, const float *const tgt_c[3], int64_t begin,
                                 int64_t end, float dt);

#endif
