/* flockmorph run for a shape-flock scene ("mode": "shape_flock"): sample, simulate, write the cache
 * (position, velocity, orientation, id, phase) and stats.json. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"

#include <math.h>
#include <stdio.h>
#include <unistd.h>

static void frame_progress(const fm_flock_info *info, int64_t frame, void *user)
{
    const cli_progress *p = user;
    if (!p->show) return;
    fprintf(stderr, "\r\033[K  frame %lld  t = %.2f s  flying %lld  arriving %lld  bound %.1f%%  (%.0f s)", (long long)frame,
            info->time, (long long)info->count[FM_PHASE_FLYING], (long long)info->count[FM_PHASE_HOMING],
            100.0 * (double)info->count[FM_PHASE_ARRIVED] / (double)p->agents, cli_seconds() - p->start);
}

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

static int write_stats(const char *path, const fm_scene_def *def, const fm_flock_model_info *mi,
                       const fm_flock_run_stats *rs, const cli_run_record *record)
{
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

static fm_status save_checkpoint(const fm_flock_model *m, const fm_flock_state *s, const fm_flock_run_stats *rs,
                                 void *path, fm_error *err)
{
    return fm_flock_checkpoint_save(path, m, s, rs, err);
}

/* A new run's cache, or the interrupted run's state and the frames its cache already holds. */
static int open_run(const cli_run_options *o, const fm_scene_def *def, const fm_flock_model *model,
                    const cli_outputs *out, fm_flock_state *state, fm_flock_run_stats *rs, fm_cache_writer **cache)
{
    fm_error err = {0};
    if (!o->resume) {
        cli_start_over(out);
        fm_cache_options copts = cli_cache_options(def);
        *cache = fm_flock_cache_create(out->cache, model, &copts, &err);
        return *cache ? 0 : cli_report(&err);
    }
    if (fm_flock_checkpoint_load(out->checkpoint, model, state, rs, &err) != FM_OK) return cli_report(&err);
    *cache = fm_cache_writer_resume(out->cache, (uint32_t)rs->frames, &err);
    return *cache ? 0 : cli_report(&err);
}

static int simulate(const cli_run_options *o, const fm_scene_def *def, const fm_flock_model *model, double prep_seconds)
{
    fm_error err = {0};
    fm_flock_model_info mi = fm_flock_model_get_info(model);
    fm_flock_state *state = fm_flock_state_create(model, o->threads, &err);
    if (!state) return cli_report(&err);
    cli_outputs out;
    cli_run_outputs(o, def, &out);
    fm_cache_writer *cache = NULL;
    fm_flock_run_stats rs;
    int rc = open_run(o, def, model, &out, state, &rs, &cache);
    if (rc) return fm_flock_state_destroy(state), rc;
    cli_progress fp = {!o->quiet && isatty(STDERR_FILENO), mi.agents, cli_seconds()};
    const fm_flock_run_control control = {frame_progress, &fp, &cli_stop_signal, o->resume, save_checkpoint,
                                          out.checkpoint, cli_checkpoint_every(o), cli_checkpoint_seconds(o)};
    cli_catch_stop_signals(1); /* the run checkpoints and stops at the end of the frame */
    fm_status st = fm_flock_run_controlled(model, state, cache, &control, &rs, &err);
    cli_catch_stop_signals(0);
    if (fp.show) fprintf(stderr, "\n");
    fm_flock_state_destroy(state);
    if (st == FM_STOPPED) return cli_report_interrupted(o, cache, rs.frames);
    if (st != FM_OK) return cli_report_failed(o, &out, cache, &err);
    if (fm_cache_writer_finish(cache, &err) != FM_OK) return cli_fail_keeping_partial_cache(&err, NULL, out.cache);
    const cli_run_record record = {"shape_flock", mi.agents, rs.frames, rs.steps, mi.time_step, prep_seconds,
                                   rs.simulate_seconds, rs.output_seconds, out.threads, out.cache};
    if ((rc = write_stats(out.stats, def, &mi, &rs, &record))) return rc;
    cli_remove_checkpoint(&out); /* the run is complete */
    printf("agents %lld, frames %lld, steps %lld, %.3g agent-steps/s; bound %.1f%%, distance to destination mean %.3g max %.3g\n",
           (long long)mi.agents, (long long)rs.frames, (long long)rs.steps, cli_agent_steps_per_second(&record),
           100 * rs.bound_fraction, rs.final_mean_distance, rs.final_max_distance);
    if (!mi.deforming && def->flock.arrival_mode == FM_ARRIVAL_BIND && !rs.all_bound)
        fprintf(stderr, "flockmorph: warning: stopped at the frame limit (%d frames) with %.1f%% of the agents not yet bound; "
                "raise time.frame_limit in the scene\n", def->frame_limit, 100 * (1 - rs.bound_fraction));
    printf("cache: %s\nstats: %s\n", out.cache, out.stats);
    return 0;
}

int cli_run_flock(const cli_run_options *o, const fm_scene_def *def)
{
    fm_error err = {0};
    int show = !o->quiet && isatty(STDERR_FILENO);
    double t0 = cli_seconds();
    fm_flock_model *model = fm_flock_model_build(def, cli_prep_progress, &show, &err);
    double prep_seconds = cli_seconds() - t0;
    if (show) fprintf(stderr, "\n");
    if (!model) return cli_report(&err);
    int rc = simulate(o, def, model, prep_seconds);
    fm_flock_model_destroy(model);
    return rc;
}
