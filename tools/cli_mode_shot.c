/* `run` for a scene with `groups` (a shot, docs/scene.md "Groups"): of tetra morphs (morph_shot.c)
 * or of shape flocks (flock_shot.c). Every group's model, the shot on one clock, one cache (the
 * mode's attributes and group) and stats.json with each group's end-state checks (cli_run.c drives
 * it through cli_mode_shot). */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "flock.h" /* the engine's internal headers: each group's model */
#include "morph.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct shot_run {
    cli_mode_run common;         /* first: cli_run.c reads it */
    fm_scene_def defs[FM_MAX_GROUPS];
    int count;
    int threads;
    int flock;                   /* shape-flock groups (flock_shot), else tetra morphs (shot) */
    fm_shot *shot;
    fm_shot_stats stats;
    fm_flock_shot *flock_shot;
    fm_flock_shot_stats flock_stats;
    fm_dist_totals scale_out; /* on P ranks: every group's, summed over the ranks */
    json_t *warnings;
} shot_run;

static const fm_scene_override *g_overrides;
static int g_override_count;

static uint64_t g_file_seed, g_run_seed; /* a wedge's derived seed replaces the file's (cli_overrides.c) */

void cli_shot_use_overrides(const fm_scene_override *set, int count, uint64_t file_seed, uint64_t run_seed)
{
    g_overrides = set, g_override_count = count, g_file_seed = file_seed, g_run_seed = run_seed;
}

/* Group g's scene, with the run's overrides and seed: from the file, or from text (the studio's
 * edited scene; NULL: the file). */
static fm_status load_group(const fm_scene_def *def, const char *text, int g, fm_scene_def *out, fm_error *err)
{
    fm_status st = text ? fm_scene_parse_group(text, strlen(text), def->scene_path, g_overrides, g_override_count, g,
                                               out, err)
                        : fm_scene_load_group(def->scene_path, g_overrides, g_override_count, g, out, err);
    if (st == FM_OK && out->seed == g_file_seed) out->seed = g_run_seed; /* a group with its own seed keeps it */
    return st;
}

static int load_groups(shot_run *r, const fm_scene_def *def)
{
    fm_error err = {0};
    r->count = def->group_count;
    for (int g = 0; g < r->count; g++)
        if (load_group(def, r->common.scene_text, g, &r->defs[g], &err) != FM_OK) return cli_report(&err);
    return 0;
}

int cli_shot_check_groups(const fm_scene_def *def)
{
    fm_error err = {0};
    fm_scene_def *group = malloc(sizeof *group); /* 120 KiB: not on the stack */
    fm_status st = group ? FM_OK : fm_fail(&err, FM_ERR_MEMORY, "out of memory");
    for (int g = 0; g < def->group_count && st == FM_OK; g++) st = load_group(def, NULL, g, group, &err);
    free(group);
    return st == FM_OK ? 0 : cli_report(&err);
}

int cli_check_shot_checkpoint(const char *path, const fm_scene_def *def)
{
    fm_error err = {0};
    fm_scene_def first;
    fm_status st = load_group(def, NULL, 0, &first, &err);
    if (st == FM_OK)
        st = def->mode == FM_MODE_SHAPE_FLOCK ? fm_flock_shot_checkpoint_check(path, &first, &err)
                                              : fm_shot_checkpoint_check(path, &first, &err);
    return st == FM_OK ? 0 : cli_report(&err);
}

/* How many groups' builds reused their kept part (the studio's runs: cli_model_keep). */
static void count_kept(cli_model_keep *keep, int count, int flock)
{
    keep->groups_reused = keep->grids_reused = keep->routes_reused = 0;
    for (int g = 0; g < count; g++) {
        keep->groups_reused += flock ? keep->flock[g].reused : keep->morph[g].reused;
        keep->grids_reused += flock ? keep->flock[g].grid_reused : keep->morph[g].grid_reused;
        keep->routes_reused += flock ? keep->flock[g].route_reused : keep->morph[g].route_reused;
    }
    keep->reused = keep->groups_reused == count;
}

static int build_morphs(shot_run *r, int *show)
{
    fm_error err = {0};
    cli_model_keep *keep = r->common.keep;
    if (keep && !cli_morph_keeps(keep)) return FM_ERR_MEMORY;
    r->shot = keep ? fm_shot_build_keeping(r->defs, r->count, 0, keep->morph, cli_prep_progress, show, &err)
                   : fm_shot_build_on(r->defs, r->count, 0, cli_dist, cli_prep_progress, show, &err); /* one model a machine */
    if (keep && r->shot) count_kept(keep, r->count, 0);
    if (!r->shot) return cli_report_build(&err);
    for (int g = 0; g < r->count; g++) {
        const fm_morph_model *m = fm_shot_model(r->shot, g);
        for (int i = 0; i < fm_morph_model_warning_count(m); i++)
            json_array_append_new(r->warnings, json_sprintf("%s: %s", r->defs[g].group.name, fm_morph_model_warning(m, i)));
    }
    r->common = (cli_mode_run){fm_shot_rows(r->shot), fm_shot_model(r->shot, 0)->dt, &r->stats.run, keep, NULL};
    return 0;
}

static int build_flocks(shot_run *r, int *show)
{
    fm_error err = {0};
    cli_model_keep *keep = r->common.keep;
    if (keep && !cli_flock_keeps(keep)) return FM_ERR_MEMORY;
    r->flock_shot = keep ? fm_flock_shot_build_keeping(r->defs, r->count, keep->flock, cli_prep_progress, show, &err)
                         : fm_flock_shot_build_on(r->defs, r->count, cli_dist, cli_prep_progress, show, &err); /* one a machine */
    if (keep && r->flock_shot) count_kept(keep, r->count, 1);
    if (!r->flock_shot) return cli_report_build(&err);
    for (int g = 0; g < r->count; g++) {
        const fm_flock_model *m = fm_flock_shot_model(r->flock_shot, g);
        for (int i = 0; i < fm_flock_model_warning_count(m); i++)
            json_array_append_new(r->warnings, json_sprintf("%s: %s", r->defs[g].group.name, fm_flock_model_warning(m, i)));
    }
    r->common = (cli_mode_run){fm_flock_shot_rows(r->flock_shot), fm_flock_shot_model(r->flock_shot, 0)->dt,
                               &r->flock_stats.run, keep, NULL};
    return 0;
}

static int build(void *run, const fm_scene_def *def, int *show)
{
    shot_run *r = run;
    r->warnings = json_array();
    r->flock = def->mode == FM_MODE_SHAPE_FLOCK;
    int rc = load_groups(r, def);
    return rc ? rc : r->flock ? build_flocks(r, show) : build_morphs(r, show);
}

/* The shot made its states; they take the run's thread count here, and on P ranks (a shot of
 * either mode) each rank's share. */
static fm_status create_state(void *run, int threads, fm_error *err)
{
    shot_run *r = run;
    if (r->flock) fm_flock_shot_set_threads(r->flock_shot, threads);
    else fm_shot_set_threads(r->shot, threads);
    if (fm_dist_size(cli_dist) == 1) return FM_OK;
    return r->flock ? fm_flock_shot_distribute(r->flock_shot, cli_dist, err) : fm_shot_distribute(r->shot, cli_dist, err);
}

static fm_cache_writer *create_cache(void *run, const fm_scene_def *def, const char *path, fm_error *err)
{
    const shot_run *r = run;
    const fm_cache_options options = cli_cache_options(def);
    static const fm_cache_attr tets[] = {FM_ATTR_TET_VERTICES, FM_ATTR_ID, FM_ATTR_PHASE, FM_ATTR_GROUP};
    static const fm_cache_attr points[] = {FM_ATTR_POSITION, FM_ATTR_VELOCITY, FM_ATTR_ORIENTATION, FM_ATTR_ID,
                                           FM_ATTR_PHASE, FM_ATTR_GROUP};
    return r->flock ? fm_cache_writer_create_attrs(path, (uint64_t)r->common.agents, def->frame_rate, points, 6, &options, err)
                    : fm_cache_writer_create_attrs(path, (uint64_t)r->common.agents, def->frame_rate, tets, 4, &options, err);
}

/* Every rank reads the shot's file and its groups' (each rank then keeps its share). */
static fm_status load_checkpoint(void *run, const char *path, fm_error *err)
{
    shot_run *r = run;
    return r->flock ? fm_flock_shot_checkpoint_load(r->flock_shot, path, &r->flock_stats, err)
                    : fm_shot_checkpoint_load(r->shot, path, &r->stats, err);
}

static fm_status simulate(void *run, fm_cache_writer *cache, const fm_run_control *control, fm_error *err)
{
    shot_run *r = run;
    fm_status st = r->flock ? fm_flock_shot_run(r->flock_shot, cache, control, &r->flock_stats, err)
                            : fm_shot_run(r->shot, cache, control, &r->stats, err);
    fm_dist_totals mine = {0};
    for (int g = 0; g < r->count; g++) { /* the groups fly one after another: their loads add up */
        const fm_dist_totals t = r->flock ? fm_flock_dist_get_totals(fm_flock_shot_state(r->flock_shot, g))
                                          : fm_morph_dist_get_totals(fm_shot_state(r->shot, g));
        mine.migrated += t.migrated, mine.ghost_agent_steps += t.ghost_agent_steps, mine.bytes_sent += t.bytes_sent;
        mine.agent_steps += t.agent_steps, mine.max_rank_agent_steps += t.max_rank_agent_steps;
        mine.busy_seconds += t.busy_seconds;
    }
    r->scale_out = cli_sum_totals(mine);
    return st;
}

static json_t *number_or_null(double x) { return isfinite(x) ? json_real(x) : json_null(); }

static json_t *group_json(const shot_run *r, int g)
{
    const fm_shot_group_stats *gs = &r->stats.group[g];
    const fm_group_def *d = &r->defs[g].group;
    const fm_morph_model_info mi = fm_morph_model_get_info(fm_shot_model(r->shot, g));
    json_t *j = json_object();
    json_object_set_new(j, "name", json_string(d->name));
    json_object_set_new(j, "agents", json_integer(gs->agents));
    json_object_set_new(j, "source_group", d->source_group < 0 ? json_null() : json_string(r->defs[d->source_group].group.name));
    json_object_set_new(j, "source_tets", json_integer(mi.source_tets));
    json_object_set_new(j, "target_tets", json_integer(mi.target_tets));
    json_object_set_new(j, "start_time", number_or_null(gs->start_time));
    json_object_set_new(j, "arrival_time", number_or_null(gs->arrival_time));
    json_object_set_new(j, "all_arrived", json_boolean(gs->all_arrived));
    json_object_set_new(j, "final_max_vertex_error", gs->all_arrived ? json_real(gs->final_max_vertex_error) : json_null());
    json_object_set_new(j, "target_tets_filled_once", json_boolean(gs->target_tets_filled_once));
    json_object_set_new(j, "inverted_tet_frames", json_integer(gs->inverted_tet_frames));
    json_object_set_new(j, "obstacles", json_integer(fm_shot_model(r->shot, g)->def.obstacle_count));
    json_object_set_new(j, "min_obstacle_clearance", number_or_null(gs->min_obstacle_clearance));
    json_object_set_new(j, "min_vertex_clearance", number_or_null(gs->min_vertex_clearance));
    json_object_set_new(j, "mde_fraction", json_real(gs->mde_fraction));
    return j;
}

static json_t *flock_group_json(const shot_run *r, int g)
{
    const fm_flock_shot_group_stats *gs = &r->flock_stats.group[g];
    const fm_group_def *d = &r->defs[g].group;
    json_t *j = json_object();
    json_object_set_new(j, "name", json_string(d->name));
    json_object_set_new(j, "agents", json_integer(gs->agents));
    json_object_set_new(j, "source_group", d->source_group < 0 ? json_null() : json_string(r->defs[d->source_group].group.name));
    json_object_set_new(j, "start_time", number_or_null(gs->start_time));
    json_object_set_new(j, "bound_time", number_or_null(gs->bound_time));
    json_object_set_new(j, "all_bound", json_boolean(gs->all_bound));
    json_object_set_new(j, "bound_fraction", json_real(gs->bound_fraction));
    json_object_set_new(j, "final_mean_distance", json_real(gs->final_mean_distance));
    json_object_set_new(j, "final_max_distance", json_real(gs->final_max_distance));
    /* the group's flock measures (docs/stats.md "Shape-flock shot"): the mean, and one entry a frame */
    const fm_flock_shot_stats *st = &r->flock_stats;
    json_t *mean = json_object(), *per_frame = json_object();
    for (int i = 0; i < FM_FLOCK_MEASURES; i++) {
        json_object_set_new(mean, fm_flock_measure_names[i], number_or_null(gs->measures_mean[i]));
        json_t *a = json_array();
        json_array_append_new(a, json_null()); /* frame 0, the rest state */
        for (int64_t f = 0; st->measures && f + 1 < st->run.frames; f++)
            json_array_append_new(a, number_or_null(st->measures[(f * st->groups + g) * FM_FLOCK_MEASURES + i]));
        json_object_set_new(per_frame, fm_flock_measure_names[i], a);
    }
    json_object_set_new(j, "flock_measures", mean);
    json_object_set_new(j, "flock_measures_per_frame", per_frame);
    return j;
}

static void morph_shot_stats(const shot_run *r, json_t *j)
{
    json_object_set_new(j, "all_arrived", json_boolean(r->stats.all_arrived));
    json_object_set_new(j, "stopped_at_frame_limit", json_boolean(!r->stats.all_arrived));
    json_object_set_new(j, "inverted_tet_frames", json_integer(r->stats.inverted_tet_frames));
    json_object_set_new(j, "min_vertex_clearance", number_or_null(r->stats.min_vertex_clearance));
}

static int write_stats(void *run, const fm_scene_def *def, const char *path, const cli_run_record *record)
{
    shot_run *r = run;
    json_t *j = cli_stats_json(def, record);
    json_t *groups = json_array();
    for (int g = 0; g < r->count; g++) json_array_append_new(groups, r->flock ? flock_group_json(r, g) : group_json(r, g));
    if (r->flock) {
        json_object_set_new(j, "all_bound", json_boolean(r->flock_stats.all_bound));
        json_object_set_new(j, "stopped_at_frame_limit", json_boolean(!r->flock_stats.all_bound));
    } else {
        morph_shot_stats(r, j);
    }
    json_object_set_new(j, "groups", groups);
    json_object_set_new(j, "meshes", cli_meshes_json(r->defs, r->count));
    json_object_set(j, "warnings", r->warnings);
    if (fm_dist_size(cli_dist) > 1) json_object_set_new(j, "scale_out", cli_scale_out_json(&r->scale_out));
    return cli_write_json(path, j);
}

static void summary(const void *run, const fm_scene_def *def)
{
    const shot_run *r = run;
    (void)def;
    printf("; %d groups", r->count);
    for (int g = 0; g < r->count; g++) {
        int done = r->flock ? r->flock_stats.group[g].all_bound : r->stats.group[g].all_arrived;
        printf("%s %s %s", g ? "," : ":", r->defs[g].group.name,
               r->flock ? (done ? "bound" : "not all bound") : (done ? "arrived" : "did not arrive"));
    }
    printf("\n");
}

static void close_run(void *run)
{
    shot_run *r = run;
    fm_shot_destroy(r->shot);
    fm_flock_shot_destroy(r->flock_shot);
    fm_flock_shot_stats_free(&r->flock_stats);
    json_decref(r->warnings);
}

/* The shot keeps checkpoints: its own file and one per group (docs/resume.md "Shots"). */
const cli_mode cli_mode_shot = {"tetra_morph", {"waiting", "flying", "homing", "arrived"}, sizeof(shot_run), build,
                                create_state, create_cache, load_checkpoint, simulate, write_stats, summary, close_run};
const cli_mode cli_mode_flock_shot = {"shape_flock", {NULL, "flying", "arriving", "bound"}, sizeof(shot_run), build,
                                      create_state, create_cache, load_checkpoint, simulate, write_stats, summary,
                                      close_run};
