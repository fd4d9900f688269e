/* Running the flockmorph CLI from a test: its exit status, stdout and stderr, optionally under a
 * file-size limit (RLIMIT_FSIZE, SIGXFSZ left at its deadly default: the CLI must ignore it so that
 * write() fails with EFBIG) or as an unprivileged user (so permissions apply even when the tests
 * run as root). Shared by
 * test_cli.c and test_bad_input.c; include after test_macros.h with _POSIX_C_SOURCE defined. */
#ifndef FM_TEST_CLI_HELPERS_H
#define FM_TEST_CLI_HELPERS_H

#include "flockmorph/flockmorph.h"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

/* A sanitizer's shadow memory needs far more address space than any RLIMIT_AS a test sets. */
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define CLI_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define CLI_SANITIZED 1
#endif
#endif

static char g_out[1 << 16], g_err[1 << 16]; /* the last command's stdout and stderr */

#define CLI_NOBODY 65534 /* uid and gid of "nobody" on Debian */
#define CLI_NOT_RUN 126  /* the child could not set up (e.g. no right to drop privileges) */

typedef struct cli_env {
    long long file_size_limit; /* bytes, > 0: RLIMIT_FSIZE of the run */
    int unprivileged;          /* run as nobody when the test runs as root */
    long long memory_limit;    /* bytes, > 0: RLIMIT_AS of the run (not under a sanitizer) */
    unsigned seconds;          /* > 0: SIGALRM ends a run that takes longer (one that hangs) */
} cli_env;

static size_t slurp(const char *path, char *buf, size_t cap)
{
    buf[0] = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    size_t n = fread(buf, 1, cap - 1, f);
    buf[n] = 0;
    fclose(f);
    return n;
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (!f) return;
    fputs(text, f);
    fclose(f);
}

/* `count` regular octahedra |x - c| <= 1 in the 1-norm (c = centers[i]) in one OBJ file, outward
 * triangles. Octahedron i's triangle 8 i + s + 1 (triangles numbered from 1 in file order) lies in
 * octant s around its centre: +x when s & 1 is 0, +y when s & 2 is 0, +z when s & 4 is 0. */
static void write_octahedra(const char *path, const double (*centers)[3], int count)
{
    FILE *f = fopen(path, "w");
    ENSURE(f != NULL);
    if (!f) return;
    for (int i = 0; i < count; i++) {
        const double *c = centers[i];
        for (int v = 0; v < 6; v++) /* +x, -x, +y, -y, +z, -z */
            fprintf(f, "v %g %g %g\n", c[0] + (v == 0) - (v == 1), c[1] + (v == 2) - (v == 3), c[2] + (v == 4) - (v == 5));
    }
    for (int i = 0; i < count; i++)
        for (int s = 0; s < 8; s++) { /* one face per octant; a reflection reverses the winding */
            int x = s & 1 ? 2 : 1, y = s & 2 ? 4 : 3, z = s & 4 ? 6 : 5, b = 6 * i;
            int odd = ((s & 1) + (s >> 1 & 1) + (s >> 2 & 1)) & 1;
            fprintf(f, "f %d %d %d\n", b + x, b + (odd ? z : y), b + (odd ? y : z));
        }
    fclose(f);
}

/* The regular octahedron |x| + |y| + |z| <= 1. */
static void write_octahedron(const char *path) { write_octahedra(path, (const double[][3]){{0, 0, 0}}, 1); }

/* In the child: stdout and stderr to files, the limits, then the shell runs `flockmorph ARGS`. */
static void cli_child(const cli_env *env, const char *out, const char *err, const char *args)
{
    int fo = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644), fe = open(err, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fo < 0 || fe < 0 || dup2(fo, 1) < 0 || dup2(fe, 2) < 0) _exit(CLI_NOT_RUN);
    if (env && env->file_size_limit > 0) {
        struct rlimit limit = {(rlim_t)env->file_size_limit, (rlim_t)env->file_size_limit};
        signal(SIGXFSZ, SIG_DFL); /* the CLI must ignore it itself, or it dies of it */
        if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(CLI_NOT_RUN);
    }
    if (env && env->seconds) alarm(env->seconds); /* survives exec */
#if !defined(CLI_SANITIZED)
    if (env && env->memory_limit > 0) {
        struct rlimit limit = {(rlim_t)env->memory_limit, (rlim_t)env->memory_limit};
        if (setrlimit(RLIMIT_AS, &limit) != 0) _exit(CLI_NOT_RUN);
    }
#endif
    if (env && env->unprivileged && geteuid() == 0 && (setgid(CLI_NOBODY) != 0 || setuid(CLI_NOBODY) != 0))
        _exit(CLI_NOT_RUN);
    static char cmd[4 * FM_PATH_MAX + 4096];
    snprintf(cmd, sizeof cmd, "'%s' %s", FM_CLI, args);
    execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
    _exit(CLI_NOT_RUN);
}

/* Runs `flockmorph ARGS` (a shell word list) in env (NULL: as is); returns its exit status (-1 if it
 * did not exit normally) and leaves its output in g_out and g_err. */
static int cli_with(const cli_env *env, const char *args)
{
    char out[FM_PATH_MAX], err[FM_PATH_MAX];
    snprintf(out, sizeof out, "%s/cli_stdout_%ld.txt", FM_TEST_TMP, (long)getpid());
    snprintf(err, sizeof err, "%s/cli_stderr_%ld.txt", FM_TEST_TMP, (long)getpid());
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) cli_child(env, out, err, args);
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid) return -1;
    slurp(out, g_out, sizeof g_out);
    slurp(err, g_err, sizeof g_err);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static int cli(const char *args) { return cli_with(NULL, args); }

#define ENSURE_EXIT(args, code)                                                                   \
    do {                                                                                          \
        int rc_ = cli(args);                                                                      \
        ENSURE_MSG(rc_ == (code), "flockmorph %s: exit %d, expected %d\nstdout: %s\nstderr: %s", \
                   (args), rc_, (code), g_out, g_err);                                            \
    } while (0)

#endif
