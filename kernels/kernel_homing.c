/* Phase 2 (FM eq 9): V_2 = speed0 * unit(P_X' - P_X), constant once set; t_f = |P_X' - P_X| / speed0.
 * Beyond the paper (issue 38), the first T_b = min(blend, t_f) of it blends the phase-1 velocity V_1
 * into the straight flight: v = V_1 + (V_e - V_1) h(tau / T_b), tau = t - t_2, and from T_b on the tet
 * flies straight at V_e, chosen so it still lands on its target at t_2 + t_f (kernels.h). */
#include "kernels.h"

#include <math.h>
#include <stddef.h>

/* The blend's weight h(s) = 3 s^2 - 2 s^3 (h(0) = 0, h(1) = 1, h'(0) = h'(1) = 0: no jump in velocity
 * or acceleration at either end, and it never overshoots) and its integral H(s) = s^3 - s^4 / 2,
 * H(1) = 1/2. */
static double blend_integral(double s) { return s * s * s * (1.0 - 0.5 * s); }

/* Each kernel's body is written once and made twice (target given, or NULL: tgt_c by slot, a
 * moving target's centroid now, issue 38), so the static target's loop has no test in it. */
#define FM_ALWAYS_INLINE static inline __attribute__((always_inline))
/* The target centroid's index for slot a. */
#define GOAL(target, a) ((target) ? (target)[a] : (a))

FM_ALWAYS_INLINE int64_t homing(float *const p[3], float *const v[3], uint8_t *phase, const int64_t *target,
                                const float *const tgt_c[3], const float *const p2[3], const float *t2,
                                const float *tf, int64_t begin, int64_t end, double time, double blend)
{
    int64_t arrived = 0;
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != FM_KERNEL_HOMING) continue;
        int64_t s = GOAL(target, a);
        const double tau = time - t2[a], tb = fmin(blend, tf[a]);
        double u = tf[a] > 0 ? tau / tf[a] : 1.0;
        if (u < 1.0 && tb > 0) { /* blended: v[] keeps V_1 all through phase 2 */
            for (int k = 0; k < 3; k++) {
                const double from = p2[k][a], to = tgt_c[k][s], v1 = v[k][a];
                /* x(T_b) = P_X + T_b (V_1 + V_e) / 2, then x(t_f) = x(T_b) + (t_f - T_b) V_e = P_X' */
                const double ve = (to - from - 0.5 * tb * v1) / (tf[a] - 0.5 * tb);
                p[k][a] = (float)(tau < tb ? from + tb * (v1 * (tau / tb) + (ve - v1) * blend_integral(tau / tb))
                                           : to - ve * (tf[a] - tau));
            }
            continue;
        }
        for (int k = 0; k < 3; k++) {
            float from = p2[k][a], to = tgt_c[k][s];
            v[k][a] = tf[a] > 0 ? (to - from) / tf[a] : 0.0f;
            p[k][a] = u >= 1.0 ? to : (float)(from + u * (to - from));
        }
        if (u >= 1.0) phase[a] = FM_KERNEL_ARRIVED, arrived++;
    }
    return arrived;
}

int64_t fm_kernel_homing(float *const p[3], float *const v[3], uint8_t *phase,
                         const int64_t *target, const float *const tgt_c[3],
                         const float *const p2[3], const float *t2, const float *tf,
                         int64_t begin, int64_t end, double time, double blend)
{
    return target ? homing(p, v, phase, target, tgt_c, p2, t2, tf, begin, end, time, blend)
                  : homing(p, v, phase, NULL, tgt_c, p2, t2, tf, begin, end, time, blend);
}

FM_ALWAYS_INLINE void homing_aim(const float *const p[3], float *const v[3], const uint8_t *phase,
                                 const int64_t *target, const float *const tgt_c[3], const float *t2,
                                 int64_t begin, int64_t end, float speed0, double time, float dt, double blend)
{
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != FM_KERNEL_HOMING) continue;
        int64_t s = GOAL(target, a);
        float d[3] = {tgt_c[0][s] - p[0][a], tgt_c[1][s] - p[1][a], tgt_c[2][s] - p[2][a]};
        float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        const double left = (double)t2[a] + blend - time; /* of the blend, at the step's start */
        const float w = left > dt ? (float)(dt / left) : 1.0f; /* v reaches the aim as the blend ends */
        for (int k = 0; k < 3; k++) {
            float aim = len > 0 ? speed0 * d[k] / len : 0.0f;
            v[k][a] = w < 1.0f ? v[k][a] + w * (aim - v[k][a]) : aim;
        }
    }
}

void fm_kernel_homing_aim(const float *const p[3], float *const v[3], const uint8_t *phase,
                          const int64_t *target, const float *const tgt_c[3], const float *t2,
                          int64_t begin, int64_t end, float speed0, double time, float dt, double blend)
{
    if (target) homing_aim(p, v, phase, target, tgt_c, t2, begin, end, speed0, time, dt, blend);
    else homing_aim(p, v, phase, NULL, tgt_c, t2, begin, end, speed0, time, dt, blend);
}

FM_ALWAYS_INLINE int64_t homing_steered(float *const p[3], const float *const v[3], uint8_t *phase,
                                        const int64_t *target, const float *const tgt_c[3], int64_t begin,
                                        int64_t end, float dt)
{
    int64_t arrived = 0;
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != FM_KERNEL_HOMING) continue;
        int64_t s = GOAL(target, a);
        float d[3] = {tgt_c[0][s] - p[0][a], tgt_c[1][s] - p[1][a], tgt_c[2][s] - p[2][a]};
        float step2 = (v[0][a] * v[0][a] + v[1][a] * v[1][a] + v[2][a] * v[2][a]) * dt * dt;
        if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= step2) { /* within one step: arrive */
            for (int k = 0; k < 3; k++) p[k][a] = tgt_c[k][s];
            phase[a] = FM_KERNEL_ARRIVED, arrived++;
            continue;
        }
        for (int k = 0; k < 3; k++) p[k][a] += v[k][a] * dt;
    }
    return arrived;
}

int64_t fm_kernel_homing_steered(float *const p[3], const float *const v[3], uint8_t *phase,
                                 const int64_t *target, const float *const tgt_c[3], int64_t begin,
                                 int64_t end, float dt)
{
    return target ? homing_steered(p, v, phase, target, tgt_c, begin, end, dt)
                  : homing_steered(p, v, phase, NULL, tgt_c, begin, end, dt);
}
