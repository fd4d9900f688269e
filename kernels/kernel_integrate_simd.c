/* Phase 1 integration with the bounding-sphere switch (FM §5.5), FM_W agents at a time: the same
 * operations as fm_kernel_integrate_flying_ref, so the same bits. Compiled twice (simd.h). */
#include "kernel_integrate.h"
#include "simd.h"

/* One agent, exactly as the reference does it. */
static int integrate_one(float *const p[3], const float *const v[3], int64_t a, float dt, fm_sphere_view sphere,
                         float r2)
{
    float x = p[0][a] + v[0][a] * dt, y = p[1][a] + v[1][a] * dt, z = p[2][a] + v[2][a] * dt;
    p[0][a] = x, p[1][a] = y, p[2][a] = z;
    float dx = x - sphere.c[0], dy = y - sphere.c[1], dz = z - sphere.c[2];
    return dx * dx + dy * dy + dz * dz < r2;
}

int64_t FM_SIMD_VARIANT(fm_integrate_sphere)(float *const p[3], const float *const v[3], const uint8_t *phase,
                                              int64_t begin, int64_t end, float dt, fm_sphere_view sphere,
                                              uint8_t *entered)
{
    const float r2 = sphere.r * sphere.r;
    const fv vdt = fv_set1(dt), cx = fv_set1(sphere.c[0]), cy = fv_set1(sphere.c[1]), cz = fv_set1(sphere.c[2]);
    const fv vr2 = fv_set1(r2);
    int64_t count = 0, a = begin;
    for (; a + FM_W <= end; a += FM_W) {
        const unsigned flying = byte_lanes_equal(phase + a, FM_KERNEL_FLYING);
        memset(entered + a, 0, FM_W);
        if (!flying) continue;
        fv x = fv_add(fv_load(p[0] + a), fv_mul(fv_load(v[0] + a), vdt));
        fv y = fv_add(fv_load(p[1] + a), fv_mul(fv_load(v[1] + a), vdt));
        fv z = fv_add(fv_load(p[2] + a), fv_mul(fv_load(v[2] + a), vdt));
        fv dx = fv_sub(x, cx), dy = fv_sub(y, cy), dz = fv_sub(z, cz);
        const unsigned inside = fv_mask(fv_lt(fv_add(fv_add(fv_mul(dx, dx), fv_mul(dy, dy)), fv_mul(dz, dz)), vr2));
        if (flying == (1u << FM_W) - 1) { /* all lanes move */
            fv_store(p[0] + a, x), fv_store(p[1] + a, y), fv_store(p[2] + a, z);
        } else {
            float xs[FM_W], ys[FM_W], zs[FM_W];
            fv_store(xs, x), fv_store(ys, y), fv_store(zs, z);
            for (int k = 0; k < FM_W; k++)
                if (flying >> k & 1) p[0][a + k] = xs[k], p[1][a + k] = ys[k], p[2][a + k] = zs[k];
        }
        for (int k = 0; k < FM_W; k++) {
            int in = (flying & inside) >> k & 1;
            entered[a + k] = (uint8_t)in;
            count += in;
        }
    }
    for (; a < end; a++) { /* the tail */
        entered[a] = 0;
        if (phase[a] != FM_KERNEL_FLYING) continue;
        if (integrate_one(p, v, a, dt, sphere, r2)) entered[a] = 1, count++;
    }
    return count;
}
