/* Phase 2 (FM eq 9): V_2 = speed0 * unit(P_X' - P_X), constant once set; t_f = |P_X' - P_X| / speed0. */
#include "kernels.h"

#include <math.h>

int64_t fm_kernel_homing(float *const p[3], float *const v[3], uint8_t *phase,
                         const int64_t *target, const float *const tgt_c[3],
                         const float *const p2[3], const float *t2, const float *tf,
                         int64_t begin, int64_t end, double time)
{
    int64_t arrived = 0;
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != FM_KERNEL_HOMING) continue;
        int64_t s = target[a];
        double u = tf[a] > 0 ? (time - t2[a]) / tf[a] : 1.0;
        for (int k = 0; k < 3; k++) {
            float from = p2[k][a], to = tgt_c[k][s];
            v[k][a] = tf[a] > 0 ? (to - from) / tf[a] : 0.0f;
            p[k][a] = u >= 1.0 ? to : (float)(from + u * (to - from));
        }
        if (u >= 1.0) phase[a] = FM_KERNEL_ARRIVED, arrived++;
    }
    return arrived;
}

void fm_kernel_homing_aim(const float *const p[3], float *const v[3], const uint8_t *phase,
                          const int64_t *target, const float *const tgt_c[3], int64_t begin,
                          int64_t end, float speed0)
{
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != FM_KERNEL_HOMING) continue;
        int64_t s = target[a];
        float d[3] = {tgt_c[0][s] - p[0][a], tgt_c[1][s] - p[1][a], tgt_c[2][s] - p[2][a]};
        float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int k = 0; k < 3; k++) v[k][a] = len > 0 ? speed0 * d[k] / len : 0.0f;
    }
}

int64_t fm_kernel_homing_steered(float *const p[3], const float *const v[3], uint8_t *phase,
                                 const int64_t *target, const float *const tgt_c[3], int64_t begin,
                                 int64_t end, float dt)
{
    int64_t arrived = 0;
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != FM_KERNEL_HOMING) continue;
        int64_t s = target[a];
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
