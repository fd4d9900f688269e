/* A shape-flock shot: the scene's groups (docs/scene.md "Groups") on one clock, in one cache: SCF's
 * flock that "transforms among different static shapes". A group from a mesh adds its n agents as
 * new rows; a group whose source is another's formed shape ("source": {"group": A}) takes over A's
 * agents, the same rows, from where they are bound on A's destinations, once A has bound them all
 * (and `start` seconds later). Each group is an ordinary flock model and state. */
#include "cache_format.h"
#include "flock.h"
#include "fm_math.h"
#include "frame_loop.h"
#include "frame_share.h"
#include "shot_checkpoint.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct fm_flock_shot {
    int count;
    fm_scene_def def[FM_MAX_GROUPS];
    fm_flock_model *model[FM_MAX_GROUPS];
    fm_flock_state *state[FM_MAX_GROUPS];
    int64_t rows, row0[FM_MAX_GROUPS]; /* each group's first row (a chain shares its head's) */
    int started[FM_MAX_GROUPS], done[FM_MAX_GROUPS], writes[FM_MAX_GROUPS];
    int64_t start_step[FM_MAX_GROUPS], done_step[FM_MAX_GROUPS], step;
    double dt, scene_lo[3], scene_hi[3];
    int32_t steps_per_frame, frame_limit;
    float *position, *velocity, *orientation; /* a frame: every row, or on P ranks the rank's share */
    uint8_t *phase, *group;
    const fm_dist *dist; /* on P ranks (NULL: one process) */
    int threads;         /* the groups' stores', made when the shot starts (make_states) */
    fm_frame_share share; /* on P ranks with a cache: each rank encodes its share of the rows */
    int64_t saved_frames; /* the frames of the last checkpoint written or loaded (0: none) */
    fm_flock_shot_stats *stats;
    int64_t measure_rows; /* rows stats->measures holds */
};

/* Whether group g can ever be done: a static target whose agents bind. */
static int binds(const fm_scene_def *def)
{
    return !fm_flock_target_moves(&def->flock) && def->flock.arrival_mode == FM_ARRIVAL_BIND;
}

static fm_status check_source_group(const fm_scene_def *def, int g, fm_error *err)
{
    const int a = def[g].group.source_group;
    if (a < 0 || binds(&def[a])) return FM_OK;
    char where[FM_PATH_MAX + 64];
    fm_scene_key_location(&def[g], "source", where, sizeof where);
    return fm_fail(err, FM_ERR_INPUT, "%s: \"%s\" never holds a formed shape to start from: its target %s; a group "
                   "starts from a static target whose agents bind (shape_flock.arrival.mode \"bind\")", where,
                   def[a].group.name, def[a].flock.deform != FM_DEFORM_NONE ? "deforms"
                   : def[a].flock.travel_point_count > 0 ? "travels (target.path.points)" : "lets its agents float");
}

/* The groups together in memory (fm_memory_check_shot): a group from another's shape has its n. */
static fm_status check_memory(const fm_flock_shot *s, fm_error *err)
{
    int64_t agents[FM_MAX_GROUPS] = {0};
    for (int g = 0; g < s->count; g++) {
        const int from = s->def[g].group.source_group;
        agents[g] = from >= 0 ? agents[from] : s->def[g].n;
    }
    return fm_memory_check_shot(s->def, agents, s->count, fm_flock_memory_estimate, err);
}

/* Group g's model: on P ranks (dist) one a machine (fm_flock_model_build_shared); else this process's,
 * kept in keep where one is given (the studio's: fm_flock_shot_build_keeping). */
static fm_flock_model *build_group(const fm_flock_shot *s, int g, const fm_dist *dist, fm_flock_keep *keep,
                                   fm_progress_fn progress, void *user, fm_error *err)
{
    const int from = s->def[g].group.source_group;
    const fm_scene_def *def = &s->def[g];
    if (keep) return from < 0 ? fm_flock_model_build_keeping(def, keep, progress, user, err)
                              : fm_flock_model_build_from_shape_keeping(def, s->model[from], keep, progress, user, err);
    return from < 0 ? fm_flock_model_build_shared(def, dist, progress, user, err)
                    : fm_flock_model_build_from_shape_shared(def, s->model[from], dist, progress, user, err);
}

static fm_status build_groups(fm_flock_shot *s, const fm_dist *dist, fm_flock_keep *keeps, fm_progress_fn progress,
                              void *user, fm_error *err)
{
    fm_status checked = check_memory(s, err); /* before any group is sampled */
    if (checked != FM_OK) return checked;
    for (int g = 0; g < s->count; g++) {
        const int from = s->def[g].group.source_group;
        fm_status st = check_source_group(s->def, g, err);
        if (st != FM_OK) return st;
        s->model[g] = build_group(s, g, dist, keeps ? &keeps[g] : NULL, progress, user, err);
        if (!s->model[g]) return err->status;
        if (from < 0) s->row0[g] = s->rows, s->rows += s->model[g]->n;
        else s->row0[g] = s->row0[from];
        s->writes[g] = from < 0;
    }
    return FM_OK;
}

/* The groups' stores, once: on one process every agent's, on P ranks each rank's slab's. */
static fm_status make_states(fm_flock_shot *s, fm_error *err)
{
    for (int g = 0; g < s->count; g++) {
        if (s->state[g]) continue;
        s->state[g] = s->dist ? fm_flock_state_create_distributed(s->model[g], s->threads, s->dist, err)
                              : fm_flock_state_create(s->model[g], s->threads, err);
        if (fm_dist_agree(s->dist, s->state[g] ? FM_OK : err->status, err) != FM_OK) return err->status;
    }
    return FM_OK;
}

/* The frame's arrays: every row, or with the cache written by P ranks the rank's share of them. */
static fm_status alloc_frame(fm_flock_shot *s, fm_error *err)
{
    const size_t n = (size_t)(s->share.on ? fm_frame_share_end(&s->share) - fm_frame_share_first(&s->share) : s->rows);
    s->position = fm_alloc(sizeof(float) * 3 * n), s->velocity = fm_alloc(sizeof(float) * 3 * n);
    s->orientation = fm_alloc(sizeof(float) * 4 * n), s->phase = fm_alloc(n), s->group = fm_alloc(n);
    if (!s->position || !s->velocity || !s->orientation || !s->phase || !s->group)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame of %lld agents", (long long)s->rows);
    return FM_OK;
}

static void set_clock(fm_flock_shot *s, const fm_scene_def *defs)
{
    s->dt = s->model[0]->dt, s->steps_per_frame = s->model[0]->steps_per_frame, s->frame_limit = defs[0].frame_limit;
    for (int k = 0; k < 3; k++) s->scene_lo[k] = INFINITY, s->scene_hi[k] = -INFINITY;
    for (int g = 0; g < s->count; g++) {
        s->start_step[g] = s->done_step[g] = -1;
        fm_grow_bounds(s->scene_lo, s->scene_hi, s->model[g]->scene_lo, 1);
        fm_grow_bounds(s->scene_lo, s->scene_hi, s->model[g]->scene_hi, 1);
    }
}

fm_flock_shot *fm_flock_shot_build(const fm_scene_def *defs, int count, fm_progress_fn progress, void *user,
                                   fm_error *err)
{
    return fm_flock_shot_build_on(defs, count, NULL, progress, user, err);
}

static fm_flock_shot *build_shot(const fm_scene_def *defs, int count, const fm_dist *dist, fm_flock_keep *keeps,
                                 fm_progress_fn progress, void *user, fm_error *err)
{
    if (count < 1 || count > FM_MAX_GROUPS) {
        fm_fail(err, FM_ERR_USAGE, "a shot has 1 to %d groups, not %d", FM_MAX_GROUPS, count);
        return NULL;
    }
    fm_flock_shot *s = calloc(1, sizeof *s);
    if (!s) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    s->count = count;
    memcpy(s->def, defs, sizeof *defs * (size_t)count);
    fm_status st = build_groups(s, dist, keeps, progress, user, err);
    if (st != FM_OK) return fm_flock_shot_destroy(s), NULL;
    set_clock(s, defs);
    return s;
}

fm_flock_shot *fm_flock_shot_build_on(const fm_scene_def *defs, int count, const fm_dist *dist, fm_progress_fn progress,
                                      void *user, fm_error *err)
{
    return build_shot(defs, count, dist, NULL, progress, user, err);
}

fm_flock_shot *fm_flock_shot_build_keeping(const fm_scene_def *defs, int count, fm_flock_keep *keeps,
                                           fm_progress_fn progress, void *user, fm_error *err)
{
    return build_shot(defs, count, NULL, keeps, progress, user, err);
}

void fm_flock_shot_destroy(fm_flock_shot *s)
{
    if (!s) return;
    for (int g = 0; g < s->count; g++) fm_flock_state_destroy(s->state[g]), fm_flock_model_destroy(s->model[g]);
    fm_free(s->position), fm_free(s->velocity), fm_free(s->orientation), fm_free(s->phase), fm_free(s->group);
    free(s);
}

void fm_flock_shot_set_threads(fm_flock_shot *s, int threads)
{
    s->threads = threads;
    for (int g = 0; g < s->count; g++)
        if (s->state[g]) s->state[g]->threads = fm_threads(threads);
}

fm_status fm_flock_shot_distribute(fm_flock_shot *s, const fm_dist *dist, fm_error *err)
{
    s->dist = dist;
    return make_states(s, err);
}

const fm_flock_state *fm_flock_shot_state(const fm_flock_shot *s, int g) { return s->state[g]; }
int fm_flock_shot_groups(const fm_flock_shot *s) { return s->count; }
int64_t fm_flock_shot_rows(const fm_flock_shot *s) { return s->rows; }
const fm_flock_model *fm_flock_shot_model(const fm_flock_shot *s, int g) { return s->model[g]; }

static void shot_step(fm_flock_shot *s)
{
    for (int g = 0; g < s->count; g++) {
        int64_t at = s->started[g] ? -1 : fm_frame_loop_group_start(&s->def[g].group, s->done_step, s->dt);
        if (at < 0 || s->step < at) continue;
        s->started[g] = 1, s->start_step[g] = s->step;
        if (s->def[g].group.source_group >= 0) s->writes[s->def[g].group.source_group] = 0, s->writes[g] = 1;
    }
    for (int g = 0; g < s->count; g++) {
        if (!s->started[g] || s->done[g]) continue;
        fm_flock_step(s->model[g], s->state[g]);
        if (binds(&s->def[g]) && s->state[g]->count[FM_PHASE_ARRIVED] == s->state[g]->n)
            s->done[g] = 1, s->done_step[g] = s->step + 1;
    }
    s->step++;
}

static int all_done(const fm_flock_shot *s)
{
    for (int g = 0; g < s->count; g++)
        if (!s->done[g]) return 0;
    return 1;
}

static const char *const SHOT_FORCES = "each group's shape_flock speeds, forces and weights";

/* Group g's agents into its rows (on P ranks gathered on rank 0 first: collective). */
static fm_status group_frame(fm_flock_shot *s, int g, fm_error *err)
{
    fm_flock_state *all = s->dist ? fm_flock_dist_gather(s->state[g], 0, err) : s->state[g];
    fm_status st = all ? FM_OK : err->status;
    if (st == FM_OK && fm_dist_rank(s->dist) == 0) {
        const size_t r = (size_t)s->row0[g];
        fm_flock_frame(all, s->position + 3 * r, s->velocity + 3 * r, s->orientation + 4 * r, s->phase + r);
        memset(s->group + r, g, (size_t)s->model[g]->n);
    }
    if (s->dist) fm_flock_dist_release(s->state[g]);
    return st;
}

/* Frame k on one process, or gathered on rank 0 (no cache to write in parallel), which checks and
 * writes it. */
static fm_status write_frame(fm_flock_shot *s, fm_cache_writer *cache, int64_t k, fm_error *err)
{
    for (int g = 0; g < s->count; g++) {
        fm_status st = s->writes[g] ? group_frame(s, g, err) : FM_OK;
        if (st != FM_OK) return st; /* the ranks agreed on it */
    }
    if (fm_dist_rank(s->dist) != 0) return FM_OK;
    fm_status st = fm_frame_check_runaway(s->position, 3, s->rows, s->scene_lo, s->scene_hi, k, SHOT_FORCES, err);
    if (st != FM_OK || !cache) return st;
    const cache_layout *l = fm_cache_writer_layout(cache);
    const void *data[CACHE_MAX_ATTRS];
    for (int i = 0; i < l->attr_count; i++) {
        const fm_cache_attr a = l->attrs[i]->attr;
        data[i] = a == FM_ATTR_POSITION ? (const void *)s->position : a == FM_ATTR_VELOCITY ? (const void *)s->velocity
                : a == FM_ATTR_ORIENTATION ? (const void *)s->orientation : a == FM_ATTR_PHASE ? (const void *)s->phase
                : a == FM_ATTR_GROUP ? (const void *)s->group : (const void *)fm_cache_writer_ids(cache);
    }
    return fm_cache_writer_add_frame_attrs(cache, data, err);
}

/* With the cache written by P ranks: group g's agents whose rows (row0 + id) lie in this rank's
 * share, sent here by the ranks that compute them, into the share's arrays (collective). */
static fm_status share_group(fm_flock_shot *s, int g, fm_error *err)
{
    const int ranks = fm_dist_size(s->dist), me = fm_dist_rank(s->dist);
    const int64_t n = s->model[g]->n, row0 = s->row0[g], first = fm_frame_share_first(&s->share);
    int64_t *begin = malloc(sizeof *begin * ((size_t)ranks + 1)); /* the shares of the group's ids */
    fm_status st = fm_dist_agree(s->dist, begin ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory"), err);
    if (st != FM_OK) return free(begin), st;
    for (int r = 0; r <= ranks; r++) begin[r] = FM_MIN(FM_MAX(s->share.begin[r] - row0, 0), n);
    const fm_flock_state *view = fm_flock_dist_share(s->state[g], begin, err);
    st = view ? FM_OK : err->status;
    if (st == FM_OK && begin[me] < begin[me + 1]) {
        const size_t at = (size_t)(row0 + begin[me] - first);
        fm_flock_frame_range(view, 0, view->slots, s->position + 3 * at, s->velocity + 3 * at, s->orientation + 4 * at,
                             s->phase + at);
        memset(s->group + at, g, (size_t)(begin[me + 1] - begin[me]));
    }
    fm_flock_dist_release(s->state[g]);
    free(begin);
    return st;
}

/* Frame k with the cache written by P ranks: each rank fills, checks and encodes its share of the
 * rows; rank 0 appends the blocks (frame_share.h). */
static fm_status write_shared_frame(fm_flock_shot *s, fm_cache_writer *cache, int64_t k, fm_error *err)
{
    fm_status st = FM_OK;
    for (int g = 0; g < s->count && st == FM_OK; g++)
        if (s->writes[g]) st = share_group(s, g, err); /* agreed by every rank */
    if (st != FM_OK) return st;
    const int64_t first = fm_frame_share_first(&s->share), end = fm_frame_share_end(&s->share);
    st = fm_frame_check_runaway_from(s->position, 3, first, end - first, s->scene_lo, s->scene_hi, k, SHOT_FORCES, err);
    const void *by_kind[CACHE_ATTR_KINDS] = {[FM_ATTR_POSITION] = s->position, [FM_ATTR_VELOCITY] = s->velocity,
                                             [FM_ATTR_ORIENTATION] = s->orientation, [FM_ATTR_PHASE] = s->phase,
                                             [FM_ATTR_GROUP] = s->group};
    if ((st = fm_dist_agree(s->dist, st, err)) == FM_OK)
        st = fm_frame_share_write(&s->share, s->dist, cache, by_kind, (uint32_t)k, &s->state[0]->slabs->totals.bytes_sent, err);
    return st;
}

/* The shot's checkpoint (shot_checkpoint.h): its clock and timings, and each group's state. */
static const fm_store_member SHOT_MEMBERS[] = {
    FM_STORE_SCALAR(fm_flock_shot, step),   FM_STORE_SCALAR(fm_flock_shot, started),    FM_STORE_SCALAR(fm_flock_shot, done),
    FM_STORE_SCALAR(fm_flock_shot, writes), FM_STORE_SCALAR(fm_flock_shot, start_step), FM_STORE_SCALAR(fm_flock_shot, done_step),
};
static const fm_store_member SHOT_STATS[] = { /* the groups' statistics are the end state's */
    FM_STORE_SCALAR(fm_flock_shot_stats, run.simulate_seconds), FM_STORE_SCALAR(fm_flock_shot_stats, run.output_seconds),
};

static const char *check_shot(const void *state)
{
    const fm_flock_shot *s = state;
    return fm_shot_ckpt_check_clock(s->count, s->step, s->started, s->done, s->writes, s->start_step, s->done_step);
}

static fm_status save_group(void *shot, int g, const char *path, int64_t frames, fm_error *err)
{
    fm_flock_shot *s = shot;
    return fm_flock_group_checkpoint_save(path, s->model[g], s->state[g], frames, err);
}

static fm_status load_group(void *shot, int g, const char *path, int64_t *frames, fm_error *err)
{
    fm_flock_shot *s = shot;
    return fm_flock_group_checkpoint_load(path, s->model[g], s->state[g], frames, err);
}

static fm_shot_ckpt shot_checkpoint(fm_flock_shot *s, fm_flock_shot_stats *stats)
{
    int64_t agents[FM_MAX_GROUPS];
    for (int g = 0; g < s->count; g++) agents[g] = s->model[g]->n;
    const fm_ckpt_store shot = {
        .members = SHOT_MEMBERS, .member_count = (int)(sizeof SHOT_MEMBERS / sizeof SHOT_MEMBERS[0]), .state = s,
        .stats = SHOT_STATS, .stats_count = (int)(sizeof SHOT_STATS / sizeof SHOT_STATS[0]), .run_stats = stats,
        .def = &s->def[0], .model_hash = fm_shot_ckpt_groups_hash(s->def, agents, s->count),
        .model_what = "the groups' scenes (their parameters or agent counts)", .check = check_shot, .frames = stats->run.frames,
        .dist = s->dist, .per_frame = &stats->measures, .per_frame_width = s->count * FM_FLOCK_MEASURES};
    return (fm_shot_ckpt){shot, s->count, s, save_group, load_group};
}

fm_status fm_flock_shot_checkpoint_check(const char *path, const fm_scene_def *def0, fm_error *err)
{
    return fm_ckpt_check(path, def0, SHOT_MEMBERS, (int)(sizeof SHOT_MEMBERS / sizeof SHOT_MEMBERS[0]), err);
}

fm_status fm_flock_shot_checkpoint_load(fm_flock_shot *s, const char *path, fm_flock_shot_stats *stats, fm_error *err)
{
    memset(stats, 0, sizeof *stats);
    fm_status st = make_states(s, err);
    if (st != FM_OK) return st;
    fm_shot_ckpt c = shot_checkpoint(s, stats);
    st = fm_dist_agree(s->dist, fm_shot_ckpt_load(path, &c, &stats->run.frames, err), err); /* each rank its slabs' */
    if (st != FM_OK) return st;
    s->saved_frames = stats->run.frames;
    return FM_OK;
}

/* Frame k's flock measures of every group (fm_flock_measure_frame, docs/stats.md "Shape-flock shot")
 * into the statistics' row k - 1, NaN for a group not started or done; on P ranks from each rank's
 * whole blocks of the group (collective), on rank 0. */
static fm_status measure_groups(fm_flock_shot *s, int64_t k, fm_error *err)
{
    const int width = s->count * FM_FLOCK_MEASURES;
    fm_status st = fm_dist_agree(s->dist, fm_frame_rows_room(&s->stats->measures, k, width, &s->measure_rows, err), err);
    s->stats->groups = s->count;
    for (int g = 0; g < s->count && st == FM_OK; g++) {
        double *out = s->stats->measures + (size_t)(k - 1) * (size_t)width + (size_t)g * FM_FLOCK_MEASURES;
        for (int i = 0; i < FM_FLOCK_MEASURES; i++) out[i] = NAN;
        if (!s->started[g] || s->done[g]) continue;
        if (!s->dist) {
            fm_flock_measure_frame_look(s->model[g], s->state[g], &s->state[g]->look, k, out);
            continue;
        }
        fm_flock_state *view = fm_flock_dist_blocks(s->state[g], err);
        st = fm_dist_agree(s->dist, view ? FM_OK : err->status, err);
        if (st == FM_OK) st = fm_flock_measure_frame_shared(s->model[g], s->state[g], view, k, out, err);
        fm_flock_dist_release(s->state[g]);
    }
    return st;
}

/* Each group's measures' mean over the frames it had agents in flight, in frame order. */
static void summarise_measures(const fm_flock_shot *s, fm_flock_shot_stats *stats)
{
    const int width = s->count * FM_FLOCK_MEASURES;
    for (int g = 0; g < s->count; g++)
        for (int i = 0; i < FM_FLOCK_MEASURES; i++) {
            double sum = 0;
            int64_t count = 0;
            for (int64_t f = 0; stats->measures && f + 1 < stats->run.frames; f++) {
                const double *row = stats->measures + (size_t)f * (size_t)width + (size_t)g * FM_FLOCK_MEASURES;
                if (!isnan(row[i]) && row[FM_FLOCK_IN_FLIGHT] > 0) sum += row[i], count++;
            }
            stats->group[g].measures_mean[i] = count > 0 ? sum / (double)count : NAN;
        }
}

void fm_flock_shot_stats_free(fm_flock_shot_stats *stats)
{
    free(stats->measures);
    stats->measures = NULL;
}

typedef struct shot_loop {
    fm_flock_shot *s;
    fm_cache_writer *cache;
    const fm_run_control *c;
} shot_loop;

static void loop_step(void *sim) { shot_step(((shot_loop *)sim)->s); }

/* The loop's checkpoint (the cache flushed, the ranks' blocks on disk): the groups' files, then the
 * shot's. */
static fm_status loop_save(void *sim, const char *path, fm_error *err)
{
    fm_flock_shot *s = ((shot_loop *)sim)->s;
    const fm_shot_ckpt c = shot_checkpoint(s, s->stats);
    return fm_shot_ckpt_save(path, &c, &s->saved_frames, err);
}

static fm_status loop_sync(void *sim, fm_error *err) { return fm_frame_share_sync(&((shot_loop *)sim)->s->share, err); }
static int loop_finished(const void *sim) { return all_done(((const shot_loop *)sim)->s); }

static fm_status loop_frame(void *sim, int64_t k, fm_error *err)
{
    shot_loop *r = sim;
    for (int g = 0; g < r->s->count; g++) /* an exchange that failed, which every rank knows */
        if (r->s->state[g]->dist_status != FM_OK) return *err = r->s->state[g]->dist_error, err->status = r->s->state[g]->dist_status;
    fm_status st = r->s->share.on ? write_shared_frame(r->s, r->cache, k, err)
                                  : fm_dist_agree(r->s->dist, write_frame(r->s, r->cache, k, err), err);
    if (st == FM_OK && k > 0) st = measure_groups(r->s, k, err);
    const int64_t *counts[FM_MAX_GROUPS];
    for (int g = 0; g < r->s->count; g++) counts[g] = r->s->state[g]->count;
    if (st == FM_OK) fm_frame_loop_shot_progress(r->c, k, r->s->step, r->s->dt, counts, r->s->writes, r->s->count);
    return st;
}

/* Group g's distances to its destinations (on P ranks summed from the ranks' blocks: collective). */
static void group_distance(fm_flock_shot *s, int g, double *mean, double *max)
{
    fm_error err = {0};
    fm_flock_state *mine = s->dist ? fm_flock_dist_blocks(s->state[g], &err) : s->state[g];
    if (mine) fm_flock_distance_blocks(mine, 0, mine->slots, s->dist, mean, max);
    else *mean = *max = NAN;
    if (s->dist) fm_flock_dist_release(s->state[g]);
}

static void finish_stats(fm_flock_shot *s, fm_flock_shot_stats *stats)
{
    stats->run.steps = s->step;
    stats->rows = s->rows;
    stats->all_bound = all_done(s);
    for (int g = 0; g < s->count; g++) {
        fm_flock_shot_group_stats *gs = &stats->group[g];
        const fm_flock_state *st = s->state[g];
        gs->agents = st->n;
        gs->all_bound = s->done[g];
        gs->start_time = s->start_step[g] < 0 ? NAN : (double)s->start_step[g] * s->dt;
        gs->bound_time = s->done_step[g] < 0 ? NAN : (double)s->done_step[g] * s->dt;
        gs->bound_fraction = (double)st->count[FM_PHASE_ARRIVED] / (double)st->n;
        group_distance(s, g, &gs->final_mean_distance, &gs->final_max_distance);
    }
    stats->groups = s->count;
    summarise_measures(s, stats);
}

fm_status fm_flock_shot_run(fm_flock_shot *s, fm_cache_writer *cache, const fm_run_control *control,
                            fm_flock_shot_stats *stats, fm_error *err)
{
    if (!control->resume) memset(stats, 0, sizeof *stats); /* else fm_flock_shot_checkpoint_load restored them */
    s->stats = stats;
    shot_loop r = {s, cache, control};
    fm_status st = make_states(s, err);
    if (st != FM_OK) return st;
    st = fm_frame_share_start(&s->share, s->dist, cache, s->state[0]->threads, control->resume, err);
    if (st == FM_OK) fm_frame_share_commit(&s->share, cache), st = fm_dist_agree(s->dist, alloc_frame(s, err), err);
    if (st == FM_OK) {
        const fm_frame_loop loop = {&r, loop_step, loop_finished, loop_frame, loop_save, s->steps_per_frame,
                                    s->frame_limit, control, &stats->run, cache, s->dist, loop_sync};
        st = fm_frame_loop_run(&loop, err);
    }
    fm_frame_share_free(&s->share);
    finish_stats(s, stats);
    return st;
}
