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
    int keep_partial_on_failure; /* commit leaves PATH.partial when it fails (the frame cache: its
                                    complete frames stay readable) */
} fm_output_file;

fm_status fm_output_open(fm_output_file *o, const char *path, fm_error *err);
/* Checks for write errors, flushes to disk, closes and renames; on any failure removes the
 * partial file and reports `detail` (if not NULL or empty) or the errno text. */
fm_status fm_output_commit(fm_output_file *o, const char *detail, fm_error *err);
void fm_output_discard(fm_output_file *o);
/* Closes PATH.partial and leaves it on disk (a cache that stopped early stays readable). */
void fm_output_keep_partial(fm_output_file *o);

/* A user's input file (scene, mesh): FM_OK if it can be opened for reading; otherwise
 * FM_ERR_INPUT with "PATH: cannot open the <what>: <reason>" (missing, a directory, permission
 * denied), or FM_ERR_IO for a failure the user did not cause. */
fm_status fm_check_input_file(const char *path, const char *what, fm_error *err);

/* What the user can do about a failed write with this errno ("" if nothing specific): disk full,
 * file-size limit, read-only file system. */
const char *fm_write_hint(int errnum);

/* scene.c: "FILE:LINE:COL: key" for a key of the loaded scene (a dotted path, list elements as
 * "obstacles.meshes[1]"), found by reading the scene file again; "FILE: key" when it cannot be
 * located, "key" for a definition built in code. For errors found after loading (model build). */
void fm_scene_key_location(const fm_scene_def *def, const char *key, char *out, size_t size);

/* Seconds from a monotonic clock. */
double fm_seconds(void);

#define FM_MIN(a, b) ((a) < (b) ? (a) : (b))
#define FM_MAX(a, b) ((a) > (b) ? (a) : (b))

#endif
