/* Internal helpers shared by the engine's source files: errors, aligned memory, clocks. */
#ifndef FM_INTERNAL_H
#define FM_INTERNAL_H

#include "flockmorph/flockmorph.h"

#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>

#define FM_ALIGN 64

/* Records status and a printf-style message in err (if not NULL) and returns status. */
fm_status fm_fail(fm_error *err, fm_status status, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* 64-byte aligned, zero-filled; size rounded up to a multiple of 64. NULL on failure. */
void *fm_alloc(size_t bytes);
void fm_free(void *p);

/* A file written as PATH.partial and renamed to PATH only when complete, so a file under its
 * final name is never half-written. */
typedef struct fm_output_file {
    FILE *f;
    char path[FM_PATH_MAX];
    char partial[FM_PATH_MAX + 16];
} fm_output_file;

fm_status fm_output_open(fm_output_file *o, const char *path, fm_error *err);
/* Checks for write errors, flushes to disk, closes and renames; on any failure removes the
 * partial file and reports `detail` (if not NULL or empty) or the errno text. */
fm_status fm_output_commit(fm_output_file *o, const char *detail, fm_error *err);
void fm_output_discard(fm_output_file *o);
/* Reopens the PATH.partial an interrupted writer left, keeps its first `keep` bytes and positions
 * at their end, to continue writing (resume). */
fm_status fm_output_reopen(fm_output_file *o, const char *path, uint64_t keep, fm_error *err);

/* Seconds from a monotonic clock. */
double fm_seconds(void);

#define FM_MIN(a, b) ((a) < (b) ? (a) : (b))
#define FM_MAX(a, b) ((a) > (b) ? (a) : (b))

#endif
