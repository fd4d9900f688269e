/* Phase 1 integration and the switch into phase 2 (FM §5.5): the scalar reference and the
 * dispatch; the SIMD variants are in kernel_integrate_simd.c. */
#include "kernel_integrate.h"
#include "simd.h"

int64_t fm_kernel_integrate_flying_ref(float *const p[3], const float *const v[3], const uint8_t *phase,
                                   int64_t begin, int64_t end, float dt, fm_sphere_view sphere,
                                   const fm_sdf_view *target_sdf, float switch_distance,
                                   uint8_t *entered)
{
    const float r2 = sphere.r * sphere.r;
    int64_t count = 0;
    for (int64_t a = begin; a < end; a++) {
        entered[a] = 0;
        if (phase[a] != FM_KERNEL_FLYING) continue;
        float x = p[0][a] + v[0][a] * dt, y = p[1][a] + v[1][a] * dt, z = p[2][a] + v[2][a] * dt;
        p[0][a] = x, p[1][a] = y, p[2][a] = z;
        float dx = x - sphere.c[0], dy = y - sphere.c[1], dz = z - sphere.c[2], g[3];
        int inside = target_sdf ? fm_sdf_sample(target_sdf, x, y, z, g) < switch_distance
                                : dx * dx + dy * dy + dz * dz < r2;
        if (inside) entered[a] = 1, count++;
    }
    return count;
}

int64_t fm_kernel_integrate_flying(float *const p[3], const float *const v[3], const uint8_t *phase,
                                   int64_t begin, int64_t end, float dt, fm_sphere_view sphere,
                                   const fm_sdf_view *target_sdf, float switch_distance,
                                   uint8_t *entered)
{
    if (!target_sdf) { /* the sphere test vectorises; the distance switch samples a grid per agent */
        fm_integrate_sphere_fn *variant = FM_SIMD_PICK(fm_integrate_sphere);
        if (variant) return variant(p, v, phase, begin, end, dt, sphere, entered);
    }
    return fm_kernel_integrate_flying_ref(p, v, phase, begin, end, dt, sphere, target_sdf, switch_distance, entered);
}
