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

fm_status fm_name_key(fm_status st, const char *key, fm_error *err)
{
    if (st != FM_OK && err) {
        char msg[sizeof err->message];
        snprintf(msg, sizeof msg, "%s", err->message);
        fm_fail(err, st, "%s: %s", key, msg);
    }
    return st;
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
    o->keep_partial_on_failure = 0;
    if (strlen(path) >= sizeof o->path) return fm_fail(err, FM_ERR_USAGE, "output path too long: %s", path);
    snprintf(o->path, sizeof o->path, "%s", path);
    snprintf(o->partial, sizeof o->partial, "%s.partial", path);
    return FM_OK;
}

fm_status fm_output_open(fm_output_file *o, const char *path, fm_error *err)
{
    if (fm_output_name(o, path, err) != FM_OK) return FM_ERR_USAGE;
    errno = 0;
    o->f = fopen(o->partial, "wb");
    if (!o->f) {
        int e = errno ? errno : EIO;
        return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", path, strerror(e), fm_write_hint(e));
    }
    return FM_OK;
}

fm_status fm_output_commit(fm_output_file *o, const char *detail, fm_error *err)
{
    int e = 0, bad = ferror(o->f) || fflush(o->f) != 0 || fsync(fileno(o->f)) != 0;
    if (bad) e = errno;
    if (fclose(o->f) != 0 && !bad) bad = 1, e = errno;
    o->f = NULL;
    if (!bad && rename(o->partial, o->path) != 0) bad = 1, e = errno;
    if (!bad) return FM_OK;
    if (!o->keep_partial_on_failure) remove(o->partial);
    if (detail && detail[0]) return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s", o->path, detail);
    e = e ? e : EIO;
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", o->path, strerror(e), fm_write_hint(e));
}

void fm_output_discard(fm_output_file *o)
{
    if (o->f) fclose(o->f), remove(o->partial);
    o->f = NULL;
}

fm_status fm_output_reopen(fm_output_file *o, const char *path, uint64_t keep, fm_error *err)
{
    if (fm_output_name(o, path, err) != FM_OK) return FM_ERR_USAGE;
    errno = 0;
    o->f = fopen(o->partial, "r+b");
    if (!o->f || ftruncate(fileno(o->f), (off_t)keep) != 0 || fseeko(o->f, (off_t)keep, SEEK_SET) != 0) {
        int e = errno ? errno : EIO;
        if (o->f) fclose(o->f);
        o->f = NULL;
        return fm_fail(err, FM_ERR_IO, "cannot resume writing '%s': %s", o->partial, strerror(e));
    }
    return FM_OK;
}

void fm_output_keep_partial(fm_output_file *o)
{
    if (o->f) fclose(o->f);
    o->f = NULL;
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
