/* Minimal test macros in the style of Box2D's test/test_macros.h: each failed check prints
 * where and why and marks the test failed; the test's main returns test_result(). */
#ifndef FM_TEST_MACROS_H
#define FM_TEST_MACROS_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static int fm_test_failures = 0;

#define ENSURE(cond)                                                                       \
    do {                                                                                   \
        if (!(cond)) {                                                                     \
            fprintf(stderr, "%s:%d: ENSURE(%s) failed\n", __FILE__, __LINE__, #cond);      \
            fm_test_failures++;                                                            \
        }                                                                                  \
    } while (0)

#define ENSURE_MSG(cond, ...)                                                              \
    do {                                                                                   \
        if (!(cond)) {                                                                     \
            fprintf(stderr, "%s:%d: ENSURE(%s) failed: ", __FILE__, __LINE__, #cond);      \
            fprintf(stderr, __VA_ARGS__);                                                  \
            fputc('\n', stderr);                                                           \
            fm_test_failures++;                                                            \
        }                                                                                  \
    } while (0)

/* |a - b| <= tol */
#define ENSURE_NEAR(a, b, tol)                                                             \
    do {                                                                                   \
        double fm_a_ = (double)(a), fm_b_ = (double)(b), fm_t_ = (double)(tol);            \
        if (!(fabs(fm_a_ - fm_b_) <= fm_t_)) {                                             \
            fprintf(stderr, "%s:%d: ENSURE_NEAR(%s, %s, %s) failed: %.17g vs %.17g\n",     \
                    __FILE__, __LINE__, #a, #b, #tol, fm_a_, fm_b_);                       \
            fm_test_failures++;                                                            \
        }                                                                                  \
    } while (0)

/* Seconds of wall time since an arbitrary start (C11's timespec_get). */
static inline double test_wall_seconds(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* 1 unless FM_TEST_ONLY, a comma-separated list of case names, is set and does not name `name`:
 * FM_TEST_ONLY=test_shot_run build/tests/test_cli runs that case alone, while working on it (a
 * case may need files an earlier one wrote). */
static inline int fm_test_selected(const char *name)
{
    const char *only = getenv("FM_TEST_ONLY");
    if (!only || !*only) return 1;
    const size_t len = strlen(name);
    for (const char *at = strstr(only, name); at; at = strstr(at + 1, name))
        if ((at == only || at[-1] == ',') && (at[len] == ',' || at[len] == 0)) return 1;
    return 0;
}

/* Runs one test function, unless FM_TEST_ONLY leaves it out, and prints its verdict and wall time
 * (where a suite's time goes, docs/testing.md). */
#define RUN_TEST(fn)                                                                       \
    do {                                                                                   \
        if (!fm_test_selected(#fn)) break;                                                 \
        int fm_before_ = fm_test_failures;                                                 \
        double fm_start_ = test_wall_seconds();                                            \
        fn();                                                                              \
        printf("%-40s %s %7.2f s\n", #fn, fm_test_failures == fm_before_ ? "ok" : "FAILED",  \
               test_wall_seconds() - fm_start_);                                           \
        fflush(stdout);                                                                    \
    } while (0)

/* splitmix64: deterministic, so a failure reproduces. */
static inline uint64_t test_next_u64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* test_next_u64 mapped to [0, 1). */
static inline double test_uniform(uint64_t *state)
{
    return (double)(test_next_u64(state) >> 11) / 9007199254740992.0;
}

static inline int test_result(void) { return fm_test_failures == 0 ? 0 : 1; }

#endif
