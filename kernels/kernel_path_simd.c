/* FM eq 3, SIMD: the nearest key point of FM_W agents at once (the O(m) part: every key point
 * against a vector of agents), then the scalar finish per agent. Same operations as the reference,
 * so the same bits. Compiled twice (simd.h). */
#include "kernel_path.h"
#include "simd.h"

/* Nearest key points of agents a .. a + FM_W - 1 into best[]. */
static void nearest_keys(const fm_path_view *path, const float *const p[3], int64_t a, int32_t *best)
{
    const fv x = fv_load(p[0] + a), y = fv_load(p[1] + a), z = fv_load(p[2] + a);
    fv best_d2 = fv_set1(INFINITY);
    iv best_i = iv_set1(0);
    for (int32_t i = 0; i < path->count; i++) {
        fv dx = fv_sub(x, fv_set1(path->q[0][i])), dy = fv_sub(y, fv_set1(path->q[1][i]));
        fv dz = fv_sub(z, fv_set1(path->q[2][i]));
        fv d2 = fv_add(fv_add(fv_mul(dx, dx), fv_mul(dy, dy)), fv_mul(dz, dz));
        fv closer = fv_lt(d2, best_d2); /* strict: ties keep the earlier key point */
        best_d2 = fv_select(closer, d2, best_d2);
        best_i = iv_select(closer, iv_set1(i), best_i);
    }
    iv_store(best, best_i);
}

void FM_SIMD_VARIANT(fm_kernel_global_velocity)(const fm_path_view *path, const float *const p[3],
                                                const uint8_t *phase, int64_t begin, int64_t end, float speed,
                                                float *const v[3])
{
    int64_t a = begin;
    for (; a + FM_W <= end; a += FM_W) {
        unsigned flying = byte_lanes_equal(phase + a, 1);
        if (!flying) continue;
        int32_t best[FM_W];
        nearest_keys(path, p, a, best);
        for (int k = 0; k < FM_W; k++)
            if (flying >> k & 1) path_velocity(path, best[k], speed, p, v, a + k);
    }
    for (; a < end; a++) /* the tail */
        if (phase[a] == 1) path_velocity(path, path_nearest_key(path, p[0][a], p[1][a], p[2][a]), speed, p, v, a);
}
