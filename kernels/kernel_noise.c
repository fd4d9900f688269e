/* The direct style velocity (kernel_noise.h): the scalar reference and the dispatch; the SIMD
 * variants are in kernel_noise_simd.c. */
#include "kernel_noise.h"

void fm_kernel_curl_add_ref(const fm_curl_view *f, const float *const p[3], const uint8_t *phase, uint8_t flying,
                            int64_t begin, int64_t end, float *const v[3])
{
    for (int64_t a = begin; a < end; a++)
        if (phase[a] == flying) curl_add_agent(f, p, a, v);
}

void fm_kernel_curl_add(const fm_curl_view *f, const float *const p[3], const uint8_t *phase, uint8_t flying,
                        int64_t begin, int64_t end, float *const v[3])
{
    fm_curl_add_fn *variant = FM_SIMD_PICK(fm_kernel_curl_add);
    (variant ? variant : fm_kernel_curl_add_ref)(f, p, phase, flying, begin, end, v);
}
