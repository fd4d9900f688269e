/* The engine's thread count (fm_internal.h): apart from fm_util.c so that the reader-only library,
 * which compiles fm_util.c, needs no OpenMP. */
#include "fm_internal.h"

#include <omp.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

int fm_threads(int requested)
{
    if (requested > 0) return requested < FM_MAX_THREADS ? requested : FM_MAX_THREADS;
    int n = omp_get_max_threads(), cap = FM_THREADS_PER_CORE * omp_get_num_procs();
    if (cap > FM_MAX_THREADS) cap = FM_MAX_THREADS;
    return n < 1 ? 1 : n < cap ? n : cap;
}

static void *thread_probe(void *arg) { return arg; }

int fm_threads_start_team(int threads)
{
    const char *stack = getenv("OMP_STACKSIZE");
    if (threads <= 1 || (stack && *stack)) return 0;
    pthread_t t[FM_MAX_THREADS];
    int started = 0, e = 0;
    while (started < threads - 1 && started < FM_MAX_THREADS && (e = pthread_create(&t[started], NULL, thread_probe, NULL)) == 0)
        started++;
    for (int i = 0; i < started; i++) pthread_join(t[i], NULL);
    if (e) return e;
#pragma omp parallel num_threads(threads)
    (void)0; /* the team, kept for later regions */
    return 0;
}

void fm_copy_parallel(void *dst, const void *src, size_t bytes, int threads)
{
    if (threads <= 1 || bytes < ((size_t)1 << 16)) {
        memcpy(dst, src, bytes);
        return;
    }
#pragma omp parallel num_threads(threads)
    {
        const size_t parts = (size_t)omp_get_num_threads(), part = (size_t)omp_get_thread_num();
        const size_t lines = (bytes + 63) / 64, lo = lines * part / parts * 64, hi = lines * (part + 1) / parts * 64;
        if (lo < bytes) memcpy((char *)dst + lo, (const char *)src + lo, (hi < bytes ? hi : bytes) - lo);
    }
}
