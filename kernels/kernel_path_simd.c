/* FM eq 3, SIMD: the nearest key point of FM_W agents at once (the O(m) part: every key point
 * against a vector of agents), then the scalar finish per agent. Same operations as the reference,
 * so the same bits. Compiled twice (simd.h). */
#include "kernel_path.h"
#include "simd.h"

/* Nearest key points of agents a .. a + FM_W - 1. */
static iv nearest_keys(const fm_path_view *path, const float *const p[3], int64_t a)
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
    return best_i;
}

/* The velocity of eq 3 for FM_W agents whose nearest key points are best_i: speed * f_i, or the unit
 * direction to C_T for those nearest the last key point, written where `flying`. The reference's
 * operations lane by lane (path_velocity without the path-width pull). */
static void store_velocities(const fm_path_view *path, const float *const p[3], int64_t a, iv best_i, float speed,
                             unsigned flying, float *const v[3])
{
    const int32_t last = path->count - 1;
    fv f[3], to[3];
    for (int k = 0; k < 3; k++) f[k] = fv_gather(path->f[k], best_i);
    to[0] = fv_sub(fv_set1(path->q[0][last]), fv_load(p[0] + a));
    to[1] = fv_sub(fv_set1(path->q[1][last]), fv_load(p[1] + a));
    to[2] = fv_sub(fv_set1(path->q[2][last]), fv_load(p[2] + a));
    const fv len = fv_sqrt(fv_add(fv_add(fv_mul(to[0], to[0]), fv_mul(to[1], to[1])), fv_mul(to[2], to[2])));
    const fv inv = fv_select(fv_gt(len, fv_set1(0.0f)), fv_div(fv_set1(1.0f), len), fv_set1(0.0f));
    const fv at_end = iv_as_mask(iv_eq_mask(best_i, last));
    float out[3][FM_W];
    for (int k = 0; k < 3; k++) fv_store(out[k], fv_mul(fv_set1(speed), fv_select(at_end, fv_mul(to[k], inv), f[k])));
    for (int l = 0; l < FM_W; l++)
        if (flying >> l & 1) v[0][a + l] = out[0][l], v[1][a + l] = out[1][l], v[2][a + l] = out[2][l];
}

void FM_SIMD_VARIANT(fm_kernel_global_velocity)(const fm_path_view *path, const float *const p[3],
                                                const uint8_t *phase, int64_t begin, int64_t end, float speed,
                                                float *const v[3])
{
    int64_t a = begin;
    for (; a + FM_W <= end; a += FM_W) {
        unsigned flying = byte_lanes_equal(phase + a, FM_KERNEL_FLYING);
        if (!flying) continue;
        const iv best_i = nearest_keys(path, p, a);
        if (path->half_width > 0) { /* the path-width pull: per agent, as the reference */
            int32_t best[FM_W];
            iv_store(best, best_i);
            for (int k = 0; k < FM_W; k++)
                if (flying >> k & 1) path_velocity(path, best[k], speed, p, v, a + k);
        } else {
            store_velocities(path, p, a, best_i, speed, flying, v);
        }
    }
    for (; a < end; a++) /* the tail */
        if (phase[a] == FM_KERNEL_FLYING) path_velocity(path, path_nearest_key(path, p[0][a], p[1][a], p[2][a]), speed, p, v, a);
}
