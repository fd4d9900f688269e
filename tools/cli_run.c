/* flockmorph run: simulate a scene, write the cache and stats.json. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"

#include <jansson.h>

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
    "                        either mode)\n"
    "\n"
    "SIGINT (Ctrl-C) or SIGTERM saves a checkpoint at the end of the current frame and exits with\n"
    "status 130 or 143; a second signal ends the run at once. docs/resume.md has the details.\n";

static int parse_run(int argc, char **argv, cli_run_options *o)
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

static void frame_progress(const fm_morph_info *info, int64_t frame, void *user)
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

static json_t *mde_frames_json(const fm_morph_run_stats *rs)
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

static int write_stats(const char *path, const fm_scene_def *def, const fm_morph_model_info *mi, const fm_morph_run_stats *rs,
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

static fm_status save_checkpoint(const fm_morph_model *m, const fm_morph_state *s, const fm_morph_run_stats *rs, void *path, fm_error *err)
{
    return fm_morph_checkpoint_save(path, m, s, rs, err);
}

/* A new run's cache, or the interrupted run's state and the frames its cache already holds. */
static int open_run(const cli_run_options *o, const fm_scene_def *def, const fm_morph_model *model, const cli_outputs *files,
                    fm_morph_state *state, fm_morph_run_stats *rs, fm_cache_writer **cache)
{
    fm_error err = {0};
    if (!o->resume) {
        cli_start_over(files);
        fm_cache_options copts = cli_cache_options(def);
        const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_ID, FM_ATTR_PHASE};
        *cache = fm_cache_writer_create_attrs(files->cache, (uint64_t)fm_morph_model_get_info(model).agents, def->frame_rate,
                                              attrs, 3, &copts, &err);
        return *cache ? 0 : cli_report(&err);
    }
    if (fm_morph_checkpoint_load(files->checkpoint, model, state, rs, &err) != FM_OK) return cli_report(&err);
    *cache = fm_cache_writer_resume(files->cache, (uint32_t)rs->frames, &err);
    if (!*cache) return fm_morph_run_stats_free(rs), cli_report(&err);
    return 0;
}

static fm_run_control run_control(const cli_run_options *o, const cli_outputs *files, cli_progress *rp)
{
    fm_run_control c = fm_default_run_control();
    c.progress = frame_progress, c.progress_user = rp;
    c.resume = o->resume;
    c.checkpoint = save_checkpoint, c.checkpoint_user = (void *)files->checkpoint;
    c.checkpoint_every = cli_checkpoint_every(o);
    c.checkpoint_seconds = cli_checkpoint_seconds(o);
    c.stop = &cli_stop_signal;
    return c;
}

/* The cache, stats.json and the summary of a finished run; the checkpoint is no longer needed. */
static int finish_run(const fm_scene_def *def, const fm_morph_model_info *mi, const cli_outputs *files, fm_cache_writer *cache,
                      fm_morph_run_stats *rs, int threads, double prep_seconds, int64_t still_flying, run_warnings *warnings)
{
    fm_error err = {0};
    if (fm_cache_writer_finish(cache, &err) != FM_OK) /* finish keeps PATH.partial on failure */
        return fm_morph_run_stats_free(rs), cli_fail_keeping_partial_cache(&err, NULL, files->cache);
    if (!rs->all_arrived) {
        char text[256];
        snprintf(text, sizeof text, "stopped at the frame limit (%d frames) with %lld agents not yet arrived; "
                 "raise time.frame_limit in the scene", def->frame_limit, (long long)still_flying);
        add_warning(warnings, text);
    }
    const cli_run_record record = {"tetra_morph", mi->agents, rs->frames, rs->steps, mi->time_step, prep_seconds,
                                   rs->simulate_seconds, rs->output_seconds, threads, files->cache};
    int rc = write_stats(files->stats, def, mi, rs, &record, warnings);
    fm_morph_run_stats_free(rs);
    if (rc) return rc;
    cli_remove_checkpoint(files);
    printf("agents %lld, frames %lld, steps %lld, %.3g agent-steps/s\n", (long long)mi->agents, (long long)rs->frames,
           (long long)rs->steps, cli_agent_steps_per_second(&record));
    printf("cache: %s\nstats: %s\n", files->cache, files->stats);
    return 0;
}

static int simulate(const cli_run_options *o, const fm_scene_def *def, fm_morph_model *model, double prep_seconds,
                    run_warnings *warnings)
{
    fm_error err = {0};
    int show = !o->quiet && isatty(STDERR_FILENO);
    fm_morph_model_info mi = fm_morph_model_get_info(model);
    fm_morph_state *state = fm_morph_state_create(model, o->threads, &err);
    if (!state) return cli_report(&err);
    cli_outputs files;
    cli_run_outputs(o, def, &files);
    fm_cache_writer *cache = NULL;
    fm_morph_run_stats rs;
    int rc = open_run(o, def, model, &files, state, &rs, &cache);
    if (rc) return fm_morph_state_destroy(state), rc;
    cli_progress rp = {show, mi.agents, cli_seconds()};
    fm_run_control control = run_control(o, &files, &rp);
    cli_catch_stop_signals(1); /* fm_morph_run_controlled checkpoints and stops at the end of the frame */
    fm_status st = fm_morph_run_controlled(model, state, cache, &control, &rs, &err);
    cli_catch_stop_signals(0);
    if (show) fprintf(stderr, "\n");
    int64_t still_flying = mi.agents - fm_morph_get_info(state).run.count[FM_PHASE_ARRIVED];
    fm_morph_state_destroy(state);
    if (st == FM_STOPPED) return fm_morph_run_stats_free(&rs), cli_report_interrupted(o, cache, rs.frames);
    if (st != FM_OK) return fm_morph_run_stats_free(&rs), cli_report_failed(o, &files, cache, &err);
    return finish_run(def, &mi, &files, cache, &rs, files.threads, prep_seconds, still_flying, warnings);
}

int cli_run(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_RUN), 0;
    cli_run_options o;
    int rc = parse_run(argc, argv, &o);
    if (rc) return rc;
    fm_error err = {0};
    fm_scene_def def;
    if (fm_scene_load(o.scene, &def, &err) != FM_OK) return cli_report(&err);
    const char *outputs[] = {def.cache_name, "stats.json"};
    if ((rc = cli_make_outdir(o.outdir, outputs, 2))) return rc;
    if (o.resume && (rc = cli_check_checkpoint(&o, &def))) return rc; /* before the long preprocessing */
    if (def.mode == FM_MODE_SHAPE_FLOCK) return cli_run_flock(&o, &def);
    int show = !o.quiet && isatty(STDERR_FILENO);
    double t0 = cli_seconds();
    fm_morph_model *model = fm_morph_model_build(&def, cli_prep_progress, &show, &err);
    double prep_seconds = cli_seconds() - t0;
    if (show) fprintf(stderr, "\n");
    if (!model) return cli_report(&err);
    run_warnings warnings = {json_array()};
    for (int i = 0; i < fm_morph_model_warning_count(model); i++) add_warning(&warnings, fm_morph_model_warning(model, i));
    rc = simulate(&o, &def, model, prep_seconds, &warnings);
    json_decref(warnings.list);
    fm_morph_model_destroy(model);
    return rc;
}

