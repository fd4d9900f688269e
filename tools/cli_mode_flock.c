/* `run` for a shape-flock scene ("mode": "shape_flock"): sample, simulate, write the cache
 * (position, velocity, orientation, id, phase) and stats.json (cli_run.c drives it through
 * cli_mode_flock). */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "flock.h" /* the engine's internal header: the decomposition */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

static json_t *number_or_null(double x) { return isfinite(x) ? json_real(x) : json_null(); }

/* The settings that shape the result, for the record. */
static json_t *settings_json(const fm_scene_def *def, const fm_flock_model_info *mi)
{
    static const char *const sampling[] = {"random", "mosaic", "stratified"}, *const match[] = {"random", "spherical", "projected"};
    static const char *const deform[] = {"none", "wave", "pulse", "sequence"}, *const arrival[] = {"bind", "float"};
    static const char *const r_over[] = {"none", "distance", "leader_speed"};
    const fm_flock_def *f = &def->flock;
    json_t *j = json_pack("{sssssssfsfsfsfsssfsfsfsisisfsf}", "sampling", sampling[f->sampling], "match", match[f->match],
                     "deform", deform[f->deform], "kalman_q", f->kalman_q, "kalman_r_position", f->kalman_r_position,
                     "kalman_r_velocity", f->kalman_r_velocity, "arrival_radius", f->arrival_radius, "arrival_mode",
                     arrival[f->arrival_mode], "path_length", mi->path_length, "path_time", mi->path_time, "leaders_end", mi->leaders_end, "fields",
                     def->field_count, "obstacles", def->obstacle_count, "max_perception_radius", mi->max_radius, "mass",
                     f->mass);
    json_object_set_new(j, "kalman_r_scale_over", json_string(r_over[f->kalman_r_over]));
    json_object_set_new(j, "target_path_length", json_real(mi->travel_length));
    json_object_set_new(j, "target_path_start", number_or_null(mi->travel_start));
    json_object_set_new(j, "target_path_end", number_or_null(mi->travel_end));
    return j;
}

/* The flock measures (fm_flock_measure): a summary, {"NAME": {"mean": x, "mid_flight": y}}, and one
 * array a measure, index k for frame k: frame 0 is the rest state, which no step made (null), and
 * null where the measure is undefined (no agent in flight). */
static json_t *measures_json(const fm_flock_run_stats *rs)
{
    json_t *j = json_object();
    for (int i = 0; i < FM_FLOCK_MEASURES; i++)
        json_object_set_new(j, fm_flock_measure_names[i], json_pack("{soso}", "mean", number_or_null(rs->measures_mean[i]),
                                                                     "mid_flight", number_or_null(rs->measures_mid_flight[i])));
    return j;
}

static json_t *measures_per_frame_json(const fm_flock_run_stats *rs)
{
    json_t *j = json_object();
    for (int i = 0; i < FM_FLOCK_MEASURES; i++) {
        json_t *a = json_array();
        json_array_append_new(a, json_null());
        for (int64_t f = 0; rs->measures && f + 1 < rs->run.frames; f++)
            json_array_append_new(a, number_or_null(rs->measures[f * FM_FLOCK_MEASURES + i]));
        json_object_set_new(j, fm_flock_measure_names[i], a);
    }
    return j;
}

/* The shape flock's run: the model, the state and the statistics. */
typedef struct flock_run {
    cli_mode_run common; /* first: what cli_run.c reads */
    fm_flock_model *model;
    fm_flock_model_info mi;
    fm_flock_state *state;
    fm_flock_run_stats rs;
    fm_dist_totals scale_out; /* on P ranks: summed over the ranks */
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
    json_object_set_new(j, "flock_measures", measures_json(rs));
    json_object_set_new(j, "flock_measures_per_frame", measures_per_frame_json(rs));
    json_object_set_new(j, "shape_flock", settings_json(def, mi));
    json_t *warnings = json_array();
    for (int i = 0; i < fm_flock_model_warning_count(r->model); i++)
        json_array_append_new(warnings, cli_json_string(fm_flock_model_warning(r->model, i)));
    json_object_set_new(j, "warnings", warnings);
    json_object_set_new(j, "field_evaluation", json_string(mi->fields_baked ? "baked" : "direct"));
    json_object_set_new(j, "field_bake_error", number_or_null(mi->field_bake_error));
    if (fm_dist_size(cli_dist) > 1) json_object_set_new(j, "scale_out", cli_scale_out_json(&r->scale_out));
    return cli_write_json(path, j);
}

static int build(void *run, const fm_scene_def *def, int *show)
{
    flock_run *r = run;
    fm_error err = {0};
    cli_model_keep *keep = r->common.keep;
    if (keep && !cli_flock_keeps(keep)) return FM_ERR_MEMORY;
    r->model = keep ? fm_flock_model_build_keeping(def, keep->flock, cli_prep_progress, show, &err)
                    : fm_flock_model_build_shared(def, cli_dist, cli_prep_progress, show, &err); /* one a machine */
    if (keep) keep->reused = keep->groups_reused = keep->flock->reused;
    if (keep) keep->grids_reused = keep->flock->grid_reused, keep->routes_reused = keep->flock->route_reused;
    if (!r->model) cli_locate_key(def, &err); /* the flock names its meshes' keys without their lines */
    if (!r->model) return cli_report_build(&err);
    r->mi = fm_flock_model_get_info(r->model);
    r->common = (cli_mode_run){r->mi.agents, r->mi.time_step, &r->rs.run, keep, NULL};
    for (int i = 0; i < fm_flock_model_warning_count(r->model); i++)
        fprintf(stderr, "flockmorph: warning: %s\n", fm_flock_model_warning(r->model, i));
    return 0;
}

fm_flock_keep *cli_flock_keeps(cli_model_keep *keep)
{
    if (!keep->flock && !(keep->flock = calloc(FM_MAX_GROUPS, sizeof *keep->flock)))
        fprintf(stderr, "flockmorph: out of memory\n");
    for (int g = 0; keep->flock && g < FM_MAX_GROUPS; g++) keep->flock[g].cancel = keep->cancel;
    return keep->flock;
}

void cli_flock_keep_free(cli_model_keep *keep)
{
    for (int g = 0; keep->flock && g < FM_MAX_GROUPS; g++) fm_flock_keep_clear(&keep->flock[g]);
    free(keep->flock);
    keep->flock = NULL;
}

static fm_status create_state(void *run, int threads, fm_error *err)
{
    flock_run *r = run;
    r->state = fm_dist_size(cli_dist) > 1 ? fm_flock_state_create_distributed(r->model, threads, cli_dist, err)
                                          : fm_flock_state_create(r->model, threads, err);
    return r->state ? FM_OK : err->status;
}

/* Position, velocity, orientation, id and phase (fm_flock_cache_create). */
static fm_cache_writer *create_cache(void *run, const fm_scene_def *def, const char *path, fm_error *err)
{
    const flock_run *r = run;
    const fm_cache_options options = cli_cache_options(def);
    return fm_flock_cache_create(path, r->model, &options, err);
}

static fm_status load_checkpoint(void *run, const char *path, fm_error *err)
{
    flock_run *r = run;
    return fm_flock_checkpoint_load(path, r->model, r->state, &r->rs, err); /* on P ranks each keeps its slab's */
}

static fm_status simulate(void *run, fm_cache_writer *cache, const fm_run_control *control, fm_error *err)
{
    flock_run *r = run;
    fm_status st = fm_flock_run_controlled(r->model, r->state, cache, control, &r->rs, err);
    r->scale_out = cli_sum_totals(fm_flock_dist_get_totals(r->state));
    return st;
}

static void summary(const void *run, const fm_scene_def *def)
{
    const flock_run *r = run;
    const fm_flock_run_stats *rs = &r->rs;
    printf("; bound %.1f%%, distance to destination mean %.3g max %.3g\n", 100 * rs->bound_fraction,
           rs->final_mean_distance, rs->final_max_distance);
    if (def->flock.deform == FM_DEFORM_NONE && def->flock.arrival_mode == FM_ARRIVAL_BIND && !rs->all_bound)
        fprintf(stderr, "flockmorph: warning: stopped at the frame limit (%d frames) with %.1f%% of the agents not yet bound; "
                "raise time.frame_limit in the scene\n", def->frame_limit, 100 * (1 - rs->bound_fraction));
}

static void close_run(void *run)
{
    flock_run *r = run;
    fm_flock_run_stats_free(&r->rs);
    fm_flock_state_destroy(r->state);
    fm_flock_model_destroy(r->model);
}

const cli_mode cli_mode_flock = {"shape_flock", {NULL, "flying", "arriving", "bound"}, sizeof(flock_run), build,
                                 create_state, create_cache, load_checkpoint, simulate, write_stats, summary,
                                 close_run};
