/* Phase 1's tets, SIMD: FM_WD agents at once in double (simd.h's dv lanes), fm_shrink_at and
 * flying_tet's operations in the same order, so the same bits; each agent's 12 floats are then
 * written together where its id (or slot) says. Compiled three times (simd.h). */
#include "kernel_synth.h"

/* fm_shrink_at for the agents a .. a + FM_WD - 1 */
static inline dv shrink_lanes(const fm_synth_view *s, int64_t a)
{
    const dv one = dv_set1(1.0);
    const dv tau = dv_sub(dv_set1(s->time), dv_div(dv_from_ints(s->id + a), dv_set1(s->launch_rate)));
    dv f = s->shrink_time > 0 ? dv_div(tau, dv_set1(s->shrink_time)) : one;
    f = dv_blend(dv_gt(f, one), one, f);
    const dv scale = dv_sub(one, dv_mul(dv_set1(1.0 - s->shrink), f));
    return dv_blend(dv_le(tau, dv_set1(0.0)), one, scale);
}

static inline void tets_lanes(const fm_synth_view *s, int64_t a, float *out)
{
    const dv scale = shrink_lanes(s, a);
    float t[12][FM_WD];
    for (int j = 0; j < 12; j++)
        dv_store_floats(t[j], dv_add(dv_from_floats(s->p[j % 3] + a), dv_mul(scale, dv_from_floats(s->rest[j] + a))));
    for (int l = 0; l < FM_WD; l++) {
        float *o = out + fm_synth_place(s, a + l);
        for (int j = 0; j < 12; j++) o[j] = t[j][l];
    }
}

void FM_SIMD_VARIANT(fm_kernel_flying_tets)(const fm_synth_view *s, const uint8_t *phase, uint8_t flying,
                                            int64_t begin, int64_t end, float *out)
{
    int64_t a = begin;
    for (; a + FM_WD <= end; a += FM_WD) {
        int all = 1;
        for (int l = 0; l < FM_WD; l++) all &= phase[a + l] == flying;
        if (all) {
            tets_lanes(s, a, out);
            continue;
        }
        for (int l = 0; l < FM_WD; l++)
            if (phase[a + l] == flying) flying_tet(s, a + l, out);
    }
    for (; a < end; a++)
        if (phase[a] == flying) flying_tet(s, a, out);
}
