/* The Kalman homing in double lanes (kernel_kalman.h): fm_kalman_covariance_step and
 * fm_kalman_homing's operations, in their order, FM_WD agents at a time. Lanes of agents not under
 * forces are computed and not written. Compiled three times (simd.h). */
#include "kernel_kalman.h"

/* The gains k_pp, k_pv of FM_WD agents' own filters from their covariances c (3 doubles an agent,
 * updated in the lanes `chosen`); fm_kalman_covariance_step, lane by lane. */
static void own_gains(const fm_kalman_lanes *k, double *c, const float *r_scale, const uint8_t *chosen, dv *k_pp,
                      dv *k_pv)
{
    double a_[FM_WD], b_[FM_WD], c_[FM_WD];
    for (int l = 0; l < FM_WD; l++) a_[l] = c[3 * l], b_[l] = c[3 * l + 1], c_[l] = c[3 * l + 2];
    const dv a = dv_load(a_), b = dv_load(b_), cc = dv_load(c_), dt = dv_set1(k->dt), one = dv_set1(1.0);
    const dv scale = dv_from_floats(r_scale);
    /* P- = A P A^T + Q */
    const dv pa = dv_add(dv_add(dv_add(a, dv_mul(dv_mul(dv_set1(2.0), b), dt)), dv_mul(dv_mul(cc, dt), dt)), dv_set1(k->q_pa));
    const dv pb = dv_add(dv_add(b, dv_mul(cc, dt)), dv_set1(k->q_pb));
    const dv pc = dv_add(cc, dv_set1(k->q_pc));
    /* K = P- (P- + R)^-1 */
    const dv sa = dv_add(pa, dv_mul(dv_set1(k->r_pos), scale));
    const dv sc = dv_add(pc, dv_mul(dv_set1(k->r_vel), k->scale_velocity ? scale : one));
    const dv det = dv_sub(dv_mul(sa, sc), dv_mul(pb, pb));
    const dv ia = dv_div(sc, det), ib = dv_div(dv_neg(pb), det), ic = dv_div(sa, det);
    const dv k0 = dv_add(dv_mul(pa, ia), dv_mul(pb, ib)), k1 = dv_add(dv_mul(pa, ib), dv_mul(pb, ic));
    const dv k2 = dv_add(dv_mul(pb, ia), dv_mul(pc, ib)), k3 = dv_add(dv_mul(pb, ib), dv_mul(pc, ic));
    /* P+ = (I - K) P-, symmetrised */
    const dv na = dv_sub(dv_mul(dv_sub(one, k0), pa), dv_mul(k1, pb));
    const dv nb = dv_mul(dv_set1(0.5), dv_add(dv_sub(dv_mul(dv_sub(one, k0), pb), dv_mul(k1, pc)),
                                              dv_add(dv_mul(dv_neg(k2), pa), dv_mul(dv_sub(one, k3), pb))));
    const dv nc = dv_add(dv_mul(dv_neg(k2), pb), dv_mul(dv_sub(one, k3), pc));
    dv_store(a_, na), dv_store(b_, nb), dv_store(c_, nc);
    for (int l = 0; l < FM_WD; l++)
        if (chosen[l]) c[3 * l] = a_[l], c[3 * l + 1] = b_[l], c[3 * l + 2] = c_[l];
    *k_pp = k0, *k_pv = k1;
}

int64_t FM_SIMD_VARIANT(fm_kernel_kalman_homing)(const fm_kalman_lanes *k, int64_t begin, int64_t end,
                                                 const uint8_t *phase, uint8_t phase_sel, const float *const p[3],
                                                 const float *const v[3], const float *const z_p[3],
                                                 const float *const z_v[3], const float *weight,
                                                 const float *max_accel, const float *const u[3], float *const h[3])
{
    const dv dt = dv_set1(k->dt), gain = dv_set1(k->gain), one = dv_set1(1.0);
    int64_t a = begin;
    for (; a + FM_WD <= end; a += FM_WD) {
        uint8_t chosen[FM_WD], any = 0;
        for (int l = 0; l < FM_WD; l++) chosen[l] = phase[a + l] == phase_sel, any |= chosen[l];
        if (!any) continue;
        dv k_pp = dv_set1(k->k_pp), k_pv = dv_set1(k->k_pv);
        if (k->p) own_gains(k, k->p + 3 * a, k->r_scale + a, chosen, &k_pp, &k_pv);
        const dv w = dv_mul(dv_from_floats(weight + a), gain);
        dv f[3], f2 = dv_set1(0.0);
        for (int c = 0; c < 3; c++) {
            const dv vc = dv_from_floats(v[c] + a);
            const dv e_p = dv_sub(dv_from_floats(z_p[c] + a), dv_add(dv_from_floats(p[c] + a), dv_mul(vc, dt)));
            const dv e_v = dv_sub(dv_from_floats(z_v[c] + a), dv_add(vc, dv_mul(dv_from_floats(u[c] + a), dt)));
            f[c] = dv_mul(w, dv_add(dv_mul(k_pp, e_p), dv_mul(k_pv, e_v)));
            f2 = dv_add(f2, dv_mul(f[c], f[c]));
        }
        dv scale = one;
        if (max_accel) {
            const dv m = dv_from_floats(max_accel + a);
            scale = dv_blend(dv_gt(f2, dv_mul(m, m)), dv_div(m, dv_sqrt(f2)), one);
        }
        float out[3][FM_WD];
        for (int c = 0; c < 3; c++) dv_store_floats(out[c], dv_mul(scale, f[c]));
        for (int l = 0; l < FM_WD; l++)
            if (chosen[l]) h[0][a + l] = out[0][l], h[1][a + l] = out[1][l], h[2][a + l] = out[2][l];
    }
    return a;
}
