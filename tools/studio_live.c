/* The studio's live scene (docs/studio.md): the scene document and its edits, Save, and the
 * worker thread that runs the scene through `run`'s own path (cli_run_scene_hooked), keeping every
 * frame the cache writer is handed (its tap) for the timeline. An edit cancels the run at its next
 * frame boundary, or its model build at the build's next stage boundary (the keep carries the stop
 * flag: cli_run.c), and the worker starts over with the latest document: a slider drag that sends
 * twenty edits runs at most the one in progress and the last. */
#define _POSIX_C_SOURCE 200809L
#include "studio.h"
#include "geom.h"
#include "obstacles.h"
#include "scene_override.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

char *studio_scene_text(const json_t *doc)
{
    /* 17 significant digits read back as the same double (what the page's numbers were). */
    char *body = json_dumps(doc, JSON_INDENT(2) | JSON_REAL_PRECISION(17));
    if (!body) return NULL;
    size_t n = strlen(body);
    char *text = realloc(body, n + 2);
    if (!text) return free(body), NULL;
    memcpy(text + n, "\n", 2);
    return text;
}

/* The output keys that change only how the cache encodes the frames it is handed: not the frames
 * the page is streamed, nor those the reader decodes from `flockmorph run` of the saved scene. */
static const char *const ENCODING_KEYS[] = {"compression_level", "delta", "key_interval"};

/* What a run of doc simulates, as text to compare: doc without the encoding keys, keys sorted,
 * numbers as the run reads them. NULL: out of memory. */
static char *run_text(const json_t *doc)
{
    json_t *copy = json_deep_copy(doc), *out = copy ? json_object_get(copy, "output") : NULL;
    for (size_t i = 0; out && i < sizeof ENCODING_KEYS / sizeof ENCODING_KEYS[0]; i++) json_object_del(out, ENCODING_KEYS[i]);
    if (out && json_object_size(out) == 0) json_object_del(copy, "output"); /* as a scene without one */
    char *text = copy ? json_dumps(copy, JSON_COMPACT | JSON_SORT_KEYS | JSON_REAL_PRECISION(17)) : NULL;
    json_decref(copy);
    return text;
}

/* Whether the run of the current generation, building, running or finished (not cancelled, not
 * failed: an edit retries a failed run) with no edit's run due, runs what s->doc says: an edit that
 * left it so (a value set to the one it has, a handle let go where it was, only the cache's
 * encoding) needs no run. With lock held. */
static int runs_doc_already(const studio *s)
{
    static const char *const live[] = {"building", "running", "finished"};
    int going = 0;
    for (size_t i = 0; i < sizeof live / sizeof live[0]; i++) going |= s->stage && !strcmp(s->stage, live[i]);
    if (s->run_wanted || s->stop || !s->run_text || !going) return 0;
    char *text = run_text(s->doc);
    int same = text && !strcmp(text, s->run_text);
    free(text);
    return same;
}

/* Drops the kept frames (a new run starts); with lock held. */
static void drop_frames(studio *s)
{
    for (uint32_t k = 0; k < s->frame_count; k++) free(s->frames[k]);
    s->frame_count = 0, s->kept_bytes = 0, s->frames_dropped = 0;
}

void studio_keep_frame(studio *s, studio_frame *f)
{
    if (s->kept_bytes + f->bytes > STUDIO_MAX_KEPT_BYTES) s->frames_dropped = 1;
    if (!s->frames_dropped && s->frame_count == s->frame_cap) {
        uint32_t cap = s->frame_cap ? 2 * s->frame_cap : 256;
        studio_frame **grown = realloc(s->frames, cap * sizeof *grown);
        if (grown) s->frames = grown, s->frame_cap = cap;
        else s->frames_dropped = 1;
    }
    if (s->frames_dropped) return free(f);
    s->frames[s->frame_count++] = f;
    s->kept_bytes += f->bytes;
}

/* Status to every page, at most every 0.1 s while frames come (a run makes hundreds a second). */
static void tell_pages(studio *s, int always)
{
    double now = cli_seconds();
    if (!always && now - s->last_status < 0.1) return;
    s->last_status = now;
    char *text = studio_status_text(s);
    if (text) studio_broadcast(s, text);
    free(text);
}

/* The cache writer's tap: the very arrays the run's cache stores (run on the worker thread). */
typedef struct run_tap {
    studio *s;
    uint32_t generation;
    uint64_t agents;
    int attr_count;
    const fm_cache_attr_info *attrs[16];
} run_tap;

static void on_frame(uint32_t frame, const void *const *data, void *user)
{
    run_tap *t = user;
    studio_frame *f = studio_frame_make(t->generation, frame, t->agents, t->attr_count, t->attrs, data);
    pthread_mutex_lock(&t->s->lock);
    if (!f) t->s->frames_dropped = 1;
    else if (frame == t->s->frame_count) studio_keep_frame(t->s, f);
    else free(f);
    tell_pages(t->s, frame == 0);
    pthread_mutex_unlock(&t->s->lock);
}

static void on_cache(fm_cache_writer *cache, void *user)
{
    run_tap *t = user;
    t->agents = fm_cache_writer_agents(cache);
    t->attr_count = fm_cache_writer_attr_count(cache);
    if (t->attr_count > 16) t->attr_count = 16;
    for (int i = 0; i < t->attr_count; i++) t->attrs[i] = fm_cache_writer_attr_at(cache, i);
    pthread_mutex_lock(&t->s->lock);
    t->s->model_kept = t->s->keep.reused, t->s->groups_kept = t->s->keep.groups_reused;
    t->s->grids_kept = t->s->keep.grids_reused, t->s->routes_kept = t->s->keep.routes_reused;
    t->s->build_seconds = t->s->keep.build_seconds;
    t->s->agents = t->agents;
    snprintf(t->s->kind, sizeof t->s->kind, "%s", studio_kind(t->attr_count, t->attrs));
    if (!t->s->run_wanted) t->s->stage = "running"; /* else an edit cancels this run: "building" stands */
    tell_pages(t->s, 1);
    pthread_mutex_unlock(&t->s->lock);
    fm_cache_writer_set_tap(cache, on_frame, t);
}

/* {"name", "vertices": [x, y, z, ...], "triangles": [a, b, c, ...]}, placed as the run places it;
 * NULL where it does not load (the run then says why). */
static json_t *shape_json(const fm_scene_def *def, const fm_mesh_ref *ref, const char *key, int obstacle)
{
    fm_mesh m = {0};
    fm_error err = {0};
    fm_status st = obstacle >= 0 ? fm_obstacle_mesh_load(def, obstacle, NULL, NULL, &m, &err)
                                 : fm_scene_mesh_load(def, ref, key, &m, &err);
    if (st != FM_OK) return NULL;
    json_t *v = json_array(), *t = json_array();
    for (int64_t i = 0; i < 3 * m.nv; i++) json_array_append_new(v, json_real((float)m.v[i]));
    for (int64_t i = 0; i < 3 * m.nt; i++) json_array_append_new(t, json_integer(m.tri[i]));
    fm_mesh_free(&m);
    return json_pack("{ssso so}", "name", key, "vertices", v, "triangles", t);
}

/* Appends shape to list, with its group's index in a shot (group >= 0: the page draws a group's path
 * between its own shapes). */
static void add_shape(json_t *list, json_t *shape, int group)
{
    if (!shape) return;
    if (group >= 0) json_object_set_new(shape, "group", json_integer(group));
    json_array_append_new(list, shape);
}

/* A scene's source and target (a shape flock's first ones) and obstacles, onto list: a shot's group
 * `group`'s, or (-1) a scene's. */
static void add_shapes(json_t *list, const fm_scene_def *def, int group)
{
    add_shape(list, def->source.path[0] ? shape_json(def, &def->source, "source", -1) : NULL, group);
    add_shape(list, def->target.path[0] ? shape_json(def, &def->target, "target", -1) : NULL, group);
    for (int i = 0; i < def->obstacle_count; i++) add_shape(list, shape_json(def, NULL, "obstacle", i), group);
}

/* The "shapes" message: the scene's, or a shot's every group's (read from text, the edited scene). */
static char *shapes_text(const fm_scene_def *def, const char *text, uint32_t generation)
{
    json_t *list = json_array();
    fm_scene_def *group = def->group_count > 0 && text ? malloc(sizeof *group) : NULL;
    fm_error err = {0};
    if (!group) add_shapes(list, def, -1);
    for (int g = 0; group && g < def->group_count; g++)
        if (fm_scene_parse_group(text, strlen(text), def->scene_path, NULL, 0, g, group, &err) == FM_OK)
            add_shapes(list, group, g);
    free(group);
    json_t *j = json_pack("{sssIso}", "type", "shapes", "generation", (json_int_t)generation, "shapes", list);
    char *out = j ? json_dumps(j, JSON_COMPACT) : NULL;
    json_decref(j);
    return out;
}

static void run_once(studio *s, const fm_scene_def *def, const char *text, uint32_t generation)
{
    char *shapes = shapes_text(def, text, generation);
    pthread_mutex_lock(&s->lock);
    if (shapes) studio_broadcast(s, shapes), free(s->shapes), s->shapes = shapes;
    pthread_mutex_unlock(&s->lock);
    cli_run_options o = {.scene = s->path, .outdir = s->outdir, .quiet = 1, .checkpoint_every = -1,
                         .stop_after_frame = -1, .log_every = 10, .wedge = -1};
    cli_utc_now(o.start_time, sizeof o.start_time);
    run_tap tap = {.s = s, .generation = generation};
    const cli_run_hooks hooks = {&s->stop, on_cache, &tap, &s->keep, text}; /* keep: the worker's alone */
    cli_last_error[0] = 0;
    int rc = cli_run_scene_hooked(&o, def, &hooks);
    pthread_mutex_lock(&s->lock);
    if (generation == s->generation && !s->run_wanted) { /* else an edit's run is due: its stage stands */
        s->stage = rc == 0 ? "finished" : rc == FM_STOPPED ? "cancelled" : "failed";
        if (rc && rc != FM_STOPPED)
            snprintf(s->failure, sizeof s->failure, "the run failed (exit status %d): %s", rc,
                     cli_last_error[0] ? cli_last_error : "the studio's terminal has its message");
        tell_pages(s, 1);
    }
    pthread_mutex_unlock(&s->lock);
}

/* Waits (with lock held) until no edit came for STUDIO_EDIT_SETTLE seconds: edits that come faster
 * than that (a slider's drag, a script's burst) start one run, not one each, now that a kept model
 * builds in milliseconds. */
static void settle_edits(studio *s)
{
    for (double left; !s->quit && (left = s->last_edit + STUDIO_EDIT_SETTLE - cli_seconds()) > 0;) {
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        long ns = until.tv_nsec + (long)(left * 1e9);
        until.tv_sec += ns / 1000000000L, until.tv_nsec = ns % 1000000000L;
        pthread_cond_timedwait(&s->wake, &s->lock, &until);
    }
}

static void *worker_main(void *arg)
{
    studio *s = arg;
    fm_scene_def *def = malloc(sizeof *def);
    pthread_mutex_lock(&s->lock);
    while (def && !s->quit) {
        if (!s->run_wanted) { pthread_cond_wait(&s->wake, &s->lock); continue; }
        settle_edits(s);
        if (s->quit) break;
        *def = *s->def;
        char *text = studio_scene_text(s->doc); /* a shot's groups are read from it */
        free(s->run_text), s->run_text = run_text(s->doc);
        s->run_wanted = 0, s->stop = 0;
        uint32_t generation = ++s->generation;
        drop_frames(s);
        s->stage = "building", s->failure[0] = 0, s->agents = 0, s->model_kept = 0, s->groups_kept = 0;
        s->grids_kept = s->routes_kept = 0;
        s->build_seconds = 0;
        tell_pages(s, 1);
        pthread_mutex_unlock(&s->lock);
        run_once(s, def, text, generation);
        free(text);
        pthread_mutex_lock(&s->lock);
    }
    pthread_mutex_unlock(&s->lock);
    free(def);
    return NULL;
}

int studio_live_open(studio *s)
{
    fm_error err = {0};
    json_error_t jerr;
    s->def = malloc(sizeof *s->def);
    if (!s->def) return fprintf(stderr, "flockmorph: out of memory\n"), FM_ERR_MEMORY;
    if (fm_scene_load(s->path, s->def, &err) != FM_OK) return cli_report(&err); /* the file's own lines */
    /* the files it may read: the scene's and, in a shot, every group's as the file names them */
    s->first_count = 1 + s->def->group_count;
    if (!(s->first = malloc(sizeof *s->first * (size_t)s->first_count)))
        return fprintf(stderr, "flockmorph: out of memory\n"), FM_ERR_MEMORY;
    s->first[0] = *s->def;
    for (int g = 0; g < s->def->group_count; g++)
        if (fm_scene_load_group(s->path, NULL, 0, g, &s->first[1 + g], &err) != FM_OK) return cli_report(&err);
    if (!(s->doc = json_load_file(s->path, 0, &jerr)))
        return fprintf(stderr, "flockmorph: %s:%d:%d: %s\n", s->path, jerr.line, jerr.column, jerr.text), FM_ERR_INPUT;
    snprintf(s->outdir, sizeof s->outdir, "/tmp/flockmorph-studio-XXXXXX");
    if (!mkdtemp(s->outdir))
        return fprintf(stderr, "flockmorph: cannot make a scratch folder in /tmp: %s\n", strerror(errno)), FM_ERR_IO;
    s->stage = "building", s->run_wanted = 1, s->frame_rate = s->def->frame_rate;
    pthread_cond_init(&s->wake, NULL);
    if (pthread_create(&s->worker, NULL, worker_main, s))
        return fprintf(stderr, "flockmorph: cannot start the studio's worker thread\n"), FM_ERR_INTERNAL;
    s->worker_started = 1;
    return 0;
}

/* Removes the scratch folder's files (the live runs' cache, stats, obstacles) and the folder. */
static void remove_outdir(const char *dir)
{
    const char *names[] = {"frames.fmc", "frames.fmc.partial", "stats.json", "stats.json.partial", "obstacles.ply",
                           "obstacles.ply.partial", "checkpoint.fmck", ".flockmorph.lock"};
    char path[FM_PATH_MAX + 64];
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        snprintf(path, sizeof path, "%s/%s", dir, names[i]), remove(path);
    if (rmdir(dir) != 0 && errno != ENOENT)
        fprintf(stderr, "flockmorph: warning: the scratch folder %s is left (%s)\n", dir, strerror(errno));
}

void studio_live_close(studio *s)
{
    if (s->worker_started) {
        pthread_mutex_lock(&s->lock);
        s->quit = 1, s->stop = 1;
        pthread_cond_signal(&s->wake);
        pthread_mutex_unlock(&s->lock);
        pthread_join(s->worker, NULL);
        pthread_cond_destroy(&s->wake);
    }
    if (s->outdir[0]) remove_outdir(s->outdir);
    cli_model_keep_free(&s->keep);
    drop_frames(s);
    free(s->frames);
    free(s->shapes);
    free(s->run_text);
    free(s->first);
    free(s->def);
    json_decref(s->doc);
}

/* The loader's message without its "FILE:LINE:COL: ": the place is in the text Save would write,
 * not in the file as it is; the edit (as `run --set` names one) says where instead. */
static void edit_message(const char *path, const char *label, const char *message, char *msg, size_t size)
{
    size_t n = strlen(path);
    int line, col, used = 0;
    if (!strncmp(message, path, n) && sscanf(message + n, ":%d:%d: %n", &line, &col, &used) == 2 && used > 0)
        message += n + (size_t)used;
    snprintf(msg, size, "%s: %s", label, message);
}

static int other_files(const studio *s, const fm_scene_def *def, const char *label, char *msg, size_t size);

/* A shot's every group read from the candidate's text as `run` reads them (fm_scene_load_group), and
 * the files each names. 0, or -1 with msg. */
static int check_groups(studio *s, const char *text, int count, const char *label, char *msg, size_t size)
{
    fm_scene_def *group = malloc(sizeof *group);
    fm_error err = {0};
    int rc = group ? 0 : (snprintf(msg, size, "out of memory"), -1);
    for (int g = 0; rc == 0 && g < count; g++) {
        if (fm_scene_parse_group(text, strlen(text), s->path, NULL, 0, g, group, &err) != FM_OK)
            edit_message(s->path, label, err.message, msg, size), rc = -1;
        else rc = other_files(s, group, label, msg, size);
    }
    free(group);
    return rc;
}

/* The candidate document read as the loader reads a file (from the text Save would write): the
 * scene, or a shot's top level and each of its groups. */
static int check_doc(studio *s, const json_t *doc, const char *label, fm_scene_def *def, char *msg, size_t size)
{
    fm_error err = {0};
    char *text = studio_scene_text(doc);
    fm_status st = text ? fm_scene_parse(text, strlen(text), s->path, def, &err)
                        : fm_fail(&err, FM_ERR_MEMORY, "out of memory");
    if (st != FM_OK) edit_message(s->path, label, err.message, msg, size);
    int rc = st != FM_OK ? -1 : check_groups(s, text, def->group_count, label, msg, size);
    free(text);
    return rc;
}

/* Applies the edit as `--set KEY=VALUE` applies one (fm_overrides_apply): dotted keys, list
 * indices, null to go back to the default. */
static json_t *edited(const json_t *doc, const char *key, const json_t *value, fm_scene_def *scratch, char *msg,
                      size_t size)
{
    char *text = json_dumps(value, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_t *cand = text ? json_deep_copy(doc) : NULL;
    fm_error err = {0};
    const fm_scene_override o = {key, text, "studio"}; /* its messages: "studio: KEY=VALUE: ..." */
    if (cand && fm_overrides_apply(cand, &o, 1, scratch, &err) != FM_OK) {
        snprintf(msg, size, "%s", err.message);
        json_decref(cand), cand = NULL;
    } else if (!cand) snprintf(msg, size, "out of memory");
    free(text);
    return cand;
}

/* A mesh path the scene (or a group of a shot) named when the studio started: the files it may read. */
static int known_file(const studio *s, const char *path)
{
    if (!path[0]) return 1;
    for (int f = 0; f < s->first_count; f++) {
        const fm_scene_def *first = &s->first[f];
        if (!strcmp(path, first->source.path) || !strcmp(path, first->target.path) ||
            !strcmp(path, first->flock.deform_sequence))
            return 1;
        for (int i = 0; i < first->obstacle_count; i++)
            if (!strcmp(path, first->obstacles[i].path)) return 1;
    }
    return 0;
}

/* The studio reads only the scene's own meshes and writes only the scene (docs/studio.md, "Safety"):
 * an edit that names another file, or another cache name, is refused. 0, or -1 with msg. */
static int other_files(const studio *s, const fm_scene_def *def, const char *label, char *msg, size_t size)
{
    const char *bad = !known_file(s, def->source.path)                ? def->source.path
                      : !known_file(s, def->target.path)              ? def->target.path
                      : !known_file(s, def->flock.deform_sequence)    ? def->flock.deform_sequence
                      : strcmp(s->first->cache_name, def->cache_name) ? def->cache_name
                                                                      : NULL;
    for (int i = 0; !bad && i < def->obstacle_count; i++)
        if (!known_file(s, def->obstacles[i].path)) bad = def->obstacles[i].path;
    if (bad) snprintf(msg, size, "%s: the studio reads only the files the scene named when it started, and writes only "
                                 "the scene: '%.300s' is refused (edit the file, then start the studio again)", label, bad);
    return bad ? -1 : 0;
}

static int edit_here(studio *s, const char *key, const json_t *value, char *msg, size_t size)
{
    char label[320], *text = json_dumps(value, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(17));
    snprintf(label, sizeof label, "set %.64s=%.200s", key, text ? text : "?");
    free(text);
    fm_scene_def *def = calloc(1, sizeof *def);
    if (!def) return snprintf(msg, size, "out of memory"), -1;
    pthread_mutex_lock(&s->lock);
    json_t *cand = NULL;
    int rc = -1;
    if ((cand = edited(s->doc, key, value, def, msg, size)) && check_doc(s, cand, label, def, msg, size) == 0 &&
        other_files(s, def, label, msg, size) == 0) {
        json_decref(s->doc), s->doc = cand, cand = NULL;
        *s->def = *def;
        s->frame_rate = def->frame_rate;
        s->dirty = 1, rc = 0;
        if (runs_doc_already(s)) { /* the run shown is the edited scene's: its frames stand */
            s->unrun_edits++;
            tell_pages(s, 1);
        } else {
            s->run_wanted = 1, s->stop = 1; /* cancels the run in progress */
            s->last_edit = cli_seconds();
            s->stage = "building"; /* the edit's run, due once the edits settle: no page takes the run before it for it */
            tell_pages(s, 1);
            pthread_cond_signal(&s->wake);
        }
    }
    pthread_mutex_unlock(&s->lock);
    json_decref(cand);
    free(def);
    return rc;
}

int studio_live_save(studio *s, char *msg, size_t size)
{
    fm_output_file out;
    fm_error err = {0};
    pthread_mutex_lock(&s->lock);
    char *text = studio_scene_text(s->doc);
    fm_status st = text ? fm_output_open(&out, s->path, &err) : fm_fail(&err, FM_ERR_MEMORY, "out of memory");
    if (st == FM_OK && fputs(text, out.f) == EOF) {
        fm_output_discard(&out);
        st = fm_fail(&err, FM_ERR_IO, "cannot write '%s': %s", s->path, strerror(errno ? errno : EIO));
    } else if (st == FM_OK) st = fm_output_commit(&out, NULL, &err); /* fsync, then the rename */
    if (st == FM_OK) s->dirty = 0;
    pthread_mutex_unlock(&s->lock);
    free(text);
    if (st != FM_OK) snprintf(msg, size, "%s", err.message);
    return st == FM_OK ? 0 : -1;
}

typedef struct edit_call {
    studio *s;
    const char *key;
    const json_t *value;
    char *msg;
    size_t size;
    int rc;
} edit_call;

static void *edit_main(void *arg)
{
    edit_call *c = arg;
    c->rc = edit_here(c->s, c->key, c->value, c->msg, c->size);
    return NULL;
}

/* On a thread of its own: the loader keeps scene definitions (120 KiB each) on its stack, more
 * than CivetWeb's connection threads have. */
int studio_live_edit(studio *s, const char *key, const json_t *value, char *msg, size_t size)
{
    edit_call c = {s, key, value, msg, size, -1};
    pthread_attr_t attr;
    pthread_t t;
    pthread_attr_init(&attr);
    pthread_attr_setstacksize(&attr, (size_t)16 << 20);
    int started = pthread_create(&t, &attr, edit_main, &c) == 0;
    pthread_attr_destroy(&attr);
    if (!started) return snprintf(msg, size, "cannot start a thread for the edit"), -1;
    pthread_join(t, NULL);
    return c.rc;
}
