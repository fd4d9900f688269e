/* The engine's thread count (fm_internal.h): apart from fm_util.c so that the reader-only library,
 * which compiles fm_util.c, needs no OpenMP. */
#include "fm_internal.h"

#include <omp.h>

int fm_threads(int requested)
{
    if (requested > 0) return requested < FM_MAX_THREADS ? requested : FM_MAX_THREADS;
    int n = omp_get_max_threads(), cap = FM_THREADS_PER_CORE * omp_get_num_procs();
    if (cap > FM_MAX_THREADS) cap = FM_MAX_THREADS;
    return n < 1 ? 1 : n < cap ? n : cap;
}
