/* The forces in float lanes (kernel_forces.h); compiled three times (simd.h). */
#include "kernel_forces.h"

/* fm_fuzzy_eval in lanes: the last piece whose start d lies beyond, the last point's weight past
 * it, the first's before it (and for NaN). */
static fv curve_at(const fm_weight_curve *c, fv d)
{
    fv r = fv_set1(c->w[0]);
    for (int32_t j = 0; j + 1 < c->count; j++) {
        const fv dj = fv_set1(c->d[j]);
        r = fv_select(fv_gt(d, dj), fv_add(fv_set1(c->w[j]), fv_mul(fv_set1(c->slope[j]), fv_sub(d, dj))), r);
    }
    return fv_select(fv_gt(d, fv_set1(c->d[c->count - 1])), fv_set1(c->w[c->count - 1]), r);
}

static inline fv length3(const fv x[3])
{
    return fv_sqrt(fv_add(fv_add(fv_mul(x[0], x[0]), fv_mul(x[1], x[1])), fv_mul(x[2], x[2])));
}

/* truncate3: |x| <= limit, scaled by limit / |x| where |x|^2 > limit^2. */
static inline void truncate_lanes(fv x[3], fv limit)
{
    const fv len2 = fv_add(fv_add(fv_mul(x[0], x[0]), fv_mul(x[1], x[1])), fv_mul(x[2], x[2]));
    const fv over = fv_gt(len2, fv_mul(limit, limit)), scale = fv_div(limit, fv_sqrt(len2));
    for (int k = 0; k < 3; k++) x[k] = fv_select(over, fv_mul(x[k], scale), x[k]);
}

static inline void load3(const float *const src[3], int64_t a, fv out[3])
{
    for (int k = 0; k < 3; k++) out[k] = fv_load(src[k] + a);
}

/* Lanes of agents under forces, as bits; stores lane l of `v` at dst[a + l] only there (a whole
 * vector where every lane is chosen, the usual case). */
static inline unsigned chosen_lanes(const fm_forces_arrays *x, int64_t a) { return byte_lanes_equal(x->phase + a, x->sel); }

static inline void store_chosen(float *dst, int64_t a, fv v, unsigned bits)
{
    if (bits == (unsigned)((1ull << FM_W) - 1)) {
        fv_store(dst + a, v);
        return;
    }
    float t[FM_W];
    fv_store(t, v);
    for (int l = 0; l < FM_W; l++)
        if (bits >> l & 1) dst[a + l] = t[l];
}

/* R's factor: over the distance d, an agent behind its leader counted no farther than the leader's
 * distance plus the curve's first x (fminf of the two); or over the leader's speed. */
static fv r_scale_lanes(const fm_forces_view *w, const fm_forces_arrays *x, int64_t a, fv d)
{
    fv e[3];
    if (!w->r_over_distance) {
        load3(x->leader_v, a, e);
        return curve_at(&w->r_scale, length3(e));
    }
    for (int k = 0; k < 3; k++) e[k] = fv_sub(fv_load(x->dest[k] + a), fv_load(x->leader[k] + a));
    const fv bound = fv_add(length3(e), fv_set1(w->r_scale.d[0]));
    const fv smaller = fv_select(fv_lt(bound, d), bound, d);          /* fminf(d, bound), d a number */
    return curve_at(&w->r_scale, fv_select(fv_gt(d, fv_set1(-1.0f)), smaller, bound)); /* d NaN: bound */
}

int64_t FM_SIMD_VARIANT(fm_kernel_other_forces)(const fm_forces_view *w, const fm_forces_arrays *x, int64_t begin,
                                                int64_t end)
{
    const fv inv_mass = fv_set1(w->inv_mass), damping = fv_set1(-w->damping), gain = fv_set1(w->external_gain);
    int64_t a = begin;
    for (; a + FM_W <= end; a += FM_W) {
        const unsigned bits = chosen_lanes(x, a);
        if (!bits) continue;
        fv to[3];
        for (int k = 0; k < 3; k++) to[k] = fv_sub(fv_load(x->dest[k] + a), fv_load(x->p[k] + a));
        const fv d = length3(to), max_accel = fv_load(x->max_accel + a);
        const fv w_steer = curve_at(&w->steer, d), w_damp = curve_at(&w->damp, d), w_ext = curve_at(&w->ext, d);
        store_chosen(x->w_homing, a, curve_at(&w->homing, d), bits);
        if (x->r_scale) store_chosen(x->r_scale, a, r_scale_lanes(w, x, a, d), bits);
        fv damp[3], ext[3];
        for (int k = 0; k < 3; k++) {
            const fv v = fv_load(x->v[k] + a);
            damp[k] = fv_mul(damping, w->tracking ? fv_sub(v, fv_load(x->dest_v[k] + a)) : v);
            ext[k] = w->fields ? fv_mul(gain, fv_load(x->ext[k] + a)) : fv_set1(0.0f);
        }
        truncate_lanes(damp, max_accel), truncate_lanes(ext, max_accel);
        const fv steer_scale = fv_mul(w_steer, inv_mass);
        for (int k = 0; k < 3; k++) {
            const fv steer = fv_mul(fv_load(x->steer[k] + a), steer_scale);
            store_chosen(x->steer[k], a, steer, bits);
            store_chosen(x->acc[k], a, fv_add(fv_add(steer, fv_mul(w_damp, damp[k])), fv_mul(w_ext, ext[k])), bits);
        }
    }
    return a;
}

int64_t FM_SIMD_VARIANT(fm_kernel_combine_forces)(const fm_forces_arrays *x, int64_t begin, int64_t end)
{
    int64_t a = begin;
    for (; a + FM_W <= end; a += FM_W) {
        const unsigned bits = chosen_lanes(x, a);
        if (!bits) continue;
        fv h[3], b[3];
        load3((const float *const *)x->ext, a, h), load3((const float *const *)x->steer, a, b);
        const fv left = fv_sub(fv_load(x->max_accel + a), length3(h));
        truncate_lanes(b, fv_select(fv_gt(left, fv_set1(0.0f)), left, fv_set1(0.0f))); /* fmaxf(0, left) */
        for (int k = 0; k < 3; k++)
            store_chosen(x->acc[k], a, fv_add(fv_load(x->acc[k] + a), fv_sub(fv_add(h[k], b[k]), fv_load(x->steer[k] + a))), bits);
    }
    return a;
}

int64_t FM_SIMD_VARIANT(fm_kernel_move_flying)(const fm_forces_arrays *x, float *const p[3], float *const v[3],
                                               uint8_t *phase, const float *max_speed, float dt, float arrival_radius,
                                               uint8_t homing, int64_t begin, int64_t end)
{
    const fv step = fv_set1(dt), half = fv_set1(0.5f), radius = fv_set1(arrival_radius);
    int64_t a = begin;
    for (; a + FM_W <= end; a += FM_W) {
        const unsigned bits = chosen_lanes(x, a);
        if (!bits) continue;
        fv v0[3], v1[3], to[3];
        for (int k = 0; k < 3; k++) v0[k] = fv_load(v[k] + a), v1[k] = fv_add(v0[k], fv_mul(fv_load(x->acc[k] + a), step));
        truncate_lanes(v1, fv_load(max_speed + a));
        for (int k = 0; k < 3; k++) {
            const fv moved = fv_add(fv_load(p[k] + a), fv_mul(fv_mul(half, fv_add(v0[k], v1[k])), step));
            store_chosen(p[k], a, moved, bits), store_chosen(v[k], a, v1[k], bits);
            to[k] = fv_sub(fv_load(x->dest[k] + a), moved);
        }
        const unsigned near = arrival_radius > 0 ? fv_mask(fv_lt(length3(to), radius)) : 0;
        for (int l = 0; l < FM_W; l++)
            if ((bits & near) >> l & 1) phase[a + l] = homing;
    }
    return a;
}
