/* The AVX2 copy of kernel_path_simd.c (compiled with -mavx2; see simd.h). */
#define FM_SIMD_AVX2_COPY 1
#include "kernel_path_simd.c"
