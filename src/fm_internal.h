/* Internal helpers shared by the engine's source files: errors, aligned memory, clocks. */
#ifndef FM_INTERNAL_H
#define FM_INTERNAL_H

#include "flockmorph/flockmorph.h"

#include <stdarg.h>
#include <stddef.h>

#define FM_ALIGN 64

/* Records status and a printf-style message in err (if not NULL) and returns status. */
fm_status fm_fail(fm_error *err, fm_status status, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* 64-byte aligned, zero-filled; size rounded up to a multiple of 64. NULL on failure. */
void *fm_alloc(size_t bytes);
void fm_free(void *p);

/* Seconds from a monotonic clock. */
double fm_seconds(void);

#define FM_MIN(a, b) ((a) < (b) ? (a) : (b))
#define FM_MAX(a, b) ((a) > (b) ? (a) : (b))

#endif
