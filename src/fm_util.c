#define _POSIX_C_SOURCE 200809L
#include "fm_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

fm_status fm_fail(fm_error *err, fm_status status, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
        err->status = status;
    }
    return status;
}

void *fm_alloc(size_t bytes)
{
    size_t rounded = (bytes + FM_ALIGN - 1) / FM_ALIGN * FM_ALIGN;
    if (rounded == 0) rounded = FM_ALIGN;
    void *p = aligned_alloc(FM_ALIGN, rounded);
    if (p) memset(p, 0, rounded);
    return p;
}

void fm_free(void *p) { free(p); }

double fm_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
