/* SIMD kernels against their scalar reference twins, bit for bit, on random inputs with the edge
 * cases: agents exactly on key points, equidistant from two key points (ties), zero vectors,
 * duplicated key points, ranges that start and end off the vector width, every phase. */
#include "kernels.h"
#include "simd.h"
#include "test_macros.h"

#include <stdlib.h>
#include <string.h>

enum { AGENTS = 1000, KEYS = 37 };

typedef struct path_case {
    float q[3][KEYS], f[3][KEYS];
    float p[3][AGENTS];
    uint8_t phase[AGENTS];
} path_case;

static void make_path_case(path_case *c, uint64_t seed)
{
    uint64_t rng = seed;
    for (int i = 0; i < KEYS; i++)
        for (int k = 0; k < 3; k++) {
            c->q[k][i] = (float)(8 * test_uniform(&rng) - 4);
            c->f[k][i] = (float)(2 * test_uniform(&rng) - 1);
        }
    for (int k = 0; k < 3; k++) c->q[k][5] = c->q[k][4]; /* a duplicated key point: a tie */
    for (int a = 0; a < AGENTS; a++) {
        for (int k = 0; k < 3; k++) c->p[k][a] = (float)(10 * test_uniform(&rng) - 5);
        c->phase[a] = (uint8_t)(test_next_u64(&rng) % 4);
    }
    for (int a = 0; a < 40; a++) { /* on a key point, the last one included (zero direction to C_T) */
        int i = a % 2 ? KEYS - 1 : (int)(test_next_u64(&rng) % KEYS);
        for (int k = 0; k < 3; k++) c->p[k][a] = c->q[k][i];
    }
    for (int a = 40; a < 60; a++) { /* midway between key points 0 and 1: an exact tie */
        for (int k = 0; k < 3; k++) c->p[k][a] = 0.5f * (c->q[k][0] + c->q[k][1]);
        c->phase[a] = 1;
    }
}

static void run_path(const path_case *c, float half_width, int64_t begin, int64_t end, float out[3][AGENTS])
{
    fm_path_view path = {{c->q[0], c->q[1], c->q[2]}, {c->f[0], c->f[1], c->f[2]}, KEYS, half_width, 2.0f};
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < AGENTS; a++) out[k][a] = -77.0f; /* untouched lanes must stay so */
    const float *p[3] = {c->p[0], c->p[1], c->p[2]};
    float *v[3] = {out[0], out[1], out[2]};
    if (fm_simd_level() == FM_SIMD_SCALAR) fm_kernel_global_velocity_ref(&path, p, c->phase, begin, end, 3.0f, v);
    else fm_kernel_global_velocity(&path, p, c->phase, begin, end, 3.0f, v);
}

static void test_path_kernel_matches_reference(void)
{
    static path_case c;
    static float want[3][AGENTS], got[3][AGENTS];
    const fm_simd best = fm_simd_set_level(FM_SIMD_AVX2);
    printf("  cpu best: %s\n", fm_simd_name(best));
    for (uint64_t seed = 1; seed <= 4; seed++) {
        make_path_case(&c, seed);
        for (int w = 0; w < 2; w++) {
            const int64_t begin = (int64_t)(seed % 5), end = AGENTS - (int64_t)(seed % 3);
            fm_simd_set_level(FM_SIMD_SCALAR);
            run_path(&c, w ? 0.5f : 0.0f, begin, end, want);
            for (int level = FM_SIMD_SSE2; level <= (int)best; level++) {
                fm_simd_set_level((fm_simd)level);
                run_path(&c, w ? 0.5f : 0.0f, begin, end, got);
                ENSURE_MSG(memcmp(want, got, sizeof want) == 0, "%s differs from the scalar reference (seed %d, width %d)",
                           fm_simd_name((fm_simd)level), (int)seed, w);
            }
        }
    }
    fm_simd_set_level(best);
}

/* The level can be forced down and never above what the CPU has. */
static void test_level_is_capped(void)
{
    fm_simd best = fm_simd_set_level(FM_SIMD_AVX2);
    ENSURE(fm_simd_set_level(FM_SIMD_SCALAR) == FM_SIMD_SCALAR);
    ENSURE(fm_simd_level() == FM_SIMD_SCALAR);
    ENSURE(fm_simd_set_level(FM_SIMD_AVX2) == best);
}

int main(void)
{
    RUN_TEST(test_level_is_capped);
    RUN_TEST(test_path_kernel_matches_reference);
    return fm_test_failures != 0;
}
