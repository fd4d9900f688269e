/* Internal helpers shared by the engine's source files: errors, aligned memory, clocks. */
#ifndef FM_INTERNAL_H
#define FM_INTERNAL_H

#include "flockmorph/flockmorph.h"

#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#define FM_ALIGN 64

/* The block scheduler: a mode's agents are split into blocks of FM_BLOCK, handed to OpenMP
 * threads; per-block results are combined in block order, so no result depends on the thread
 * count. Small enough that 10^4 agents make ten blocks. */
enum { FM_BLOCK = 1024 };

/* Records status and a printf-style message in err (if not NULL) and returns status. */
fm_status fm_fail(fm_error *err, fm_status status, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* On failure (st != FM_OK) prefixes err's message with "<key>: " (the scene key that named the
 * failing input); returns st. */
fm_status fm_name_key(fm_status st, const char *key, fm_error *err);

/* A model build's stage boundary: reports stage (NULL: none) to progress (NULL: none), then stops the
 * build where cancel (the studio's flag, set by an edit that supersedes the run; NULL: none) is set:
 * FM_STOPPED, with a message no one is shown (docs/studio.md, "An edit and the model"). */
fm_status fm_build_stage(fm_progress_fn progress, void *user, const char *stage, double fraction,
                         const volatile sig_atomic_t *cancel, fm_error *err);

/* 64-byte aligned, zero-filled; size rounded up to a multiple of 64. NULL on failure. */
void *fm_alloc(size_t bytes);
void fm_free(void *p);

/* A file written under a temporary name in its destination folder and renamed to PATH only when
 * complete, so a file under its final name is never half-written. The temporary file is created
 * exclusively (O_CREAT | O_EXCL | O_NOFOLLOW) as PATH.partial.XXXXXX, a name no other process
 * chose, in the folder held open: neither it nor PATH is ever opened through a symlink planted
 * there, and two processes writing one PATH never share a file. A writer that keeps its partial
 * file (the frame cache, for --resume) renames it to the fixed PATH.partial. */
typedef struct fm_output_file {
    FILE *f;                     /* fm_output_open's stream, or NULL */
    int fd;                      /* the temporary file (f's descriptor when f is open), or -1 */
    int dir;                     /* the destination folder, or -1 */
    char path[FM_PATH_MAX];
    char partial[FM_PATH_MAX + 32]; /* the temporary file's path (messages, other ranks); before a
                                       file is created, PATH.partial */
    int keep_partial_on_failure; /* commit leaves PATH.partial when it fails (the frame cache: its
                                    complete frames stay readable) */
    int fixed;                   /* the temporary file is the fixed PATH.partial (fm_output_open_fixed) */
} fm_output_file;

/* The suffix of a partial file kept under its fixed name, and the longest a temporary name adds. */
#define FM_PARTIAL_SUFFIX ".partial"
#define FM_TEMP_SUFFIX_MAX (sizeof FM_PARTIAL_SUFFIX - 1 + 7) /* .partial.XXXXXX */

/* Sets o's names (PATH and PATH.partial) without opening anything. */
fm_status fm_output_name(fm_output_file *o, const char *path, fm_error *err);
/* Creates the temporary file (o->fd, o->partial) exclusively in PATH's folder. */
fm_status fm_output_create(fm_output_file *o, const char *path, fm_error *err);
/* fm_output_create, with a stream on it (o->f). */
fm_status fm_output_open(fm_output_file *o, const char *path, fm_error *err);
/* The same with the fixed PATH.partial as the temporary file, made afresh (whatever was there, a
 * link included, is removed, never followed; a directory there is an error), for a file only one
 * writer makes at a time, under the output folder's lock: the run's cache, whose partial file
 * --resume continues and a watcher sees grow, and its checkpoint. Commit renames it only while the
 * name is still this writer's file. */
fm_status fm_output_create_fixed(fm_output_file *o, const char *path, fm_error *err);
fm_status fm_output_open_fixed(fm_output_file *o, const char *path, fm_error *err);
/* Renames the closed temporary file to PATH and syncs the folder; 0 or the errno. */
int fm_output_rename(fm_output_file *o);
/* Checks for write errors, flushes to disk, closes and renames; on any failure removes the
 * partial file and reports `detail` (if not NULL or empty) or the errno text. */
fm_status fm_output_commit(fm_output_file *o, const char *detail, fm_error *err);
/* Closes and removes the temporary file. */
void fm_output_discard(fm_output_file *o);
/* Reopens the PATH.partial an interrupted writer left (a regular file, not through a symlink),
 * keeps its first `keep` bytes and positions at their end, to continue writing (resume). */
fm_status fm_output_reopen(fm_output_file *o, const char *path, uint64_t keep, fm_error *err);

/* Closes the partial file and leaves it on disk as PATH.partial (a cache that stopped early stays
 * readable, and --resume continues it). */
void fm_output_keep_partial(fm_output_file *o);

/* A user's input file (scene, mesh, cache, checkpoint): FM_OK if it is a regular file that can be
 * opened for reading; otherwise FM_ERR_INPUT with "PATH: cannot open the <what>: <reason>"
 * (missing, a directory, a FIFO or device, permission denied), or FM_ERR_IO for a failure the user
 * did not cause. Never blocks (a FIFO is refused without being opened). */
fm_status fm_check_input_file(const char *path, const char *what, fm_error *err);

/* A user's JSON file (the scene, a wedge file) read whole and NUL-terminated into a malloc'ed
 * buffer (*out_len bytes before the NUL), without the UTF-8 byte-order mark some editors write
 * first (RFC 8259 lets a parser ignore one; jansson does not), so that every such file takes one
 * alike. fm_check_input_file first; a file of max_bytes or more is not a <what> and is refused
 * (FM_ERR_INPUT) before it is read to its end. NULL on failure, with the status in *st and the
 * message ("PATH: ...") in err. */
char *fm_read_text_file(const char *path, const char *what, size_t max_bytes, size_t *out_len, fm_status *st,
                        fm_error *err);

/* The OpenMP threads the engine uses when asked for `requested`: that many (at most
 * FM_MAX_THREADS, the --threads limit), or for 0 OpenMP's default capped at FM_MAX_THREADS and at
 * FM_THREADS_PER_CORE x the cores. The default comes from OMP_NUM_THREADS, which nothing bounds:
 * 100000 threads would exhaust the stacks and crash the first parallel region, and more threads
 * than a few per core only make the run slower (results never depend on the count). */
#define FM_MAX_THREADS 1024
#define FM_THREADS_PER_CORE 4
int fm_threads(int requested);
/* Starts this thread's OpenMP team of `threads` (issue 42): libgomp ends the process with exit 1
 * ("Thread creation failed") when it cannot create a team's thread, as under ulimit -v when the
 * stacks do not fit. So the threads are first tried as plain threads (the default stack size, as
 * libgomp makes them without OMP_STACKSIZE; with it set, nothing is tried), whose failure can be
 * reported, and the team is started at once in the room they leave; libgomp keeps its threads for
 * every later region of as many threads on this thread, so none has to be made later, when the
 * run's memory may have taken that room. 0, or the errno of the thread that could not start (the
 * team is then not started). */
int fm_threads_start_team(int threads);
/* memcpy(dst, src, bytes) on `threads` OpenMP threads, each a contiguous part in whole 64-byte
 * lines (one thread below 64 KiB): the copy-back of a store's re-sort, which on one thread held the
 * re-sort to about 1.2x from 1 to 2 threads (issue 40). */
void fm_copy_parallel(void *dst, const void *src, size_t bytes, int threads);

/* What the user can do about a failed write with this errno ("" if nothing specific): disk full,
 * file-size limit, read-only file system. */
const char *fm_write_hint(int errnum);

/* A library could not start (Embree's device: its threads and their memory). `what` names it;
 * `code` is its error code and `says_memory` whether that code means out of memory. Out of memory
 * (FM_ERR_MEMORY, exit 4) when it says so, or when an address-space limit (ulimit -v) is set, the
 * likely cause of a start that fails for a reason the library does not give; internal otherwise. */
fm_status fm_library_start_failed(fm_error *err, const char *what, int code, int says_memory);
/* A file name pattern (wave_%03d.obj, f.%04d.png): exactly one integer conversion %d, %i or %u with
 * an optional 0 flag and a width of at most FM_PATTERN_WIDTH_DIGITS digits (a width of 10^9 would
 * make snprintf write a gigabyte of blanks), and %% for a literal %. 1 if it is one, else 0. */
#define FM_PATTERN_WIDTH_DIGITS 2
int fm_one_integer_conversion(const char *pattern);

/* x in the fewest significant digits (up to 17) that read back as exactly x, so that two values a
 * message compares never print alike ("10000001 is out of range: must be <= 10000000", where %g
 * says 1e+07 twice). Writes into buf (FM_DOUBLE_CHARS bytes) and returns it. */
#define FM_DOUBLE_CHARS 32
const char *fm_shortest(char *buf, double x);

/* Seconds from a monotonic clock. */
double fm_seconds(void);

/* splitmix64 (Steele, Lea & Flood 2014): the next value of a well-mixed 64-bit stream. */
static inline uint64_t fm_splitmix64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* Counter-based randomness: 64 random bits that depend only on (seed, stream, index), so any
 * thread may draw them in any order. */
static inline uint64_t fm_random_bits(uint64_t seed, uint64_t stream, uint64_t index)
{
    uint64_t s = seed ^ (stream * 0xD1B54A32D192ED03ull);
    s = fm_splitmix64(&s) ^ index;
    return fm_splitmix64(&s);
}

/* fm_random_bits mapped to [0, 1) with 53 bits. */
static inline double fm_random_unit(uint64_t seed, uint64_t stream, uint64_t index)
{
    return (double)(fm_random_bits(seed, stream, index) >> 11) * 0x1p-53;
}

#define FM_MIN(a, b) ((a) < (b) ? (a) : (b))
#define FM_MAX(a, b) ((a) > (b) ? (a) : (b))

#endif
