/* FM eq 3, SIMD: the nearest key point of FM_W agents at once (the O(m) part: key points against a
 * vector of agents), then the scalar finish per agent. Same operations as the reference, so the
 * same bits. The key points are taken in groups of KEY_GROUP consecutive ones, each in a bounding
 * sphere, and a vector of agents skips a group none of its flying agents can find its nearest key
 * point in (below); the others are scanned in order as the reference scans them all. Compiled three
 * times (simd.h). */
#include "kernel_path.h"
#include "simd.h"

enum { KEY_GROUP = 8, MAX_KEY_GROUPS = 64 };

/* Groups of KEY_GROUP consecutive key points (the last may be shorter): centre, radius (inflated by
 * 1e-5 of itself over float rounding) and a probe, the group's middle key point. */
typedef struct key_groups {
    int32_t count;
    float c[3][MAX_KEY_GROUPS], r[MAX_KEY_GROUPS];
    int32_t probe[MAX_KEY_GROUPS];
} key_groups;

/* The groups of the path, or count 0 where there are too few (or too many) key points for them. */
static void key_groups_of(const fm_path_view *path, key_groups *G)
{
    G->count = path->count >= 2 * KEY_GROUP ? (path->count + KEY_GROUP - 1) / KEY_GROUP : 0;
    if (G->count > MAX_KEY_GROUPS) G->count = 0;
    for (int32_t g = 0; g < G->count; g++) {
        const int32_t first = g * KEY_GROUP, end = first + KEY_GROUP < path->count ? first + KEY_GROUP : path->count;
        float r2 = 0;
        for (int k = 0; k < 3; k++) {
            float lo = path->q[k][first], hi = lo;
            for (int32_t i = first; i < end; i++) lo = fminf(lo, path->q[k][i]), hi = fmaxf(hi, path->q[k][i]);
            G->c[k][g] = 0.5f * (lo + hi);
        }
        for (int32_t i = first; i < end; i++) {
            const float dx = path->q[0][i] - G->c[0][g], dy = path->q[1][i] - G->c[1][g], dz = path->q[2][i] - G->c[2][g];
            r2 = fmaxf(r2, dx * dx + dy * dy + dz * dz);
        }
        G->r[g] = sqrtf(r2) * (1 + 1e-5f);
        G->probe[g] = (first + end) / 2;
    }
}

static fv squared_distance(fv x, fv y, fv z, float qx, float qy, float qz)
{
    const fv dx = fv_sub(x, fv_set1(qx)), dy = fv_sub(y, fv_set1(qy)), dz = fv_sub(z, fv_set1(qz));
    return fv_add(fv_add(fv_mul(dx, dx), fv_mul(dy, dy)), fv_mul(dz, dz));
}

/* Scans key points [first, end) into the running nearest (best_d2, best_i), as the reference does. */
static inline void scan_keys(const fm_path_view *path, int32_t first, int32_t end, fv x, fv y, fv z, fv *best_d2,
                             iv *best_i)
{
    for (int32_t i = first; i < end; i++) {
        const fv d2 = squared_distance(x, y, z, path->q[0][i], path->q[1][i], path->q[2][i]);
        const fv closer = fv_lt(d2, *best_d2); /* strict: ties keep the earlier key point */
        *best_d2 = fv_select(closer, d2, *best_d2);
        *best_i = iv_select(closer, iv_set1(i), *best_i);
    }
}

/* Nearest key points of agents a .. a + FM_W - 1 with the groups: u, the least squared distance to
 * a probe, bounds each agent's nearest key point's; a group whose centre is farther than
 * (sqrt(u) + radius) * (1 + 5e-5) from every flying agent holds only key points more than 1e-4
 * (relative, in squared distance) beyond that, which float rounding (a few 1e-8 in these sums of
 * non-negative terms) cannot bring level with the nearest, so the reference would pick none of
 * them, ties included. The other groups are scanned in order. */
static iv nearest_keys_grouped(const fm_path_view *path, const key_groups *G, const float *const p[3], int64_t a,
                               unsigned flying)
{
    const fv x = fv_load(p[0] + a), y = fv_load(p[1] + a), z = fv_load(p[2] + a);
    fv u = fv_set1(INFINITY);
    for (int32_t g = 0; g < G->count; g++) {
        const int32_t i = G->probe[g];
        const fv d2 = squared_distance(x, y, z, path->q[0][i], path->q[1][i], path->q[2][i]);
        u = fv_select(fv_lt(d2, u), d2, u);
    }
    const fv reach0 = fv_sqrt(u);
    const unsigned all = FM_W == 32 ? ~0u : (1u << FM_W) - 1, idle = all & ~flying;
    fv best_d2 = fv_set1(INFINITY);
    iv best_i = iv_set1(0);
    for (int32_t g = 0; g < G->count; g++) {
        const fv reach = fv_add(reach0, fv_set1(G->r[g]));
        const fv bound = fv_add(fv_mul(fv_mul(reach, reach), fv_set1(1 + 1e-4f)), fv_set1(1e-20f));
        const fv far = fv_gt(squared_distance(x, y, z, G->c[0][g], G->c[1][g], G->c[2][g]), bound);
        if ((fv_mask(far) | idle) == all) continue;
        const int32_t first = g * KEY_GROUP;
        scan_keys(path, first, first + KEY_GROUP < path->count ? first + KEY_GROUP : path->count, x, y, z, &best_d2,
                  &best_i);
    }
    return best_i;
}

/* Nearest key points of agents a .. a + FM_W - 1. */
static iv nearest_keys(const fm_path_view *path, const float *const p[3], int64_t a)
{
    const fv x = fv_load(p[0] + a), y = fv_load(p[1] + a), z = fv_load(p[2] + a);
    fv best_d2 = fv_set1(INFINITY);
    iv best_i = iv_set1(0);
    scan_keys(path, 0, path->count, x, y, z, &best_d2, &best_i);
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
    key_groups G;
    key_groups_of(path, &G);
    int64_t a = begin;
    for (; a + FM_W <= end; a += FM_W) {
        unsigned flying = byte_lanes_equal(phase + a, FM_KERNEL_FLYING);
        if (!flying) continue;
        const iv best_i = G.count ? nearest_keys_grouped(path, &G, p, a, flying) : nearest_keys(path, p, a);
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
