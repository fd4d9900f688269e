/* Phase 2 (FM eq 9): V_2 = speed0 * unit(P_X' - P_X), constant once set; t_f = |P_X' - P_X| / speed0. */
#include "kernels.h"

int64_t fm_kernel_homing(float *const p[3], float *const v[3], uint8_t *phase,
                         const int64_t *target, const float *const tgt_c[3],
                         const float *const p2[3], const float *t2, const float *tf,
                         int64_t begin, int64_t end, double time)
{
    int64_t arrived = 0;
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != 2) continue;
        int64_t s = target[a];
        double u = tf[a] > 0 ? (time - t2[a]) / tf[a] : 1.0;
        for (int k = 0; k < 3; k++) {
            float from = p2[k][a], to = tgt_c[k][s];
            v[k][a] = tf[a] > 0 ? (to - from) / tf[a] : 0.0f;
            p[k][a] = u >= 1.0 ? to : (float)(from + u * (to - from));
        }
        if (u >= 1.0) phase[a] = 3, arrived++;
    }
    return arrived;
}
