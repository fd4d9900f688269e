/* Helpers shared by the commands: errors, option parsing, output directories, cache frames. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "cache_format.h"
#include "scene_internal.h"
#include "shot_checkpoint.h"

#include <omp.h>

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

double cli_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The command a usage text describes: the word after "usage: flockmorph " ("" for <command>). */
static void usage_command(const char *usage, char *cmd, size_t size)
{
    static const char prefix[] = "usage: flockmorph ";
    size_t len = 0;
    if (!strncmp(usage, prefix, sizeof prefix - 1)) {
        usage += sizeof prefix - 1;
        while (usage[len] >= 'a' && usage[len] <= 'z') len++;
    }
    snprintf(cmd, size, "%.*s", (int)FM_MIN(len, size - 1), usage);
}

int cli_usage_error(const char *usage, const char *fmt, const char *arg)
{
    char cmd[32];
    usage_command(usage, cmd, sizeof cmd);
    fprintf(stderr, "flockmorph: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\nsee 'flockmorph help%s%s'\n", cmd[0] ? " " : "", cmd);
    return FM_ERR_USAGE;
}

_Thread_local char cli_last_error[sizeof ((fm_error *)0)->message];

int cli_report(const fm_error *err)
{
    snprintf(cli_last_error, sizeof cli_last_error, "%s", err->message);
    fprintf(stderr, "flockmorph: error: %s\n", err->message);
    return err->status ? (int)err->status : FM_ERR_INTERNAL;
}

int cli_report_build(const fm_error *err)
{
    return err->status == FM_STOPPED ? FM_STOPPED : cli_report(err);
}

/* The length of a scene key at the start of msg followed by ": " ("source.mesh",
 * "obstacles.meshes[0]"; not a file name such as "wave_000.obj"), or 0; the key in key. */
static size_t leading_key(const char *msg, char *key, size_t size)
{
    size_t n = strspn(msg, "abcdefghijklmnopqrstuvwxyz0123456789_.[]");
    if (!n || n >= size || strncmp(msg + n, ": ", 2)) return 0;
    snprintf(key, size, "%.*s", (int)n, msg);
    return fm_scene_is_key(key) ? n : 0;
}

void cli_locate_key(const fm_scene_def *def, fm_error *err)
{
    char key[128], msg[sizeof err->message], where[FM_PATH_MAX + 64];
    size_t n = leading_key(err->message, key, sizeof key);
    if (!n || !def->scene_path[0]) return;
    snprintf(msg, sizeof msg, "%s", err->message + n + 2);
    fm_scene_key_location(def, key, where, sizeof where);
    fm_fail(err, err->status, "%s: %s", where, msg);
}

void cli_locate_quantum(const fm_scene_def *def, fm_error *err)
{
    if (!(def->cache_quantum > 0) || !strstr(err->message, CACHE_QUANTUM_FAILURE)) return;
    char msg[sizeof err->message], where[FM_PATH_MAX + 64];
    snprintf(msg, sizeof msg, "%s", err->message);
    fm_scene_key_location(def, "output.quantum", where, sizeof where);
    fm_fail(err, err->status, "%s: %s; a value v needs a quantum of at least |v| / 2^31: raise output.quantum, or set "
            "it to 0 (lossless)", where, msg);
}

int cli_check_json_path(const char *option, const char *path)
{
    json_t *t = json_string(path); /* jansson's UTF-8 check, the one stats.json meets */
    json_decref(t);
    if (t) return 0;
    fprintf(stderr, "flockmorph: error: %s %s: the path is not UTF-8 text; stats.json records it as JSON, which must "
            "be UTF-8: rename the directory or choose another -o\n", option, path);
    return FM_ERR_USAGE;
}

json_t *cli_json_string(const char *text)
{
    json_t *t = json_string(text);
    if (t) return t;
    char kept[4 * FM_PATH_MAX + 1];
    size_t n = 0;
    for (const unsigned char *c = (const unsigned char *)text; *c && n + 5 < sizeof kept; c++)
        n += (size_t)snprintf(kept + n, sizeof kept - n, *c < 0x80 ? "%c" : "\\x%02X", *c);
    return json_string(kept);
}

int cli_wants_help(int argc, char **argv)
{
    for (int i = 0; i < argc; i++)
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) return 1;
    return 0;
}

int cli_parse_number(const char *s, double *out)
{
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end || !isfinite(v)) return -1;
    *out = v;
    return 0;
}

int cli_parse_positive(const char *s, double *out)
{
    double v;
    if (cli_parse_number(s, &v) || !(v > 0.0)) return -1;
    *out = v;
    return 0;
}

int cli_parse_int(const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi) return -1;
    *out = v;
    return 0;
}

int cli_check_frame_pattern(const char *pattern) { return fm_one_integer_conversion(pattern) ? 0 : -1; }

int cli_frame_name(char *out, size_t size, const char *pattern, long frame)
{
    /* the one conversion becomes %ld, so an int-sized argument cannot be misread */
    char fmt[FM_PATH_MAX + 8];
    size_t j = 0;
    for (const char *p = pattern; *p && j + 4 < sizeof fmt; p++) {
        fmt[j++] = *p;
        if (*p != '%') continue;
        if (p[1] == '%') { fmt[j++] = *++p; continue; }
        while (*++p >= '0' && *p <= '9' && j + 4 < sizeof fmt) fmt[j++] = *p;
        fmt[j++] = 'l', fmt[j++] = 'd';
    }
    fmt[j] = 0;
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wformat-nonliteral"
    int len = snprintf(out, size, fmt, frame);
#pragma GCC diagnostic pop
    return len < 0 || (size_t)len >= size ? -1 : 0;
}

/* mkdir -p: creates dir and any missing parents; on failure `failed` names the one that failed. */
static int make_dirs(const char *dir, char *failed, size_t size)
{
    char path[FM_PATH_MAX];
    if (snprintf(path, sizeof path, "%s", dir) >= (int)sizeof path) return errno = ENAMETOOLONG, -1;
    for (char *p = path + 1;; p++) {
        if (*p && *p != '/') continue;
        char end = *p;
        *p = 0;
        if (mkdir(path, 0777) != 0 && errno != EEXIST) return snprintf(failed, size, "%s", path), -1;
        if (!end) return 0;
        *p = '/';
    }
}

/* An output name (or its .partial) that exists as a directory would fail only after the run. */
static int check_output_name(const char *dir, const char *name)
{
    char path[2 * FM_PATH_MAX];
    struct stat st;
    size_t longest = strlen(dir) + 1 + strlen(name) + strlen(".partial");
    if (longest >= FM_PATH_MAX) /* the file would fail to open only after the preprocessing, exit 3 */
        return fprintf(stderr, "flockmorph: error: -o %s: the path is too long: %s/%s.partial, which the run writes "
                       "there, would be %zu bytes, more than the %d a path may have; choose a shorter -o\n", dir, dir, name,
                       longest, FM_PATH_MAX - 1), FM_ERR_USAGE;
    for (int partial = 0; partial < 2; partial++) {
        snprintf(path, sizeof path, "%s/%s%s", dir, name, partial ? ".partial" : "");
        if (stat(path, &st) == 0 && S_ISDIR(st.st_mode))
            return fprintf(stderr, "flockmorph: error: -o %s: cannot write %s: a directory of that name is in the "
                           "way\n", dir, path), FM_ERR_USAGE;
    }
    return 0;
}

int cli_make_outdir(const char *dir, const char *const *names, int count)
{
    struct stat st;
    char failed[FM_PATH_MAX] = "";
    if (stat(dir, &st) == 0) {
        if (!S_ISDIR(st.st_mode))
            return fprintf(stderr, "flockmorph: error: -o %s: exists and is not a directory\n", dir), FM_ERR_USAGE;
    } else if (make_dirs(dir, failed, sizeof failed) != 0) {
        int e = errno;
        char step[FM_PATH_MAX + 16] = "";
        if (failed[0] && strcmp(failed, dir)) snprintf(step, sizeof step, " (creating %s)", failed);
        fprintf(stderr, "flockmorph: error: -o %s: cannot create the output directory%s: %s\n", dir, step, strerror(e));
        return FM_ERR_USAGE;
    }
    if (access(dir, W_OK | X_OK) != 0)
        return fprintf(stderr, "flockmorph: error: -o %s: cannot write to the output directory: %s\n", dir,
                       strerror(errno)), FM_ERR_USAGE;
    for (int i = 0; i < count; i++) {
        int rc = check_output_name(dir, names[i]);
        if (rc) return rc;
    }
    return 0;
}

static int g_lock_fd = -1;                  /* the held lock, until cli_unlock_outdir or exit */
static char g_lock_path[FM_PATH_MAX + 32];

/* Whether fd is still the file named path: the run that held the lock before may have removed
 * it between this run's open and its flock (it removes the file while it holds the lock). */
static int still_named(int fd, const char *path)
{
    struct stat held, named;
    return fstat(fd, &held) == 0 && lstat(path, &named) == 0 && held.st_dev == named.st_dev &&
           held.st_ino == named.st_ino;
}

/* flock(2) rather than a file whose existence is the lock: the kernel releases it when the run
 * ends in any way (kill -9 included), so a dead run never blocks the next. The descriptor is kept
 * open (and the lock held) until cli_unlock_outdir or the process's exit. */
int cli_lock_outdir(const char *dir)
{
    snprintf(g_lock_path, sizeof g_lock_path, "%s/" FM_OUTPUT_LOCK, dir);
    for (int attempt = 0; attempt < 100; attempt++) {
        int fd = open(g_lock_path, O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
        if (fd < 0)
            return fprintf(stderr, "flockmorph: error: -o %s: cannot create the lock file %s: %s\n", dir, g_lock_path,
                           strerror(errno)), FM_ERR_USAGE;
        if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
            int e = errno;
            close(fd);
            if (e == EWOULDBLOCK)
                return fprintf(stderr, "flockmorph: error: -o %s: another run uses this output directory (it holds %s); "
                               "wait for it to finish or choose another -o\n", dir, g_lock_path), FM_ERR_USAGE;
            return fprintf(stderr, "flockmorph: error: -o %s: cannot lock %s: %s\n", dir, g_lock_path, strerror(e)),
                   FM_ERR_USAGE;
        }
        if (still_named(fd, g_lock_path)) return g_lock_fd = fd, 0;
        close(fd); /* a finished run removed it: lock the file that is there now */
    }
    return fprintf(stderr, "flockmorph: error: -o %s: cannot lock %s: it keeps being replaced\n", dir, g_lock_path),
           FM_ERR_USAGE;
}

void cli_unlock_outdir(void)
{
    if (g_lock_fd < 0) return;
    unlink(g_lock_path); /* while still held: a run that opened it meanwhile sees it gone and retries */
    close(g_lock_fd);
    g_lock_fd = -1;
}

int cli_refuse_earlier_results(const char *dir, const char *cache_name)
{
    const char *names[] = {cache_name, FM_OUTPUT_STATS};
    for (int i = 0; i < 2; i++) {
        char path[2 * FM_PATH_MAX];
        struct stat st;
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        if (lstat(path, &st) == 0)
            return fprintf(stderr, "flockmorph: error: -o %s: holds the results of an earlier run (%s); pass --overwrite to "
                           "replace them, or choose another -o\n", dir, path), FM_ERR_USAGE;
    }
    return 0;
}

/* "WxH", each a whole number in [lo, hi] and nothing after: 0, or -1 (an overflowing
 * 4294967312x4294967312 and 64x64junk included). */
static int parse_size(const char *s, long lo, long hi, int *width, int *height)
{
    const char *x = strchr(s, 'x');
    char w[24];
    long wv, hv;
    if (!x || (size_t)(x - s) >= sizeof w) return -1;
    snprintf(w, sizeof w, "%.*s", (int)(x - s), s);
    if (cli_parse_int(w, lo, hi, &wv) || cli_parse_int(x + 1, lo, hi, &hv)) return -1;
    *width = (int)wv, *height = (int)hv;
    return 0;
}

int cli_parse_frame_options(int argc, char **argv, const char *usage, int optional_out, cli_frame_options *o)
{
    memset(o, 0, sizeof *o);
    o->width = 960, o->height = 540, o->view = "front";
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if ((!strcmp(a, "-o") || !strcmp(a, "--output")) && i + 1 < argc) o->out = argv[++i];
        else if (!strcmp(a, "--frame") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], -2000000000L, 2000000000L, &o->frame)) return cli_usage_error(usage, "--frame wants a whole number, not '%s'", argv[i]);
            o->has_frame = 1;
        } else if (!strcmp(a, "--size") && i + 1 < argc) {
            if (parse_size(argv[++i], 16, 16384, &o->width, &o->height))
                return cli_usage_error(usage, "--size wants WIDTHxHEIGHT between 16 and 16384, not '%s'", argv[i]);
        } else if (!strcmp(a, "--view") && i + 1 < argc) o->view = argv[++i];
        else if (a[0] == '-' && a[1]) return cli_usage_error(usage, "unknown or incomplete option '%s'", a);
        else if (!o->cache) o->cache = a;
        else return cli_usage_error(usage, "unexpected argument '%s'", a);
    }
    if (!o->cache) return cli_usage_error(usage, "%s", "no cache file given");
    if (!o->out && !optional_out) return cli_usage_error(usage, "%s", "no output file given (-o FILE)");
    return 0;
}

int cli_open_cache(const char *path, fm_cache_reader **reader)
{
    fm_error err = {0};
    *reader = fm_cache_open(path, &err);
    if (!*reader) return cli_report(&err);
    if (fm_cache_warning(*reader)[0]) fprintf(stderr, "flockmorph: warning: %s\n", fm_cache_warning(*reader));
    return 0;
}

int cli_pick_frame(const char *cache, uint32_t frames, long k, uint32_t *frame)
{
    long j = k < 0 ? k + (long)frames : k;
    if (j < 0 || j >= (long)frames) {
        fprintf(stderr, "flockmorph: error: %s has %ld frames (0..%ld); there is no frame %ld\n", cache, (long)frames, (long)frames - 1, k);
        return FM_ERR_USAGE;
    }
    *frame = (uint32_t)j;
    return 0;
}

int cli_parse_frame_range(const char *spec, cli_frame_range *range)
{
    memset(range, 0, sizeof *range);
    range->step = 1;
    const char *colon = strchr(spec, ':'), *second = colon ? strchr(colon + 1, ':') : NULL;
    char first[32] = "", last[32] = "";
    size_t len = colon ? (size_t)(colon - spec) : strlen(spec);
    size_t last_len = second ? (size_t)(second - colon - 1) : colon ? strlen(colon + 1) : 0;
    if (len >= sizeof first || last_len >= sizeof last) return -1;
    if (second && cli_parse_int(second + 1, 1, 2000000000L, &range->step)) return -1;
    memcpy(first, spec, len);
    if (colon) memcpy(last, colon + 1, last_len);
    else if (!len) return -1; /* "" is not a frame */
    if (first[0] && cli_parse_int(first, -2000000000L, 2000000000L, &range->first)) return -1;
    if (last[0] && cli_parse_int(last, -2000000000L, 2000000000L, &range->last)) return -1;
    range->has_first = first[0] != 0;
    range->has_last = colon ? last[0] != 0 : 1;
    if (!colon) range->last = range->first;
    return 0;
}

int cli_resolve_frame_range(const char *cache, uint32_t frames, const cli_frame_range *range, uint32_t *first, uint32_t *last)
{
    int rc = cli_pick_frame(cache, frames, range->has_first ? range->first : 0, first);
    if (!rc) rc = cli_pick_frame(cache, frames, range->has_last ? range->last : -1, last);
    if (!rc && *first > *last) {
        fprintf(stderr, "flockmorph: error: frame range %u:%u of %s is empty (first after last)\n", *first, *last, cache);
        rc = FM_ERR_USAGE;
    }
    if (!rc) *last = *first + (*last - *first) / (uint32_t)range->step * (uint32_t)range->step;
    return rc;
}

/* Opens the cache and reads the chosen frame (default last). */
int cli_load_frame(const cli_frame_options *o, fm_cache_reader **reader, float **verts, uint32_t *frame)
{
    fm_error err = {0};
    fm_cache_reader *r;
    int rc = cli_open_cache(o->cache, &r);
    if (rc) return rc;
    if ((rc = cli_pick_frame(o->cache, fm_cache_frames(r), o->has_frame ? o->frame : -1, frame))) return fm_cache_close(r), rc;
    *verts = malloc(sizeof(float) * 12 * (fm_cache_agents(r) ? fm_cache_agents(r) : 1));
    if (!*verts) return fm_cache_close(r), fprintf(stderr, "flockmorph: error: out of memory\n"), FM_ERR_MEMORY;
    if (fm_cache_read_frame(r, *frame, *verts, &err) != FM_OK) {
        free(*verts);
        fm_cache_close(r);
        return cli_report(&err);
    }
    *reader = r;
    return 0;
}

void cli_prep_progress(const char *stage, double fraction, void *user)
{
    if (*(const int *)user) fprintf(stderr, "\r\033[K  preprocessing: %-24s %3.0f%%", stage, 100 * fraction);
}

fm_cache_options cli_cache_options(const fm_scene_def *def)
{
    fm_cache_options copts = fm_default_cache_options();
    copts.compression_level = def->compression_level;
    copts.delta = def->cache_delta, copts.key_interval = def->cache_key_interval, copts.quantum = def->cache_quantum;
    copts.piece_agents = def->cache_piece_agents;
    return copts;
}

int cli_write_json(const char *path, json_t *j)
{
    fm_output_file out;
    fm_error err = {0};
    fm_status st = fm_output_open(&out, path, &err);
    if (st == FM_OK) {
        if (json_dumpf(j, out.f, JSON_INDENT(2) | JSON_REAL_PRECISION(10)) == 0 && fputc('\n', out.f) != EOF)
            st = fm_output_commit(&out, NULL, &err);
        else {
            int e = errno ? errno : EIO;
            fm_output_discard(&out);
            st = fm_fail(&err, FM_ERR_IO, "cannot write '%s': %s%s", path, strerror(e), fm_write_hint(e));
        }
    }
    json_decref(j);
    return st == FM_OK ? 0 : cli_report(&err);
}

double cli_agent_steps_per_second(const cli_run_record *r)
{
    return r->simulate_seconds > 0 ? (double)r->agents * (double)r->steps / r->simulate_seconds : 0;
}

json_t *cli_stats_json(const fm_scene_def *def, const cli_run_record *r)
{
    json_t *j = json_object();
    /* which flockmorph wrote it, so a pipeline can tell results of different builds apart */
    json_object_set_new(j, "version", json_string(FM_VERSION_STRING));
    if (r->options) cli_stats_provenance(j, r->options);
    json_object_set_new(j, "meshes", cli_meshes_json(def, def->group_count > 0 && def->group_index < 0 ? 0 : 1));
    json_object_set_new(j, "mode", json_string(r->mode));
    json_object_set_new(j, "agents", json_integer(r->agents));
    json_object_set_new(j, "frames", json_integer(r->frames));
    json_object_set_new(j, "steps", json_integer(r->steps));
    json_object_set_new(j, "time_step", json_real(r->time_step));
    json_object_set_new(j, "frame_rate", json_real(def->frame_rate));
    json_object_set_new(j, "preprocess_seconds", json_real(r->preprocess_seconds));
    json_object_set_new(j, "simulate_seconds", json_real(r->simulate_seconds));
    json_object_set_new(j, "output_seconds", json_real(r->output_seconds));
    json_object_set_new(j, "agent_steps_per_second", json_real(cli_agent_steps_per_second(r)));
    json_object_set_new(j, "steps_per_second", json_real(r->simulate_seconds > 0 ? (double)r->steps / r->simulate_seconds : 0));
    json_object_set_new(j, "threads", json_integer(r->threads));
    json_object_set_new(j, "ranks", json_integer(fm_dist_size(cli_dist))); /* MPI processes: threads each */
    json_object_set_new(j, "seed", json_integer((json_int_t)def->seed));
    cli_stats_cache_path(j, r->cache);
    if (r->options) json_object_set_new(j, "axes", cli_axes_json(&r->options->axes));
    return j;
}

void cli_run_outputs(const cli_run_options *o, const fm_scene_def *def, cli_outputs *out)
{
    snprintf(out->cache, sizeof out->cache, "%s/%s", o->outdir, def->cache_name);
    snprintf(out->stats, sizeof out->stats, "%s/" FM_OUTPUT_STATS, o->outdir);
    snprintf(out->checkpoint, sizeof out->checkpoint, "%s/" FM_OUTPUT_CHECKPOINT, o->outdir);
    snprintf(out->obstacles, sizeof out->obstacles, "%s/" FM_OUTPUT_OBSTACLES, o->outdir);
    out->threads = fm_threads(o->threads);
}

enum { DEFAULT_CHECKPOINT_SECONDS = 60 };

int64_t cli_checkpoint_every(const cli_run_options *o) { return o->checkpoint_every > 0 ? o->checkpoint_every : 0; }

double cli_checkpoint_seconds(const cli_run_options *o) { return o->checkpoint_every < 0 ? DEFAULT_CHECKPOINT_SECONDS : 0; }

void cli_remove_checkpoint(const cli_outputs *out)
{
    char partial[sizeof out->checkpoint + 16];
    snprintf(partial, sizeof partial, "%s.partial", out->checkpoint); /* left if killed while writing one */
    remove(out->checkpoint), remove(partial);
    fm_shot_ckpt_remove_groups(out->checkpoint); /* a shot's groups' files beside it */
}

void cli_start_over(const cli_outputs *out)
{
    if (access(out->checkpoint, F_OK) == 0)
        fprintf(stderr, "flockmorph: warning: starting over: %s of an interrupted run is removed (--resume "
                "continues such a run)\n", out->checkpoint);
    cli_remove_checkpoint(out); /* this run's cache replaces the one it describes */
    cli_remove_previous_results(out->cache, out->stats);
    remove(out->obstacles); /* render draws one it finds beside the cache: not a previous scene's */
}

int cli_check_checkpoint(const cli_run_options *o, const fm_scene_def *def)
{
    cli_outputs out;
    fm_error err = {0};
    cli_run_outputs(o, def, &out);
    if (def->group_count > 0) return cli_check_shot_checkpoint(out.checkpoint, def);
    return fm_checkpoint_check(out.checkpoint, def, &err) == FM_OK ? 0 : cli_report(&err);
}

/* Prints an argument so a shell reads it back unchanged. */
static void print_shell_word(FILE *f, const char *s)
{
    if (s[strspn(s, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-./=:,+@%")] == 0) {
        fputs(s, f);
        return;
    }
    fputc('\'', f);
    for (; *s; s++) *s == '\'' ? fputs("'\\''", f) : fputc(*s, f);
    fputc('\'', f);
}

static void print_resume_command(const cli_run_options *o)
{
    fputs("flockmorph run ", stderr);
    print_shell_word(stderr, o->scene);
    for (int i = 0; i < o->set_count; i++) fputs(" --set ", stderr), print_shell_word(stderr, o->sets[i]);
    if (o->wedge_file) {
        fputs(" --wedge-file ", stderr);
        print_shell_word(stderr, o->wedge_file);
        fprintf(stderr, " --wedge %ld", o->wedge);
    }
    fputs(" -o ", stderr);
    print_shell_word(stderr, o->outdir);
    fputs(" --resume\n", stderr);
}

int cli_report_interrupted(const cli_run_options *o, fm_cache_writer *cache, int64_t frames)
{
    fm_cache_writer_close_partial(cache);
    fprintf(stderr, "flockmorph: interrupted at frame %lld; checkpoint written; resume with: ", (long long)frames - 1);
    print_resume_command(o);
    return 128 + cli_stop_signal;
}

int cli_report_stopped_as_asked(const cli_run_options *o, fm_cache_writer *cache, int64_t frames)
{
    fm_cache_writer_close_partial(cache);
    fprintf(stderr, "flockmorph: stopped after frame %lld (--stop-after-frame); checkpoint written; continue with: ",
            (long long)frames - 1);
    print_resume_command(o);
    return 0;
}

int cli_report_failed(const cli_run_options *o, const cli_outputs *out, fm_cache_writer *cache, const fm_error *err)
{
    if (access(out->checkpoint, F_OK) != 0) return cli_fail_keeping_partial_cache(err, cache, out->cache);
    int rc = cli_report(err);
    fm_cache_writer_close_partial(cache);
    fprintf(stderr, "flockmorph: the last checkpoint and the partial cache are kept; once the problem is fixed, "
            "resume with: ");
    print_resume_command(o);
    return rc;
}

void cli_remove_previous_results(const char *cache, const char *stats)
{
    remove(cache), remove(stats);
}

/* The partial cache of a failed run: how many complete frames it holds, or removed if none. */
static void report_partial_cache(const char *cache)
{
    char partial[FM_PATH_MAX + 320];
    snprintf(partial, sizeof partial, "%s.partial", cache);
    fm_error ignored = {0};
    fm_cache_reader *r = fm_cache_open(partial, &ignored);
    if (r && fm_cache_frames(r) > 0)
        fprintf(stderr, "flockmorph: the %u complete frames written before the error are in %s (flockmorph inspect, "
                "export and render read it); delete it to free the space\n", fm_cache_frames(r), partial);
    else
        remove(partial);
    fm_cache_close(r);
    fprintf(stderr, "flockmorph: no stats.json was written: the run did not finish\n");
}

int cli_fail_keeping_partial_cache(const fm_error *err, fm_cache_writer *cache, const char *cache_path)
{
    int rc = cli_report(err);
    fm_cache_writer_close_partial(cache);
    report_partial_cache(cache_path);
    return rc;
}

int cli_agree(int rc, fm_error *err)
{
    fm_error shared = {0};
    if (err) shared = *err;
    if (!err || err->status != (fm_status)rc) shared.message[0] = 0; /* rc's reason was printed where it arose */
    int agreed = (int)fm_dist_agree(cli_dist, (fm_status)rc, &shared);
    if (agreed != rc && cli_is_root()) {
        if (shared.message[0]) cli_report(&shared);
        else fprintf(stderr, "flockmorph: another rank failed (exit status %d); FM_RANK_OUTPUT=1 shows its messages\n", agreed);
    }
    return agreed;
}

volatile sig_atomic_t cli_stop_signal;

/* The first SIGINT / SIGTERM asks the run to stop at the end of the frame; a second one (an
 * impatient user) takes the default action at once. */
static void on_stop_signal(int sig)
{
    if (cli_stop_signal) {
        signal(sig, SIG_DFL);
        raise(sig);
        return;
    }
    cli_stop_signal = sig;
}

static void handle_stop_signals(void (*handler)(int))
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = handler;
    sa.sa_flags = SA_RESTART; /* the cache writer's I/O carries on */
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}

void cli_catch_stop_signals(int catch) { handle_stop_signals(catch ? on_stop_signal : SIG_DFL); }

static volatile sig_atomic_t g_say_preparing_stopped; /* rank 0 says it; the other ranks end quietly */

/* During the model build, which cannot stop halfway (TetGen, sampling): say why, and end at once
 * with 128 + the signal, as an interrupted run does. Only write(2) and _exit(2) here: both are
 * async-signal-safe, stdio is not. Nothing was written yet but the manifest. */
static void on_signal_while_preparing(int sig)
{
    static const char term[] = "flockmorph: interrupted by SIGTERM while preparing the run (before frame 0): "
                               "nothing to save; run it again\n";
    static const char intr[] = "flockmorph: interrupted by SIGINT while preparing the run (before frame 0): "
                               "nothing to save; run it again\n";
    if (g_say_preparing_stopped) {
        ssize_t written = write(STDERR_FILENO, sig == SIGTERM ? term : intr, (sig == SIGTERM ? sizeof term : sizeof intr) - 1);
        (void)written; /* a message that could not be written is lost; the status still says it */
    }
    _exit(128 + sig);
}

void cli_end_on_stop_signals(int end)
{
    g_say_preparing_stopped = cli_is_root();
    handle_stop_signals(end ? on_signal_while_preparing : SIG_DFL);
}

fm_dist_totals cli_sum_totals(fm_dist_totals mine)
{
    fm_dist_sum_i64(cli_dist, &mine.migrated, 1);
    fm_dist_sum_i64(cli_dist, &mine.ghost_agent_steps, 1);
    fm_dist_sum_i64(cli_dist, &mine.bytes_sent, 1);
    mine.busiest_seconds = mine.busy_seconds;
    fm_dist_max_f64(cli_dist, &mine.busiest_seconds, 1);
    fm_dist_sum_f64(cli_dist, &mine.busy_seconds, 1); /* a timing: no result depends on its order */
    struct rusage usage;
    mine.peak_rss_bytes = getrusage(RUSAGE_SELF, &usage) == 0 ? (int64_t)usage.ru_maxrss * 1024 : 0; /* Linux: KiB */
    fm_dist_max_i64(cli_dist, &mine.peak_rss_bytes, 1);
    return mine;
}

json_t *cli_scale_out_json(const fm_dist_totals *t)
{
    double agent_steps = (double)FM_MAX(t->agent_steps, 1);
    return json_pack("{sIsfsfsfsfsIsI}", "ranks", (json_int_t)fm_dist_size(cli_dist), "bytes_sent_per_agent_step",
                     (double)t->bytes_sent / agent_steps, "halo_agents_per_agent_step",
                     (double)t->ghost_agent_steps / agent_steps, "load_imbalance",
                     t->agent_steps > 0 ? (double)t->max_rank_agent_steps * fm_dist_size(cli_dist) / (double)t->agent_steps : 1.0,
                     "busy_imbalance",
                     t->busy_seconds > 0 ? t->busiest_seconds * fm_dist_size(cli_dist) / t->busy_seconds : 1.0,
                     "migrations", (json_int_t)t->migrated, "max_rank_peak_rss_bytes", (json_int_t)t->peak_rss_bytes);
}

/* The OpenMP team started before any parallel region, where a failure is out of memory (exit 4)
 * rather than libgomp's exit 1 (fm_threads_start_team). */
int cli_threads_fit(int threads)
{
    const int e = fm_threads_start_team(threads);
    if (!e) return 0;
    fm_error err = {0};
    fm_fail(&err, e == EAGAIN ? FM_ERR_MEMORY : FM_ERR_INTERNAL, "cannot start %d threads: %s%s", threads, strerror(e),
            e == EAGAIN ? ": out of memory for their stacks (ulimit -v, or the thread limit); --threads 1 needs none" : "");
    return cli_report(&err);
}
