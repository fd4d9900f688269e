/* `run` for a shape-flock scene ("mode": "shape_flock"): sample, simulate, write the cache
 * (position, velocity, orientation, id, phase) and stats.json (cli_run.c drives it through
 * cli_mode_flock). */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"

#include <math.h>
#include <stdio.h>
#include <unistd.h>

static json_t *number_or_null(double x) { return isfinite(x) ? json_real(x) : json_null(); }

/* The settings that shape the result, for the record. */
static json_t *settings_json(const fm_scene_def *def, const fm_flock_model_info *mi)
{
    static const char *const sampling[] = {"random", "mosaic", "stratified"}, *const match[] = {"random", "spherical"};
    static const char *const deform[] = {"none", "wave", "pulse", "sequence"}, *const arrival[] = {"bind", "float"};
    const fm_flock_def *f = &def->flock;
    return json_pack("{sssssssfsfsfsfsssfsfsisisfsf}", "sampling", sampling[f->sampling], "match", match[f->match],
                     "deform", deform[f->deform], "kalman_q", f->kalman_q, "kalman_r_position", f->kalman_r_position,
                     "kalman_r_velocity", f->kalman_r_velocity, "arrival_radius", f->arrival_radius, "arrival_mode",
                     arrival[f->arrival_mode], "path_length", mi->path_length, "path_time", mi->path_time, "fields",
                     def->field_count, "obstacles", def->obstacle_count, "max_perception_radius", mi->max_radius, "mass",
                     f->mass);
}

/* The shape flock's run: the model, the state and the statistics. */
typedef struct flock_run {
    fm_flock_model *model;
    fm_flock_model_info mi;
    fm_flock_state *state;
    fm_flock_run_stats rs;
} flock_run;

static int write_stats(void *run, const fm_scene_def *def, const char *path, const cli_run_record *record)
{
    const flock_run *r = run;
    const fm_flock_model_info *mi = &r->mi;
    const fm_flock_run_stats *rs = &r->rs;
    json_t *j = cli_stats_json(def, record);
    json_object_set_new(j, "all_bound", json_boolean(rs->all_bound));
    json_object_set_new(j, "stopped_at_frame_limit", json_boolean(rs->stopped_at_frame_limit));
    json_object_set_new(j, "final_mean_distance", number_or_null(rs->final_mean_distance));
    json_object_set_new(j, "final_max_distance", number_or_null(rs->final_max_distance));
    json_object_set_new(j, "bound_fraction", json_real(rs->bound_fraction));
    json_object_set_new(j, "tracking_lag", number_or_null(rs->tracking_lag));
    json_object_set_new(j, "tracking_frames", json_integer(rs->tracking_frames));
    json_object_set_new(j, "shape_flock", settings_json(def, mi));
    return cli_write_json(path, j);
}

static int build(void *run, const fm_scene_def *def, int *show)
{
    flock_run *r = run;
    fm_error err = {0};
    r->model = fm_flock_model_build(def, cli_prep_progress, show, &err);
    if (!r->model) return cli_report(&err);
    r->mi = fm_flock_model_get_info(r->model);
    return 0;
}

/* A new run's cache, or the interrupted run's state and the frames its cache already holds. */
static int open_run(void *run, const cli_run_options *o, const fm_scene_def *def, const cli_outputs *out,
                    fm_cache_writer **cache)
{
    flock_run *r = run;
    fm_error err = {0};
    if (!(r->state = fm_flock_state_create(r->model, o->threads, &err))) return cli_report(&err);
    if (!o->resume) {
        cli_start_over(out);
        fm_cache_options copts = cli_cache_options(def);
        *cache = fm_flock_cache_create(out->cache, r->model, &copts, &err);
        return *cache ? 0 : cli_report(&err);
    }
    if (fm_flock_checkpoint_load(out->checkpoint, r->model, r->state, &r->rs, &err) != FM_OK) return cli_report(&err);
    *cache = fm_cache_writer_resume(out->cache, (uint32_t)r->rs.frames, &err);
    return *cache ? 0 : cli_report(&err);
}

static int64_t agents(const void *run)
{
    return ((const flock_run *)run)->mi.agents;
}

static fm_status simulate(void *run, fm_cache_writer *cache, const fm_run_control *control, fm_error *err)
{
    flock_run *r = run;
    return fm_flock_run_controlled(r->model, r->state, cache, control, &r->rs, err);
}

static int64_t frames(const void *run)
{
    return ((const flock_run *)run)->rs.frames;
}

static void totals(const void *run, cli_run_record *record)
{
    const flock_run *r = run;
    record->frames = r->rs.frames, record->steps = r->rs.steps, record->time_step = r->mi.time_step;
    record->simulate_seconds = r->rs.simulate_seconds, record->output_seconds = r->rs.output_seconds;
}

static void summary(const void *run, const fm_scene_def *def)
{
    const flock_run *r = run;
    const fm_flock_run_stats *rs = &r->rs;
    printf("; bound %.1f%%, distance to destination mean %.3g max %.3g\n", 100 * rs->bound_fraction,
           rs->final_mean_distance, rs->final_max_distance);
    if (!r->mi.deforming && def->flock.arrival_mode == FM_ARRIVAL_BIND && !rs->all_bound)
        fprintf(stderr, "flockmorph: warning: stopped at the frame limit (%d frames) with %.1f%% of the agents not yet bound; "
                "raise time.frame_limit in the scene\n", def->frame_limit, 100 * (1 - rs->bound_fraction));
}

static void close_run(void *run)
{
    flock_run *r = run;
    fm_flock_state_destroy(r->state);
    fm_flock_model_destroy(r->model);
}

const cli_mode cli_mode_flock = {"shape_flock", {NULL, "flying", "arriving", "bound"}, sizeof(flock_run), build,
                                 open_run, agents, simulate, frames, totals, write_stats, summary, close_run};
