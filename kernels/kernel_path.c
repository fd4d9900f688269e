/* FM eq 3: the global velocity along the user path. The scalar reference and the dispatch; the
 * SIMD variants are in kernel_path_simd.c. */
#include "kernel_path.h"
#include "simd.h"

void fm_kernel_global_velocity_ref(const fm_path_view *path, const float *const p[3], const uint8_t *phase,
                                   int64_t begin, int64_t end, float speed, float *const v[3])
{
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != FM_KERNEL_FLYING) continue;
        int32_t i = path_nearest_key(path, p[0][a], p[1][a], p[2][a]);
        path_velocity(path, i, speed, p, v, a);
    }
}

void fm_kernel_global_velocity(const fm_path_view *path, const float *const p[3], const uint8_t *phase,
                               int64_t begin, int64_t end, float speed, float *const v[3])
{
    fm_global_velocity_fn *variant = FM_SIMD_PICK(fm_kernel_global_velocity);
    (variant ? variant : fm_kernel_global_velocity_ref)(path, p, phase, begin, end, speed, v);
}
