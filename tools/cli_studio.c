/* flockmorph studio: shape the flock live in a browser, or play back a cache (docs/studio.md).
 * The pieces are in studio.h; this file is the command: its options, where the built page is,
 * the token and the address, and the wait for Ctrl-C. */
#define _GNU_SOURCE /* getrandom */
#include "cli.h"

#include <stdio.h>
#include <string.h>

static const char *const USAGE_STUDIO =
    "usage: flockmorph studio SCENE.json|CACHE.fmc [--port N] [--host H] [--no-browser] [-o DIR]\n"
    "\n"
    "Serves a page that shows the scene's flock as the engine runs it, with a timeline, the path's\n"
    "control points as handles to drag, a sketch mode and the main parameters; an edit runs the\n"
    "scene again from the start, and Save writes the scene file (what `flockmorph run` of it writes\n"
    "is, byte for byte, what the page showed). A cache (.fmc) is played back. Prints the address to\n"
    "open, which holds a random token every request needs. Ctrl-C ends it.\n"
    "\n"
    "  --port N       the port (default 8765; 0: any free one, printed)\n"
    "  --host H       the address to listen on (default 127.0.0.1: this machine only)\n"
    "  --no-browser   do not open the address in a browser\n"
    "  -o, --output DIR  where the page's Render button writes: `flockmorph run` of the saved\n"
    "                 scene with -o DIR (without it, Render is off: the studio writes only the scene)\n";

#ifdef FM_HAVE_STUDIO
#include "studio.h"

#include <errno.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

extern char **environ;

typedef struct studio_options {
    const char *input, *host, *output;
    long port;
    int no_browser;
} studio_options;

static int parse_studio(int argc, char **argv, studio_options *o)
{
    *o = (studio_options){.host = "127.0.0.1", .port = 8765};
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--port") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 0, 65535, &o->port))
                return cli_usage_error(USAGE_STUDIO, "--port wants a port number from 0 to 65535, not '%s'", argv[i]);
        } else if (!strcmp(a, "--host") && i + 1 < argc) {
            o->host = argv[++i];
            if (!o->host[0] || strlen(o->host) > 200 || strpbrk(o->host, ",:[] "))
                return cli_usage_error(USAGE_STUDIO, "--host wants an IPv4 address or a host name, not '%s'", o->host);
        } else if ((!strcmp(a, "-o") || !strcmp(a, "--output")) && i + 1 < argc) o->output = argv[++i];
        else if (!strcmp(a, "--no-browser")) o->no_browser = 1;
        else if (a[0] == '-') return cli_usage_error(USAGE_STUDIO, "unknown or incomplete option '%s'", a);
        else if (!o->input) o->input = a;
        else return cli_usage_error(USAGE_STUDIO, "unexpected argument '%s'", a);
    }
    if (!o->input) return cli_usage_error(USAGE_STUDIO, "%s", "no scene file or cache given");
    return 0;
}

/* 128 random bits as hex, from the kernel (as Jupyter's token). */
static int make_token(char *out)
{
    unsigned char bytes[STUDIO_TOKEN_CHARS / 2];
    if (getrandom(bytes, sizeof bytes, 0) != (ssize_t)sizeof bytes)
        return fprintf(stderr, "flockmorph: studio: no random bytes for the token: %s\n", strerror(errno)), FM_ERR_IO;
    for (size_t i = 0; i < sizeof bytes; i++) sprintf(out + 2 * i, "%02x", bytes[i]);
    return 0;
}

static int has_index(const char *dir)
{
    char path[FM_PATH_MAX + 200];
    struct stat st;
    snprintf(path, sizeof path, "%s/index.html", dir);
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* The built page: $FM_STUDIO_PAGE, else where `cmake --install` puts it beside the installed
 * binary (PREFIX/bin/flockmorph, PREFIX/share/flockmorph/studio), else the build tree's
 * (BUILD/flockmorph, BUILD/studio). "" when none holds index.html. */
static void find_page(char *out, size_t size)
{
    char exe[FM_PATH_MAX];
    const char *env = getenv("FM_STUDIO_PAGE");
    out[0] = 0;
    if (env && env[0]) { snprintf(out, size, "%s", env); return; }
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0) return;
    exe[n] = 0;
    char *slash = strrchr(exe, '/');
    if (!slash) return;
    *slash = 0;
    const char *tails[] = {"/../share/flockmorph/studio", "/studio"};
    for (size_t i = 0; i < 2; i++) {
        char dir[FM_PATH_MAX + 64];
        snprintf(dir, sizeof dir, "%s%s", exe, tails[i]);
        if (has_index(dir) && realpath(dir, out)) return;
    }
    out[0] = 0;
}

static int is_cache(const char *path)
{
    size_t n = strlen(path);
    return n > 4 && !strcmp(path + n - 4, ".fmc");
}

/* xdg-open where there is a desktop to open it on; a failure only means the user opens it. */
static void open_browser(const char *url)
{
    if (!getenv("DISPLAY") && !getenv("WAYLAND_DISPLAY")) return;
    char *args[] = {"xdg-open", (char *)url, NULL};
    pid_t pid;
    if (posix_spawnp(&pid, "xdg-open", NULL, NULL, args, environ) != 0)
        fprintf(stderr, "flockmorph: studio: could not start xdg-open; open the address yourself\n");
}

static int start(studio *s)
{
    int rc = make_token(s->token);
    if (!rc) rc = s->playback ? studio_playback_open(s) : studio_live_open(s);
    if (!rc) rc = studio_server_start(s);
    return rc;
}

/* Ctrl-C or SIGTERM; blocked in every thread first, so that only this wait takes them. */
static void wait_for_stop(const sigset_t *stop)
{
    int sig;
    while (sigwait(stop, &sig) != 0) {}
}

static int serve(studio *s, const studio_options *o)
{
    sigset_t stop;
    sigemptyset(&stop), sigaddset(&stop, SIGINT), sigaddset(&stop, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop, NULL); /* before any thread starts: they inherit it */
    int rc = start(s);
    if (!rc) {
        char url[400];
        const int everywhere = !strcmp(s->host, "0.0.0.0"); /* opened here as 127.0.0.1 */
        snprintf(url, sizeof url, "http://%s:%d/%s/", everywhere ? "127.0.0.1" : s->host, s->port, s->token);
        printf("flockmorph studio: %s %s\n  open %s\n  (Ctrl-C ends it)\n", s->playback ? "playing" : "running", s->path, url);
        if (everywhere) printf("  listening on every address: from elsewhere, this machine's name or address in place of 127.0.0.1\n");
        if (!s->page_dir[0]) printf("  the page is not built: tools/setup.sh builds it (Node and npm; docs/studio.md)\n");
        fflush(stdout);
        if (!o->no_browser) open_browser(url);
        wait_for_stop(&stop);
        printf("flockmorph studio: stopped\n");
    }
    studio_server_stop(s);
    studio_render_stop(s);
    if (s->playback && s->reader) fm_cache_close(s->reader);
    if (!s->playback) studio_live_close(s);
    return rc;
}

int cli_studio(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_STUDIO), 0;
    studio_options o;
    int rc = parse_studio(argc, argv, &o);
    if (rc) return rc;
    studio *s = calloc(1, sizeof *s);
    if (!s) return fprintf(stderr, "flockmorph: out of memory\n"), FM_ERR_MEMORY;
    snprintf(s->path, sizeof s->path, "%s", o.input);
    snprintf(s->host, sizeof s->host, "%s", o.host);
    snprintf(s->render_dir, sizeof s->render_dir, "%s", o.output ? o.output : "");
    s->port = (int)o.port;
    s->playback = is_cache(o.input);
    find_page(s->page_dir, sizeof s->page_dir);
    pthread_mutex_init(&s->lock, NULL);
    rc = serve(s, &o);
    pthread_mutex_destroy(&s->lock);
    free(s);
    return rc;
}

#else

int cli_studio(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_STUDIO), 0;
    fprintf(stderr, "flockmorph: this flockmorph was built without CivetWeb: install libcivetweb-dev "
                    "(tools/setup.sh does) and build again\n");
    return FM_ERR_USAGE;
}

#endif
