/* Video through the ffmpeg program (Debian package ffmpeg): raw RGB frames go to its stdin, it
 * encodes H.264 into a temporary file that this process created exclusively beside PATH
 * (fm_output_create: never a symlink, never another writer's), and finish() renames that to PATH
 * once ffmpeg exits with 0.
 *
 * ffmpeg reads a socket rather than a pipe so that frames can be sent with MSG_NOSIGNAL: if ffmpeg
 * dies, a write fails with EPIPE instead of killing this process with SIGPIPE, and no process-wide
 * signal disposition has to change. ffmpeg's stdout and stderr go to an unlinked temporary file
 * that error messages quote. */
#define _GNU_SOURCE /* SOCK_CLOEXEC */
#include "fm_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <spawn.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

#define FM_VIDEO_MAX_DIM 16384
#define FM_VIDEO_LOG_QUOTE 1200 /* bytes of ffmpeg's stderr quoted in an error */

struct fm_video_writer {
    pid_t pid;     /* ffmpeg, or 0 once waited for */
    int fd;        /* our end of the socket ffmpeg reads as stdin, or -1 */
    FILE *log;     /* ffmpeg's stdout and stderr */
    int width, height;
    fm_output_file out; /* PATH and the temporary file ffmpeg writes */
};

/* The end of ffmpeg's stderr (at most FM_VIDEO_LOG_QUOTE bytes, trailing blanks cut). */
static void log_tail(FILE *log, char *out, size_t cap)
{
    out[0] = 0;
    if (!log || fseek(log, 0, SEEK_END) != 0) return;
    long size = ftell(log);
    long from = size > FM_VIDEO_LOG_QUOTE ? size - FM_VIDEO_LOG_QUOTE : 0;
    if (size < 0 || fseek(log, from, SEEK_SET) != 0) return;
    size_t n = fread(out, 1, cap - 1, log);
    out[n] = 0;
    while (n > 0 && (out[n - 1] == '\n' || out[n - 1] == ' ' || out[n - 1] == '\r')) out[--n] = 0;
}

/* Waits for ffmpeg; returns its exit status, or -1 if a signal ended it (*sig says which). */
static int wait_ffmpeg(fm_video_writer *v, int *sig)
{
    int status = 0;
    *sig = 0;
    while (waitpid(v->pid, &status, 0) < 0)
        if (errno != EINTR) return v->pid = 0, -1;
    v->pid = 0;
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    if (WIFSIGNALED(status)) *sig = WTERMSIG(status);
    return -1;
}

static void close_input(fm_video_writer *v)
{
    if (v->fd >= 0) close(v->fd);
    v->fd = -1;
}

static void free_writer(fm_video_writer *v)
{
    close_input(v);
    if (v->log) fclose(v->log);
    free(v);
}

/* Waits for ffmpeg and reports how it failed, quoting its stderr; removes the partial file. */
static fm_status ffmpeg_failed(fm_video_writer *v, const char *what, fm_error *err)
{
    close_input(v);
    int sig = 0, code = v->pid ? wait_ffmpeg(v, &sig) : -1;
    fm_output_discard(&v->out);
    char tail[FM_VIDEO_LOG_QUOTE + 1], how[64];
    log_tail(v->log, tail, sizeof tail);
    if (code >= 0) snprintf(how, sizeof how, "exit status %d", code);
    else if (sig) snprintf(how, sizeof how, "killed by signal %d", sig);
    else snprintf(how, sizeof how, "status unknown");
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': ffmpeg %s (%s)%s%s", v->out.path, what, how,
                   tail[0] ? "; it said:\n" : "", tail);
}

static fm_status check_args(const char *path, int width, int height, double fps, fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "video: no output path given");
    if (strlen(path) >= FM_PATH_MAX) return fm_fail(err, FM_ERR_USAGE, "output path too long: %s", path);
    if (width < 2 || height < 2 || width > FM_VIDEO_MAX_DIM || height > FM_VIDEO_MAX_DIM ||
        width % 2 || height % 2)
        return fm_fail(err, FM_ERR_USAGE,
                       "video '%s': size %dx%d must be even numbers in 2..%d (H.264 4:2:0)", path,
                       width, height, FM_VIDEO_MAX_DIM);
    if (!(fps > 0.0 && fps <= 1000.0))
        return fm_fail(err, FM_ERR_USAGE, "video '%s': %g frames per second is outside (0, 1000]",
                       path, fps);
    return FM_OK;
}

/* Starts ffmpeg with stdin = child_in and stdout, stderr = the log. */
static int spawn_ffmpeg(fm_video_writer *v, int child_in, double fps)
{
    char size[32], rate[32];
    snprintf(size, sizeof size, "%dx%d", v->width, v->height);
    snprintf(rate, sizeof rate, "%.9g", fps);
    /* BT.709 in TV range, converted with that matrix and tagged so (the stream's VUI and the mp4's
     * colr atom), so players do not guess; +faststart puts the index (moov) before the frames */
    char *argv[] = {"ffmpeg", "-hide_banner", "-nostats", "-loglevel", "error", "-y",
                    "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", size, "-r", rate, "-i", "-",
                    "-vf", "scale=out_color_matrix=bt709:out_range=tv", "-c:v", "libx264", "-pix_fmt", "yuv420p",
                    "-colorspace", "bt709", "-color_primaries", "bt709", "-color_trc", "bt709", "-color_range", "tv",
                    "-movflags", "+faststart", "-f", "mp4", v->out.partial, NULL};
    posix_spawn_file_actions_t fa;
    int rc = posix_spawn_file_actions_init(&fa);
    if (rc) return rc;
    int log_fd = fileno(v->log);
    if (!(rc = posix_spawn_file_actions_adddup2(&fa, child_in, STDIN_FILENO)) &&
        !(rc = posix_spawn_file_actions_adddup2(&fa, log_fd, STDOUT_FILENO)))
        rc = posix_spawn_file_actions_adddup2(&fa, log_fd, STDERR_FILENO);
    if (!rc) rc = posix_spawnp(&v->pid, "ffmpeg", &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc) v->pid = 0;
    return rc;
}

fm_video_writer *fm_video_open(const char *path, int width, int height, double fps, fm_error *err)
{
    if (check_args(path, width, height, fps, err) != FM_OK) return NULL;
    fm_video_writer *v = calloc(1, sizeof *v);
    if (!v) return fm_fail(err, FM_ERR_MEMORY, "video '%s': out of memory", path), NULL;
    v->fd = -1;
    v->width = width, v->height = height;
    /* Create the file ffmpeg will write (-y: it truncates that file), so that a missing or
     * read-only directory is reported plainly, before any frame is rendered. */
    if (fm_output_create(&v->out, path, err) != FM_OK) {
        free(v);
        return NULL;
    }
    close(v->out.fd), v->out.fd = -1;
    int sv[2] = {-1, -1};
    errno = 0;
    v->log = tmpfile();
    if (!v->log || fcntl(fileno(v->log), F_SETFD, FD_CLOEXEC) != 0 ||
        socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) {
        fm_fail(err, FM_ERR_IO, "video '%s': cannot set up ffmpeg's input and log: %s", path,
                strerror(errno ? errno : EIO));
        fm_output_discard(&v->out);
        free_writer(v);
        return NULL;
    }
    int rc = spawn_ffmpeg(v, sv[1], fps);
    close(sv[1]);
    v->fd = sv[0];
    if (rc == ENOENT) {
        fm_fail(err, FM_ERR_IO,
                "cannot write '%s': the ffmpeg program is not installed or not on PATH (it encodes "
                ".mp4; Debian package ffmpeg)", path);
    } else if (rc) {
        fm_fail(err, FM_ERR_IO, "cannot write '%s': cannot run ffmpeg: %s", path, strerror(rc));
    }
    if (rc) {
        fm_output_discard(&v->out);
        free_writer(v);
        return NULL;
    }
    return v;
}

fm_status fm_video_add_frame(fm_video_writer *v, const unsigned char *rgb, fm_error *err)
{
    if (!v || !rgb) return fm_fail(err, FM_ERR_USAGE, "video: no writer or no frame given");
    if (v->fd < 0) return fm_fail(err, FM_ERR_USAGE, "video '%s': the writer has failed", v->out.path);
    size_t left = 3 * (size_t)v->width * (size_t)v->height;
    const unsigned char *p = rgb;
    while (left > 0) {
        ssize_t sent = send(v->fd, p, left, MSG_NOSIGNAL);
        if (sent < 0 && errno == EINTR) continue;
        if (sent <= 0) return ffmpeg_failed(v, "stopped reading frames", err);
        p += sent, left -= (size_t)sent;
    }
    return FM_OK;
}

/* Flushes the finished file to disk before it gets its final name. */
static int sync_file(const char *path)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    if (fd < 0) return -1;
    int rc = fsync(fd);
    close(fd);
    return rc;
}

static uint64_t big_endian(const unsigned char *p, int bytes)
{
    uint64_t x = 0;
    for (int i = 0; i < bytes; i++) x = x << 8 | p[i];
    return x;
}

/* ffmpeg exits 0 even when writing its file failed (a full disk, a file-size limit: it logs the
 * error and carries on; issue 42), leaving an MP4 without the index a player reads (the moov box).
 * So the file is checked: its top-level boxes (a 32-bit size and a type; size 1: a 64-bit size
 * follows; size 0: to the end) must tile it exactly, mdat and moov among them. NULL when it is
 * whole, else what is wrong. */
static const char *mp4_incomplete(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (f && fseeko(f, 0, SEEK_END) != 0) fclose(f), f = NULL;
    if (!f) return "it cannot be read back";
    const uint64_t size = (uint64_t)ftello(f);
    uint64_t at = 0;
    int moov = 0, mdat = 0;
    const char *why = NULL;
    while (!why && at < size) {
        unsigned char h[16];
        if (fseeko(f, (off_t)at, SEEK_SET) != 0 || fread(h, 1, 8, f) != 8) why = "it ends inside a box's header";
        uint64_t box = why ? 0 : big_endian(h, 4);
        if (!why && box == 1) box = fread(h + 8, 1, 8, f) == 8 ? big_endian(h + 8, 8) : 0;
        else if (!why && box == 0) box = size - at;
        if (!why && (box < 8 || box > size - at)) why = "a box runs past the end of the file";
        moov |= !why && !memcmp(h + 4, "moov", 4), mdat |= !why && !memcmp(h + 4, "mdat", 4);
        at += box;
    }
    fclose(f);
    if (!why && !moov) why = "it has no moov box (the index a player reads)";
    if (!why && !mdat) why = "it has no mdat box (the frames)";
    return why;
}

/* ffmpeg exited 0 but its file is not whole: an I/O error naming what is wrong and quoting it. */
static fm_status ffmpeg_left_incomplete(fm_video_writer *v, const char *why, fm_error *err)
{
    char tail[FM_VIDEO_LOG_QUOTE + 1];
    log_tail(v->log, tail, sizeof tail);
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': ffmpeg exited with 0 but the file it wrote is incomplete: %s "
                   "(the disk is full or a file-size limit was reached?)%s%s", v->out.path, why,
                   tail[0] ? "; it said:\n" : "", tail);
}

fm_status fm_video_finish(fm_video_writer *v, fm_error *err)
{
    if (!v) return fm_fail(err, FM_ERR_USAGE, "video: no writer given");
    if (v->fd < 0) {
        fm_status st = fm_fail(err, FM_ERR_USAGE, "video '%s': the writer has failed", v->out.path);
        fm_video_abort(v);
        return st;
    }
    close_input(v); /* end of input: ffmpeg writes the file and exits */
    int sig = 0, code = wait_ffmpeg(v, &sig);
    fm_status st = FM_OK;
    const char *incomplete = code == 0 ? mp4_incomplete(v->out.partial) : NULL;
    if (code != 0) {
        st = ffmpeg_failed(v, "failed", err);
    } else if (incomplete) {
        st = ffmpeg_left_incomplete(v, incomplete, err);
        fm_output_discard(&v->out); /* the folder closed; the temporary file removed */
    } else {
        errno = 0;
        int e = sync_file(v->out.partial) != 0 ? (errno ? errno : EIO) : fm_output_rename(&v->out);
        if (e) st = fm_fail(err, FM_ERR_IO, "cannot write '%s': %s", v->out.path, strerror(e));
        fm_output_discard(&v->out); /* the folder closed; the temporary file removed if it is left */
    }
    free_writer(v);
    return st;
}

void fm_video_abort(fm_video_writer *v)
{
    if (!v) return;
    close_input(v);
    if (v->pid > 0) {
        int sig;
        kill(v->pid, SIGTERM); /* the ffmpeg this writer started, by its pid */
        wait_ffmpeg(v, &sig);
    }
    fm_output_discard(&v->out);
    free_writer(v);
}
