/* The machine's limits, measured in the benchmark's own run, and the step's cost model: the bytes
 * and floating-point operations of one agent-step, counted kernel by kernel from the code (the
 * counts are documented in docs/performance.md). Header-only: only bench_suite uses it. */
#ifndef FM_BENCH_ROOFLINE_H
#define FM_BENCH_ROOFLINE_H

#include "morph.h"

#include <immintrin.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <string.h>

typedef struct fm_machine {
    char cpu[128];
    double triad_gbps;   /* STREAM triad a = b + s c on 3 × 128 MiB of doubles, best of 5 */
    double peak_gflops;  /* 2 flops per lane per fused multiply-add, 16 lanes (AVX-512) or 8 (AVX2 + FMA) */
    double clock_ghz;    /* one thread's cycles a second: dependent integer additions, best of 3 */
} fm_machine;

static void machine_cpu_name(char *out, size_t size)
{
    snprintf(out, size, "unknown");
    FILE *f = fopen("/proc/cpuinfo", "r");
    char line[512];
    while (f && fgets(line, sizeof line, f)) {
        if (strncmp(line, "model name", 10) != 0) continue;
        const char *v = strchr(line, ':');
        if (v) snprintf(out, size, "%s", v + 2);
        out[strcspn(out, "\n")] = 0;
        break;
    }
    if (f) fclose(f);
}

static double stream_triad_gbps(int threads)
{
    const size_t n = (size_t)1 << 24;
    double *a = fm_alloc(n * sizeof(double)), *b = fm_alloc(n * sizeof(double)), *c = fm_alloc(n * sizeof(double));
    if (!a || !b || !c) return fm_free(a), fm_free(b), fm_free(c), NAN;
#pragma omp parallel for num_threads(threads) schedule(static)
    for (size_t i = 0; i < n; i++) a[i] = 0, b[i] = 1, c[i] = 2; /* first touch by the same threads */
    double best = INFINITY;
    for (int rep = 0; rep < 5; rep++) {
        double t0 = fm_seconds();
#pragma omp parallel for num_threads(threads) schedule(static)
        for (size_t i = 0; i < n; i++) a[i] = b[i] + 3.0 * c[i];
        best = fmin(best, fm_seconds() - t0);
    }
    double check = a[n / 2];
    fm_free(a), fm_free(b), fm_free(c);
    return check == 7.0 ? 3.0 * sizeof(double) * (double)n / best / 1e9 : NAN; /* STREAM counts 3 words */
}

/* 12 independent FMA chains per thread hide the latency; the sum is printed nowhere but kept. */
__attribute__((target("avx2,fma"))) static double fma_flops(long iterations)
{
    __m256 acc[12];
    for (int k = 0; k < 12; k++) acc[k] = _mm256_set1_ps((float)k);
    const __m256 mul = _mm256_set1_ps(0.999999f), add = _mm256_set1_ps(1e-7f);
    for (long i = 0; i < iterations; i++)
        for (int k = 0; k < 12; k++) acc[k] = _mm256_fmadd_ps(acc[k], mul, add);
    float out[8], sum = 0;
    for (int k = 0; k < 12; k++) {
        _mm256_storeu_ps(out, acc[k]);
        for (int j = 0; j < 8; j++) sum += out[j];
    }
    return sum;
}

/* The same with 512-bit vectors, for a CPU with AVX-512 (the kernels use it there). */
__attribute__((target("avx512f"))) static double fma_flops_512(long iterations)
{
    __m512 acc[12];
    for (int k = 0; k < 12; k++) acc[k] = _mm512_set1_ps((float)k);
    const __m512 mul = _mm512_set1_ps(0.999999f), add = _mm512_set1_ps(1e-7f);
    for (long i = 0; i < iterations; i++)
        for (int k = 0; k < 12; k++) acc[k] = _mm512_fmadd_ps(acc[k], mul, add);
    float sum = 0;
    for (int k = 0; k < 12; k++) sum += _mm512_reduce_add_ps(acc[k]);
    return sum;
}

/* The widest FMA the CPU has, on every thread at once, best of 3. */
static double peak_gflops(int threads)
{
    const int wide = __builtin_cpu_supports("avx512f");
    if (!wide && !__builtin_cpu_supports("fma")) return NAN;
    const long iterations = 20000000;
    const double lanes = wide ? 16 : 8;
    double best = INFINITY, sink = 0;
    for (int rep = 0; rep < 3; rep++) {
        double t0 = fm_seconds();
#pragma omp parallel num_threads(threads) reduction(+ : sink)
        sink += wide ? fma_flops_512(iterations) : fma_flops(iterations);
        best = fmin(best, fm_seconds() - t0);
    }
    if (sink == 12345.678) printf(" "); /* keeps the loop */
    return 2.0 * lanes * 12 * (double)iterations * threads / best / 1e9;
}

/* A chain of dependent additions retires one a cycle on any x86-64 core, whatever else it can issue:
 * additions a second are the clock the steps see (turbo included), which this VM's missing
 * performance counters would otherwise give. */
static double clock_ghz(void)
{
    const long additions = 400000000;
    double best = INFINITY;
    long x = 0;
    for (int rep = 0; rep < 3; rep++) {
        double t0 = fm_seconds();
        for (long i = 0; i < additions; i += 4) __asm__ volatile("add $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\tadd $1, %0" : "+r"(x));
        best = fmin(best, fm_seconds() - t0);
    }
    return x == 3 * additions ? (double)additions / best / 1e9 : NAN;
}

static fm_machine fm_measure_machine(int threads)
{
    fm_machine m;
    machine_cpu_name(m.cpu, sizeof m.cpu);
    m.triad_gbps = stream_triad_gbps(threads);
    m.peak_gflops = peak_gflops(threads);
    m.clock_ghz = clock_ghz();
    return m;
}

/* One agent-step's traffic and arithmetic. Bytes: the SoA arrays each kernel streams (reads and
 * writes), plus one 64-byte line per random lookup (field grid corners, distance grid, the MDE
 * grid's rows), which is the cost of a miss; with the store re-sorted most of those hit the cache,
 * so the byte count is an upper bound on DRAM traffic. Flops: adds, multiplies, divides, square
 * roots and compares of the arithmetic, per flying agent. */
typedef struct fm_cost {
    double bytes, flops;
} fm_cost;

static fm_cost fm_step_cost(const fm_morph_model *m, const double *stage_ns)
{
    (void)stage_ns;
    const double keys = m->key_count;
    fm_cost c = {0, 0};
    c.bytes += 12 + 1 + 12, c.flops += 9 * keys + 10;                       /* path, eq 3 */
    if (m->def.field_count > 0) c.bytes += 12 + 1 + 24 + 2 * 64, c.flops += 95; /* baked field, trilinear */
    /* d_t once at the centroid, kept with R_X (8 B written, 8 read) for the contact step; the look-ahead
     * sample of eq 8 only near obstacles, which the model leaves out as rare */
    if (m->obstacles) c.bytes += 12 + 24 + 64 + 16, c.flops += 75;
    if (m->def.d_min > 0) {
        c.bytes += 12 + 1 + 4 + 2 * 20 + 16;                                  /* grid build (counting sort) */
        c.bytes += 12 + 1 + 24 + 12 + 1 + 3 * 64, c.flops += 27 * 9 + 20;    /* MDE walk, ~1 agent per cell */
    }
    c.bytes += 24 + 12 + 1 + 1, c.flops += 14;                               /* move + phase switch */
    c.bytes += 12 + 1 + 4 + 48 + 48, c.flops += 29;                          /* synthesis of 4 vertices */
    c.bytes += 2.0 * (36 + 4 + 1 + 8 + 8 + 16 + 2 + 8) / FM_RESORT_INTERVAL; /* re-sort, amortised */
    return c;
}

typedef struct fm_roofline {
    double gbps, gflops, fraction;
    const char *bound;
} fm_roofline;

static fm_roofline fm_roofline_of(const fm_cost *c, double agent_steps_per_second, const fm_machine *mc)
{
    fm_roofline r;
    r.gbps = c->bytes * agent_steps_per_second / 1e9;
    r.gflops = c->flops * agent_steps_per_second / 1e9;
    double fb = mc->triad_gbps > 0 ? r.gbps / mc->triad_gbps : 0, ff = mc->peak_gflops > 0 ? r.gflops / mc->peak_gflops : 0;
    r.fraction = fmax(fb, ff);
    r.bound = fb >= ff ? "memory bandwidth" : "floating point";
    return r;
}

#endif
