/* Homing with a Kalman filter (SCF "Homing Behavior", eq 9).
 *
 * Each agent's state is x = [Pos; Vel]. Per step of length dt the paper's filter is
 *     predict   x- = A x + B u,  P- = A P A^T + Q,   A = [I dt I; 0 I],  B = [0; dt I],  u = acceleration
 *     update    K = P- H^T (H P- H^T + R)^-1,  x+ = x- + K (z - H x-),  P+ = (I - K H) P-,   H = I
 * where x is the agent's own state at the start of the step and u the acceleration of its other
 * forces (steering, damping, external), and the measurement z is the state of its virtual leader
 * at the end of the step: the point on its path (eq 12), then its destination on the target
 * surface, moving with it when the target deforms. (The paper writes the update from x_{k-1|k-1};
 * we use the predicted state, as Kalman does.) The homing force of eq 9,
 *     F_h = 2 m (Pos+ - Pos - Vel dt) / dt^2,
 * is the constant force that carries the agent to the posterior position Pos+ in one step. The
 * fuzzy weight scales it and MaxForce then bounds it (SCF: MaxForce keeps "flock behavior within a
 * reasonable range"): unbounded, eq 9 with the default R pulls at about 94 units/s^2 per unit of
 * position error and 79 per unit/s of velocity error, which pins an agent to its leader.
 *
 * Because A, B and H act on each axis alike and Q and R are diagonal per axis, the filter is three
 * independent 2x2 filters with the same covariance; and since the covariance recursion does not
 * depend on the measurements, P and K are the same for every agent: they are advanced once per step
 * (fm_kalman_advance) and applied to all agents over the SoA arrays (fm_kalman_homing).
 *
 * Q is the white-noise-acceleration model with spectral density q (units^2/s^3):
 *     Q = q [dt^3/3  dt^2/2; dt^2/2  dt]
 * and R = diag(r_position, r_velocity) (units^2, units^2/s^2). A larger R trusts the leader less, so
 * the agent tracks it more loosely; R -> 0 makes Pos+ the leader's position (the paper keeps R away
 * from zero to keep the flocking fluctuations; both must be > 0 here). P starts at 0: the agent knows
 * its own state, so the gain grows from 0 to its steady value over the first steps.
 *
 * R adjustable over the run (SCF: R sets how closely the agents follow the virtual leaders): with
 * shape_flock.kalman.r_scale each agent's position variance is r_position times a curve of its
 * distance to the destination or of its leader's speed (the velocity variance stays r_velocity, so
 * a loosely held agent still flies at its leader's velocity, unless scale_velocity scales it too),
 * so P and K become the agent's own
 * (fm_kalman_agents): the same recursion per agent, only when it is under forces. With the scale 1
 * everywhere it is the shared filter's arithmetic, bit for bit. */
#ifndef FM_KALMAN_H
#define FM_KALMAN_H

#include <stdint.h>

typedef struct fm_kalman {
    double dt, q, r_pos, r_vel;
    int scale_velocity; /* fm_kalman_covariance_step's r_scale applies to r_vel too (0: r_pos only) */
    double p[3];   /* posterior covariance per axis: [pos-pos, pos-vel, vel-vel] */
    double k[4];   /* gain of the last advance, row-major 2x2 */
} fm_kalman;

/* Per-agent filters: p holds 3 doubles an agent (its posterior covariance, 0 at the start), r_scale
 * the factor of its R for this step. */
typedef struct fm_kalman_agents {
    double *p;
    const float *r_scale;
} fm_kalman_agents;

/* dt > 0, q >= 0, r_pos > 0, r_vel > 0 (callers validate). */
void fm_kalman_init(fm_kalman *kf, double dt, double q, double r_pos, double r_vel);

/* One step of the covariance recursion: P- from P, the gain K, then P+. */
void fm_kalman_advance(fm_kalman *kf);

/* The same for a covariance p (3 doubles, updated in place) with R's position variance scaled by
 * r_scale (and its velocity variance too with kf->scale_velocity); the gain into k. */
void fm_kalman_covariance_step(const fm_kalman *kf, double r_scale, double p[3], double k[4]);

/* For agents a in [begin, end) with phase[a] == phase_sel: h(a) = weight[a] * F_h / m (eq 9, with the
 * gain of the last advance, or with own != NULL each agent's own filter advanced here), u being the acceleration of the agent's other forces (the prediction's
 * B u) and z_p, z_v the leader's position and velocity at the end of the step, truncated to
 * |h| <= max_accel[a] (MaxForce / m; NULL: unbounded). Others are untouched; h may be u (each agent
 * reads its u before it writes h). Computed in double per agent; no allocation. */
void fm_kalman_homing(const fm_kalman *kf, const fm_kalman_agents *own, int64_t begin, int64_t end, const uint8_t *phase,
                      uint8_t phase_sel, const float *const p[3], const float *const v[3],
                      const float *const z_p[3], const float *const z_v[3], const float *weight,
                      const float *max_accel, const float *const u[3], float *const h[3]);

#endif
