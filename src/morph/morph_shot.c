/* A shot: several tetra morphs (the scene's groups, docs/scene.md "Groups") on one clock, written
 * to one cache. Each group is an ordinary model and state; what the shot adds is when each starts,
 * which cache rows each writes, and the shapes the groups are to each other as obstacles.
 *
 *   rows      a group that starts from a mesh adds its n agents as new rows; a group that starts
 *             from another's formed shape ("source": {"group": A}) takes over A's rows when it
 *             starts: its agent with source tet j is the agent of A that formed A's target slot j,
 *             and writes its vertices in that agent's vertex order, so the rows run on unbroken
 *   starts    a group starts `start` seconds into the shot, or after the step where its `after`
 *             group's last agent arrived; its own clock starts at 0 then
 *   obstacles a group that avoids another sees that group's target if it flies after it, its
 *             source if it flies before it (fm_shot_build refuses a pair that may fly together) */
#include "morph.h"
#include "fm_math.h"
#include "frame_loop.h"
#include "frame_share.h"
#include "shot_checkpoint.h"
#include "cache_format.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct fm_shot {
    int count;
    fm_scene_def def[FM_MAX_GROUPS]; /* each group's, with the shapes of the groups it avoids as obstacles */
    fm_scene_def first;           /* group 0's as loaded (its checkpoint's scene: fm_shot_checkpoint_check) */
    fm_morph_model *model[FM_MAX_GROUPS];
    fm_morph_state *state[FM_MAX_GROUPS];
    int64_t rows;
    int64_t row0[FM_MAX_GROUPS];  /* a group from a mesh: its first row */
    int64_t *row[FM_MAX_GROUPS];  /* a group from another's shape, once started: each agent's row */
    uint8_t *perm[FM_MAX_GROUPS]; /* ... and the even permutation from its vertex order to the row's */
    int started[FM_MAX_GROUPS], arrived[FM_MAX_GROUPS], writes[FM_MAX_GROUPS];
    int64_t start_step[FM_MAX_GROUPS], arrival_step[FM_MAX_GROUPS], step;
    int threads;                  /* the states' (made by fm_shot_distribute on P ranks, else by the run) */
    int64_t saved_frames;         /* the frames of the last checkpoint written or loaded (0: none) */
    double dt;
    double scene_lo[3], scene_hi[3]; /* the union of the groups' scene bounds (runaway check) */
    int32_t steps_per_frame, frame_limit;
    float *verts, *scratch;       /* a frame (rows x 12, or on P ranks the rank's share), one group's tets */
    uint8_t *phases, *groups, *scratch_phases;
    fm_shot_stats *stats;
    const fm_dist *dist;          /* on P ranks (NULL: one process) */
    fm_frame_share share;         /* on P ranks with a cache: each rank encodes its share of the rows */
    float *own;                   /* ... and a group's own agents' tets in slot order */
    int64_t own_capacity;
};

/* Whether group a starts only after group b has arrived (through any chain of `after`). */
static int starts_after(const fm_scene_def *def, int a, int b)
{
    for (int g = def[a].group.after; g >= 0; g = def[g].group.after)
        if (g == b) return 1;
    return 0;
}

/* Group g's obstacles: the scene's, then the shape of each group it avoids. */
static fm_status add_group_obstacles(fm_scene_def *def, int g, fm_error *err)
{
    fm_scene_def *d = &def[g];
    for (int k = 0; k < d->group.avoid_count; k++) {
        int h = d->group.avoid[k];
        int after = starts_after(def, g, h), before = starts_after(def, h, g);
        char where[FM_PATH_MAX + 64];
        fm_scene_key_location(d, "avoid", where, sizeof where);
        if (!after && !before)
            return fm_fail(err, FM_ERR_INPUT, "%s: \"%s\" may fly while \"%s\" does (neither starts after the other), "
                           "so its shape is no fixed obstacle: give one of them an \"after\" the other",
                           where, def[h].group.name, d->group.name);
        if (d->obstacle_count == FM_MAX_OBSTACLES)
            return fm_fail(err, FM_ERR_INPUT, "%s: more than %d obstacles with the groups'", where, FM_MAX_OBSTACLES);
        d->obstacles[d->obstacle_count++] = after ? def[h].target : def[h].source;
    }
    return FM_OK;
}

/* Whether a later group starts from group g's formed shape (and so reads its double targets). */
static int is_a_source(const fm_shot *s, int g)
{
    for (int h = g + 1; h < s->count; h++)
        if (s->def[h].group.source_group == g) return 1;
    return 0;
}

/* The groups together in memory (fm_memory_check_shot), with the agents known so far: a built
 * group's, else its scene's n or its source group's. */
static fm_status check_memory(const fm_shot *s, fm_error *err)
{
    int64_t agents[FM_MAX_GROUPS] = {0};
    for (int g = 0; g < s->count; g++) {
        const int from = s->def[g].group.source_group;
        agents[g] = s->model[g] ? s->model[g]->n : from >= 0 ? agents[from] : s->def[g].n;
    }
    return fm_memory_check_shot(s->def, agents, s->count, fm_morph_memory_estimate, err);
}

/* dist: on P ranks, one model a machine (fm_morph_model_build_group_shared); NULL: this process's own,
 * each kept in keeps[g] where keeps is given (the studio's: fm_shot_build_keeping) */
static fm_status build_models(fm_shot *s, const fm_dist *dist, fm_morph_keep *keeps, fm_progress_fn progress,
                              void *user, fm_error *err)
{
    for (int g = 0; g < s->count; g++) {
        fm_status st = check_memory(s, err); /* before TetGen, and again with each group's tet count */
        if (st == FM_OK) st = add_group_obstacles(s->def, g, err);
        if (st != FM_OK) return st;
        const int from = s->def[g].group.source_group;
        const fm_morph_model *source = from < 0 ? NULL : s->model[from];
        s->model[g] = keeps ? fm_morph_model_build_group_keeping(&s->def[g], source, is_a_source(s, g), &keeps[g],
                                                                 progress, user, err)
                            : fm_morph_model_build_group_shared(&s->def[g], source, is_a_source(s, g), dist, progress,
                                                                user, err);
        if (!s->model[g]) return err->status;
        if (from < 0) s->row0[g] = s->rows, s->rows += s->model[g]->n;
        s->writes[g] = from < 0;
        if (s->model[g]->dt != s->model[0]->dt || s->model[g]->steps_per_frame != s->model[0]->steps_per_frame)
            return fm_fail(err, FM_ERR_INTERNAL, "group %d has another time step", g);
    }
    for (int g = 0; g < s->count; g++) fm_morph_model_drop_targets(s->model[g]); /* every group is built */
    return check_memory(s, err);
}

/* Every group's state: on one process each holds all its agents; on P ranks (dist) each starts
 * with the rank's share of them and grows as agents come. */
static fm_status create_states(fm_shot *s, const fm_dist *dist, fm_error *err)
{
    for (int g = 0; g < s->count; g++) {
        s->state[g] = dist ? fm_morph_state_create_distributed(s->model[g], s->threads, dist, err)
                           : fm_morph_state_create(s->model[g], s->threads, err);
        if (!s->state[g]) return err->status;
    }
    return FM_OK;
}

/* The frame's buffers: every row and a group's tets, or with the cache written by P ranks the
 * rank's share of the rows (scratch then gathers one group's rows of it). */
static fm_status alloc_frame(fm_shot *s, fm_error *err)
{
    int64_t rows = s->rows, most = 0;
    for (int g = 0; g < s->count; g++) most = FM_MAX(most, s->model[g]->n);
    if (s->share.on) rows = most = fm_frame_share_end(&s->share) - fm_frame_share_first(&s->share);
    s->verts = fm_alloc(sizeof(float) * 12 * (size_t)rows);
    s->scratch = fm_alloc(sizeof(float) * 12 * (size_t)most);
    s->phases = fm_alloc((size_t)rows), s->groups = fm_alloc((size_t)rows);
    s->scratch_phases = fm_alloc((size_t)most);
    if (!s->verts || !s->scratch || !s->phases || !s->groups || !s->scratch_phases)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame of %lld agents", (long long)rows);
    return FM_OK;
}

fm_shot *fm_shot_build(const fm_scene_def *defs, int count, int threads, fm_progress_fn progress, void *user,
                       fm_error *err)
{
    return fm_shot_build_on(defs, count, threads, NULL, progress, user, err);
}

static fm_shot *build_shot(const fm_scene_def *defs, int count, int threads, const fm_dist *dist, fm_morph_keep *keeps,
                           fm_progress_fn progress, void *user, fm_error *err)
{
    if (count < 1 || count > FM_MAX_GROUPS) {
        fm_fail(err, FM_ERR_USAGE, "a shot has 1 to %d groups, not %d", FM_MAX_GROUPS, count);
        return NULL;
    }
    fm_shot *s = calloc(1, sizeof *s);
    if (!s) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    s->count = count;
    memcpy(s->def, defs, sizeof *defs * (size_t)count);
    s->first = defs[0];
    s->threads = threads;
    fm_status st = build_models(s, dist, keeps, progress, user, err);
    if (st != FM_OK) return fm_shot_destroy(s), NULL;
    s->dt = s->model[0]->dt, s->steps_per_frame = s->model[0]->steps_per_frame;
    s->frame_limit = defs[0].frame_limit;
    for (int k = 0; k < 3; k++) s->scene_lo[k] = INFINITY, s->scene_hi[k] = -INFINITY;
    for (int g = 0; g < count; g++)
        fm_grow_bounds(s->scene_lo, s->scene_hi, s->model[g]->scene_lo, 1),
        fm_grow_bounds(s->scene_lo, s->scene_hi, s->model[g]->scene_hi, 1);
    for (int g = 0; g < count; g++) s->start_step[g] = s->arrival_step[g] = -1;
    return s;
}

fm_shot *fm_shot_build_on(const fm_scene_def *defs, int count, int threads, const fm_dist *dist, fm_progress_fn progress,
                          void *user, fm_error *err)
{
    return build_shot(defs, count, threads, dist, NULL, progress, user, err);
}

fm_shot *fm_shot_build_keeping(const fm_scene_def *defs, int count, int threads, fm_morph_keep *keeps,
                               fm_progress_fn progress, void *user, fm_error *err)
{
    return build_shot(defs, count, threads, NULL, keeps, progress, user, err);
}

void fm_shot_destroy(fm_shot *s)
{
    if (!s) return;
    for (int g = 0; g < s->count; g++) {
        fm_morph_state_destroy(s->state[g]), fm_morph_model_destroy(s->model[g]);
        fm_free(s->row[g]), fm_free(s->perm[g]);
    }
    fm_free(s->verts), fm_free(s->scratch), fm_free(s->phases), fm_free(s->groups), fm_free(s->scratch_phases);
    fm_free(s->own);
    free(s);
}

void fm_shot_set_threads(fm_shot *s, int threads)
{
    s->threads = threads;
    for (int g = 0; g < s->count; g++)
        if (s->state[g]) s->state[g]->threads = fm_threads(threads);
}

int fm_shot_groups(const fm_shot *s) { return s->count; }
int64_t fm_shot_rows(const fm_shot *s) { return s->rows; }
const fm_morph_model *fm_shot_model(const fm_shot *s, int g) { return s->model[g]; }
const fm_morph_state *fm_shot_state(const fm_shot *s, int g) { return s->state[g]; }

fm_status fm_shot_distribute(fm_shot *s, const fm_dist *dist, fm_error *err)
{
    if (s->state[0]) return fm_fail(err, FM_ERR_USAGE, "fm_shot_distribute: the shot has run already");
    s->dist = dist;
    return create_states(s, dist, err);
}

/* Which agent of a state holds each target slot, and with which vertex order: on P ranks every
 * rank's agents, gathered on every rank (each puts its agents' tets into their rows). */
typedef struct slot_holder {
    int64_t target;
    int32_t id;
    uint8_t perm, pad[3];
} slot_holder;

static fm_status gather_slot_holders(const fm_morph_state *from, slot_holder **all, int64_t *total, fm_error *err)
{
    const int64_t slots = fm_morph_slots(from);
    slot_holder *mine = fm_alloc(sizeof(slot_holder) * (size_t)FM_MAX(slots, 1));
    fm_status st = mine ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)slots);
    for (int64_t k = 0; st == FM_OK && k < slots; k++) mine[k] = (slot_holder){from->target[k], from->id[k], from->perm[k], {0}};
    st = fm_dist_agree(from->dist, st, err);
    *all = NULL, *total = 0;
    if (st == FM_OK && !from->dist) *all = mine, *total = slots, mine = NULL;
    else if (st == FM_OK) st = fm_dist_allgather(from->dist, mine, slots, sizeof(slot_holder), (void **)all, total, err);
    fm_free(mine);
    return st;
}

/* Group g (from group a's formed shape) takes over a's rows: its agent with source tet j (a's
 * target slot j) gets the row, and the vertex order, of a's agent that holds slot j. */
static fm_status take_over_rows(fm_shot *s, int g, fm_error *err)
{
    const int a = s->def[g].group.source_group;
    slot_holder *holders;
    int64_t held;
    fm_status st = gather_slot_holders(s->state[a], &holders, &held, err);
    s->writes[a] = 0, s->writes[g] = 1;
    if (st != FM_OK) return fm_free(holders), st;
    const fm_morph_model *m = s->model[g];
    int64_t n = m->n, *agent_of_slot = fm_alloc(sizeof(int64_t) * (size_t)n);
    uint8_t *perm_of_slot = fm_alloc((size_t)n);
    s->row[g] = fm_alloc(sizeof(int64_t) * (size_t)n), s->perm[g] = fm_alloc((size_t)n);
    st = agent_of_slot && perm_of_slot && s->row[g] && s->perm[g]
             ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)n);
    if ((st = fm_dist_agree(s->dist, st, err)) != FM_OK) {
        fm_free(agent_of_slot), fm_free(perm_of_slot), fm_free(holders);
        return st;
    }
    for (int64_t k = 0; k < held; k++)
        agent_of_slot[holders[k].target] = holders[k].id, perm_of_slot[holders[k].target] = holders[k].perm;
    fm_free(holders);
    for (int64_t i = 0; i < n; i++) {
        int64_t slot = m->src_index[i], agent = agent_of_slot[slot];
        s->row[g][i] = s->row[a] ? s->row[a][agent] : s->row0[a] + agent;
        s->perm[g][i] = perm_of_slot[slot];
        if (s->perm[a]) s->perm[g][i] = fm_compose_even_permutations(s->perm[a][agent], perm_of_slot[slot]);
    }
    fm_free(agent_of_slot), fm_free(perm_of_slot);
    return FM_OK;
}

static fm_status start_groups(fm_shot *s, fm_error *err)
{
    for (int g = 0; g < s->count; g++) {
        int64_t at = s->started[g] ? -1 : fm_frame_loop_group_start(&s->def[g].group, s->arrival_step, s->dt);
        if (at < 0 || s->step < at) continue;
        if (s->def[g].group.source_group >= 0) {
            fm_status st = take_over_rows(s, g, err);
            if (st != FM_OK) return st;
        }
        s->started[g] = 1, s->start_step[g] = s->step;
    }
    return FM_OK;
}

/* One step of the shot: the groups that may start do, the started ones that still fly step. */
static fm_status shot_step(fm_shot *s, fm_error *err)
{
    fm_status st = start_groups(s, err);
    if (st != FM_OK) return st;
    for (int g = 0; g < s->count; g++) {
        if (!s->started[g] || s->arrived[g]) continue;
        fm_morph_step(s->model[g], s->state[g]);
        if (s->state[g]->count[FM_PHASE_ARRIVED] == s->state[g]->n) s->arrived[g] = 1, s->arrival_step[g] = s->step + 1;
    }
    s->step++;
    return FM_OK;
}

static int all_arrived(const fm_shot *s)
{
    for (int g = 0; g < s->count; g++)
        if (!s->arrived[g]) return 0;
    return 1;
}

/* Group g's tets into its rows (in the rows' vertex order), with its phases and its index, from
 * the group's frame in s->scratch. */
static void scatter_group(fm_shot *s, int g)
{
    const fm_morph_model *m = s->model[g];
    for (int64_t i = 0; i < m->n; i++) {
        int64_t r = s->row[g] ? s->row[g][i] : s->row0[g] + i;
        const uint8_t *perm = fm_even_permutations[s->perm[g] ? s->perm[g][i] : 0];
        for (int v = 0; v < 4; v++) memcpy(s->verts + 12 * r + 3 * v, s->scratch + 12 * i + 3 * perm[v], 3 * sizeof(float));
        s->phases[r] = s->scratch_phases[i], s->groups[r] = (uint8_t)g;
    }
}

/* The frame's per-group measures while it writes: its vertices' clearance from its obstacles and
 * its inverted tets, from `count` of its tets (with d, the rank's: the least and the sum over the
 * ranks, exact in any order). */
static void measure_group(fm_shot *s, int g, const float *tets, int64_t count, const fm_dist *d)
{
    fm_shot_group_stats *gs = &s->stats->group[g];
    double nearest = -fm_morph_vertex_clearance(s->model[g], tets, (size_t)count);
    int64_t inverted = fm_count_inverted_tets(tets, (size_t)count);
    fm_dist_max_f64(d, &nearest, 1), fm_dist_sum_i64(d, &inverted, 1);
    gs->min_vertex_clearance = fmin(gs->min_vertex_clearance, -nearest);
    gs->inverted_tet_frames += inverted;
}

/* Group g's frame in s->scratch (tets by agent id) and s->scratch_phases: on P ranks gathered on
 * rank 0 (collective). */
static fm_status group_frame(fm_shot *s, int g, fm_error *err)
{
    if (s->dist) return fm_morph_dist_frame(s->model[g], s->state[g], s->scratch, s->scratch_phases, err);
    fm_morph_tet_vertices(s->model[g], s->state[g], s->scratch);
    fm_morph_phases(s->state[g], s->scratch_phases);
    return FM_OK;
}

static const char *const SHOT_SPEEDS = "each group's speed0, omega1, style and obstacles";

/* Frame k: every group that writes, into its rows; checked and written (on P ranks gathered on rank
 * 0, which checks and writes it: without a cache to write in parallel). */
static fm_status write_frame(fm_shot *s, fm_cache_writer *cache, int64_t k, fm_error *err)
{
    const int root = fm_dist_rank(s->dist) == 0;
    for (int g = 0; g < s->count; g++) {
        fm_status st = s->writes[g] ? group_frame(s, g, err) : FM_OK;
        if (st != FM_OK) return st; /* the ranks agreed on it */
        if (s->writes[g] && root) scatter_group(s, g), measure_group(s, g, s->scratch, s->model[g]->n, NULL);
    }
    if (!root) return FM_OK;
    fm_status st = fm_frame_check_runaway(s->verts, 12, s->rows, s->scene_lo, s->scene_hi, k, SHOT_SPEEDS, err);
    if (st != FM_OK || !cache) return st;
    const cache_layout *l = fm_cache_writer_layout(cache);
    const void *data[CACHE_MAX_ATTRS];
    for (int i = 0; i < l->attr_count; i++) {
        fm_cache_attr a = l->attrs[i]->attr;
        data[i] = a == FM_ATTR_TET_VERTICES ? (const void *)s->verts : a == FM_ATTR_PHASE ? (const void *)s->phases
                  : a == FM_ATTR_GROUP      ? (const void *)s->groups : (const void *)fm_cache_writer_ids(cache);
    }
    return fm_cache_writer_add_frame_attrs(cache, data, err);
}

/* With the cache written by P ranks: the tets of group g whose rows lie in this rank's share, put
 * there by the ranks that hold them (collective). */
static fm_status share_group(fm_shot *s, int g, fm_error *err)
{
    fm_morph_state *st_g = s->state[g];
    fm_status st = fm_dist_agree(s->dist, fm_morph_own_room(st_g, &s->own, &s->own_capacity, err), err);
    const fm_morph_rows rows = {s->row0[g], s->row[g], s->perm[g], (uint8_t)g, s->groups};
    if (st == FM_OK) st = fm_morph_dist_frame_share(s->model[g], st_g, s->share.begin, &rows, s->own, s->verts, s->phases, err);
    return st; /* agreed by every rank */
}

/* Group g's rows of the rank's share (every group's written), together in scratch, measured. */
static void measure_shared_group(fm_shot *s, int g)
{
    const int64_t share = fm_frame_share_end(&s->share) - fm_frame_share_first(&s->share);
    int64_t count = 0;
    for (int64_t r = 0; r < share; r++)
        if (s->groups[r] == g) memcpy(s->scratch + 12 * count++, s->verts + 12 * r, 12 * sizeof(float));
    measure_group(s, g, s->scratch, count, s->dist);
}

/* Frame k with the cache written by P ranks: each rank fills, checks and encodes its share of the
 * rows; rank 0 appends the blocks (frame_share.h). */
static fm_status write_shared_frame(fm_shot *s, fm_cache_writer *cache, int64_t k, fm_error *err)
{
    fm_status st = FM_OK;
    for (int g = 0; g < s->count && st == FM_OK; g++)
        if (s->writes[g]) st = share_group(s, g, err);
    if (st != FM_OK) return st;
    for (int g = 0; g < s->count; g++)
        if (s->writes[g]) measure_shared_group(s, g);
    const int64_t first = fm_frame_share_first(&s->share), end = fm_frame_share_end(&s->share);
    st = fm_frame_check_runaway_from(s->verts, 12, first, end - first, s->scene_lo, s->scene_hi, k, SHOT_SPEEDS, err);
    const void *by_kind[CACHE_ATTR_KINDS] = {[FM_ATTR_TET_VERTICES] = s->verts, [FM_ATTR_PHASE] = s->phases,
                                             [FM_ATTR_GROUP] = s->groups};
    if ((st = fm_dist_agree(s->dist, st, err)) == FM_OK)
        st = fm_frame_share_write(&s->share, s->dist, cache, by_kind, (uint32_t)k, &s->state[0]->slabs->totals.bytes_sent, err);
    return st;
}

/* The shot's checkpoint (shot_checkpoint.h): its clock and statistics, and each group's state. */
static const fm_store_member SHOT_MEMBERS[] = {
    FM_STORE_SCALAR(fm_shot, step),  FM_STORE_SCALAR(fm_shot, started),    FM_STORE_SCALAR(fm_shot, arrived),
    FM_STORE_SCALAR(fm_shot, writes), FM_STORE_SCALAR(fm_shot, start_step), FM_STORE_SCALAR(fm_shot, arrival_step),
};
static const fm_store_member SHOT_STATS[] = { /* the groups' measures so far (the rest is the end state's) */
    FM_STORE_SCALAR(fm_shot_stats, run.simulate_seconds), FM_STORE_SCALAR(fm_shot_stats, run.output_seconds),
    FM_STORE_SCALAR(fm_shot_stats, group),
};

static const char *check_shot(const void *state)
{
    const fm_shot *s = state;
    return fm_shot_ckpt_check_clock(s->count, s->step, s->started, s->arrived, s->writes, s->start_step, s->arrival_step);
}

static fm_status save_group(void *shot, int g, const char *path, int64_t frames, fm_error *err)
{
    fm_shot *s = shot;
    return fm_morph_group_checkpoint_save(path, s->model[g], s->state[g], frames, err);
}

static fm_status load_group(void *shot, int g, const char *path, int64_t *frames, fm_error *err)
{
    fm_shot *s = shot;
    return fm_morph_group_checkpoint_load(path, s->model[g], s->state[g], frames, err);
}

static fm_shot_ckpt shot_checkpoint(fm_shot *s, fm_shot_stats *stats)
{
    int64_t agents[FM_MAX_GROUPS];
    for (int g = 0; g < s->count; g++) agents[g] = s->model[g]->n;
    const fm_ckpt_store shot = {
        .members = SHOT_MEMBERS, .member_count = (int)(sizeof SHOT_MEMBERS / sizeof SHOT_MEMBERS[0]), .state = s,
        .stats = SHOT_STATS, .stats_count = (int)(sizeof SHOT_STATS / sizeof SHOT_STATS[0]), .run_stats = stats,
        .def = &s->first, .model_hash = fm_shot_ckpt_groups_hash(s->def, agents, s->count),
        .model_what = "the groups' scenes (their parameters or agent counts)", .check = check_shot, .frames = stats->run.frames,
        .dist = s->dist};
    return (fm_shot_ckpt){shot, s->count, s, save_group, load_group};
}

fm_status fm_shot_checkpoint_check(const char *path, const fm_scene_def *def0, fm_error *err)
{
    return fm_ckpt_check(path, def0, SHOT_MEMBERS, (int)(sizeof SHOT_MEMBERS / sizeof SHOT_MEMBERS[0]), err);
}

fm_status fm_shot_checkpoint_load(fm_shot *s, const char *path, fm_shot_stats *stats, fm_error *err)
{
    memset(stats, 0, sizeof *stats);
    fm_status st = s->state[0] ? FM_OK : create_states(s, NULL, err); /* one process: the run has not made them */
    fm_shot_ckpt c = shot_checkpoint(s, stats);
    if (st == FM_OK) st = fm_shot_ckpt_load(path, &c, &stats->run.frames, err);
    if ((st = fm_dist_agree(s->dist, st, err)) != FM_OK) return st; /* before the collectives below */
    s->saved_frames = stats->run.frames;
    for (int g = 0; g < s->count && st == FM_OK; g++) /* the rows of the groups that took over others', in order */
        if (s->started[g] && s->def[g].group.source_group >= 0) st = take_over_rows(s, g, err);
    return st;
}

/* The shot in the shared frame loop (frame_loop.h). */
typedef struct shot_run {
    fm_shot *s;
    fm_cache_writer *cache;
    const fm_run_control *c;
    fm_status step_status;
    fm_error step_error;
} shot_run;

static void loop_step(void *sim)
{
    shot_run *r = sim;
    if (r->step_status == FM_OK) r->step_status = shot_step(r->s, &r->step_error);
}

static int loop_finished(const void *sim)
{
    const shot_run *r = sim;
    return all_arrived(r->s) || r->step_status != FM_OK;
}

static fm_status loop_frame(void *sim, int64_t k, fm_error *err)
{
    shot_run *r = sim;
    if (r->step_status != FM_OK) return *err = r->step_error, r->step_status;
    for (int g = 0; g < r->s->count; g++) /* an exchange that failed, which every rank knows */
        if (r->s->state[g]->dist_status != FM_OK) return *err = r->s->state[g]->dist_error, err->status = r->s->state[g]->dist_status;
    fm_status st = r->s->share.on ? write_shared_frame(r->s, r->cache, k, err)
                                  : fm_dist_agree(r->s->dist, write_frame(r->s, r->cache, k, err), err);
    const int64_t *counts[FM_MAX_GROUPS];
    for (int g = 0; g < r->s->count; g++) counts[g] = r->s->state[g]->count;
    if (st == FM_OK) fm_frame_loop_shot_progress(r->c, k, r->s->step, r->s->dt, counts, r->s->writes, r->s->count);
    return st;
}

/* The loop's checkpoint (the cache flushed, the ranks' blocks on disk): the groups' files, then the
 * shot's. */
static fm_status loop_save(void *sim, const char *path, fm_error *err)
{
    shot_run *r = sim;
    const fm_shot_ckpt c = shot_checkpoint(r->s, r->s->stats);
    return fm_shot_ckpt_save(path, &c, &r->s->saved_frames, err);
}

static fm_status loop_sync(void *sim, fm_error *err) { return fm_frame_share_sync(&((shot_run *)sim)->s->share, err); }

/* Group g's largest distance of a vertex from its target's: from its tets by id in scratch (every
 * agent), or with the cache written by P ranks from the rank's own agents' tets in slot order. */
static double final_vertex_error(fm_shot *s, int g)
{
    fm_error ignored = {0};
    if (!s->share.on) return fm_morph_tet_vertices(s->model[g], s->state[g], s->scratch),
                             fm_morph_final_vertex_error(s->model[g], s->state[g], s->scratch, 0);
    const int room = fm_morph_own_room(s->state[g], &s->own, &s->own_capacity, &ignored) == FM_OK;
    if (room) fm_morph_tet_vertices_by_slot(s->model[g], s->state[g], s->own);
    return fm_morph_final_vertex_error(s->model[g], s->state[g], room ? s->own : NULL, 1); /* collective */
}

/* Each group's end-state checks. */
static void finish_stats(fm_shot *s, fm_shot_stats *stats)
{
    stats->inverted_tet_frames = 0, stats->min_vertex_clearance = INFINITY;
    stats->all_arrived = all_arrived(s);
    stats->run.steps = s->step;
    stats->rows = s->rows;
    for (int g = 0; g < s->count; g++) {
        fm_shot_group_stats *gs = &stats->group[g];
        gs->agents = s->model[g]->n;
        gs->all_arrived = s->arrived[g];
        gs->final_max_vertex_error = final_vertex_error(s, g);
        gs->target_tets_filled_once = fm_morph_targets_taken_once(s->state[g]);
        gs->start_time = s->start_step[g] < 0 ? NAN : (double)s->start_step[g] * s->dt;
        gs->arrival_time = s->arrival_step[g] < 0 ? NAN : (double)s->arrival_step[g] * s->dt;
        gs->min_obstacle_clearance = s->state[g]->min_clearance;
        gs->mde_fraction = s->state[g]->flying_agent_steps
                               ? (double)s->state[g]->mde_agent_steps / (double)s->state[g]->flying_agent_steps : 0.0;
        stats->inverted_tet_frames += gs->inverted_tet_frames;
        stats->min_vertex_clearance = fmin(stats->min_vertex_clearance, gs->min_vertex_clearance);
    }
}

fm_status fm_shot_run(fm_shot *s, fm_cache_writer *cache, const fm_run_control *control, fm_shot_stats *stats,
                      fm_error *err)
{
    if (!control->resume) { /* else fm_shot_checkpoint_load restored them */
        memset(stats, 0, sizeof *stats);
        for (int g = 0; g < s->count; g++) stats->group[g].min_vertex_clearance = INFINITY;
    }
    s->stats = stats;
    shot_run r = {s, cache, control, FM_OK, {0}};
    fm_status st = s->state[0] ? FM_OK : create_states(s, NULL, err); /* one process */
    if (st != FM_OK) return st;
    st = fm_frame_share_start(&s->share, s->dist, cache, s->state[0]->threads, control->resume, err);
    if (st == FM_OK && s->share.on && s->rows > INT32_MAX) fm_frame_share_free(&s->share); /* rows in int32 records */
    if (st == FM_OK) fm_frame_share_commit(&s->share, cache), st = fm_dist_agree(s->dist, alloc_frame(s, err), err);
    const int ready = st == FM_OK; /* the frame's buffers, on every rank */
    if (ready) {
        const fm_frame_loop loop = {&r, loop_step, loop_finished, loop_frame, loop_save, s->steps_per_frame,
                                    s->frame_limit, control, &stats->run, cache, s->dist, loop_sync};
        st = fm_frame_loop_run(&loop, err);
    }
    if (ready) finish_stats(s, stats);
    fm_frame_share_free(&s->share);
    return st;
}
