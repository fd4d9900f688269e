/* Run-time choice of the kernels' instruction set (simd.h). */
#include "simd.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

static _Atomic int chosen = -1;

static fm_simd cpu_best(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq")) return FM_SIMD_AVX512;
    if (__builtin_cpu_supports("avx2")) return FM_SIMD_AVX2;
    if (__builtin_cpu_supports("sse2")) return FM_SIMD_SSE2;
#endif
    return FM_SIMD_SCALAR;
}

static fm_simd from_environment(fm_simd best)
{
    const char *e = getenv("FM_SIMD");
    if (!e) return best;
    fm_simd want = !strcmp(e, "scalar") ? FM_SIMD_SCALAR
                   : !strcmp(e, "sse2")  ? FM_SIMD_SSE2
                   : !strcmp(e, "avx2")  ? FM_SIMD_AVX2
                                         : FM_SIMD_AVX512;
    return want < best ? want : best;
}

fm_simd fm_simd_level(void)
{
    int level = atomic_load_explicit(&chosen, memory_order_relaxed);
    if (level < 0) {
        level = (int)from_environment(cpu_best());
        atomic_store_explicit(&chosen, level, memory_order_relaxed);
    }
    return (fm_simd)level;
}

fm_simd fm_simd_set_level(fm_simd level)
{
    fm_simd best = cpu_best();
    int use = (int)(level < best ? level : best);
    atomic_store_explicit(&chosen, use, memory_order_relaxed);
    return (fm_simd)use;
}

const char *fm_simd_name(fm_simd level)
{
    static const char *const names[] = {"scalar", "sse2", "avx2", "avx512"};
    return level >= FM_SIMD_SCALAR && level <= FM_SIMD_AVX512 ? names[level] : "?";
}
