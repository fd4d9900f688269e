/* What bench_suite's two modes share: the options, the repetitions, the state hash and the peak
 * memory. bench_suite.c holds main and the tetra morph's mode (--mode morph), suite_flock.h the
 * shape flock's (--mode flock). */
#ifndef FM_BENCH_SUITE_H
#define FM_BENCH_SUITE_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

enum { SUITE_MAX_SIZES = 8 };

typedef enum suite_mode { SUITE_MORPH, SUITE_FLOCK } suite_mode;

typedef struct suite_options {
    suite_mode mode;
    long agents[SUITE_MAX_SIZES];
    int agent_count;
    long steps, threads;
    int scenarios, machine;
    int sampling;             /* flock: an fm_flock_sampling, or -1 for the scene's own */
    int density_sweep;        /* flock: throughput against the mean neighbour count (suite_flock.h) */
    char scene[4096];
} suite_options;

/* FNV-1a, so runs can be compared bit for bit. */
static inline uint64_t suite_fnv(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

static const uint64_t SUITE_FNV_BASIS = 0xcbf29ce484222325ull;

/* Repetitions of the S timed steps for n agents: enough for about 5 * 10^6 agent-steps in all, so a
 * small n is not timed over a few milliseconds; the fastest repetition counts. */
static inline long suite_repetitions(int64_t n, long steps)
{
    long reps = (long)ceil(5e6 / ((double)n * (double)steps));
    return reps < 1 ? 1 : reps > 25 ? 25 : reps;
}

/* One repetition: fills `result` (a mode's own struct) and returns its wall seconds and the hash of
 * the state it ended in; nonzero on failure. */
typedef int (*suite_once_fn)(void *ctx, void *result, double *seconds, uint64_t *hash);

/* The fastest of `reps` repetitions into `best`, `scratch` the same size; *hash is the common end
 * state's hash, or 0 when the repetitions disagreed (reported as not deterministic). */
static inline int suite_fastest(long reps, suite_once_fn once, void *ctx, void *best, void *scratch, size_t size,
                                uint64_t *hash)
{
    double fastest = INFINITY;
    uint64_t first = 0;
    int same = 1;
    for (long rep = 0; rep < reps; rep++) {
        double seconds;
        uint64_t h;
        if (once(ctx, scratch, &seconds, &h)) return -1;
        if (rep == 0) first = h;
        same &= h == first;
        if (seconds < fastest) {
            fastest = seconds;
            memcpy(best, scratch, size);
        }
    }
    *hash = same ? first : 0;
    return 0;
}

/* Peak resident memory of the process per agent (VmHWM from /proc/self/status). */
static inline double suite_bytes_per_agent(int64_t n)
{
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    double kb = NAN;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "VmHWM: %lf kB", &kb) == 1) break;
    if (f) fclose(f);
    return 1024.0 * kb / (double)n;
}

#endif
