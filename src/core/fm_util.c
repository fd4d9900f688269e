#define _POSIX_C_SOURCE 200809L
#include "fm_internal.h"


#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <errno.h>
#include <fcntl.h>
#include <time.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

/* A message longer than err's buffer keeps its start and its end, with "..." between: a long path
 * (the part that makes it long) is cut in its middle, and the reason, which comes last, stays. */
static void keep_ends(char *out, size_t cap, const char *text, size_t len)
{
    size_t head = (cap - 4) / 2, tail = cap - 4 - head;
    while (head > 0 && ((unsigned char)text[head] & 0xC0) == 0x80) head--; /* whole UTF-8 characters */
    while (tail > 0 && ((unsigned char)text[len - tail] & 0xC0) == 0x80) tail--;
    snprintf(out, cap, "%.*s...%s", (int)head, text, text + len - tail);
}

fm_status fm_fail(fm_error *err, fm_status status, const char *fmt, ...)
{
    if (!err) return status;
    char whole[4 * FM_PATH_MAX + sizeof err->message]; /* a few paths and the words around them */
    va_list ap;
    va_start(ap, fmt);
    int len = vsnprintf(whole, sizeof whole, fmt, ap);
    va_end(ap);
    size_t kept = len < 0 ? 0 : FM_MIN((size_t)len, sizeof whole - 1);
    if (kept < sizeof err->message) memcpy(err->message, whole, kept + 1);
    else keep_ends(err->message, sizeof err->message, whole, kept);
    err->status = status;
    return status;
}

fm_status fm_name_key(fm_status st, const char *key, fm_error *err)
{
    if (st != FM_OK && err) {
        char msg[sizeof err->message];
        snprintf(msg, sizeof msg, "%s", err->message);
        fm_fail(err, st, "%s: %s", key, msg);
    }
    return st;
}

fm_status fm_build_stage(fm_progress_fn progress, void *user, const char *stage, double fraction,
                         const volatile sig_atomic_t *cancel, fm_error *err)
{
    if (progress && stage) progress(stage, fraction, user);
    return cancel && *cancel ? fm_fail(err, FM_STOPPED, "the model build was cancelled by an edit") : FM_OK;
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

fm_status fm_output_name(fm_output_file *o, const char *path, fm_error *err)
{
    o->f = NULL;
    o->fd = o->dir = -1;
    o->keep_partial_on_failure = o->fixed = 0;
    if (strlen(path) >= sizeof o->path) return fm_fail(err, FM_ERR_USAGE, "output path too long: %s", path);
    snprintf(o->path, sizeof o->path, "%s", path);
    snprintf(o->partial, sizeof o->partial, "%s" FM_PARTIAL_SUFFIX, path);
    return FM_OK;
}

/* The last component of a path ("frames.fmc" of "out/frames.fmc"). */
static const char *base_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

/* Opens the folder that holds o->path (o->dir). */
static int open_folder(fm_output_file *o)
{
    char dir[FM_PATH_MAX];
    const char *name = base_name(o->path);
    size_t len = (size_t)(name - o->path);
    if (len == 0) snprintf(dir, sizeof dir, ".");
    else snprintf(dir, sizeof dir, "%.*s", (int)(len > 1 ? len - 1 : len), o->path); /* "/x": "/" */
    o->dir = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    return o->dir >= 0 ? 0 : -1;
}

static void close_folder(fm_output_file *o)
{
    if (o->dir >= 0) close(o->dir);
    o->dir = -1;
}

/* Six characters no other writer of this name is likely to choose; O_EXCL settles a collision. */
static void temp_suffix(char out[8])
{
    static const char digits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
    static _Atomic uint64_t counter;
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    uint64_t bits = fm_random_bits((uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec, (uint64_t)getpid(),
                                   counter++);
    out[0] = '.';
    for (int i = 1; i < 7; i++, bits /= 62) out[i] = digits[bits % 62];
    out[7] = 0;
}

static int create_exclusive(const fm_output_file *o)
{
    return openat(o->dir, base_name(o->partial), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
}

/* A name of its own: PATH.partial.XXXXXX. */
static void create_unique(fm_output_file *o)
{
    for (int attempt = 0; attempt < 100 && o->fd < 0; attempt++) {
        char suffix[8];
        temp_suffix(suffix);
        snprintf(o->partial, sizeof o->partial, "%s" FM_PARTIAL_SUFFIX "%s", o->path, suffix);
        if ((o->fd = create_exclusive(o)) < 0 && errno != EEXIST) break;
    }
}

/* The fixed PATH.partial, made afresh: an earlier run's file (or a link) there is removed, not
 * followed; a directory in the way is an error (EISDIR). */
static void create_fixed(fm_output_file *o)
{
    if (unlinkat(o->dir, base_name(o->partial), 0) == 0 || errno == ENOENT) o->fd = create_exclusive(o);
    o->fixed = 1;
}

static fm_status create(fm_output_file *o, const char *path, int fixed, fm_error *err)
{
    if (fm_output_name(o, path, err) != FM_OK) return FM_ERR_USAGE;
    errno = 0;
    if (open_folder(o) == 0 && fixed) create_fixed(o);
    else if (o->dir >= 0) create_unique(o);
    if (o->fd >= 0) return FM_OK;
    int e = errno ? errno : EIO;
    close_folder(o);
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", path, strerror(e), fm_write_hint(e));
}

fm_status fm_output_create(fm_output_file *o, const char *path, fm_error *err) { return create(o, path, 0, err); }

fm_status fm_output_create_fixed(fm_output_file *o, const char *path, fm_error *err) { return create(o, path, 1, err); }

/* A stream on the created file. */
static fm_status open_stream(fm_output_file *o, const char *path, fm_status st, fm_error *err)
{
    if (st != FM_OK) return st;
    if ((o->f = fdopen(o->fd, "wb"))) return FM_OK;
    int e = errno ? errno : ENOMEM;
    fm_output_discard(o);
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s", path, strerror(e));
}

fm_status fm_output_open(fm_output_file *o, const char *path, fm_error *err)
{
    return open_stream(o, path, fm_output_create(o, path, err), err);
}

fm_status fm_output_open_fixed(fm_output_file *o, const char *path, fm_error *err)
{
    return open_stream(o, path, fm_output_create_fixed(o, path, err), err);
}

/* Whether the fixed PATH.partial is still this writer's file (o->fd), not one another writer of
 * the same PATH made after removing this one's; 0 or the errno. */
static int still_ours(const fm_output_file *o, int fd)
{
    struct stat mine, named;
    if (!o->fixed || fd < 0) return 0;
    if (fstat(fd, &mine) != 0 || fstatat(o->dir, base_name(o->partial), &named, AT_SYMLINK_NOFOLLOW) != 0) return errno;
    return mine.st_dev == named.st_dev && mine.st_ino == named.st_ino ? 0 : EBUSY;
}

int fm_output_rename(fm_output_file *o)
{
    if (renameat(o->dir, base_name(o->partial), o->dir, base_name(o->path)) != 0) return errno ? errno : EIO;
    fsync(o->dir); /* the new name itself reaches the disk */
    close_folder(o);
    return 0;
}

/* Closes the stream or descriptor; 0 or the errno of a failed close. */
static int close_file(fm_output_file *o)
{
    int e = 0;
    if (o->f) e = fclose(o->f) != 0 ? (errno ? errno : EIO) : 0;
    else if (o->fd >= 0) e = close(o->fd) != 0 ? (errno ? errno : EIO) : 0;
    o->f = NULL, o->fd = -1;
    return e;
}

fm_status fm_output_commit(fm_output_file *o, const char *detail, fm_error *err)
{
    int e = 0, bad = ferror(o->f) || fflush(o->f) != 0 || fsync(fileno(o->f)) != 0;
    if (bad) e = errno;
    if (!bad && (e = still_ours(o, fileno(o->f))) != 0) {
        bad = 1;
        if (e == EBUSY) detail = "another writer of this name replaced its partial file";
    }
    int closed = close_file(o);
    if (closed && !bad) bad = 1, e = closed;
    if (!bad && (e = fm_output_rename(o)) != 0) bad = 1;
    if (!bad) return FM_OK;
    if (o->keep_partial_on_failure) fm_output_keep_partial(o);
    else fm_output_discard(o);
    if (detail && detail[0]) return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s", o->path, detail);
    e = e ? e : EIO;
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", o->path, strerror(e), fm_write_hint(e));
}

void fm_output_discard(fm_output_file *o)
{
    int ours = still_ours(o, o->f ? fileno(o->f) : o->fd) == 0; /* never another writer's PATH.partial */
    close_file(o);
    if (o->dir >= 0 && ours) unlinkat(o->dir, base_name(o->partial), 0);
    close_folder(o);
}

fm_status fm_output_reopen(fm_output_file *o, const char *path, uint64_t keep, fm_error *err)
{
    if (fm_output_name(o, path, err) != FM_OK) return FM_ERR_USAGE;
    o->fixed = 1; /* PATH.partial itself */
    errno = 0;
    struct stat st;
    if (open_folder(o) == 0) o->fd = openat(o->dir, base_name(o->partial), O_RDWR | O_NOFOLLOW | O_CLOEXEC);
    if (o->fd >= 0 && fstat(o->fd, &st) == 0 && !S_ISREG(st.st_mode)) errno = EINVAL; /* never a FIFO or device */
    else if (o->fd >= 0 && (o->f = fdopen(o->fd, "r+b")) && ftruncate(o->fd, (off_t)keep) == 0 &&
             fseeko(o->f, (off_t)keep, SEEK_SET) == 0)
        return FM_OK;
    int e = errno ? errno : EIO;
    close_file(o);
    close_folder(o);
    if (e == ELOOP || e == EINVAL) /* not the file a run left: the user's to fix */
        return fm_fail(err, FM_ERR_INPUT, "cannot resume writing '%s': %s", o->partial,
                       e == ELOOP ? "it is a symbolic link, which the run does not follow" : "not a regular file");
    return fm_fail(err, FM_ERR_IO, "cannot resume writing '%s': %s", o->partial, strerror(e));
}

void fm_output_keep_partial(fm_output_file *o)
{
    close_file(o);
    char kept[sizeof o->partial];
    snprintf(kept, sizeof kept, "%s" FM_PARTIAL_SUFFIX, base_name(o->path));
    /* the fixed name --resume reads; rename() replaces whatever is there, never through a link */
    if (o->dir >= 0 && strcmp(base_name(o->partial), kept) != 0 && renameat(o->dir, base_name(o->partial), o->dir, kept) == 0)
        snprintf(o->partial, sizeof o->partial, "%s" FM_PARTIAL_SUFFIX, o->path);
    close_folder(o);
}

int fm_one_integer_conversion(const char *pattern)
{
    int conversions = 0;
    for (const char *p = pattern; *p; p++) {
        if (*p != '%') continue;
        if (*++p == '%') continue;
        if (*p == '0') p++;
        for (int digits = 0; *p >= '0' && *p <= '9'; p++)
            if (++digits > FM_PATTERN_WIDTH_DIGITS) return 0;
        if (*p != 'd' && *p != 'i' && *p != 'u') return 0;
        conversions++;
    }
    return conversions == 1;
}

const char *fm_shortest(char *buf, double x)
{
    if (x == floor(x) && fabs(x) < 1e15) return snprintf(buf, FM_DOUBLE_CHARS, "%.0f", x), buf; /* 10000000, not 1e+07 */
    for (int digits = 6; digits <= 17; digits++) {
        snprintf(buf, FM_DOUBLE_CHARS, "%.*g", digits, x);
        if (strtod(buf, NULL) == x || x != x) break;
    }
    return buf;
}

const char *fm_write_hint(int errnum)
{
    switch (errnum) {
    case ENOSPC: return " (the disk is full: free space or write elsewhere with -o)";
    case EDQUOT: return " (the disk quota is used up: free space or write elsewhere with -o)";
    case EFBIG: return " (the file-size limit was reached: see `ulimit -f`, or lower n or time.frame_limit)";
    case EROFS: return " (the file system is read-only: write elsewhere with -o)";
    default: return "";
    }
}

/* Errors that describe the path the user gave, rather than a failing machine. */
static int user_caused(int errnum)
{
    return errnum == ENOENT || errnum == ENOTDIR || errnum == EACCES || errnum == EPERM || errnum == ELOOP ||
           errnum == ENAMETOOLONG || errnum == EISDIR || errnum == ENXIO;
}

/* What a file that is not a regular file is, for the message; NULL for a regular file. */
static const char *not_regular(mode_t mode)
{
    if (S_ISREG(mode)) return NULL;
    if (S_ISDIR(mode)) return "it is a directory";
    if (S_ISFIFO(mode)) return "it is a FIFO (named pipe), not a regular file";
    if (S_ISCHR(mode) || S_ISBLK(mode)) return "it is a device, not a regular file";
    return "it is not a regular file";
}

/* Only regular files are read: a FIFO would block the read until a writer comes (forever, if none
 * does), and /dev/zero or /dev/urandom never end. stat() first, so that nothing but a regular file
 * is ever opened; then the open that checks the permission, with O_NONBLOCK in case the path was
 * replaced by a FIFO in between (fstat then catches it). */
fm_status fm_check_input_file(const char *path, const char *what, fm_error *err)
{
    struct stat st;
    int e = 0;
    const char *kind = NULL;
    if (stat(path, &st) != 0) e = errno;
    else if (!(kind = not_regular(st.st_mode))) {
        int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
        if (fd < 0) e = errno;
        else if (fstat(fd, &st) != 0) e = errno;
        else kind = not_regular(st.st_mode);
        if (fd >= 0) close(fd);
    }
    if (kind) return fm_fail(err, FM_ERR_INPUT, "%s: cannot open the %s: %s", path, what, kind);
    if (!e) return FM_OK;
    return fm_fail(err, user_caused(e) ? FM_ERR_INPUT : FM_ERR_IO, "%s: cannot open the %s: %s", path, what,
                   strerror(e));
}

/* Reads f to its end into a growing buffer, NUL-terminated; stops once the buffer would have to
 * grow to max_bytes or more (*too_big then set): such a file is not read to its end. */
static char *read_stream(FILE *f, size_t max_bytes, size_t *out_len, int *too_big)
{
    size_t cap = 1 << 16, len = 0;
    char *text = malloc(cap);
    *too_big = 0;
    while (text) {
        len += fread(text + len, 1, cap - len - 1, f);
        if (len < cap - 1) break;
        if (cap >= max_bytes) {
            free(text);
            *too_big = 1;
            return NULL;
        }
        char *bigger = realloc(text, cap *= 2);
        if (!bigger) free(text);
        text = bigger;
    }
    if (text) text[len] = 0;
    *out_len = len;
    return text;
}

/* JSON text holds no NUL byte (RFC 8259: not even between tokens; jansson calls one the end of
 * the file): refused where it is, by line and column (in bytes, from 1). */
static fm_status check_no_nul(const char *path, const char *text, size_t len, fm_error *err)
{
    const char *nul = memchr(text, 0, len);
    if (!nul) return FM_OK;
    int line = 1;
    const char *line_start = text;
    for (const char *c = text; c < nul; c++)
        if (*c == '\n') line++, line_start = c + 1;
    return fm_fail(err, FM_ERR_INPUT, "%s:%d:%d: a NUL byte, which JSON text may not hold (is it a binary file?)", path,
                   line, (int)(nul - line_start) + 1);
}

char *fm_read_text_file(const char *path, const char *what, size_t max_bytes, size_t *out_len, fm_status *st,
                        fm_error *err)
{
    if ((*st = fm_check_input_file(path, what, err)) != FM_OK) return NULL;
    FILE *f = fopen(path, "rb");
    if (!f) {
        *st = fm_fail(err, FM_ERR_IO, "%s: cannot open the %s: %s", path, what, strerror(errno));
        return NULL;
    }
    size_t len = 0;
    int too_big;
    char *text = read_stream(f, max_bytes, &len, &too_big);
    int bad = ferror(f);
    fclose(f);
    if (too_big) {
        *st = fm_fail(err, FM_ERR_INPUT, "%s: the %s is larger than %zu MiB: it is not a %s", path, what,
                      max_bytes >> 20, what);
        return NULL;
    }
    if (!text || bad) {
        free(text);
        *st = fm_fail(err, bad ? FM_ERR_IO : FM_ERR_MEMORY, "%s: cannot read the %s", path, what);
        return NULL;
    }
    if (len >= 3 && !memcmp(text, "\xEF\xBB\xBF", 3)) memmove(text, text + 3, (len -= 3) + 1); /* the mark */
    if ((*st = check_no_nul(path, text, len, err)) != FM_OK) return free(text), NULL;
    *out_len = len;
    return text;
}


fm_status fm_library_start_failed(fm_error *err, const char *what, int code, int says_memory)
{
    struct rlimit limit;
    const int limited = getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY;
    if (!says_memory && !limited)
        return fm_fail(err, FM_ERR_INTERNAL, "%s could not start (error %d)", what, code);
    char why[96] = "";
    if (limited) snprintf(why, sizeof why, " (the address-space limit, ulimit -v, is %.0f MB)", (double)limit.rlim_cur / 1e6);
    return fm_fail(err, FM_ERR_MEMORY, "out of memory: %s could not start (error %d)%s", what, code, why);
}
