/* Checkpoint and resume (docs/resume.md): a run stopped, killed or interrupted and then resumed
 * finishes with the cache and stats.json of an uninterrupted run, byte for byte (timings aside);
 * a checkpoint of another scene or model, or a damaged one, is refused and never used.
 *
 * The scene: an octahedron flies 20 units around an octahedral obstacle through a time-varying
 * baked wind with MDE on, so every kind of state the step carries is exercised. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "flock.h"
#include "morph.h"
#include "test_macros.h"

#include <errno.h>
#include <jansson.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

#define DIR_ FM_TEST_TMP "/resume"
#define SCENE DIR_ "/scene.json"

/* ---------------------------------------------------------------- files */

static char *slurp(const char *path, size_t *len)
{
    *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 1 << 16;
    char *buf = malloc(cap + 1);
    while (buf) {
        *len += fread(buf + *len, 1, cap - *len, f);
        if (*len < cap) break;
        char *bigger = realloc(buf, 2 * cap + 1);
        if (!bigger) free(buf);
        buf = bigger, cap *= 2;
    }
    fclose(f);
    if (buf) buf[*len] = 0;
    return buf;
}

static int exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static long long file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (long long)st.st_size : -1;
}

/* 1 if both files exist and hold the same bytes. */
static int same_bytes(const char *a, const char *b)
{
    size_t na, nb;
    char *x = slurp(a, &na), *y = slurp(b, &nb);
    int same = x && y && na == nb && memcmp(x, y, na) == 0;
    free(x), free(y);
    return same;
}

/* stats.json without its timing keys, which differ between any two runs, and the command line and
 * start time, which differ between a run and its resumption: sorted, as text (malloc'ed). */
static char *stats_without_timings(const char *path)
{
    static const char *const varying[] = {"preprocess_seconds", "simulate_seconds", "output_seconds",
                                          "agent_steps_per_second", "steps_per_second", "command_line", "start_time"};
    json_t *j = json_load_file(path, 0, NULL);
    if (!j) return NULL;
    for (size_t i = 0; i < sizeof varying / sizeof varying[0]; i++) json_object_del(j, varying[i]);
    char *text = json_dumps(j, JSON_SORT_KEYS | JSON_INDENT(2) | JSON_REAL_PRECISION(17));
    json_decref(j);
    return text;
}

/* A regular octahedron |x| + |y| + |z| <= r with outward triangles. */
static void write_octahedron(const char *path, double r)
{
    FILE *f = fopen(path, "w");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (!f) return;
    fprintf(f, "v %g 0 0\nv %g 0 0\nv 0 %g 0\nv 0 %g 0\nv 0 0 %g\nv 0 0 %g\n", r, -r, r, -r, r, -r);
    for (int s = 0; s < 8; s++) { /* one face per octant; a reflection reverses the winding */
        int x = s & 1 ? 2 : 1, y = s & 2 ? 4 : 3, z = s & 4 ? 6 : 5;
        int odd = ((s & 1) + (s >> 1 & 1) + (s >> 2 & 1)) & 1;
        fprintf(f, "f %d %d %d\n", x, odd ? z : y, odd ? y : z);
    }
    fclose(f);
}

/* Creates dir with the mesh oct.obj and opens dir/scene.json for writing (NULL on failure). */
static FILE *create_scene(const char *dir)
{
    char path[FM_PATH_MAX];
    mkdir(dir, 0777);
    snprintf(path, sizeof path, "%s/oct.obj", dir);
    write_octahedron(path, 1.0);
    snprintf(path, sizeof path, "%s/scene.json", dir);
    FILE *f = fopen(path, "w");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    return f;
}

/* The test scene with n agents in dir (with its mesh), `seed` varying the parameters. */
static void write_scene_n(const char *dir, int seed, int n)
{
    FILE *f = create_scene(dir);
    if (!f) return;
    fprintf(f, "{\n"
               "  \"source\": {\"mesh\": \"oct.obj\", \"translate\": [-10, 0, 0]},\n"
               "  \"target\": {\"mesh\": \"oct.obj\", \"translate\": [10, 0, 0]},\n"
               "  \"n\": %d, \"speed0\": 4, \"launch_rate\": 200, \"seed\": %d,\n"
               "  \"time\": {\"frame_rate\": 24, \"time_step\": 0.0208333333333333333},\n"
               "  \"path\": {\"points\": [[0, 2.2, 0]]},\n"
               "  \"obstacles\": {\"meshes\": [{\"mesh\": \"oct.obj\", \"scale\": 1.5}], \"k_a\": 1.0, \"voxel\": 0.15},\n"
               "  \"mde\": {\"d_min\": 0.05},\n"
               "  \"style\": {\"grid\": [12, 12, 12], \"fields\": [{\"type\": \"wind\", \"direction\": [0, 1, 0],\n"
               "             \"speed\": 0.3, \"turbulence\": 0.3, \"scale\": 2, \"period\": 1}]}\n"
               "}\n", n, seed);
    fclose(f);
}

/* The test scene (1500 agents). */
static void write_scene(const char *dir, int seed) { write_scene_n(dir, seed, 1500); }

/* ---------------------------------------------------------------- in process */

static fm_morph_model *g_model;
static fm_scene_def g_def;

typedef struct stop_after {
    int64_t frame;             /* stop after this frame; < 0: once every phase has agents */
    int64_t stopped_after;
    volatile sig_atomic_t flag;
} stop_after;

static void stop_progress(const fm_run_info *info, int64_t frame, void *user)
{
    stop_after *sa = user;
    int all_phases = info->count[0] > 0 && info->count[1] > 0 && info->count[2] > 0 && info->count[3] > 0;
    if (!sa->flag && (sa->frame >= 0 ? frame >= sa->frame : all_phases)) sa->flag = 1, sa->stopped_after = frame;
}

/* An uninterrupted run to `cache`. */
static void run_whole(const char *cache, fm_morph_run_stats *rs)
{
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(g_model, 1, &err);
    fm_cache_writer *w = fm_cache_writer_create(cache, (uint64_t)g_model->n, g_def.frame_rate, g_def.compression_level, &err);
    ENSURE_MSG(s && w, "%s", err.message);
    if (!s || !w) return;
    ENSURE_MSG(fm_morph_run(g_model, s, w, NULL, NULL, rs, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    fm_morph_state_destroy(s);
}

/* Every saved member of two states holds the same bytes. */
static void ensure_same_state(const fm_morph_state *a, const fm_morph_state *b)
{
    for (int i = 0; i < fm_morph_state_member_count; i++) {
        const fm_store_member *mb = &fm_morph_state_members[i];
        const char *pa = (const char *)a + mb->offset, *pb = (const char *)b + mb->offset;
        size_t bytes = mb->bytes;
        if (mb->per_agent) {
            memcpy(&pa, pa, sizeof pa), memcpy(&pb, pb, sizeof pb);
            bytes *= (size_t)a->n;
        }
        ENSURE_MSG(memcmp(pa, pb, bytes) == 0, "member %s differs after the round trip", mb->name);
    }
}

/* Runs until the progress callback raises the stop flag after frame `stop_frame` (< 0: once
 * agents are in every phase), checkpointing every 5 frames; returns the stopped state (the caller
 * destroys it). */
static fm_morph_state *run_until_stopped(const char *cache, const char *ckpt, int64_t stop_frame, fm_morph_run_stats *rs)
{
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(g_model, 2, &err);
    fm_cache_writer *w = fm_cache_writer_create(cache, (uint64_t)g_model->n, g_def.frame_rate, g_def.compression_level, &err);
    ENSURE_MSG(s && w, "%s", err.message);
    if (!s || !w) return s;
    stop_after sa = {stop_frame, -1, 0};
    fm_run_control c = fm_default_run_control();
    c.progress = stop_progress, c.progress_user = &sa;
    c.checkpoint_path = ckpt, c.checkpoint_every = 5; /* the run saves its own checkpoint there */
    c.stop = &sa.flag;
    ENSURE_MSG(fm_morph_run_controlled(g_model, s, w, &c, rs, &err) == FM_STOPPED, "%s", err.message);
    ENSURE_MSG(sa.stopped_after >= 0 && rs->run.frames == sa.stopped_after + 1, "stopped with %lld frames, expected %lld",
               (long long)rs->run.frames, (long long)sa.stopped_after + 1);
    fm_cache_writer_close_partial(w);
    return s;
}

static void test_stop_restore_continue_same_bytes(void)
{
    const char *whole = DIR_ "/whole.fmc", *cache = DIR_ "/stopped.fmc", *ckpt = DIR_ "/inproc.fmck";
    fm_morph_run_stats ref, first, rest;
    run_whole(whole, &ref);
    ENSURE_MSG(ref.run.frames > 40 && ref.all_arrived, "the scene should take a while and finish: %lld frames", (long long)ref.run.frames);
    fm_morph_state *stopped = run_until_stopped(cache, ckpt, -1, &first); /* agents in every phase */
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(g_model, 1, &err);
    ENSURE_MSG(s && fm_morph_checkpoint_load(ckpt, g_model, s, &rest, &err) == FM_OK, "%s", err.message);
    if (stopped && s) ensure_same_state(stopped, s);
    ENSURE(rest.run.frames == first.run.frames && rest.inverted_tet_frames == first.inverted_tet_frames);
    ENSURE(memcmp(rest.mde_fraction, first.mde_fraction, sizeof(double) * (size_t)(first.run.frames - 1)) == 0);
    fm_cache_writer *w = fm_cache_writer_resume(cache, (uint32_t)rest.run.frames, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    fm_run_control c = fm_default_run_control();
    c.resume = 1;
    if (s && w) {
        ENSURE_MSG(fm_morph_run_controlled(g_model, s, w, &c, &rest, &err) == FM_OK, "%s", err.message);
        ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    }
    ENSURE_MSG(same_bytes(whole, cache), "the resumed cache differs from the uninterrupted one");
    ENSURE(rest.run.frames == ref.run.frames && rest.run.steps == ref.run.steps && rest.all_arrived == ref.all_arrived);
    ENSURE(rest.inverted_tet_frames == ref.inverted_tet_frames && rest.morph_fallbacks == ref.morph_fallbacks);
    ENSURE(memcmp(rest.mde_fraction, ref.mde_fraction, sizeof(double) * (size_t)(ref.run.frames - 1)) == 0);
    ENSURE(memcmp(&rest.mde_fraction_mean, &ref.mde_fraction_mean, sizeof(double)) == 0);
    ENSURE(rest.final_max_vertex_error == ref.final_max_vertex_error);
    ENSURE(memcmp(&rest.min_obstacle_clearance, &ref.min_obstacle_clearance, sizeof(double)) == 0);
    ENSURE(memcmp(&rest.min_vertex_clearance, &ref.min_vertex_clearance, sizeof(double)) == 0);
    ENSURE_MSG(ref.min_vertex_clearance >= 0 && ref.min_vertex_clearance < 1.0, "vertex clearance %g",
               ref.min_vertex_clearance);
    ENSURE_MSG(ref.min_obstacle_clearance < 1.0, "the flock should pass the obstacle (clearance %g)", ref.min_obstacle_clearance);
    fm_morph_run_stats_free(&ref), fm_morph_run_stats_free(&first), fm_morph_run_stats_free(&rest);
    fm_morph_state_destroy(stopped), fm_morph_state_destroy(s);
}

typedef struct flush_probe {
    const char *partial;
    fm_cache_writer *w;
    int calls;
    int64_t frames[8];
    int on_disk_ok;
} flush_probe;

/* A checkpoint hook that checks the cache's frames are on disk when it is called. */
static fm_status probe_hook(int64_t frames, void *user, fm_error *err)
{
    flush_probe *p = user;
    if (p->calls < 8) p->frames[p->calls] = frames;
    p->calls++;
    fm_cache_reader *r = fm_cache_open(p->partial, err);
    p->on_disk_ok &= r && fm_cache_frames(r) == (uint32_t)frames && fm_cache_writer_frames(p->w) == (uint32_t)frames;
    fm_cache_close(r);
    return FM_OK;
}

/* Runs the scene with the probe as checkpoint hook; returns the frames written. */
static int64_t run_probed(flush_probe *p, int64_t every, double seconds)
{
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(g_model, 1, &err);
    fm_cache_writer *w = fm_cache_writer_create(DIR_ "/probe.fmc", (uint64_t)g_model->n, 24, 1, &err);
    ENSURE(s && w);
    if (!s || !w) return 0;
    *p = (flush_probe){DIR_ "/probe.fmc.partial", w, 0, {0}, 1};
    fm_run_control c = fm_default_run_control();
    c.checkpoint = probe_hook, c.checkpoint_user = p, c.checkpoint_every = every, c.checkpoint_seconds = seconds;
    fm_morph_run_stats rs;
    ENSURE(fm_morph_run_controlled(g_model, s, w, &c, &rs, &err) == FM_OK);
    ENSURE_MSG(p->on_disk_ok, "a checkpoint was taken before its frames were on disk");
    fm_cache_writer_abort(w);
    fm_morph_run_stats_free(&rs);
    fm_morph_state_destroy(s);
    return rs.run.frames;
}

static void test_checkpoints_every_k_frames_after_flush(void)
{
    flush_probe p;
    int64_t frames = run_probed(&p, 7, 0);
    ENSURE_MSG(p.calls == (int)((frames - 1) / 7), "%d checkpoints in %lld frames", p.calls, (long long)frames);
    for (int i = 0; i < p.calls && i < 8; i++) ENSURE(p.frames[i] == 7 * (i + 1));
    frames = run_probed(&p, 0, 1e-9); /* by wall time: due at every frame boundary */
    ENSURE_MSG(p.calls == (int)(frames - 1), "%d checkpoints in %lld frames", p.calls, (long long)frames);
    ENSURE(run_probed(&p, 0, 0) > 0 && p.calls == 0);
}

/* A checkpoint after 24 frames, written by run_until_stopped; returns its bytes. */
static char *checkpoint_bytes(size_t *len)
{
    fm_morph_run_stats rs;
    fm_morph_state *s = run_until_stopped(DIR_ "/damage.fmc", DIR_ "/damage.fmck", 23, &rs);
    fm_morph_run_stats_free(&rs), fm_morph_state_destroy(s);
    return slurp(DIR_ "/damage.fmck", len);
}

static fm_status load_bytes(const char *bytes, size_t len, fm_error *err)
{
    FILE *f = fopen(DIR_ "/damaged.fmck", "wb");
    if (!f) return FM_ERR_IO;
    fwrite(bytes, 1, len, f);
    fclose(f);
    fm_morph_state *s = fm_morph_state_create(g_model, 1, err);
    fm_morph_run_stats rs;
    fm_status st = fm_morph_checkpoint_load(DIR_ "/damaged.fmck", g_model, s, &rs, err);
    if (st == FM_OK) fm_morph_run_stats_free(&rs);
    fm_morph_state_destroy(s);
    return st;
}

static void test_damaged_checkpoints_refused(void)
{
    size_t len;
    char *good = checkpoint_bytes(&len);
    ENSURE(good && len > 1000);
    if (!good) return;
    fm_error err = {0};
    ENSURE_MSG(load_bytes(good, len, &err) == FM_OK, "%s", err.message);
    int refused = 0, tried = 0, checksum_named = 0;
    for (size_t at = 0; at < len; at += at < 80 ? 1 : 331, tried++) { /* every header byte, then a sample */
        good[at] ^= 0x10;
        fm_status st = load_bytes(good, len, &err);
        good[at] ^= 0x10;
        refused += st == FM_ERR_INPUT;
        checksum_named += strstr(err.message, "checksum mismatch") != NULL;
    }
    ENSURE_MSG(refused == tried, "%d of %d flipped bytes were refused", refused, tried);
    ENSURE(checksum_named > tried / 2);
    for (size_t cut = 0; cut < len; cut += len / 7 + 1)
        ENSURE_MSG(load_bytes(good, cut, &err) == FM_ERR_INPUT, "cut at %zu accepted", cut);
    free(good);
}

static void test_other_scene_or_model_refused(void)
{
    fm_error err = {0};
    fm_scene_def other = g_def;
    ENSURE(fm_checkpoint_check(DIR_ "/damage.fmck", &g_def, &err) == FM_OK);
    other.seed++;
    ENSURE(fm_checkpoint_check(DIR_ "/damage.fmck", &other, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "different scene"), "%s", err.message);
    other = g_def;
    snprintf(other.scene_path, sizeof other.scene_path, "elsewhere/scene.json"); /* where it lies: irrelevant */
    snprintf(other.source.path, sizeof other.source.path, "elsewhere/oct.obj");
    ENSURE_MSG(fm_checkpoint_check(DIR_ "/damage.fmck", &other, &err) == FM_OK, "%s", err.message);
    other = g_def;
    other.fields[0].speed = 0.31;
    ENSURE(fm_checkpoint_check(DIR_ "/damage.fmck", &other, &err) == FM_ERR_INPUT);
    ENSURE(fm_checkpoint_check(DIR_ "/missing.fmck", &g_def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "nothing to resume"), "%s", err.message);

    /* the same parameters on a different mesh: the model hash tells */
    mkdir(DIR_ "/bigger", 0777);
    write_octahedron(DIR_ "/bigger/oct.obj", 1.05);
    other = g_def;
    snprintf(other.target.path, sizeof other.target.path, "%s", DIR_ "/bigger/oct.obj");
    fm_morph_model *m = fm_morph_model_build(&other, NULL, NULL, &err);
    ENSURE_MSG(m != NULL, "%s", err.message);
    fm_morph_state *s = m ? fm_morph_state_create(m, 1, &err) : NULL;
    fm_morph_run_stats rs;
    if (s) ENSURE(fm_morph_checkpoint_load(DIR_ "/damage.fmck", m, s, &rs, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "different model"), "%s", err.message);
    fm_morph_state_destroy(s);
    fm_morph_model_destroy(m);
}

/* ---------------------------------------------------------------- the command line */

/* Removes what an earlier run left in out. */
static void clear_outputs(const char *out)
{
    static const char *const names[] = {"frames.fmc", "frames.fmc.partial", "stats.json", "checkpoint.fmck"};
    char path[FM_PATH_MAX + 32];
    for (int i = 0; i < 4; i++) snprintf(path, sizeof path, "%s/%s", out, names[i]), remove(path);
}

/* Starts `flockmorph run SCENE -o OUT ARGS...` with stdout and stderr to OUT.log; returns its pid. */
static pid_t start_scene(const char *scene, const char *out, const char *extra)
{
    char log[FM_PATH_MAX];
    snprintf(log, sizeof log, "%s.log", out);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    char *argv[16] = {(char *)FM_CLI, "run", (char *)scene, "-o", (char *)out, "--threads", "1", "--quiet"};
    char words[256];
    snprintf(words, sizeof words, "%s", extra);
    int argc = 8;
    for (char *w = strtok(words, " "); w && argc < 15; w = strtok(NULL, " ")) argv[argc++] = w;
    argv[argc] = NULL;
    pid_t pid = -1;
    ENSURE(posix_spawn(&pid, FM_CLI, &fa, NULL, argv, environ) == 0);
    posix_spawn_file_actions_destroy(&fa);
    return pid;
}

static pid_t start_run(const char *out, const char *extra) { return start_scene(SCENE, out, extra); }

/* The child's exit status, 128 + signal if a signal ended it. */
static int wait_status(pid_t pid)
{
    int status;
    if (waitpid(pid, &status, 0) != pid) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

static int run_to_end(const char *out, const char *extra) { return wait_status(start_run(out, extra)); }

static long long now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (long long)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static void sleep_ms(long ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* Polls (1 ms) until `path` is larger than `bytes`; 0 if the child exited first. */
static int wait_for_size(pid_t pid, const char *path, long long bytes)
{
    for (;;) {
        if (file_size(path) > bytes) return 1;
        if (waitpid(pid, NULL, WNOHANG) == pid) return 0;
        sleep_ms(1);
    }
}

static void copy_file(const char *from, const char *to)
{
    size_t len;
    char *bytes = slurp(from, &len);
    FILE *f = fopen(to, "wb");
    ENSURE(bytes && f);
    if (bytes && f) fwrite(bytes, 1, len, f);
    if (f) fclose(f);
    free(bytes);
}

/* DIR/NAME in one of a few rotating buffers (a test names a handful of files at once). */
static const char *in(const char *dir, const char *name)
{
    static char bufs[8][FM_PATH_MAX];
    static int next;
    char *buf = bufs[next++ % 8];
    snprintf(buf, FM_PATH_MAX, "%s/%s", dir, name);
    return buf;
}

/* A scene whose interrupted runs are compared with its uninterrupted one, kept as DIR/ref.fmc and
 * DIR/ref.json. Every run of a case writes to the same OUT, so stats.json's "cache" path is the same
 * too. */
typedef struct run_case {
    const char *scene, *dir, *out;
    long long ref_bytes; /* the reference cache's size: interruptions happen at fractions of it */
} run_case;

#define OUT DIR_ "/out"
static run_case g_tetra = {SCENE, DIR_, OUT, 0};

static void reference_run(run_case *c)
{
    clear_outputs(c->out);
    ENSURE_MSG(wait_status(start_scene(c->scene, c->out, "")) == 0, "see %s.log", c->out);
    ENSURE(rename(in(c->out, "frames.fmc"), in(c->dir, "ref.fmc")) == 0);
    ENSURE(rename(in(c->out, "stats.json"), in(c->dir, "ref.json")) == 0);
    c->ref_bytes = file_size(in(c->dir, "ref.fmc"));
}

/* Resumes the run in OUT and compares the finished cache and stats.json with the reference. */
static void resume_and_compare(const run_case *c, const char *what)
{
    int rc = wait_status(start_scene(c->scene, c->out, "--resume"));
    size_t len;
    char log_path[FM_PATH_MAX + 8];
    snprintf(log_path, sizeof log_path, "%s.log", c->out);
    char *log = slurp(log_path, &len);
    ENSURE_MSG(rc == 0, "%s: resume exited %d: %s", what, rc, log ? log : "");
    free(log);
    ENSURE_MSG(same_bytes(in(c->out, "frames.fmc"), in(c->dir, "ref.fmc")), "%s: the resumed cache differs", what);
    char *a = stats_without_timings(in(c->out, "stats.json")), *b = stats_without_timings(in(c->dir, "ref.json"));
    ENSURE_MSG(a && b && strcmp(a, b) == 0, "%s: stats.json differs:\n%s\nvs\n%s", what, a ? a : "", b ? b : "");
    free(a), free(b);
    ENSURE_MSG(!exists(in(c->out, "checkpoint.fmck")) && !exists(in(c->out, "frames.fmc.partial")), "%s: leftovers", what);
}

/* Frame `frame` of every attribute of an open cache, one after the other, into buf (malloc'ed). */
static size_t read_all_attrs(fm_cache_reader *r, uint32_t frame, unsigned char **buf)
{
    size_t bytes = 0, at = 0;
    for (int i = 0; i < fm_cache_attr_count(r); i++) bytes += fm_cache_attr_at(r, i)->bytes_per_agent * fm_cache_agents(r);
    *buf = malloc(bytes);
    fm_error err = {0};
    for (int i = 0; *buf && i < fm_cache_attr_count(r); i++) {
        const fm_cache_attr_info *a = fm_cache_attr_at(r, i);
        ENSURE_MSG(fm_cache_read_attr(r, frame, a->attr, *buf + at, &err) == FM_OK, "%s", err.message);
        at += a->bytes_per_agent * fm_cache_agents(r);
    }
    return bytes;
}

/* The complete frames of `partial` (at least 2, fewer than `whole` has) hold the bytes of `whole`'s,
 * attribute by attribute. */
static void ensure_prefix_of(const char *partial, const char *whole)
{
    fm_error err = {0};
    fm_cache_reader *p = fm_cache_open(partial, &err), *w = p ? fm_cache_open(whole, &err) : NULL;
    ENSURE_MSG(p && w, "%s", err.message);
    uint32_t frames = p && w ? fm_cache_frames(p) : 0;
    ENSURE_MSG(frames >= 2 && (!w || frames < fm_cache_frames(w)), "%u of %u frames", frames, w ? fm_cache_frames(w) : 0);
    for (uint32_t f = 0; f < frames; f++) {
        unsigned char *a, *b;
        size_t na = read_all_attrs(p, f, &a), nb = read_all_attrs(w, f, &b);
        ENSURE_MSG(a && b && na == nb && memcmp(a, b, na) == 0, "frame %u differs from the uninterrupted run's", f);
        free(a), free(b);
    }
    fm_cache_close(p), fm_cache_close(w);
}

static void kill9_then_resume(const run_case *c)
{
    clear_outputs(c->out);
    pid_t pid = start_scene(c->scene, c->out, "--checkpoint-every 5");
    int alive = wait_for_size(pid, in(c->out, "checkpoint.fmck"), 0);
    alive = alive && wait_for_size(pid, in(c->out, "frames.fmc.partial"), c->ref_bytes / 2); /* many frames later */
    ENSURE_MSG(alive, "the run ended before it could be killed");
    kill(pid, SIGKILL);
    ENSURE(wait_status(pid) == 128 + SIGKILL);
    ENSURE(exists(in(c->out, "checkpoint.fmck")) && exists(in(c->out, "frames.fmc.partial")) &&
           !exists(in(c->out, "frames.fmc")));
    resume_and_compare(c, "kill -9");
}

/* Interrupts a run with `sig` once it has written some frames (the previous run's results lying
 * in OUT), checks the exit status, the message and the files left: the checkpoint, and the partial
 * cache whose frames are the uninterrupted run's, no frames.fmc, no stats.json. Then resumes it. */
static void interrupt_then_resume(const run_case *c, int sig, int status, double fraction, const char *what)
{
    clear_outputs(c->out);
    copy_file(in(c->dir, "ref.fmc"), in(c->out, "frames.fmc"));
    copy_file(in(c->dir, "ref.json"), in(c->out, "stats.json"));
    pid_t pid = start_scene(c->scene, c->out, "--overwrite"); /* they go: the folder is refused without it */
    ENSURE_MSG(wait_for_size(pid, in(c->out, "frames.fmc.partial"), (long long)(fraction * (double)c->ref_bytes)),
               "%s: the run ended too soon", what);
    kill(pid, sig);
    int rc = wait_status(pid);
    size_t len;
    char log_path[FM_PATH_MAX + 8], resume[FM_PATH_MAX + 32];
    snprintf(log_path, sizeof log_path, "%s.log", c->out);
    snprintf(resume, sizeof resume, " -o %s --resume", c->out);
    char *log = slurp(log_path, &len);
    ENSURE_MSG(rc == status, "%s: exit %d, expected %d: %s", what, rc, status, log ? log : "");
    ENSURE_MSG(log && strstr(log, "interrupted at frame ") && strstr(log, "checkpoint written; resume with: flockmorph run ")
               && strstr(log, resume), "%s: %s", what, log ? log : "");
    free(log);
    ENSURE_MSG(exists(in(c->out, "checkpoint.fmck")) && !exists(in(c->out, "frames.fmc")) && !exists(in(c->out, "stats.json")),
               "%s: the checkpoint should be kept, no cache or stats.json left", what);
    ensure_prefix_of(in(c->out, "frames.fmc.partial"), in(c->dir, "ref.fmc"));
    resume_and_compare(c, what);
}

/* A run split into segments (--stop-after-frame, as under a farm's time limit): each exits 0 at its
 * frame with the checkpoint kept, saying how to continue; the last, a plain --resume, finishes with
 * the uninterrupted run's cache and stats.json. A segment's frame past the run's end just ends it. */
static void segments_then_resume(const run_case *c, const char *what)
{
    clear_outputs(c->out);
    static const char *const segments[] = {"--stop-after-frame 3", "--resume --stop-after-frame 9",
                                           "--resume --stop-after-frame 9"}; /* the third stops at once */
    for (int k = 0; k < 3; k++) {
        int rc = wait_status(start_scene(c->scene, c->out, segments[k]));
        size_t len;
        char log_path[FM_PATH_MAX + 8], said[64];
        snprintf(log_path, sizeof log_path, "%s.log", c->out);
        snprintf(said, sizeof said, "stopped after frame %d (--stop-after-frame)", k ? 9 : 3);
        char *log = slurp(log_path, &len);
        ENSURE_MSG(rc == 0 && log && strstr(log, said) && strstr(log, "checkpoint written; continue with: flockmorph run "),
                   "%s, %s: exit %d: %s", what, segments[k], rc, log ? log : "");
        free(log);
        ENSURE_MSG(exists(in(c->out, "checkpoint.fmck")) && !exists(in(c->out, "frames.fmc")), "%s: %s", what, segments[k]);
    }
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(in(c->out, "frames.fmc.partial"), &err);
    ENSURE_MSG(r && fm_cache_frames(r) == 10, "%s: %s", what, r ? "not 10 frames" : err.message);
    fm_cache_close(r);
    ensure_prefix_of(in(c->out, "frames.fmc.partial"), in(c->dir, "ref.fmc"));
    resume_and_compare(c, what);
}

static void test_segments_then_resume(void) { segments_then_resume(&g_tetra, "segments"); }

/* examples/wedges/segment.sh, as a farm's chain of tasks runs it: frames up to 4, up to 11, then
 * to an END past the run's end (it finishes), then once more (it does nothing): the finished cache
 * is the uninterrupted run's. */
static void test_segment_script(void)
{
    clear_outputs(OUT);
    static const char *const ends[] = {"4", "11", "2000000000", "2000000000"};
    for (int k = 0; k < 4; k++) {
        char cmd[4 * FM_PATH_MAX];
        snprintf(cmd, sizeof cmd, "FLOCKMORPH='%s' '%s/examples/wedges/segment.sh' '%s' '%s' %s --threads 1 --quiet "
                 "> '%s.log' 2>&1", FM_CLI, FM_SOURCE_DIR, SCENE, OUT, ends[k], OUT);
        int rc = system(cmd);
        size_t len;
        char *log = slurp(OUT ".log", &len);
        ENSURE_MSG(WIFEXITED(rc) && WEXITSTATUS(rc) == 0, "segment to %s: exit %d: %s", ends[k], WEXITSTATUS(rc),
                   log ? log : "");
        if (k == 3) ENSURE_MSG(log && strstr(log, "holds a finished run: nothing to do"), "%s", log ? log : "");
        free(log);
        ENSURE_MSG(exists(OUT "/checkpoint.fmck") == (k < 2), "segment to %s: the checkpoint", ends[k]);
    }
    ENSURE(same_bytes(OUT "/frames.fmc", DIR_ "/ref.fmc"));
}

static void test_kill9_then_resume(void) { kill9_then_resume(&g_tetra); }
/* SIGTERM while the model is built (examples/words at 3·10^5 tets: seconds of TetGen and
 * bisection before frame 0): the run says so and ends at once with 143, leaving no cache. Without
 * the handler the default action would end it with the same status but in silence. */
static void test_sigterm_while_preparing(void)
{
    const char *out = DIR_ "/preparing";
    char manifest[FM_PATH_MAX + 32], partial[FM_PATH_MAX + 32], log_path[FM_PATH_MAX + 8];
    snprintf(manifest, sizeof manifest, "%s/" FM_OUTPUT_MANIFEST, out);
    snprintf(partial, sizeof partial, "%s/frames.fmc.partial", out);
    snprintf(log_path, sizeof log_path, "%s.log", out);
    clear_outputs(out);
    remove(manifest);
    pid_t pid = start_scene(FM_SOURCE_DIR "/examples/words/scene.json", out, "--set n=300000");
    /* the manifest is written once the output folder is taken, just before the build */
    ENSURE_MSG(wait_for_size(pid, manifest, 0), "%s", "the run ended before it could be interrupted");
    sleep_ms(300);
    long long t0 = now_ms();
    kill(pid, SIGTERM);
    int rc = wait_status(pid);
    long long waited = now_ms() - t0;
    size_t len;
    char *log = slurp(log_path, &len);
    ENSURE_MSG(rc == 143, "exit %d, expected 143: %s", rc, log ? log : "");
    ENSURE_MSG(log && strstr(log, "flockmorph: interrupted by SIGTERM while preparing the run (before frame 0): nothing "
                                  "to save; run it again\n"), "no message: %s", log ? log : "");
    ENSURE_MSG(waited < 5000, "it took %lld ms to end", waited);
    ENSURE_MSG(!exists(partial), "%s", "a cache was started: the signal came after the build");
    free(log);
}

static void test_sigint_then_resume(void) { interrupt_then_resume(&g_tetra, SIGINT, 130, 0.6, "SIGINT"); }
static void test_sigterm_then_resume(void) { interrupt_then_resume(&g_tetra, SIGTERM, 143, 0.3, "SIGTERM"); }

/* `flockmorph run scene -o out --resume` exits 2 naming `why`, and writes no cache. */
static void ensure_refused(const char *scene_dir, const char *out, const char *why)
{
    char cmd[4 * FM_PATH_MAX], cache[FM_PATH_MAX + 16];
    snprintf(cache, sizeof cache, "%s/frames.fmc", out);
    long long cache_before = file_size(cache);
    snprintf(cmd, sizeof cmd, "'%s' run '%s/scene.json' -o '%s' --resume --quiet > '%s.log' 2>&1", FM_CLI, scene_dir, out, out);
    int rc = system(cmd);
    snprintf(cmd, sizeof cmd, "%s.log", out);
    size_t len;
    char *log = slurp(cmd, &len);
    ENSURE_MSG(WIFEXITED(rc) && WEXITSTATUS(rc) == 2 && log && strstr(log, why), "exit %d: %s", WEXITSTATUS(rc), log ? log : "");
    free(log);
    ENSURE(file_size(cache) == cache_before);
}

/* A checkpoint and partial cache of the (tetra) test scene in OUT, copied to `other_out` too. */
static void interrupted_run_copied_to(const char *other_out)
{
    clear_outputs(OUT);
    pid_t pid = start_run(OUT, "");
    ENSURE(wait_for_size(pid, OUT "/frames.fmc.partial", 300000));
    kill(pid, SIGINT);
    ENSURE(wait_status(pid) == 130);
    mkdir(other_out, 0777);
    clear_outputs(other_out);
    copy_file(OUT "/checkpoint.fmck", in(other_out, "checkpoint.fmck"));
    copy_file(OUT "/frames.fmc.partial", in(other_out, "frames.fmc.partial"));
}

static void test_cli_refuses_other_scene_and_damage(void)
{
    const char *other = DIR_ "/other";
    write_scene(other, 8); /* another seed */
    interrupted_run_copied_to(DIR_ "/other/out");
    ensure_refused(other, DIR_ "/other/out", "written for a different scene");

    size_t len;
    char *bytes = slurp(OUT "/checkpoint.fmck", &len);
    ENSURE(bytes && len > 100);
    if (!bytes) return;
    bytes[len / 2] ^= 1;
    FILE *f = fopen(OUT "/checkpoint.fmck", "wb");
    if (f) fwrite(bytes, 1, len, f), fclose(f);
    free(bytes);
    ensure_refused(DIR_, OUT, "checksum mismatch");
    ENSURE(exists(OUT "/checkpoint.fmck") && exists(OUT "/frames.fmc.partial")); /* refused, not removed */

    /* without --resume the run starts over, says so, and finishes as usual */
    ENSURE(run_to_end(OUT, "--checkpoint-every 0") == 0);
    char *log = slurp(OUT ".log", &len);
    ENSURE_MSG(log && strstr(log, "warning: starting over"), "%s", log ? log : "");
    free(log);
    ENSURE(same_bytes(OUT "/frames.fmc", DIR_ "/ref.fmc") && !exists(OUT "/checkpoint.fmck"));
    ensure_refused(DIR_, OUT, "nothing to resume");
}

/* `flockmorph run SCENE -o OUT ARGS` while another run uses OUT: exit 1 at once, naming OUT and
 * saying another run uses it. */
static void ensure_locked_out(const char *scene, const char *out, const char *args)
{
    char cmd[4 * FM_PATH_MAX], log_path[FM_PATH_MAX + 16], expect[FM_PATH_MAX + 64];
    snprintf(log_path, sizeof log_path, "%s.second.log", out);
    snprintf(cmd, sizeof cmd, "'%s' run '%s' -o '%s' --quiet %s > '%s' 2>&1", FM_CLI, scene, out, args, log_path);
    long long t0 = now_ms();
    int rc = system(cmd);
    double seconds = (double)(now_ms() - t0) / 1000;
    size_t len;
    char *log = slurp(log_path, &len);
    snprintf(expect, sizeof expect, "-o %s: another run uses this output directory", out);
    ENSURE_MSG(WIFEXITED(rc) && WEXITSTATUS(rc) == 1 && log && strstr(log, expect), "second run %s: exit %d: %s", args,
               WEXITSTATUS(rc), log ? log : "");
    ENSURE_MSG(seconds < 5, "the second run took %.1f s to be refused", seconds);
    free(log);
}

/* Two runs into one output directory: while the first runs (LOCK_AGENTS agents, a few seconds), a
 * second (new or --resume) is refused and touches nothing, and the first finishes with the cache and
 * stats.json of an undisturbed run of the same scene. */
#define LOCK_DIR DIR_ "/lock"
#if defined(__SANITIZE_ADDRESS__)
/* The sanitizer build steps about 10 times slower: 20000 agents took 84 s of CPU a run there (7.7 s
 * in Release), and 2000 still outlast the two refused starts; the same code either way. */
#define LOCK_AGENTS 2000
#else
/* 10000 agents launch for 50 s of the scene's time (1200 frames), seconds of CPU after the first
 * checkpoint where a refused start takes a tenth of one; 20000 took 7.7 s of CPU a run, twice. */
#define LOCK_AGENTS 10000
#endif
static void test_second_run_into_same_outdir_refused(void)
{
    run_case c = {LOCK_DIR "/scene.json", LOCK_DIR, LOCK_DIR "/out", 0};
    write_scene_n(LOCK_DIR, 7, LOCK_AGENTS);
    mkdir(c.out, 0777);
    reference_run(&c); /* undisturbed, into the same OUT, so stats.json's "cache" is the same */
    clear_outputs(c.out);
    pid_t first = start_scene(c.scene, c.out, "--checkpoint-every 5");
    ENSURE_MSG(wait_for_size(first, in(c.out, "checkpoint.fmck"), 0), "the first run ended too soon");
    ensure_locked_out(c.scene, c.out, "");
    ensure_locked_out(c.scene, c.out, "--resume");
    ENSURE_MSG(waitpid(first, NULL, WNOHANG) == 0, "the first run ended before the second was refused: the test "
               "proves nothing");
    ENSURE(wait_status(first) == 0);
    ENSURE_MSG(same_bytes(in(c.out, "frames.fmc"), in(c.dir, "ref.fmc")), "the first run's cache differs from an "
               "undisturbed run's");
    char *a = stats_without_timings(in(c.out, "stats.json")), *b = stats_without_timings(in(c.dir, "ref.json"));
    ENSURE_MSG(a && b && strcmp(a, b) == 0, "the first run's stats.json differs:\n%s\nvs\n%s", a ? a : "", b ? b : "");
    free(a), free(b);
    ENSURE(!exists(in(c.out, "checkpoint.fmck")) && !exists(in(c.out, "frames.fmc.partial")));
    /* the lock went with the first run (and its file): the next run takes the directory (exit 0, not
     * 1); frame 0 shows that, so it stops there rather than run the scene a third time */
    ENSURE(!exists(in(c.out, FM_OUTPUT_LOCK)));
    ENSURE(wait_status(start_scene(c.scene, c.out, "--stop-after-frame 0 --overwrite")) == 0);
    ENSURE(exists(in(c.out, "checkpoint.fmck")) && exists(in(c.out, "frames.fmc.partial")));
}

/* ---------------------------------------------------------------- the shape flock */

/* A waving target (destinations and their velocities change every step, the tracking lag sums up),
 * a baked wind and a vortex (the style-field grid), an obstacle's push and floating agents: every
 * kind of state the flock's step carries. The obstacle's voxel is the tetra scene's 0.15: the
 * default (1/160 of the extent) made its distance grid 2.6 s of CPU of every model build in Release
 * and 8 s under the sanitizers, where a run's 100 frames take 0.3 s and 1.3 s (docs/testing.md). */
#define FLOCK_DIR DIR_ "/flock"
static run_case g_flock = {FLOCK_DIR "/scene.json", FLOCK_DIR, FLOCK_DIR "/out", 0};

static void write_flock_scene(void)
{
    FILE *f = create_scene(FLOCK_DIR);
    if (!f) return;
    fprintf(f, "{\n"
               "  \"mode\": \"shape_flock\",\n"
               "  \"source\": {\"mesh\": \"oct.obj\", \"translate\": [-10, 0, 0]},\n"
               "  \"target\": {\"mesh\": \"oct.obj\", \"translate\": [10, 0, 0], \"scale\": 2},\n"
               "  \"n\": 1500, \"seed\": 3, \"speed0\": 6,\n"
               "  \"time\": {\"frame_rate\": 24, \"time_step\": 0.0208333333333333333, \"frame_limit\": 100},\n"
               "  \"path\": {\"points\": [[0, 5, 0]]},\n"
               "  \"obstacles\": {\"meshes\": [{\"mesh\": \"oct.obj\", \"translate\": [0, 2, 0]}], \"k_a\": 1.0, \"voxel\": 0.15},\n"
               "  \"style\": {\"grid\": [12, 12, 12], \"fields\": [{\"type\": \"wind\", \"direction\": [0, 1, 0],\n"
               "             \"speed\": 0.3, \"turbulence\": 0.3, \"scale\": 2, \"period\": 1},\n"
               "             {\"type\": \"vortex\", \"center\": [0, 0, 0], \"axis\": [0, 0, 1], \"strength\": 0.3}]},\n"
               "  \"shape_flock\": {\"sampling\": \"random\", \"path_time\": 2,\n"
               "                  \"arrival\": {\"mode\": \"float\"},\n"
               "                  \"deform\": {\"type\": \"wave\", \"amplitude\": 0.3, \"period\": 1}}\n"
               "}\n");
    fclose(f);
}

static void test_flock_segments_then_resume(void) { segments_then_resume(&g_flock, "flock segments"); }
static void test_flock_kill9_then_resume(void) { kill9_then_resume(&g_flock); }
static void test_flock_sigint_then_resume(void) { interrupt_then_resume(&g_flock, SIGINT, 130, 0.6, "flock SIGINT"); }
static void test_flock_sigterm_then_resume(void) { interrupt_then_resume(&g_flock, SIGTERM, 143, 0.3, "flock SIGTERM"); }

/* In process: a flock checkpoint restores the store into a fresh state (another thread count), and
 * is refused for the model of the same scene with other meshes under the same file names. */
static void test_flock_checkpoint_restores_or_refuses_model(void)
{
    fm_scene_def def;
    fm_error err = {0};
    ENSURE(fm_scene_load(g_flock.scene, &def, &err) == FM_OK);
    fm_flock_model *m = fm_flock_model_build(&def, NULL, NULL, &err);
    fm_flock_state *s = m ? fm_flock_state_create(m, 1, &err) : NULL, *t = m ? fm_flock_state_create(m, 2, &err) : NULL;
    ENSURE_MSG(s && t, "%s", err.message);
    if (!s || !t) return;
    for (int k = 0; k < 30; k++) fm_flock_step(m, s);
    s->lag_sum = 0.25;
    const char *path = in(FLOCK_DIR, "inprocess.fmck");
    double measures[2 * FM_FLOCK_MEASURES];
    for (int i = 0; i < 2 * FM_FLOCK_MEASURES; i++) measures[i] = 0.5 + i;
    fm_flock_run_stats saved = {.run = {.frames = 3, .simulate_seconds = 1.5}, .tracking_frames = 2, .measures = measures}, got;
    ENSURE_MSG(fm_flock_checkpoint_save(path, m, s, &saved, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(fm_flock_checkpoint_load(path, m, t, &got, &err) == FM_OK, "%s", err.message);
    ENSURE(got.run.frames == 3 && got.run.simulate_seconds == 1.5 && got.tracking_frames == 2);
    ENSURE(got.measures && !memcmp(got.measures, measures, sizeof measures)); /* the per-frame flock measures */
    fm_flock_run_stats_free(&got);
    ENSURE(t->step == 30 && t->time == s->time && t->lag_sum == 0.25 && !memcmp(&t->kalman, &s->kalman, sizeof s->kalman));
    /* by id: s's store is re-sorted in space (flock_resort.c), t's restored in id order */
    const size_t n = (size_t)s->n;
    float *fs = malloc(sizeof(float) * 10 * n), *ft = malloc(sizeof(float) * 10 * n);
    uint8_t *ps = malloc(n), *pt = malloc(n);
    fm_flock_frame(s, fs, fs + 3 * n, fs + 6 * n, ps), fm_flock_frame(t, ft, ft + 3 * n, ft + 6 * n, pt);
    ENSURE(!memcmp(fs, ft, sizeof(float) * 10 * n) && !memcmp(ps, pt, n));
    free(fs), free(ft), free(ps), free(pt);

    const char *other = FLOCK_DIR "/other";
    mkdir(other, 0777);
    copy_file(g_flock.scene, in(other, "scene.json"));
    write_octahedron(in(other, "oct.obj"), 1.1);
    fm_scene_def def2;
    ENSURE(fm_scene_load(in(other, "scene.json"), &def2, &err) == FM_OK);
    fm_flock_model *m2 = fm_flock_model_build(&def2, NULL, NULL, &err);
    fm_flock_state *u = m2 ? fm_flock_state_create(m2, 1, &err) : NULL;
    ENSURE_MSG(u != NULL, "%s", err.message);
    if (u) {
        ENSURE(fm_flock_checkpoint_load(path, m2, u, &got, &err) == FM_ERR_INPUT);
        ENSURE_MSG(strstr(err.message, "written for a different model: the samples"), "%s", err.message);
    }
    fm_flock_state_destroy(u), fm_flock_model_destroy(m2);
    fm_flock_state_destroy(s), fm_flock_state_destroy(t), fm_flock_model_destroy(m);
}

/* With R over the run each agent's own Kalman covariance is part of the store: saved and restored
 * (the run without it saves that member empty, above). */
static void test_flock_checkpoint_keeps_own_filters(void)
{
    fm_scene_def def;
    fm_error err = {0};
    ENSURE(fm_scene_load(g_flock.scene, &def, &err) == FM_OK);
    def.flock.kalman_r_over = FM_KALMAN_R_OVER_DISTANCE;
    def.flock.kalman_r_scale = (fm_fuzzy_def){.count = 2, .d = {0, 30}, .w = {1, 8}};
    fm_flock_model *m = fm_flock_model_build(&def, NULL, NULL, &err);
    fm_flock_state *s = m ? fm_flock_state_create(m, 1, &err) : NULL, *t = m ? fm_flock_state_create(m, 2, &err) : NULL;
    ENSURE_MSG(s && t && s->kalman_p && t->kalman_p, "%s", err.message);
    if (!s || !t || !s->kalman_p) return;
    for (int k = 0; k < 30; k++) fm_flock_step(m, s);
    ENSURE(s->kalman_p[0] != s->kalman_p[3 * (s->n - 1)]); /* the agents' filters differ */
    const char *path = in(FLOCK_DIR, "own_filters.fmck");
    double measures[FM_FLOCK_MEASURES] = {0};
    fm_flock_run_stats saved = {.run = {.frames = 2}, .measures = measures}, got;
    ENSURE_MSG(fm_flock_checkpoint_save(path, m, s, &saved, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(fm_flock_checkpoint_load(path, m, t, &got, &err) == FM_OK, "%s", err.message);
    fm_flock_run_stats_free(&got);
    int same = 1; /* by id: s's store is re-sorted in space, t's restored in id order */
    for (int64_t id = 0; id < s->n; id++)
        same &= !memcmp(t->kalman_p + 3 * fm_flock_slot_of(t, id), s->kalman_p + 3 * fm_flock_slot_of(s, id), 3 * sizeof(double));
    ENSURE(same);
    fm_flock_state_destroy(s), fm_flock_state_destroy(t), fm_flock_model_destroy(m);
}

/* One mode's checkpoint is another scene's for the other mode: refused, nothing changed. */
static void test_flock_refuses_tetra_checkpoint(void)
{
    interrupted_run_copied_to(g_flock.out);
    ensure_refused(FLOCK_DIR, g_flock.out, "written for a different scene");
    ENSURE(exists(in(g_flock.out, "checkpoint.fmck")) && exists(in(g_flock.out, "frames.fmc.partial")));
}

int main(void)
{
    write_scene(DIR_, 7);
    fm_error err = {0};
    if (fm_scene_load(SCENE, &g_def, &err) != FM_OK || !(g_model = fm_morph_model_build(&g_def, NULL, NULL, &err))) {
        fprintf(stderr, "cannot build the test scene: %s\n", err.message);
        return 1;
    }
    RUN_TEST(test_stop_restore_continue_same_bytes);
    RUN_TEST(test_checkpoints_every_k_frames_after_flush);
    RUN_TEST(test_damaged_checkpoints_refused);
    RUN_TEST(test_other_scene_or_model_refused);
    fm_morph_model_destroy(g_model);
    reference_run(&g_tetra);
    RUN_TEST(test_kill9_then_resume);
    RUN_TEST(test_segments_then_resume);
    RUN_TEST(test_segment_script);
    RUN_TEST(test_sigterm_while_preparing);
    RUN_TEST(test_sigint_then_resume);
    RUN_TEST(test_sigterm_then_resume);
    RUN_TEST(test_cli_refuses_other_scene_and_damage);
    RUN_TEST(test_second_run_into_same_outdir_refused);
    write_flock_scene();
    reference_run(&g_flock);
    RUN_TEST(test_flock_kill9_then_resume);
    RUN_TEST(test_flock_segments_then_resume);
    RUN_TEST(test_flock_sigint_then_resume);
    RUN_TEST(test_flock_sigterm_then_resume);
    RUN_TEST(test_flock_refuses_tetra_checkpoint);
    RUN_TEST(test_flock_checkpoint_restores_or_refuses_model);
    RUN_TEST(test_flock_checkpoint_keeps_own_filters);
    return test_result();
}
