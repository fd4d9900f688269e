/* The virtual leaders in double lanes (kernel_leader.h); compiled three times (simd.h). */
#include "kernel_leader.h"

static inline dv dv_clamp01(dv x) /* x < 0 ? 0 : x > 1 ? 1 : x (NaN stays) */
{
    const dv zero = dv_set1(0.0), one = dv_set1(1.0);
    const dv y = dv_blend(dv_gt(zero, x), zero, x);
    return dv_blend(dv_gt(y, one), one, y);
}

/* fm_flock_leader's normalised time x of the lanes (t - delay) / path_time. */
static dv leader_time(const fm_leader_view *w, const float *const start[3], int64_t a)
{
    dv delay = dv_set1(0.0);
    if (w->inv_range > 0) {
        const dv x = dv_add(dv_add(dv_mul(dv_set1(w->axis[0]), dv_from_floats(start[0] + a)),
                                   dv_mul(dv_set1(w->axis[1]), dv_from_floats(start[1] + a))),
                            dv_mul(dv_set1(w->axis[2]), dv_from_floats(start[2] + a)));
        const dv back = dv_sub(dv_set1(1.0), dv_mul(dv_sub(x, dv_set1(w->lo)), dv_set1(w->inv_range)));
        delay = dv_mul(dv_set1(w->spread), dv_clamp01(back));
    }
    return dv_div(dv_sub(dv_set1(w->t), delay), dv_set1(w->path_time));
}

/* fm_bspline_eval_table at s (in [0, 1)), coordinate k of R, for the lanes. */
static void path_at(const fm_leader_view *w, dv s, dv r[3])
{
    const dv samples = dv_set1((double)w->samples);
    const dv x = dv_mul(dv_clamp01(s), samples);
    dv j = dv_floor(x); /* x >= 0: the scalar code's truncation */
    j = dv_blend(dv_le(samples, j), dv_set1((double)(w->samples - 1)), j);
    const dv t = dv_sub(x, j), t2 = dv_mul(t, t), t3 = dv_mul(t2, t), h = dv_set1(1.0 / w->samples);
    const dv two = dv_set1(2.0), three = dv_set1(3.0);
    const dv h00 = dv_add(dv_sub(dv_mul(two, t3), dv_mul(three, t2)), dv_set1(1.0));
    const dv h10 = dv_add(dv_sub(t3, dv_mul(two, t2)), t);
    const dv h01 = dv_add(dv_mul(dv_set1(-2.0), t3), dv_mul(three, t2));
    const dv h11 = dv_sub(t3, t2);
    const di at = di_from_dv(dv_mul(j, dv_set1(6.0))), next = di_add(at, di_set1(6));
    for (int k = 0; k < 3; k++)
        r[k] = dv_add(dv_add(dv_add(dv_mul(h00, dv_gather(w->arc + k, at)), dv_mul(dv_mul(h10, h), dv_gather(w->arc + 3 + k, at))),
                             dv_mul(h01, dv_gather(w->arc + k, next))),
                      dv_mul(dv_mul(h11, h), dv_gather(w->arc + 3 + k, next)));
}

/* fm_path_map_blend for the lanes: r on the path, c1 the start, c2 the destination, s, f. */
static void map_blend(const fm_leader_view *w, const dv r[3], const dv c1[3], const dv c2[3], dv s, dv f, dv out[3])
{
    const dv one = dv_set1(1.0);
    dv cc = dv_set1(0.0);
    for (int k = 0; k < 3; k++) cc = dv_add(cc, dv_mul(dv_sub(c2[k], c1[k]), dv_sub(c2[k], c1[k])));
    const dv alpha = w->oo > 0 ? dv_sqrt(dv_div(cc, dv_set1(w->oo))) : one;
    for (int k = 0; k < 3; k++) {
        const dv o1 = dv_set1(w->o1[k]), o2 = dv_set1(w->o2[k]);
        const dv o = dv_add(dv_mul(dv_sub(one, s), o1), dv_mul(s, o2));
        const dv c = dv_add(dv_add(o, dv_mul(dv_sub(one, f), dv_sub(c1[k], o1))), dv_mul(f, dv_sub(c2[k], o2)));
        out[k] = dv_add(dv_sub(dv_mul(alpha, r[k]), dv_mul(alpha, o)), c);
    }
}

/* The layout's blend f of the lanes' fractions u (layout_blend in flock_model.c). */
static dv blend_of(const fm_leader_view *w, dv u)
{
    if (!(w->reform > 0)) return u;
    const dv zero = dv_set1(0.0), one = dv_set1(1.0);
    const dv x = dv_div(dv_sub(u, dv_set1(1 - w->reform)), dv_set1(w->reform));
    const dv smooth = dv_mul(dv_mul(x, x), dv_sub(dv_set1(3.0), dv_mul(dv_set1(2.0), x)));
    return dv_blend(dv_le(x, zero), zero, dv_blend(dv_le(one, x), one, smooth));
}

int64_t FM_SIMD_VARIANT(fm_kernel_leaders)(const fm_leader_view *w, const uint8_t *phase, uint8_t skip,
                                           const float *const start[3], const float *const dest[3],
                                           float *const leader[3], float *const leader_v[3], int64_t begin,
                                           int64_t end, int64_t *left, int64_t *left_count)
{
    const dv zero = dv_set1(0.0), one = dv_set1(1.0), e_in = dv_set1(w->e_in);
    int64_t a = begin;
    for (; a + FM_WD <= end; a += FM_WD) {
        /* eased(): 0 before the start, 1 after the end, the cruise between the ramps */
        const dv x = leader_time(w, start, a);
        const dm before = dv_le(x, zero), after = dv_le(one, x);
        const dv cruise = dv_mul(dv_set1(w->top), dv_sub(dv_add(dv_mul(dv_set1(0.5), e_in), x), e_in));
        const dv u = dv_blend(before, zero, dv_blend(after, one, cruise));
        const dv f = blend_of(w, u);
        dv c1[3], c2[3], r[3], z[3];
        for (int k = 0; k < 3; k++) c1[k] = dv_from_floats(start[k] + a), c2[k] = dv_from_floats(dest[k] + a);
        path_at(w, dv_blend(dv_le(u, u), u, zero), r); /* a NaN lane (not written) reads the table's start */
        map_blend(w, r, c1, c2, u, f, z);
        const dm arrived = dv_le(one, u);
        double xs[FM_WD];
        dv_store(xs, x);
        float out[3][FM_WD], vel[3][FM_WD];
        for (int k = 0; k < 3; k++) {
            const dv zk = dv_blend(arrived, c2[k], z[k]);
            dv_store_floats(out[k], zk);
            dv_store_floats(vel[k], dv_mul(dv_sub(zk, dv_from_floats(leader[k] + a)), dv_set1(w->inv_dt)));
        }
        for (int l = 0; l < FM_WD; l++) {
            if (phase[a + l] == skip) continue;
            const double xl = xs[l];
            if (!(xl <= 0) && !(xl >= 1) && (xl < w->e_in || 1 - xl < w->e_out)) { /* on a ramp: eased()'s sine */
                left[(*left_count)++] = a + l;
                continue;
            }
            for (int k = 0; k < 3; k++) leader_v[k][a + l] = vel[k][l], leader[k][a + l] = out[k][l];
        }
    }
    return a;
}
