/* The AVX-512 copy of kernel_integrate_simd.c (compiled with -mavx512f -mavx512dq; see simd.h). */
#define FM_SIMD_AVX512_COPY 1
#include "kernel_integrate_simd.c"
