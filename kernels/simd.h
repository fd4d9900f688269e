/* One small wide-vector layer for the kernels: FM_W float lanes of the widest instruction set this
 * translation unit is compiled for (AVX-512: 16, AVX2: 8, SSE2: 4, otherwise 1).
 *
 * A kernel with a SIMD body (kernels/<name>_simd.c) is compiled three times: as it is for the
 * baseline (SSE2 on x86-64), and in the copies <name>_simd_avx2.c and <name>_simd_avx512.c that
 * CMakeLists.txt generates, which only include it again under -mavx2 and -mavx512f -mavx512dq. Its
 * entry point picks the variant at run time with FM_SIMD_PICK (fm_simd_level(), from cpuid, overridable with the environment variable
 * FM_SIMD=scalar|sse2|avx2|avx512 or fm_simd_set_level). Every kernel keeps a scalar
 * reference twin (the _ref functions) that the tests compare with: the vector bodies use the same
 * IEEE operations in the same order (no FMA contraction: -ffp-contract=off), so they match it bit
 * for bit.
 *
 * Only what the kernels use is here: loads of SoA floats, arithmetic, compares and selects. */
#ifndef FM_SIMD_H
#define FM_SIMD_H

#include <stdint.h>
#include <math.h>
#include <string.h>

typedef enum fm_simd { FM_SIMD_SCALAR = 0, FM_SIMD_SSE2 = 1, FM_SIMD_AVX2 = 2, FM_SIMD_AVX512 = 3 } fm_simd;
#define FM_SIMD_BEST FM_SIMD_AVX512

/* The level the kernels use: the best the CPU has, unless FM_SIMD or fm_simd_set_level says less. */
fm_simd fm_simd_level(void);
/* Forces a level (capped at what the CPU has); returns the level now in use. For tests, benches. */
fm_simd fm_simd_set_level(fm_simd level);
const char *fm_simd_name(fm_simd level);

#if defined(__AVX512F__) && defined(__AVX512DQ__)
#include <immintrin.h>
#define FM_W 16
/* Compares give __mmask16 here; the layer widens them to all-ones lanes, as the narrower levels
 * have them, so kernels are written once. */
typedef __m512 fv;
typedef __m512i iv;
static inline fv fv_load(const float *p) { return _mm512_loadu_ps(p); }
static inline void fv_store(float *p, fv x) { _mm512_storeu_ps(p, x); }
static inline fv fv_set1(float x) { return _mm512_set1_ps(x); }
static inline fv fv_add(fv a, fv b) { return _mm512_add_ps(a, b); }
static inline fv fv_sub(fv a, fv b) { return _mm512_sub_ps(a, b); }
static inline fv fv_mul(fv a, fv b) { return _mm512_mul_ps(a, b); }
static inline fv fv_div(fv a, fv b) { return _mm512_div_ps(a, b); }
static inline fv fv_sqrt(fv a) { return _mm512_sqrt_ps(a); }
static inline fv fv_from_mask(__mmask16 m) { return _mm512_castsi512_ps(_mm512_movm_epi32(m)); }
static inline __mmask16 fv_to_mask(fv m) { return _mm512_movepi32_mask(_mm512_castps_si512(m)); }
static inline fv fv_lt(fv a, fv b) { return fv_from_mask(_mm512_cmp_ps_mask(a, b, _CMP_LT_OQ)); }
static inline fv fv_gt(fv a, fv b) { return fv_from_mask(_mm512_cmp_ps_mask(a, b, _CMP_GT_OQ)); }
static inline fv fv_gather(const float *table, iv idx) { return _mm512_i32gather_ps(idx, table, 4); }
static inline iv iv_eq_mask(iv a, int32_t b) { return _mm512_movm_epi32(_mm512_cmpeq_epi32_mask(a, _mm512_set1_epi32(b))); }
static inline fv iv_as_mask(iv m) { return _mm512_castsi512_ps(m); }
static inline fv fv_select(fv mask, fv a, fv b) { return _mm512_mask_blend_ps(fv_to_mask(mask), b, a); }
static inline unsigned fv_mask(fv m) { return (unsigned)fv_to_mask(m); }
static inline iv iv_set1(int32_t x) { return _mm512_set1_epi32(x); }
static inline iv iv_iota(int32_t x) { return _mm512_add_epi32(_mm512_set1_epi32(x), _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)); }
static inline iv iv_select(fv mask, iv a, iv b) { return _mm512_mask_blend_epi32(fv_to_mask(mask), b, a); }
static inline void iv_store(int32_t *p, iv x) { _mm512_storeu_si512((void *)p, x); }
static inline iv iv_add(iv a, iv b) { return _mm512_add_epi32(a, b); }
static inline iv iv_and(iv a, int32_t m) { return _mm512_and_si512(a, _mm512_set1_epi32(m)); }
static inline iv iv_from_fv(fv a) { return _mm512_cvttps_epi32(a); } /* truncates */
/* table[idx] and table[idx + 1] of a byte table readable 3 bytes past idx + 1, from one gather */
static inline void iv_gather_u8_pair(const uint8_t *table, iv idx, iv *at, iv *next)
{
    const iv w = _mm512_i32gather_epi32(idx, (const void *)table, 1);
    *at = iv_and(w, 0xff), *next = iv_and(_mm512_srli_epi32(w, 8), 0xff);
}
/* table[idx] of a 16-entry table, idx in [0, 16): one register and a permute */
static inline fv fv_lookup16(const float table[16], iv idx) { return _mm512_permutexvar_ps(idx, _mm512_loadu_ps(table)); }
static inline unsigned byte_lanes_equal(const uint8_t *p, uint8_t value)
{
    __m128i b = _mm_loadu_si128((const __m128i *)p);
    return (unsigned)_mm_movemask_epi8(_mm_cmpeq_epi8(b, _mm_set1_epi8((char)value))) & 0xffffu;
}
#elif defined(__AVX2__)
#include <immintrin.h>
#define FM_W 8
typedef __m256 fv;
typedef __m256i iv;
static inline fv fv_load(const float *p) { return _mm256_loadu_ps(p); }
static inline void fv_store(float *p, fv x) { _mm256_storeu_ps(p, x); }
static inline fv fv_set1(float x) { return _mm256_set1_ps(x); }
static inline fv fv_add(fv a, fv b) { return _mm256_add_ps(a, b); }
static inline fv fv_sub(fv a, fv b) { return _mm256_sub_ps(a, b); }
static inline fv fv_mul(fv a, fv b) { return _mm256_mul_ps(a, b); }
static inline fv fv_div(fv a, fv b) { return _mm256_div_ps(a, b); }
static inline fv fv_sqrt(fv a) { return _mm256_sqrt_ps(a); }
static inline fv fv_lt(fv a, fv b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
static inline fv fv_gt(fv a, fv b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
/* table[idx[k]] in lane k */
static inline fv fv_gather(const float *table, iv idx) { return _mm256_i32gather_ps(table, idx, 4); }
static inline iv iv_eq_mask(iv a, int32_t b) { return _mm256_cmpeq_epi32(a, _mm256_set1_epi32(b)); }
static inline fv iv_as_mask(iv m) { return _mm256_castsi256_ps(m); }
/* mask ? a : b (mask lanes all ones or all zeros) */
static inline fv fv_select(fv mask, fv a, fv b) { return _mm256_blendv_ps(b, a, mask); }
/* Lane k of a compare result as bit k. */
static inline unsigned fv_mask(fv m) { return (unsigned)_mm256_movemask_ps(m); }
static inline iv iv_set1(int32_t x) { return _mm256_set1_epi32(x); }
static inline iv iv_iota(int32_t x) { return _mm256_add_epi32(_mm256_set1_epi32(x), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)); }
static inline iv iv_select(fv mask, iv a, iv b)
{
    return _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(b), _mm256_castsi256_ps(a), mask));
}
static inline void iv_store(int32_t *p, iv x) { _mm256_storeu_si256((__m256i *)p, x); }
static inline iv iv_add(iv a, iv b) { return _mm256_add_epi32(a, b); }
static inline iv iv_and(iv a, int32_t m) { return _mm256_and_si256(a, _mm256_set1_epi32(m)); }
static inline iv iv_from_fv(fv a) { return _mm256_cvttps_epi32(a); }
static inline void iv_gather_u8_pair(const uint8_t *table, iv idx, iv *at, iv *next)
{
    const iv w = _mm256_i32gather_epi32((const int *)(const void *)table, idx, 1);
    *at = iv_and(w, 0xff), *next = iv_and(_mm256_srli_epi32(w, 8), 0xff);
}
/* two 8-entry permutes and a blend on idx > 7 */
static inline fv fv_lookup16(const float table[16], iv idx)
{
    const fv lo = _mm256_permutevar8x32_ps(_mm256_loadu_ps(table), idx);
    const fv hi = _mm256_permutevar8x32_ps(_mm256_loadu_ps(table + 8), idx);
    return _mm256_blendv_ps(lo, hi, _mm256_castsi256_ps(_mm256_cmpgt_epi32(idx, _mm256_set1_epi32(7))));
}
/* Lanes whose byte equals `value`, as a bit mask (lane k = bit k). */
static inline unsigned byte_lanes_equal(const uint8_t *p, uint8_t value)
{
    __m128i b = _mm_loadl_epi64((const __m128i *)p);
    return (unsigned)_mm_movemask_epi8(_mm_cmpeq_epi8(b, _mm_set1_epi8((char)value))) & 0xffu;
}
#elif defined(__SSE2__)
#include <emmintrin.h>
#define FM_W 4
typedef __m128 fv;
typedef __m128i iv;
static inline fv fv_load(const float *p) { return _mm_loadu_ps(p); }
static inline void fv_store(float *p, fv x) { _mm_storeu_ps(p, x); }
static inline fv fv_set1(float x) { return _mm_set1_ps(x); }
static inline fv fv_add(fv a, fv b) { return _mm_add_ps(a, b); }
static inline fv fv_sub(fv a, fv b) { return _mm_sub_ps(a, b); }
static inline fv fv_mul(fv a, fv b) { return _mm_mul_ps(a, b); }
static inline fv fv_div(fv a, fv b) { return _mm_div_ps(a, b); }
static inline fv fv_sqrt(fv a) { return _mm_sqrt_ps(a); }
static inline fv fv_lt(fv a, fv b) { return _mm_cmplt_ps(a, b); }
static inline fv fv_gt(fv a, fv b) { return _mm_cmpgt_ps(a, b); }
static inline fv fv_gather(const float *table, iv idx)
{
    int32_t i[4];
    _mm_storeu_si128((__m128i *)i, idx);
    return _mm_setr_ps(table[i[0]], table[i[1]], table[i[2]], table[i[3]]);
}
static inline iv iv_eq_mask(iv a, int32_t b) { return _mm_cmpeq_epi32(a, _mm_set1_epi32(b)); }
static inline fv iv_as_mask(iv m) { return _mm_castsi128_ps(m); }
static inline fv fv_select(fv mask, fv a, fv b) { return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b)); }
static inline unsigned fv_mask(fv m) { return (unsigned)_mm_movemask_ps(m); }
static inline iv iv_set1(int32_t x) { return _mm_set1_epi32(x); }
static inline iv iv_iota(int32_t x) { return _mm_add_epi32(_mm_set1_epi32(x), _mm_setr_epi32(0, 1, 2, 3)); }
static inline iv iv_select(fv mask, iv a, iv b)
{
    __m128i m = _mm_castps_si128(mask);
    return _mm_or_si128(_mm_and_si128(m, a), _mm_andnot_si128(m, b));
}
static inline void iv_store(int32_t *p, iv x) { _mm_storeu_si128((__m128i *)p, x); }
static inline iv iv_add(iv a, iv b) { return _mm_add_epi32(a, b); }
static inline iv iv_and(iv a, int32_t m) { return _mm_and_si128(a, _mm_set1_epi32(m)); }
static inline iv iv_from_fv(fv a) { return _mm_cvttps_epi32(a); }
static inline void iv_gather_u8_pair(const uint8_t *table, iv idx, iv *at, iv *next)
{
    int32_t i[4];
    _mm_storeu_si128((__m128i *)i, idx);
    *at = _mm_setr_epi32(table[i[0]], table[i[1]], table[i[2]], table[i[3]]);
    *next = _mm_setr_epi32(table[i[0] + 1], table[i[1] + 1], table[i[2] + 1], table[i[3] + 1]);
}
static inline fv fv_lookup16(const float table[16], iv idx) { return fv_gather(table, idx); }
static inline unsigned byte_lanes_equal(const uint8_t *p, uint8_t value)
{
    int32_t word;
    memcpy(&word, p, 4);
    __m128i b = _mm_cvtsi32_si128(word);
    return (unsigned)_mm_movemask_epi8(_mm_cmpeq_epi8(b, _mm_set1_epi8((char)value))) & 0xfu;
}
#else
#define FM_W 1
typedef float fv;
typedef int32_t iv;
static inline fv fv_load(const float *p) { return *p; }
static inline void fv_store(float *p, fv x) { *p = x; }
static inline fv fv_set1(float x) { return x; }
static inline fv fv_add(fv a, fv b) { return a + b; }
static inline fv fv_sub(fv a, fv b) { return a - b; }
static inline fv fv_mul(fv a, fv b) { return a * b; }
static inline fv fv_div(fv a, fv b) { return a / b; }
static inline fv fv_sqrt(fv a) { return __builtin_sqrtf(a); }
static inline fv fv_lt(fv a, fv b) { uint32_t m = a < b ? ~0u : 0u; fv r; memcpy(&r, &m, 4); return r; }
static inline fv fv_gt(fv a, fv b) { return fv_lt(b, a); }
static inline fv fv_gather(const float *table, iv idx) { return table[idx]; }
static inline iv iv_eq_mask(iv a, int32_t b) { return a == b ? -1 : 0; }
static inline fv iv_as_mask(iv m) { fv r; memcpy(&r, &m, 4); return r; }
static inline fv fv_select(fv mask, fv a, fv b) { uint32_t m; memcpy(&m, &mask, 4); return m ? a : b; }
static inline unsigned fv_mask(fv m) { uint32_t b; memcpy(&b, &m, 4); return b != 0; }
static inline iv iv_set1(int32_t x) { return x; }
static inline iv iv_iota(int32_t x) { return x; } /* x, x + 1, ... in the lanes */
static inline iv iv_select(fv mask, iv a, iv b) { uint32_t m; memcpy(&m, &mask, 4); return m ? a : b; }
static inline void iv_store(int32_t *p, iv x) { *p = x; }
static inline iv iv_add(iv a, iv b) { return a + b; }
static inline iv iv_and(iv a, int32_t m) { return a & m; }
static inline iv iv_from_fv(fv a) { return (int32_t)a; }
static inline void iv_gather_u8_pair(const uint8_t *table, iv idx, iv *at, iv *next)
{
    *at = table[idx], *next = table[idx + 1];
}
static inline fv fv_lookup16(const float table[16], iv idx) { return table[idx]; }
static inline unsigned byte_lanes_equal(const uint8_t *p, uint8_t value) { return *p == value; }
#endif

/* Doubles: FM_WD lanes (AVX-512: 8, AVX2: 4, SSE2: 2, otherwise 1), with int32 index lanes `di`
 * beside them, for kernels whose reference works in double (the curl noise, the boids' steering, the
 * flock's frames). Only what they use: arithmetic, square root, sign, floor, min/max, conversion from
 * floats, gathers from small tables. */
#if defined(__AVX512F__) && defined(__AVX512DQ__)
#define FM_WD 8
typedef __m512d dv;
typedef __m256i di;
static inline dv dv_set1(double x) { return _mm512_set1_pd(x); }
static inline dv dv_add(dv a, dv b) { return _mm512_add_pd(a, b); }
static inline dv dv_sub(dv a, dv b) { return _mm512_sub_pd(a, b); }
static inline dv dv_mul(dv a, dv b) { return _mm512_mul_pd(a, b); }
/* a > b ? a : b and a < b ? a : b (b when a is NaN), as the x86 instructions define them */
static inline dv dv_max(dv a, dv b) { return _mm512_max_pd(a, b); }
static inline dv dv_min(dv a, dv b) { return _mm512_min_pd(a, b); }
static inline dv dv_floor(dv a) { return _mm512_roundscale_pd(a, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC); }
static inline dv dv_from_floats(const float *p) { return _mm512_cvtps_pd(_mm256_loadu_ps(p)); }
static inline void dv_store(double *p, dv x) { _mm512_storeu_pd(p, x); }
static inline dv dv_load(const double *p) { return _mm512_loadu_pd(p); }
static inline dv dv_sqrt(dv a) { return _mm512_sqrt_pd(a); }
/* |x| with the sign of s, as copysign */
static inline dv dv_copysign(dv x, dv s)
{
    const __m512d sign = _mm512_set1_pd(-0.0);
    return _mm512_or_pd(_mm512_andnot_pd(sign, x), _mm512_and_pd(sign, s));
}
static inline dv dv_neg(dv x) { return _mm512_xor_pd(x, _mm512_set1_pd(-0.0)); }
static inline di di_from_dv(dv a) { return _mm512_cvttpd_epi32(a); } /* truncates */
static inline di di_add(di a, di b) { return _mm256_add_epi32(a, b); }
static inline di di_and(di a, int32_t m) { return _mm256_and_si256(a, _mm256_set1_epi32(m)); }
static inline di di_set1(int32_t x) { return _mm256_set1_epi32(x); }
/* table[idx] of a byte table readable 3 bytes past its last index */
static inline di di_gather_u8(const uint8_t *table, di idx)
{
    return di_and(_mm256_i32gather_epi32((const int *)(const void *)table, idx, 1), 0xff);
}
/* table[idx] and table[idx + 1] from one gather (its 32 bits hold both) */
static inline void di_gather_u8_pair(const uint8_t *table, di idx, di *at, di *next)
{
    const di w = _mm256_i32gather_epi32((const int *)(const void *)table, idx, 1);
    *at = di_and(w, 0xff), *next = di_and(_mm256_srli_epi32(w, 8), 0xff);
}
static inline dv dv_gather(const double *table, di idx) { return _mm512_i32gather_pd(idx, table, 8); }
/* table[idx] of a 16-entry table, idx in [0, 16): two registers and a permute, not a gather (a
 * gather of 8 doubles costs several times a permute on this machine's Zen) */
static inline dv dv_lookup16(const double table[16], di idx)
{
    return _mm512_permutex2var_pd(_mm512_loadu_pd(table), _mm512_cvtepi32_epi64(idx), _mm512_loadu_pd(table + 8));
}
static inline dv dv_div(dv a, dv b) { return _mm512_div_pd(a, b); }
static inline dv dv_from_ints(const int32_t *p) { return _mm512_cvtepi32_pd(_mm256_loadu_si256((const __m256i *)p)); }
/* rounds to float as a C cast does (to nearest) */
static inline void dv_store_floats(float *p, dv x) { _mm256_storeu_ps(p, _mm512_cvtpd_ps(x)); }
typedef __mmask8 dm;
static inline dm dv_le(dv a, dv b) { return _mm512_cmp_pd_mask(a, b, _CMP_LE_OQ); }
static inline dm dv_gt(dv a, dv b) { return _mm512_cmp_pd_mask(a, b, _CMP_GT_OQ); }
static inline dv dv_blend(dm m, dv a, dv b) { return _mm512_mask_blend_pd(m, b, a); } /* m ? a : b */
#elif defined(__AVX2__)
#define FM_WD 4
typedef __m256d dv;
typedef __m128i di;
static inline dv dv_set1(double x) { return _mm256_set1_pd(x); }
static inline dv dv_add(dv a, dv b) { return _mm256_add_pd(a, b); }
static inline dv dv_sub(dv a, dv b) { return _mm256_sub_pd(a, b); }
static inline dv dv_mul(dv a, dv b) { return _mm256_mul_pd(a, b); }
static inline dv dv_max(dv a, dv b) { return _mm256_max_pd(a, b); }
static inline dv dv_min(dv a, dv b) { return _mm256_min_pd(a, b); }
static inline dv dv_floor(dv a) { return _mm256_floor_pd(a); }
static inline dv dv_from_floats(const float *p) { return _mm256_cvtps_pd(_mm_loadu_ps(p)); }
static inline void dv_store(double *p, dv x) { _mm256_storeu_pd(p, x); }
static inline dv dv_load(const double *p) { return _mm256_loadu_pd(p); }
static inline dv dv_sqrt(dv a) { return _mm256_sqrt_pd(a); }
static inline dv dv_copysign(dv x, dv s)
{
    const __m256d sign = _mm256_set1_pd(-0.0);
    return _mm256_or_pd(_mm256_andnot_pd(sign, x), _mm256_and_pd(sign, s));
}
static inline dv dv_neg(dv x) { return _mm256_xor_pd(x, _mm256_set1_pd(-0.0)); }
static inline di di_from_dv(dv a) { return _mm256_cvttpd_epi32(a); }
static inline di di_add(di a, di b) { return _mm_add_epi32(a, b); }
static inline di di_and(di a, int32_t m) { return _mm_and_si128(a, _mm_set1_epi32(m)); }
static inline di di_set1(int32_t x) { return _mm_set1_epi32(x); }
static inline di di_gather_u8(const uint8_t *table, di idx)
{
    return di_and(_mm_i32gather_epi32((const int *)(const void *)table, idx, 1), 0xff);
}
static inline void di_gather_u8_pair(const uint8_t *table, di idx, di *at, di *next)
{
    const di w = _mm_i32gather_epi32((const int *)(const void *)table, idx, 1);
    *at = di_and(w, 0xff), *next = di_and(_mm_srli_epi32(w, 8), 0xff);
}
static inline dv dv_gather(const double *table, di idx) { return _mm256_i32gather_pd(table, idx, 8); }
static inline dv dv_lookup16(const double table[16], di idx) { return dv_gather(table, idx); }
static inline dv dv_div(dv a, dv b) { return _mm256_div_pd(a, b); }
static inline dv dv_from_ints(const int32_t *p) { return _mm256_cvtepi32_pd(_mm_loadu_si128((const __m128i *)p)); }
static inline void dv_store_floats(float *p, dv x) { _mm_storeu_ps(p, _mm256_cvtpd_ps(x)); }
typedef __m256d dm;
static inline dm dv_le(dv a, dv b) { return _mm256_cmp_pd(a, b, _CMP_LE_OQ); }
static inline dm dv_gt(dv a, dv b) { return _mm256_cmp_pd(a, b, _CMP_GT_OQ); }
static inline dv dv_blend(dm m, dv a, dv b) { return _mm256_blendv_pd(b, a, m); }
#else
/* SSE2 has no floor and no gathers, and the scalar build no vectors: lanes in plain arrays, which
 * the compiler keeps in registers where it can. */
#define FM_WD 2
typedef struct { double l[FM_WD]; } dv;
typedef struct { int32_t l[FM_WD]; } di;
#define FM_DV_MAP(expr)                                  \
    dv r;                                                \
    for (int k = 0; k < FM_WD; k++) r.l[k] = (expr);     \
    return r
#define FM_DI_MAP(expr)                                  \
    di r;                                                \
    for (int k = 0; k < FM_WD; k++) r.l[k] = (expr);     \
    return r
static inline dv dv_set1(double x) { FM_DV_MAP(x); }
static inline dv dv_add(dv a, dv b) { FM_DV_MAP(a.l[k] + b.l[k]); }
static inline dv dv_sub(dv a, dv b) { FM_DV_MAP(a.l[k] - b.l[k]); }
static inline dv dv_mul(dv a, dv b) { FM_DV_MAP(a.l[k] * b.l[k]); }
static inline dv dv_max(dv a, dv b) { FM_DV_MAP(a.l[k] > b.l[k] ? a.l[k] : b.l[k]); }
static inline dv dv_min(dv a, dv b) { FM_DV_MAP(a.l[k] < b.l[k] ? a.l[k] : b.l[k]); }
/* exact for |a| < 2^63 (the callers clamp) */
static inline dv dv_floor(dv a) { FM_DV_MAP((double)(int64_t)a.l[k] - (a.l[k] < (double)(int64_t)a.l[k])); }
static inline dv dv_from_floats(const float *p) { FM_DV_MAP((double)p[k]); }
static inline void dv_store(double *p, dv x) { memcpy(p, x.l, sizeof x.l); }
static inline dv dv_load(const double *p) { FM_DV_MAP(p[k]); }
static inline dv dv_sqrt(dv a) { FM_DV_MAP(sqrt(a.l[k])); }
static inline dv dv_copysign(dv x, dv s) { FM_DV_MAP(copysign(x.l[k], s.l[k])); }
static inline dv dv_neg(dv x) { FM_DV_MAP(-x.l[k]); }
static inline di di_from_dv(dv a) { FM_DI_MAP((int32_t)a.l[k]); }
static inline di di_add(di a, di b) { FM_DI_MAP(a.l[k] + b.l[k]); }
static inline di di_and(di a, int32_t m) { FM_DI_MAP(a.l[k] & m); }
static inline di di_set1(int32_t x) { FM_DI_MAP(x); }
static inline di di_gather_u8(const uint8_t *table, di idx) { FM_DI_MAP(table[idx.l[k]]); }
static inline void di_gather_u8_pair(const uint8_t *table, di idx, di *at, di *next)
{
    *at = di_gather_u8(table, idx), *next = di_gather_u8(table, di_add(idx, di_set1(1)));
}
static inline dv dv_gather(const double *table, di idx) { FM_DV_MAP(table[idx.l[k]]); }
static inline dv dv_lookup16(const double table[16], di idx) { return dv_gather(table, idx); }
static inline dv dv_div(dv a, dv b) { FM_DV_MAP(a.l[k] / b.l[k]); }
static inline dv dv_from_ints(const int32_t *p) { FM_DV_MAP((double)p[k]); }
static inline void dv_store_floats(float *p, dv x)
{
    for (int k = 0; k < FM_WD; k++) p[k] = (float)x.l[k];
}
typedef di dm; /* lanes all ones or zero */
static inline dm dv_le(dv a, dv b) { FM_DI_MAP(a.l[k] <= b.l[k] ? -1 : 0); }
static inline dm dv_gt(dv a, dv b) { FM_DI_MAP(a.l[k] > b.l[k] ? -1 : 0); }
static inline dv dv_blend(dm m, dv a, dv b) { FM_DV_MAP(m.l[k] ? a.l[k] : b.l[k]); }
#undef FM_DV_MAP
#undef FM_DI_MAP
#endif

/* Names a SIMD variant of a kernel: <name>_avx512 and <name>_avx2 in the -mavx512f and -mavx2
 * copies (whose wrappers define FM_SIMD_AVX512_COPY or FM_SIMD_AVX2_COPY), <name>_base in the
 * baseline one (SSE2 on x86-64, wider with FM_NATIVE). */
/* Declares the three variants of a kernel whose function type is `type`. */
#define FM_SIMD_DECLARE(type, name) type name##_base, name##_avx2, name##_avx512

/* The variant of kernel `name` for the level the kernels use (fm_simd_level()); NULL at the scalar
 * level, where the caller runs the kernel's reference twin. The one dispatch of every kernel. */
#define FM_SIMD_PICK(name)                                                                     \
    (fm_simd_level() == FM_SIMD_AVX512 ? name##_avx512                                          \
     : fm_simd_level() == FM_SIMD_AVX2 ? name##_avx2                                            \
     : fm_simd_level() == FM_SIMD_SSE2 ? name##_base : NULL)

#if defined(FM_SIMD_AVX512_COPY)
#define FM_SIMD_VARIANT(name) name##_avx512
#elif defined(FM_SIMD_AVX2_COPY)
#define FM_SIMD_VARIANT(name) name##_avx2
#else
#define FM_SIMD_VARIANT(name) name##_base
#endif

#endif
