/* FM eq 3: the global velocity along the user path. */
#include "kernels.h"

#include <math.h>

/* Index of the key point nearest to (x, y, z); ties go to the earlier key point. */
static int32_t nearest_key(const fm_path_view *path, float x, float y, float z)
{
    int32_t best = 0;
    float best_d2 = INFINITY;
    for (int32_t i = 0; i < path->count; i++) {
        float dx = x - path->q[0][i], dy = y - path->q[1][i], dz = z - path->q[2][i];
        float d2 = dx * dx + dy * dy + dz * dz;
        if (d2 < best_d2) best_d2 = d2, best = i;
    }
    return best;
}

void fm_kernel_global_velocity(const fm_path_view *path, const float *const p[3],
                               const uint8_t *phase, int64_t begin, int64_t end, float speed,
                               float *const v[3])
{
    const int32_t last = path->count - 1;
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != 1) continue;
        float x = p[0][a], y = p[1][a], z = p[2][a];
        int32_t i = nearest_key(path, x, y, z);
        float f[3] = {path->f[0][i], path->f[1][i], path->f[2][i]};
        if (i == last) { /* past the end of the path: head for C_T */
            f[0] = path->q[0][last] - x, f[1] = path->q[1][last] - y, f[2] = path->q[2][last] - z;
            float len = sqrtf(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
            float inv = len > 0 ? 1.0f / len : 0.0f;
            f[0] *= inv, f[1] *= inv, f[2] *= inv;
        }
        for (int k = 0; k < 3; k++) v[k][a] = speed * f[k];
    }
}
