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
    "usage: flockmorph run SCENE.json -o OUTDIR [--threads N] [--quiet]\n"
    "\n"
    "Reads the scene (docs/scene.md), tetrahedralizes and subdivides the meshes, simulates until\n"
    "every agent has arrived (or the scene's frame limit), and writes OUTDIR/<output.cache>\n"
    "(default frames.fmc, docs/cache-format.md) and OUTDIR/stats.json. OUTDIR is created if needed.\n"
    "\n"
    "  -o, --output DIR   output directory (required)\n"
    "  --threads N        worker threads (default: all cores); results do not depend on N\n"
    "  --quiet            no progress display (it is shown only on a terminal anyway)\n";


typedef struct run_options {
    const char *scene, *outdir;
    int threads, quiet;
} run_options;

static int parse_run(int argc, char **argv, run_options *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        long v;
        if ((!strcmp(a, "-o") || !strcmp(a, "--output")) && i + 1 < argc) o->outdir = argv[++i];
        else if (!strcmp(a, "--threads") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 1, 1024, &v)) return cli_usage_error(USAGE_RUN, "--threads wants a whole number from 1 to 1024, not '%s'", argv[i]);
            o->threads = (int)v;
        } else if (!strcmp(a, "--quiet") || !strcmp(a, "-q")) o->quiet = 1;
        else if (a[0] == '-') return cli_usage_error(USAGE_RUN, "unknown or incomplete option '%s'", a);
        else if (!o->scene) o->scene = a;
        else return cli_usage_error(USAGE_RUN, "unexpected argument '%s'", a);
    }
    if (!o->scene) return cli_usage_error(USAGE_RUN, "%s", "no scene file given");
    if (!o->outdir) return cli_usage_error(USAGE_RUN, "%s", "no output directory given (-o OUTDIR)");
    return 0;
}

static void prep_progress(const char *stage, double fraction, void *user)
{
    if (*(const int *)user) fprintf(stderr, "\r\033[K  preprocessing: %-24s %3.0f%%", stage, 100 * fraction);
}

typedef struct run_progress {
    int show;
    int64_t agents;
    double start;
} run_progress;

static void frame_progress(const fm_state_info *info, int64_t frame, void *user)
{
    const run_progress *p = user;
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

static int write_stats(const char *path, const fm_scene_def *def, const fm_model_info *mi, const fm_run_stats *rs,
                       int threads, double preprocess_seconds, const char *cache_path)
{
    json_t *j = json_object();
    json_object_set_new(j, "agents", json_integer(mi->agents));
    json_object_set_new(j, "source_tets", json_integer(mi->source_tets));
    json_object_set_new(j, "target_tets", json_integer(mi->target_tets));
    json_object_set_new(j, "frames", json_integer(rs->frames));
    json_object_set_new(j, "steps", json_integer(rs->steps));
    json_object_set_new(j, "time_step", json_real(mi->time_step));
    json_object_set_new(j, "frame_rate", json_real(def->frame_rate));
    json_object_set_new(j, "launch_rate", json_real(mi->launch_rate));
    json_object_set_new(j, "preprocess_seconds", json_real(preprocess_seconds));
    json_object_set_new(j, "simulate_seconds", json_real(rs->simulate_seconds));
    json_object_set_new(j, "output_seconds", json_real(rs->output_seconds));
    double rate = rs->simulate_seconds > 0 ? (double)mi->agents * (double)rs->steps / rs->simulate_seconds : 0;
    json_object_set_new(j, "agent_steps_per_second", json_real(rate));
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
    json_object_set_new(j, "threads", json_integer(threads));
    json_object_set_new(j, "seed", json_integer((json_int_t)def->seed));
    json_object_set_new(j, "cache", json_string(cache_path));
    fm_output_file out;
    fm_error err = {0};
    fm_status st = fm_output_open(&out, path, &err);
    if (st == FM_OK) {
        if (json_dumpf(j, out.f, JSON_INDENT(2) | JSON_REAL_PRECISION(10)) == 0 && fputc('\n', out.f) != EOF)
            st = fm_output_commit(&out, NULL, &err);
        else
            fm_output_discard(&out), st = fm_fail(&err, FM_ERR_IO, "cannot write '%s'", path);
    }
    json_decref(j);
    return st == FM_OK ? 0 : cli_report(&err);
}

static int simulate(const run_options *o, const fm_scene_def *def, fm_model *model, double prep_seconds)
{
    fm_error err = {0};
    int show = !o->quiet && isatty(STDERR_FILENO);
    fm_model_info mi = fm_model_get_info(model);
    fm_state *state = fm_state_create(model, o->threads, &err);
    if (!state) return cli_report(&err);
    int threads = o->threads > 0 ? o->threads : omp_get_max_threads();
    char cache_path[FM_PATH_MAX + 300], stats_path[FM_PATH_MAX + 16];
    snprintf(cache_path, sizeof cache_path, "%s/%s", o->outdir, def->cache_name);
    snprintf(stats_path, sizeof stats_path, "%s/stats.json", o->outdir);
    fm_cache_options copts = fm_default_cache_options();
    copts.compression_level = def->compression_level;
    copts.delta = def->cache_delta, copts.key_interval = def->cache_key_interval, copts.quantum = def->cache_quantum;
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_PHASE};
    fm_cache_writer *cache = fm_cache_writer_create_attrs(cache_path, (uint64_t)mi.agents, def->frame_rate, attrs, 2, &copts, &err);
    if (!cache) return fm_state_destroy(state), cli_report(&err);
    run_progress rp = {show, mi.agents, cli_seconds()};
    fm_run_stats rs;
    fm_status st = fm_run(model, state, cache, frame_progress, &rp, &rs, &err);
    if (show) fprintf(stderr, "\n");
    int64_t still_flying = mi.agents - fm_state_get_info(state).count[FM_PHASE_ARRIVED];
    fm_state_destroy(state);
    if (st != FM_OK) return fm_cache_writer_abort(cache), fm_run_stats_free(&rs), cli_report(&err);
    if (fm_cache_writer_finish(cache, &err) != FM_OK) return fm_run_stats_free(&rs), cli_report(&err);
    int rc = write_stats(stats_path, def, &mi, &rs, threads, prep_seconds, cache_path);
    fm_run_stats_free(&rs);
    if (rc) return rc;
    printf("agents %lld, frames %lld, steps %lld, %.3g agent-steps/s\n", (long long)mi.agents, (long long)rs.frames,
           (long long)rs.steps, rs.simulate_seconds > 0 ? (double)mi.agents * (double)rs.steps / rs.simulate_seconds : 0.0);
    if (!rs.all_arrived)
        fprintf(stderr, "flockmorph: warning: stopped at the frame limit (%d frames) with %lld agents not yet arrived; "
                "raise time.frame_limit in the scene\n", def->frame_limit, (long long)still_flying);
    printf("cache: %s\nstats: %s\n", cache_path, stats_path);
    return 0;
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
    if ((rc = cli_make_outdir(o.outdir, &err))) return rc;
    int show = !o.quiet && isatty(STDERR_FILENO);
    double t0 = cli_seconds();
    fm_model *model = fm_model_build(&def, prep_progress, &show, &err);
    double prep_seconds = cli_seconds() - t0;
    if (show) fprintf(stderr, "\n");
    if (!model) return cli_report(&err);
    rc = simulate(&o, &def, model, prep_seconds);
    fm_model_destroy(model);
    return rc;
}

