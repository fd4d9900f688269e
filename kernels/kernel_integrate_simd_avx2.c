/* The AVX2 copy of kernel_integrate_simd.c (compiled with -mavx2; see simd.h). */
#define FM_SIMD_AVX2_COPY 1
#include "kernel_integrate_simd.c"
