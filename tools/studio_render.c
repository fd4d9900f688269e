/* The studio's Render button (docs/studio.md, "Render"): `flockmorph run` of the saved scene as a
 * child process, the very command a farm runs, into the folder the studio was given with --output
 * (it writes nowhere else on its own). Its progress lines (--log-every 1) go to every page as
 * {"type": "render", "state": "running", "line": ...}, then its end with the exit status. */
#define _GNU_SOURCE
#include "studio.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

/* {"type": "render", "state", "line", "exit", "output"} to every page; with lock held. */
static void tell_render(studio *s, const char *state, const char *line, int exit_status)
{
    json_t *j = json_pack("{sssssssiss}", "type", "render", "state", state, "line", line, "exit", exit_status, "output",
                          s->render_dir);
    char *text = j ? json_dumps(j, JSON_COMPACT) : NULL;
    if (text) studio_broadcast(s, text);
    json_decref(j), free(text);
}

/* Reads the child's output a line at a time (at most one line to the pages every 0.25 s, and the
 * last), then its exit status. */
static void *render_main(void *arg)
{
    studio *s = arg;
    FILE *out = fdopen(s->render_fd, "r");
    char line[1024] = "", last[1024] = "";
    double told = 0;
    while (out && fgets(line, sizeof line, out)) {
        line[strcspn(line, "\n")] = 0;
        snprintf(last, sizeof last, "%s", line);
        if (cli_seconds() - told < 0.25) continue;
        told = cli_seconds();
        pthread_mutex_lock(&s->lock);
        tell_render(s, "running", line, -1);
        pthread_mutex_unlock(&s->lock);
    }
    if (out) fclose(out);
    int status = 0;
    while (waitpid(s->render_pid, &status, 0) < 0 && errno == EINTR) {}
    int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    pthread_mutex_lock(&s->lock);
    tell_render(s, code == 0 ? "finished" : "failed", last, code);
    s->rendering = 0;
    pthread_mutex_unlock(&s->lock);
    return NULL;
}

/* The child: this binary's `run`, stdout and stderr into the pipe, the signals unblocked (the
 * studio blocks them in every thread for its own wait) so that Ctrl-C's checkpoint works there. */
static int spawn_run(studio *s, int write_fd, pid_t *pid)
{
    /* --overwrite: Render again after an edit replaces the last render (the folder the studio was
     * started with --output for) */
    char *args[] = {"flockmorph", "run", s->path, "-o", s->render_dir, "--overwrite", "--log-every", "1", NULL};
    posix_spawn_file_actions_t fa;
    posix_spawnattr_t attr;
    sigset_t none;
    sigemptyset(&none);
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, write_fd, STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&fa, write_fd, STDERR_FILENO);
    posix_spawnattr_init(&attr);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK);
    int rc = posix_spawn(pid, "/proc/self/exe", &fa, &attr, args, environ);
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&attr);
    return rc;
}

/* With lock held: why a render cannot start now, or NULL. */
static const char *render_refusal(const studio *s)
{
    if (s->playback) return "render: a played cache has no scene to run";
    if (!s->render_dir[0]) return "render: start the studio with --output DIR to render (flockmorph run SCENE -o DIR)";
    if (s->rendering) return "render: a render is running";
    if (s->dirty) return "render: save the scene first (Render runs the saved file)";
    return NULL;
}

int studio_render_start(studio *s, char *msg, size_t size)
{
    int fds[2] = {-1, -1}, rc = -1;
    pthread_mutex_lock(&s->lock);
    const char *refused = render_refusal(s);
    if (!refused && s->render_joinable) pthread_join(s->render_thread, NULL), s->render_joinable = 0; /* the last one's */
    if (refused) snprintf(msg, size, "%s", refused);
    else if (pipe2(fds, O_CLOEXEC) != 0 || spawn_run(s, fds[1], &s->render_pid) != 0)
        snprintf(msg, size, "render: cannot start flockmorph run: %s", strerror(errno));
    else {
        s->render_fd = fds[0], fds[0] = -1;
        s->rendering = 1;
        if (pthread_create(&s->render_thread, NULL, render_main, s) == 0) s->render_joinable = 1, rc = 0;
        else kill(s->render_pid, SIGKILL), close(s->render_fd), s->rendering = 0;
        if (rc == 0) tell_render(s, "running", "started", -1);
        else snprintf(msg, size, "render: cannot start its reader thread");
    }
    pthread_mutex_unlock(&s->lock);
    if (fds[0] >= 0) close(fds[0]);
    if (fds[1] >= 0) close(fds[1]); /* the child has its own copy */
    return rc;
}

/* At the end: a render still running is stopped as Ctrl-C stops a run (its checkpoint written). */
void studio_render_stop(studio *s)
{
    pthread_mutex_lock(&s->lock);
    if (s->rendering) kill(s->render_pid, SIGTERM);
    int joinable = s->render_joinable;
    s->render_joinable = 0;
    pthread_mutex_unlock(&s->lock);
    if (joinable) pthread_join(s->render_thread, NULL);
}
