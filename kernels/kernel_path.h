/* FM eq 3 internals shared by the scalar reference and the SIMD variants of the path kernel. */
#ifndef FM_KERNEL_PATH_H
#define FM_KERNEL_PATH_H

#include "kernels.h"
#include "simd.h"

#include <math.h>

/* FM §5.1 path width: pull back toward segment Q_i Q_{i+1} when farther than half_width. */
static inline void path_attraction(const fm_path_view *path, int32_t i, float x, float y, float z,
                                   float *const v[3], int64_t a)
{
    float q[3] = {path->q[0][i], path->q[1][i], path->q[2][i]};
    float e[3] = {path->q[0][i + 1] - q[0], path->q[1][i + 1] - q[1], path->q[2][i + 1] - q[2]};
    float len2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
    float s = len2 > 0 ? ((x - q[0]) * e[0] + (y - q[1]) * e[1] + (z - q[2]) * e[2]) / len2 : 0;
    s = s < 0 ? 0 : s > 1 ? 1 : s;
    float d[3] = {q[0] + s * e[0] - x, q[1] + s * e[1] - y, q[2] + s * e[2] - z};
    float dist = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (dist <= path->half_width) return;
    float pull = path->attraction * (dist - path->half_width) / dist;
    for (int k = 0; k < 3; k++) v[k][a] += pull * d[k];
}

/* Agent a's velocity once its nearest key point i is known: speed * f_i, or toward C_T past the
 * end of the path, plus the path-width pull. */
static inline void path_velocity(const fm_path_view *path, int32_t i, float speed, const float *const p[3],
                                 float *const v[3], int64_t a)
{
    const int32_t last = path->count - 1;
    float x = p[0][a], y = p[1][a], z = p[2][a];
    float f[3] = {path->f[0][i], path->f[1][i], path->f[2][i]};
    if (i == last) { /* past the end of the path: head for C_T */
        f[0] = path->q[0][last] - x, f[1] = path->q[1][last] - y, f[2] = path->q[2][last] - z;
        float len = sqrtf(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        float inv = len > 0 ? 1.0f / len : 0.0f;
        f[0] *= inv, f[1] *= inv, f[2] *= inv;
    }
    for (int k = 0; k < 3; k++) v[k][a] = speed * f[k];
    if (path->half_width > 0 && i < last) path_attraction(path, i, x, y, z, v, a);
}

/* Index of the key point nearest to (x, y, z); ties go to the earlier key point. */
static inline int32_t path_nearest_key(const fm_path_view *path, float x, float y, float z)
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

/* The SIMD variants (kernel_path_simd.c). */
typedef void fm_global_velocity_fn(const fm_path_view *path, const float *const p[3], const uint8_t *phase,
                                   int64_t begin, int64_t end, float speed, float *const v[3]);
FM_SIMD_DECLARE(fm_global_velocity_fn, fm_kernel_global_velocity);

#endif
