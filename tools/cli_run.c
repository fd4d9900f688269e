/* flockmorph run: simulate a scene, write the cache and stats.json. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"

#include <jansson.h>
#include <omp.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *const USAGE_RUN =
    "usage: flockmorph run SCENE.json -o OUTDIR [--threads N] [--quiet] [--checkpoint-every K] [--resume]\n"
    "\n"
    "Reads the scene (docs/scene.md) and runs its mode: the tetra morph tetrahedralizes and\n"
    "subdivides the meshes and simulates until every agent has arrived; the shape flock\n"
    "(\"mode\": \"shape_flock\", docs/shape-flock.md) samples the surfaces and simulates until every\n"
    "agent is bound; both stop at the scene's frame limit. Writes OUTDIR/<output.cache> (default\n"
    "frames.fmc, docs/cache-format.md) and OUTDIR/stats.json. OUTDIR is created if needed.\n"
    "\n"
    "  -o, --output DIR      output directory (required)\n"
    "  --threads N           worker threads (default: all cores); results do not depend on N\n"
    "  --quiet               no progress display (it is shown only on a terminal anyway)\n"
    "  --checkpoint-every K  save the run to OUTDIR/checkpoint.fmck every K frames; 0: only when\n"
    "                        interrupted (default: every 60 s of wall time)\n"
    "  --resume              continue the run saved in OUTDIR/checkpoint.fmck (same scene;\n"
    "                        checkpoints are for the tetra morph only)\n"
    "\n"
    "SIGINT (Ctrl-C) or SIGTERM saves a checkpoint at the end of the current frame and exits with\n"
    "status 130 or 143; a second signal ends the run at once. docs/resume.md has the details.\n"
    "The shape flock has no checkpoints: it refuses --resume and --checkpoint-every, and a signal\n"
    "stops it at the end of the frame, keeping the frames so far readable as <cache>.partial.\n";

enum { DEFAULT_CHECKPOINT_SECONDS = 60 };
static const char CHECKPOINT_NAME[] = "checkpoint.fmck";

typedef struct run_options {
    const char *scene, *outdir;
    int threads, quiet, resume;
    long checkpoint_every; /* -1: by wall time (the default) */
} run_options;

static int parse_run(int argc, char **argv, run_options *o)
{
    memset(o, 0, sizeof *o);
    o->checkpoint_every = -1;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        long v;
        if ((!strcmp(a, "-o") || !strcmp(a, "--output")) && i + 1 < argc) o->outdir = argv[++i];
        else if (!strcmp(a, "--threads") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 1, 1024, &v)) return cli_usage_error(USAGE_RUN, "--threads wants a whole number from 1 to 1024, not '%s'", argv[i]);
            o->threads = (int)v;
        } else if (!strcmp(a, "--checkpoint-every") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 0, 2000000000L, &o->checkpoint_every))
                return cli_usage_error(USAGE_RUN, "--checkpoint-every wants a whole number of frames >= 0, not '%s'", argv[i]);
        } else if (!strcmp(a, "--resume")) o->resume = 1;
        else if (!strcmp(a, "--quiet") || !strcmp(a, "-q")) o->quiet = 1;
        else if (a[0] == '-') return cli_usage_error(USAGE_RUN, "unknown or incomplete option '%s'", a);
        else if (!o->scene) o->scene = a;
        else return cli_usage_error(USAGE_RUN, "unexpected argument '%s'", a);
    }
    if (!o->scene) return cli_usage_error(USAGE_RUN, "%s", "no scene file given");
    if (!o->outdir) return cli_usage_error(USAGE_RUN, "%s", "no output directory given (-o OUTDIR)");
    return 0;
}

static void frame_progress(const fm_state_info *info, int64_t frame, void *user)
{
    const cli_progress *p = user;
    if (!p->show) return;
    double done = (double)info->count[FM_PHASE_ARRIVED] / (double)p->agents;
    fprintf(stderr, "\r\033[K  frame %lld  t = %.2f s  waiting %lld  flying %lld  homing %lld  arrived %.1f%%  (%.0f s)",
            (long long)frame, info->time, (long long)info->count[0], (long long)info->count[1],
            (long long)info->count[2], 100 * done, cli_seconds() - p->start);
}

static json_t *vec3_json(const double v[3])
{
    return json_pack("[fff]", v[0], v[1], v[2]);
}

/* The velocity-model settings of the run (FM Table I's parameters, grid and style columns). */
static json_t *velocity_json(const fm_scene_def *def)
{
    static const char *const kinds[] = {"curl_noise", "wind", "gravity", "vortex"};
    json_t *fields = json_array();
    for (int i = 0; i < def->field_count; i++) {
        const fm_field_def *f = &def->fields[i];
        json_t *o = json_pack("{ss}", "type", kinds[f->kind]);
        if (f->kind == FM_FIELD_CURL_NOISE) json_object_set_new(o, "gain", json_real(f->gain)), json_object_set_new(o, "scale", json_real(f->scale));
        if (f->kind == FM_FIELD_WIND || f->kind == FM_FIELD_GRAVITY)
            json_object_set_new(o, "direction", vec3_json(f->direction)), json_object_set_new(o, "speed", json_real(f->speed));
        if (f->kind == FM_FIELD_WIND)
            json_object_set_new(o, "turbulence", json_real(f->turbulence)), json_object_set_new(o, "scale", json_real(f->scale)),
            json_object_set_new(o, "period", json_real(f->period));
        if (f->kind == FM_FIELD_VORTEX)
            json_object_set_new(o, "center", vec3_json(f->center)), json_object_set_new(o, "axis", vec3_json(f->axis)),
            json_object_set_new(o, "strength", json_real(f->strength));
        json_array_append_new(fields, o);
    }
    json_t *grid = def->field_grid[0] > 0 ? json_pack("[iii]", def->field_grid[0], def->field_grid[1], def->field_grid[2]) : json_null();
    return json_pack("{sfsfsosososisfsfsbsfsfsfsfss}", "omega1", def->omega1, "omega2", def->omega2, "fields", fields,
                     "field_grid", grid, "field_evaluation", json_string(def->field_grid[0] > 0 ? "baked" : "direct"),
                     "obstacles", def->obstacle_count, "k_a", def->k_a, "obstacle_voxel", def->obstacle_voxel,
                     "avoid_in_phase2", def->avoid_in_phase2 != 0, "d_min", def->d_min, "mde_speed", def->mde_speed,
                     "path_width", def->path_width, "path_attraction", def->path_attraction,
                     "phase_switch", def->phase_switch == FM_SWITCH_DISTANCE ? "distance" : "sphere");
}

static json_t *mde_frames_json(const fm_run_stats *rs)
{
    json_t *a = json_array();
    for (int64_t f = 0; f + 1 < rs->frames; f++)
        json_array_append_new(a, isnan(rs->mde_fraction[f]) ? json_null() : json_real(rs->mde_fraction[f]));
    return a;
}

/* The model's warnings and the run's own (stopped at the frame limit), printed and kept for stats.json. */
typedef struct run_warnings {
    json_t *list;
} run_warnings;

static void add_warning(run_warnings *w, const char *text)
{
    fprintf(stderr, "flockmorph: warning: %s\n", text);
    json_array_append_new(w->list, json_string(text));
}

static int write_stats(const char *path, const fm_scene_def *def, const fm_model_info *mi, const fm_run_stats *rs,
                       const cli_run_record *record, const run_warnings *warnings)
{
    json_t *j = cli_stats_json(def, record);
    json_object_set_new(j, "source_tets", json_integer(mi->source_tets));
    json_object_set_new(j, "target_tets", json_integer(mi->target_tets));
    json_object_set_new(j, "launch_rate", json_real(mi->launch_rate));
    json_object_set_new(j, "all_arrived", json_boolean(rs->all_arrived));
    json_object_set_new(j, "stopped_at_frame_limit", json_boolean(rs->stopped_at_frame_limit));
    json_object_set_new(j, "final_max_vertex_error", rs->all_arrived ? json_real(rs->final_max_vertex_error) : json_null());
    json_object_set_new(j, "target_tets_filled_once", json_boolean(rs->target_tets_filled_once));
    json_object_set_new(j, "inverted_tet_frames", json_integer(rs->inverted_tet_frames));
    json_object_set_new(j, "morph_fallbacks", json_integer(rs->morph_fallbacks));
    json_object_set_new(j, "mde_fraction_mean", json_real(rs->mde_fraction_mean));
    json_object_set_new(j, "mde_fraction_per_frame", mde_frames_json(rs));
    json_object_set_new(j, "min_obstacle_clearance",
                        isinf(rs->min_obstacle_clearance) ? json_null() : json_real(rs->min_obstacle_clearance));
    json_object_set_new(j, "velocity_model", velocity_json(def));
    json_object_set_new(j, "source_volume", json_real(mi->source_volume));
    json_object_set_new(j, "target_volume", json_real(mi->target_volume));
    json_object_set_new(j, "target_sphere_radius", json_real(mi->sphere_radius));
    json_object_set(j, "warnings", warnings->list);
    return cli_write_json(path, j);
}

static fm_status save_checkpoint(const fm_model *m, const fm_state *s, const fm_run_stats *rs, void *path, fm_error *err)
{
    return fm_checkpoint_save(path, m, s, rs, err);
}

typedef struct run_files {
    char cache[FM_PATH_MAX + 300], stats[FM_PATH_MAX + 16], checkpoint[FM_PATH_MAX + 32];
} run_files;

static void remove_checkpoint(const run_files *files)
{
    char partial[sizeof files->checkpoint + 16];
    snprintf(partial, sizeof partial, "%s.partial", files->checkpoint); /* left if killed while writing one */
    remove(files->checkpoint), remove(partial);
}

/* A new run's cache, or the interrupted run's state and the frames its cache already holds. */
static int open_run(const run_options *o, const fm_scene_def *def, const fm_model *model, const run_files *files,
                    fm_state *state, fm_run_stats *rs, fm_cache_writer **cache)
{
    fm_error err = {0};
    if (!o->resume) {
        if (access(files->checkpoint, F_OK) == 0)
            fprintf(stderr, "flockmorph: warning: starting over: %s of an interrupted run is removed (--resume "
                    "continues such a run)\n", files->checkpoint);
        remove_checkpoint(files); /* this run's cache replaces the one it describes */
        cli_remove_previous_results(files->cache, files->stats);
        fm_cache_options copts = fm_default_cache_options();
        copts.compression_level = def->compression_level;
        copts.delta = def->cache_delta, copts.key_interval = def->cache_key_interval, copts.quantum = def->cache_quantum;
        const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_PHASE};
        *cache = fm_cache_writer_create_attrs(files->cache, (uint64_t)fm_model_get_info(model).agents, def->frame_rate,
                                              attrs, 2, &copts, &err);
        return *cache ? 0 : cli_report(&err);
    }
    if (fm_checkpoint_load(files->checkpoint, model, state, rs, &err) != FM_OK) return cli_report(&err);
    *cache = fm_cache_writer_resume(files->cache, (uint32_t)rs->frames, &err);
    if (!*cache) return fm_run_stats_free(rs), cli_report(&err);
    return 0;
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

static void print_resume_command(const run_options *o)
{
    fputs("flockmorph run ", stderr);
    print_shell_word(stderr, o->scene);
    fputs(" -o ", stderr);
    print_shell_word(stderr, o->outdir);
    fputs(" --resume\n", stderr);
}

/* After a stop: the cache keeps its frames as .partial for --resume; exit 128 + signal. */
static int report_interrupted(const run_options *o, fm_cache_writer *cache, const fm_run_stats *rs)
{
    fm_cache_writer_close_partial(cache);
    fprintf(stderr, "flockmorph: interrupted at frame %lld; checkpoint written; resume with: ", (long long)rs->frames - 1);
    print_resume_command(o);
    return 128 + cli_stop_signal;
}

/* A run that failed (a full disk, say) after a checkpoint can still be resumed once the cause is
 * fixed: keep the checkpoint and the partial cache. Without one, the partial cache stays readable
 * up to its last complete frame (or goes, if it has none). */
static int report_failed(const run_options *o, const run_files *files, fm_cache_writer *cache, const fm_error *err)
{
    if (access(files->checkpoint, F_OK) != 0) return cli_fail_keeping_partial_cache(err, cache, files->cache);
    int rc = cli_report(err);
    fm_cache_writer_close_partial(cache);
    fprintf(stderr, "flockmorph: the last checkpoint and the partial cache are kept; once the problem is fixed, "
            "resume with: ");
    print_resume_command(o);
    return rc;
}

static fm_run_control run_control(const run_options *o, const run_files *files, cli_progress *rp)
{
    fm_run_control c = fm_default_run_control();
    c.progress = frame_progress, c.progress_user = rp;
    c.resume = o->resume;
    c.checkpoint = save_checkpoint, c.checkpoint_user = (void *)files->checkpoint;
    c.checkpoint_every = o->checkpoint_every > 0 ? o->checkpoint_every : 0;
    c.checkpoint_seconds = o->checkpoint_every < 0 ? DEFAULT_CHECKPOINT_SECONDS : 0;
    c.stop = &cli_stop_signal;
    return c;
}

/* The cache, stats.json and the summary of a finished run; the checkpoint is no longer needed. */
static int finish_run(const fm_scene_def *def, const fm_model_info *mi, const run_files *files, fm_cache_writer *cache,
                      fm_run_stats *rs, int threads, double prep_seconds, int64_t still_flying, run_warnings *warnings)
{
    fm_error err = {0};
    if (fm_cache_writer_finish(cache, &err) != FM_OK) /* finish keeps PATH.partial on failure */
        return fm_run_stats_free(rs), cli_fail_keeping_partial_cache(&err, NULL, files->cache);
    if (!rs->all_arrived) {
        char text[256];
        snprintf(text, sizeof text, "stopped at the frame limit (%d frames) with %lld agents not yet arrived; "
                 "raise time.frame_limit in the scene", def->frame_limit, (long long)still_flying);
        add_warning(warnings, text);
    }
    const cli_run_record record = {"tetra_morph", mi->agents, rs->frames, rs->steps, mi->time_step, prep_seconds,
                                   rs->simulate_seconds, rs->output_seconds, threads, files->cache};
    int rc = write_stats(files->stats, def, mi, rs, &record, warnings);
    fm_run_stats_free(rs);
    if (rc) return rc;
    remove_checkpoint(files);
    printf("agents %lld, frames %lld, steps %lld, %.3g agent-steps/s\n", (long long)mi->agents, (long long)rs->frames,
           (long long)rs->steps, rs->simulate_seconds > 0 ? (double)mi->agents * (double)rs->steps / rs->simulate_seconds : 0.0);
    printf("cache: %s\nstats: %s\n", files->cache, files->stats);
    return 0;
}

static int simulate(const run_options *o, const fm_scene_def *def, fm_model *model, double prep_seconds,
                    run_warnings *warnings)
{
    fm_error err = {0};
    int show = !o->quiet && isatty(STDERR_FILENO);
    fm_model_info mi = fm_model_get_info(model);
    fm_state *state = fm_state_create(model, o->threads, &err);
    if (!state) return cli_report(&err);
    int threads = o->threads > 0 ? o->threads : omp_get_max_threads();
    run_files files;
    snprintf(files.cache, sizeof files.cache, "%s/%s", o->outdir, def->cache_name);
    snprintf(files.stats, sizeof files.stats, "%s/stats.json", o->outdir);
    snprintf(files.checkpoint, sizeof files.checkpoint, "%s/%s", o->outdir, CHECKPOINT_NAME);
    fm_cache_writer *cache = NULL;
    fm_run_stats rs;
    int rc = open_run(o, def, model, &files, state, &rs, &cache);
    if (rc) return fm_state_destroy(state), rc;
    cli_progress rp = {show, mi.agents, cli_seconds()};
    fm_run_control control = run_control(o, &files, &rp);
    cli_catch_stop_signals(1); /* fm_run_controlled checkpoints and stops at the end of the frame */
    fm_status st = fm_run_controlled(model, state, cache, &control, &rs, &err);
    cli_catch_stop_signals(0);
    if (show) fprintf(stderr, "\n");
    int64_t still_flying = mi.agents - fm_state_get_info(state).count[FM_PHASE_ARRIVED];
    fm_state_destroy(state);
    if (st == FM_STOPPED) return fm_run_stats_free(&rs), report_interrupted(o, cache, &rs);
    if (st != FM_OK) return fm_run_stats_free(&rs), report_failed(o, &files, cache, &err);
    return finish_run(def, &mi, &files, cache, &rs, threads, prep_seconds, still_flying, warnings);
}

static int check_checkpoint(const run_options *o, const fm_scene_def *def)
{
    char path[FM_PATH_MAX + 32];
    fm_error err = {0};
    snprintf(path, sizeof path, "%s/%s", o->outdir, CHECKPOINT_NAME);
    return fm_checkpoint_check(path, def, &err) == FM_OK ? 0 : cli_report(&err);
}

int cli_run(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_RUN), 0;
    run_options o;
    int rc = parse_run(argc, argv, &o);
    if (rc) return rc;
    fm_error err = {0};
    fm_scene_def def;
    if (fm_scene_load(o.scene, &def, &err) != FM_OK) return cli_report(&err);
    const char *outputs[] = {def.cache_name, "stats.json"};
    if ((rc = cli_make_outdir(o.outdir, outputs, 2))) return rc;
    if (def.mode == FM_MODE_SHAPE_FLOCK) {
        if (o.resume || o.checkpoint_every > 0)
            return cli_usage_error(USAGE_RUN, "%s", "--resume and --checkpoint-every apply to the tetra morph only");
        const cli_run_options flock = {o.scene, o.outdir, o.threads, o.quiet};
        return cli_run_flock(&flock, &def);
    }
    if (o.resume && (rc = check_checkpoint(&o, &def))) return rc; /* before the long preprocessing */
    int show = !o.quiet && isatty(STDERR_FILENO);
    double t0 = cli_seconds();
    fm_model *model = fm_model_build(&def, cli_prep_progress, &show, &err);
    double prep_seconds = cli_seconds() - t0;
    if (show) fprintf(stderr, "\n");
    if (!model) return cli_report(&err);
    run_warnings warnings = {json_array()};
    for (int i = 0; i < fm_model_warning_count(model); i++) add_warning(&warnings, fm_model_warning(model, i));
    rc = simulate(&o, &def, model, prep_seconds, &warnings);
    json_decref(warnings.list);
    fm_model_destroy(model);
    return rc;
}

