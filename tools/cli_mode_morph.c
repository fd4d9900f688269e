/* `run` for a tetra-morph scene (the default "mode"): tetrahedralize and subdivide, simulate, write
 * the cache (tet vertices, id, phase) and stats.json with the end-state checks and the velocity
 * model (cli_run.c drives it through cli_mode_morph). */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "morph.h" /* the engine's internal header: the decomposition */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static json_t *vec3_json(const double v[3])
{
    return json_pack("[fff]", v[0], v[1], v[2]);
}

/* The velocity-model settings of the run (FM Table I's parameters, grid and style columns). */
static json_t *velocity_json(const fm_scene_def *def, const fm_morph_model_info *mi)
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
    return json_pack("{sfsfsfsfsosososisfsfsbsfsfsfsfsssf}", "omega1", def->omega1, "omega2", def->omega2,
                     "field_fade_distance", mi->field_fade_distance, "field_fade_time", mi->field_fade_time,
                     "fields", fields,
                     "field_grid", grid, "field_evaluation", json_string(mi->fields_baked ? "baked" : "direct"),
                     "obstacles", def->obstacle_count, "k_a", def->k_a, "obstacle_voxel", def->obstacle_voxel,
                     "avoid_in_phase2", def->avoid_in_phase2 != 0, "d_min", def->d_min, "mde_speed", def->mde_speed,
                     "path_width", def->path_width, "path_attraction", def->path_attraction,
                     "phase_switch", def->phase_switch == FM_SWITCH_DISTANCE ? "distance" : "sphere",
                     "phase2_blend_time", def->blend_time);
}

/* One entry per frame, index k for frame k: frame 0 is the rest state, which no step made (null);
 * mde_fraction[k - 1] is frame k's, null for a frame without flying tets. */
static json_t *mde_frames_json(const fm_morph_run_stats *rs)
{
    json_t *a = json_array();
    json_array_append_new(a, json_null());
    for (int64_t f = 0; f + 1 < rs->run.frames; f++)
        json_array_append_new(a, isnan(rs->mde_fraction[f]) ? json_null() : json_real(rs->mde_fraction[f]));
    return a;
}

/* The tetra morph's run: the model, the state and the statistics, and the warnings (the model's and
 * the run's own: stopped at the frame limit), printed and kept for stats.json. */
typedef struct morph_run {
    cli_mode_run common; /* first: what cli_run.c reads */
    fm_morph_model *model;
    fm_morph_model_info mi;
    fm_morph_state *state;
    fm_morph_run_stats rs;
    fm_dist_totals scale_out; /* on P ranks: summed over the ranks */
    json_t *warnings;
} morph_run;

static void add_warning(morph_run *r, const char *text)
{
    fprintf(stderr, "flockmorph: warning: %s\n", text);
    json_array_append_new(r->warnings, cli_json_string(text));
}

/* stats.json's source_quality / target_quality: the agents' tets and TetGen's before subdivision. */
static json_t *quality_json(const fm_morph_tet_quality *agents, const fm_morph_tet_quality *tetgen)
{
    json_t *q = json_object();
    json_object_set_new(q, "bound", json_real(agents->bound));
    json_object_set_new(q, "max_ratio", json_real(agents->max_ratio));
    json_object_set_new(q, "share_above", json_real(agents->share_above));
    json_object_set_new(q, "tetgen_max_ratio", json_real(tetgen->max_ratio));
    json_object_set_new(q, "tetgen_share_above", json_real(tetgen->share_above));
    json_object_set_new(q, "share_above_4", json_real(agents->share_above_4));
    json_object_set_new(q, "median_ratio", json_real(agents->median_ratio));
    json_object_set_new(q, "tetgen_share_above_4", json_real(tetgen->share_above_4));
    json_object_set_new(q, "tetgen_median_ratio", json_real(tetgen->median_ratio));
    return q;
}

static const char *const PHASE_NAMES[4] = {"waiting", "flying", "homing", "arrived"};

/* The frame limit's warning (issue 38): how many agents have not arrived, in which phase, and the
 * first few by id with their distance outside the switch sphere (docs/errors.md). */
typedef struct { char text[1024]; } stragglers_message;
static stragglers_message stragglers_text(const fm_scene_def *def, const fm_morph_run_stats *rs)
{
    stragglers_message m;
    const int64_t *n = rs->stragglers;
    size_t len = (size_t)snprintf(m.text, sizeof m.text,
                                  "stopped at the frame limit (%d frames) with %lld agents not yet arrived (%lld waiting "
                                  "to launch, %lld flying in phase 1, %lld homing in phase 2); first by id:",
                                  def->frame_limit, (long long)(n[0] + n[1] + n[2]), (long long)n[0], (long long)n[1],
                                  (long long)n[2]);
    for (int i = 0; i < rs->stragglers_listed && len < sizeof m.text; i++)
        len += (size_t)snprintf(m.text + len, sizeof m.text - len, "%s %lld %s %.3g from the switch sphere", i ? "," : "",
                                (long long)rs->straggler[i].id, PHASE_NAMES[rs->straggler[i].phase & 3],
                                rs->straggler[i].sphere_distance);
    if (len < sizeof m.text)
        snprintf(m.text + len, sizeof m.text - len, "; raise time.frame_limit in the scene (tets that circle outside "
                 "the switch sphere are held there by the style fields or obstacles: see style.fade_time)");
    return m;
}

/* stats.json's "stragglers": null when every agent arrived. */
static json_t *stragglers_json(const fm_morph_run_stats *rs)
{
    if (rs->all_arrived) return json_null();
    json_t *first = json_array();
    for (int i = 0; i < rs->stragglers_listed; i++)
        json_array_append_new(first, json_pack("{sIsssf}", "id", (json_int_t)rs->straggler[i].id, "phase",
                                               PHASE_NAMES[rs->straggler[i].phase & 3], "sphere_distance",
                                               rs->straggler[i].sphere_distance));
    const int64_t *n = rs->stragglers;
    return json_pack("{sIsIsIsIso}", "count", (json_int_t)(n[0] + n[1] + n[2]), "waiting", (json_int_t)n[0], "flying",
                     (json_int_t)n[1], "homing", (json_int_t)n[2], "first", first);
}

static int write_stats(void *run, const fm_scene_def *def, const char *path, const cli_run_record *record)
{
    morph_run *r = run;
    const fm_morph_model_info *mi = &r->mi;
    const fm_morph_run_stats *rs = &r->rs;
    if (!rs->all_arrived) add_warning(r, stragglers_text(def, rs).text);
    json_t *j = cli_stats_json(def, record);
    json_object_set_new(j, "source_tets", json_integer(mi->source_tets));
    json_object_set_new(j, "target_tets", json_integer(mi->target_tets));
    json_object_set_new(j, "source_refined_tets", json_integer(mi->source_refined_tets));
    json_object_set_new(j, "target_refined_tets", json_integer(mi->target_refined_tets));
    json_object_set_new(j, "source_quality", quality_json(&mi->source_quality, &mi->source_tetgen_quality));
    json_object_set_new(j, "target_quality", quality_json(&mi->target_quality, &mi->target_tetgen_quality));
    json_object_set_new(j, "launch_rate", json_real(mi->launch_rate));
    json_object_set_new(j, "all_arrived", json_boolean(rs->all_arrived));
    json_object_set_new(j, "stopped_at_frame_limit", json_boolean(rs->stopped_at_frame_limit));
    json_object_set_new(j, "final_max_vertex_error", rs->all_arrived ? json_real(rs->final_max_vertex_error) : json_null());
    json_object_set_new(j, "target_tets_filled_once", json_boolean(rs->target_tets_filled_once));
    json_object_set_new(j, "inverted_tet_frames", json_integer(rs->inverted_tet_frames));
    json_object_set_new(j, "morph_fallbacks", json_integer(rs->morph_fallbacks));
    json_object_set_new(j, "mde_fraction_mean", json_real(rs->mde_fraction_mean));
    json_object_set_new(j, "mde_fraction_per_frame", mde_frames_json(rs));
    json_object_set_new(j, "stragglers", stragglers_json(rs));
    json_object_set_new(j, "min_obstacle_clearance",
                        isinf(rs->min_obstacle_clearance) ? json_null() : json_real(rs->min_obstacle_clearance));
    json_object_set_new(j, "min_vertex_clearance",
                        isinf(rs->min_vertex_clearance) ? json_null() : json_real(rs->min_vertex_clearance));
    /* issue 38's global detour: 0 without obstacles, so every run has the same keys */
    const int obstacles = def->obstacle_count > 0;
    json_object_set_new(j, "path_routed", json_integer(obstacles ? mi->path_routed : 0));
    json_object_set_new(j, "detour_time", json_real(obstacles ? mi->detour_time : 0.0));
    json_object_set_new(j, "detour_agent_steps", json_integer(obstacles ? rs->detour_agent_steps : 0));
    json_t *velocity = velocity_json(def, mi);
    json_object_set_new(velocity, "field_bake_error", isnan(mi->field_bake_error) ? json_null() : json_real(mi->field_bake_error));
    json_object_set_new(j, "velocity_model", velocity);
    json_object_set_new(j, "source_volume", json_real(mi->source_volume));
    json_object_set_new(j, "target_volume", json_real(mi->target_volume));
    json_object_set_new(j, "target_sphere_radius", json_real(mi->sphere_radius));
    if (fm_dist_size(cli_dist) > 1) json_object_set_new(j, "scale_out", cli_scale_out_json(&r->scale_out));
    json_object_set(j, "warnings", r->warnings);
    return cli_write_json(path, j);
}

static int build(void *run, const fm_scene_def *def, int *show)
{
    morph_run *r = run;
    fm_error err = {0};
    r->warnings = json_array();
    cli_model_keep *keep = r->common.keep;
    if (keep && !cli_morph_keeps(keep)) return FM_ERR_MEMORY;
    r->model = keep ? fm_morph_model_build_keeping(def, keep->morph, cli_prep_progress, show, &err)
                    : fm_morph_model_build_shared(def, cli_dist, cli_prep_progress, show, &err); /* one a machine */
    if (keep) keep->reused = keep->groups_reused = keep->morph->reused;
    if (keep) keep->grids_reused = keep->morph->grid_reused, keep->routes_reused = keep->morph->route_reused;
    if (!r->model) return cli_report_build(&err);
    r->mi = fm_morph_model_get_info(r->model);
    r->common = (cli_mode_run){r->mi.agents, r->mi.time_step, &r->rs.run, keep, NULL};
    for (int i = 0; i < fm_morph_model_warning_count(r->model); i++) add_warning(r, fm_morph_model_warning(r->model, i));
    return 0;
}

fm_morph_keep *cli_morph_keeps(cli_model_keep *keep)
{
    if (!keep->morph && !(keep->morph = calloc(FM_MAX_GROUPS, sizeof *keep->morph)))
        fprintf(stderr, "flockmorph: out of memory\n");
    for (int g = 0; keep->morph && g < FM_MAX_GROUPS; g++) keep->morph[g].cancel = keep->cancel;
    return keep->morph;
}

void cli_morph_keep_free(cli_model_keep *keep)
{
    for (int g = 0; keep->morph && g < FM_MAX_GROUPS; g++) fm_morph_keep_clear(&keep->morph[g]);
    free(keep->morph);
    keep->morph = NULL;
}

static fm_status create_state(void *run, int threads, fm_error *err)
{
    morph_run *r = run;
    r->state = fm_dist_size(cli_dist) > 1 ? fm_morph_state_create_distributed(r->model, threads, cli_dist, err)
                                          : fm_morph_state_create(r->model, threads, err);
    return r->state ? FM_OK : err->status;
}

/* Tet vertices, ids and phases. */
static fm_cache_writer *create_cache(void *run, const fm_scene_def *def, const char *path, fm_error *err)
{
    const morph_run *r = run;
    const fm_cache_options options = cli_cache_options(def);
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_ID, FM_ATTR_PHASE};
    return fm_cache_writer_create_attrs(path, (uint64_t)r->mi.agents, def->frame_rate, attrs, 3, &options, err);
}

static fm_status load_checkpoint(void *run, const char *path, fm_error *err)
{
    morph_run *r = run;
    return fm_morph_checkpoint_load(path, r->model, r->state, &r->rs, err); /* on P ranks each keeps its slab's */
}

static fm_status simulate(void *run, fm_cache_writer *cache, const fm_run_control *control, fm_error *err)
{
    morph_run *r = run;
    fm_status st = fm_morph_run_controlled(r->model, r->state, cache, control, &r->rs, err);
    r->scale_out = cli_sum_totals(fm_morph_dist_get_totals(r->state));
    return st;
}

static void summary(const void *run, const fm_scene_def *def)
{
    (void)run, (void)def;
    printf("\n");
}

static void close_run(void *run)
{
    morph_run *r = run;
    fm_morph_run_stats_free(&r->rs);
    fm_morph_state_destroy(r->state);
    fm_morph_model_destroy(r->model);
    json_decref(r->warnings);
}

const cli_mode cli_mode_morph = {"tetra_morph", {"waiting", "flying", "homing", "arrived"}, sizeof(morph_run), build,
                                 create_state, create_cache, load_checkpoint, simulate, write_stats, summary,
                                 close_run};
