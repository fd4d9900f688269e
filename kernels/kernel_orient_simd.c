/* The flock's frames, FM_WD agents at a time in double lanes (kernel_orient.h): the closed form of
 * fm_flock_update_orientation, its operations in its order lane by lane, so the same bits; a lane
 * near vertical (or at rest) is left to the scalar function. Compiled three times (simd.h). */
#include "kernel_orient.h"
#include "simd.h"

void FM_SIMD_VARIANT(fm_kernel_orient_along)(float *q, const float *const v[3], const uint8_t *phase, uint8_t skip,
                                             int64_t begin, int64_t end)
{
    const dv half = dv_set1(0.5), one = dv_set1(1.0);
    int64_t a = begin;
    for (; a + FM_WD <= end; a += FM_WD) {
        const dv vx = dv_from_floats(v[0] + a), vy = dv_from_floats(v[1] + a), vz = dv_from_floats(v[2] + a);
        const dv len = dv_sqrt(dv_add(dv_add(dv_mul(vx, vx), dv_mul(vy, vy)), dv_mul(vz, vz)));
        const dv x0 = dv_div(vx, len), x1 = dv_div(vy, len), x2 = dv_div(vz, len);
        const dv h = dv_sqrt(dv_add(dv_mul(x0, x0), dv_mul(x1, x1)));
        const dv cos_psi = dv_div(x0, h);
        const dv qa = dv_sqrt(dv_mul(half, dv_add(one, cos_psi)));
        const dv qb = dv_copysign(dv_sqrt(dv_mul(half, dv_sub(one, cos_psi))), x1);
        const dv qc = dv_sqrt(dv_mul(half, dv_add(one, h)));
        const dv qd = dv_copysign(dv_sqrt(dv_mul(half, dv_sub(one, h))), dv_neg(x2));
        float out[4][FM_WD];
        dv_store_floats(out[0], dv_mul(qa, qc)), dv_store_floats(out[1], dv_mul(dv_neg(qb), qd));
        dv_store_floats(out[2], dv_mul(qa, qd)), dv_store_floats(out[3], dv_mul(qb, qc));
        double lens[FM_WD], hs[FM_WD];
        dv_store(lens, len), dv_store(hs, h);
        for (int l = 0; l < FM_WD; l++) {
            if (phase[a + l] == skip) continue;
            if (!(lens[l] > 1e-12) || !(hs[l] >= 1e-3)) { /* at rest, or near vertical */
                const float vl[3] = {v[0][a + l], v[1][a + l], v[2][a + l]};
                fm_flock_update_orientation(q + 4 * (a + l), vl);
                continue;
            }
            for (int c = 0; c < 4; c++) q[4 * (a + l) + c] = out[c][l];
        }
    }
    for (; a < end; a++) /* the tail */
        if (phase[a] != skip) {
            const float vl[3] = {v[0][a], v[1][a], v[2][a]};
            fm_flock_update_orientation(q + 4 * a, vl);
        }
}
