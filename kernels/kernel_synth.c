/* Phase 1's tets (kernel_synth.h): the scalar reference and the dispatch; the SIMD variants are in
 * kernel_synth_simd.c. */
#include "kernel_synth.h"

void fm_kernel_flying_tets_ref(const fm_synth_view *s, const uint8_t *phase, uint8_t flying, int64_t begin,
                               int64_t end, float *out)
{
    for (int64_t a = begin; a < end; a++)
        if (phase[a] == flying) flying_tet(s, a, out);
}

void fm_kernel_flying_tets(const fm_synth_view *s, const uint8_t *phase, uint8_t flying, int64_t begin,
                           int64_t end, float *out)
{
    fm_flying_tets_fn *variant = FM_SIMD_PICK(fm_kernel_flying_tets);
    (variant ? variant : fm_kernel_flying_tets_ref)(s, phase, flying, begin, end, out);
}
