/* fm_morph_run: fm_morph_step in the shared frame loop (frame_loop.h), with the end-state checks
 * reported in stats.json. */
#include "frame_loop.h"
#include "frame_share.h"
#include "morph.h"
#include "cache_format.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static double signed_volume6(const float *t)
{
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; k++)
        a[k] = (double)t[3 + k] - t[k], b[k] = (double)t[6 + k] - t[k], c[k] = (double)t[9 + k] - t[k];
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

int64_t fm_count_inverted_tets(const float *verts, size_t n)
{
    int64_t count = 0;
#pragma omp parallel for num_threads(fm_threads(0)) reduction(+ : count) schedule(static)
    for (int64_t i = 0; i < (int64_t)n; i++) count += !(signed_volume6(verts + 12 * i) > 0);
    return count;
}

/* Largest distance between an agent's vertex and its target tet's matching vertex (a moving
 * target's at the state's time, in float as the frame has it). */
double fm_morph_final_vertex_error(const fm_morph_model *m, const fm_morph_state *s, const float *verts, int by_slot)
{
    double worst = !verts || s->launched < s->n ? INFINITY : 0; /* on P ranks the waiting agents are in no store */
    if (m->motion) fm_morph_motion_prepare(m, s->motion_now, s->time);
    for (int64_t a = 0; a < fm_morph_slots(s) && worst < INFINITY; a++) { /* slot a: agent id[a]; verts by id */
        if (s->target[a] < 0) {
            worst = INFINITY; /* not arrived: the loop ends */
            continue;
        }
        const uint8_t *perm = fm_even_permutations[s->perm[a]];
        const float *t = m->tgt_f + 12 * s->target[a];
        float moved[12];
        if (m->motion) {
            double d[12], c[3];
            fm_morph_motion_tet(m, s->motion_now, s->target[a], d, c);
            for (int j = 0; j < 12; j++) moved[j] = (float)d[j];
            t = moved;
        }
        const float *v = verts + 12 * (size_t)(by_slot ? a : s->id[a]);
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++) worst = fmax(worst, fabs((double)v[3 * i + k] - (double)t[3 * perm[i] + k]));
    }
    fm_dist_max_f64(s->dist, &worst, 1);
    return worst;
}

static int each_target_taken_once_here(int64_t n, const int64_t *target, int64_t count)
{
    if (n < 1) return 1;
    uint8_t *taken = calloc((size_t)n, 1);
    if (!taken) return 0;
    int ok = count == n;
    for (int64_t a = 0; a < count && ok; a++) {
        int64_t t = target[a];
        ok = t >= 0 && t < n && !taken[t];
        if (ok) taken[t] = 1;
    }
    free(taken);
    return ok;
}

/* Every target slot taken by exactly one agent (on P ranks: checked on rank 0, told to all). */
int fm_morph_targets_taken_once(const fm_morph_state *s)
{
    if (!s->dist) return each_target_taken_once_here(s->n, s->target, s->n);
    void *all = NULL;
    int64_t total = 0, ok = 0;
    if (fm_dist_gather(s->dist, s->target, s->active_end, sizeof(int64_t), &all, &total, NULL) == FM_OK)
        ok = fm_dist_rank(s->dist) == 0 && each_target_taken_once_here(s->n, all, total);
    fm_free(all);
    fm_dist_bcast(s->dist, &ok, sizeof ok, 0);
    return (int)ok;
}

/* Hands the frame to the cache in the attributes it was created with: the tetra morph has tet
 * vertices, ids and phases. */
static fm_status cache_frame(fm_cache_writer *cache, const float *verts, const uint8_t *phases, fm_error *err)
{
    const cache_layout *l = fm_cache_writer_layout(cache);
    const void *data[CACHE_MAX_ATTRS];
    for (int i = 0; i < l->attr_count; i++) {
        if (l->attrs[i]->attr == FM_ATTR_TET_VERTICES) data[i] = verts;
        else if (l->attrs[i]->attr == FM_ATTR_PHASE) data[i] = phases;
        else if (l->attrs[i]->attr == FM_ATTR_ID) data[i] = fm_cache_writer_ids(cache); /* frames are in id order */
        else return fm_fail(err, FM_ERR_USAGE, "the tetra morph cannot write the cache attribute '%s'", l->attrs[i]->name);
    }
    return fm_cache_writer_add_frame_attrs(cache, data, err);
}

/* What sets the tetra morph's speeds, for a runaway's message. */
static const char *const MORPH_SPEEDS = "speed0 and omega1, time.time_step, style.omega2 and the fields' gain, speed "
                                        "and strength, mde.speed, path.attraction";

/* Vertices whose grid distance is within this many voxels of the frame's smallest are measured
 * exactly: the grid's nodes are exact and trilinear interpolation of a distance errs by less than
 * a voxel, so the nearest vertex is among them. */
static const float EXACT_WITHIN_VOXELS = 2.0f;

/* The smallest grid distance over every vertex of n tets. */
static float grid_min_vertex(const fm_sdf_view *g, const float *verts, int64_t vertices)
{
    float least = INFINITY;
#pragma omp parallel for num_threads(fm_threads(0)) reduction(min : least) schedule(static)
    for (int64_t i = 0; i < vertices; i++)
        least = fminf(least, fm_sdf_sample(g, verts[3 * i], verts[3 * i + 1], verts[3 * i + 2], NULL));
    return least;
}

double fm_morph_vertex_clearance(const fm_morph_model *m, const float *verts, size_t n)
{
    if (!m->obstacles || n == 0) return INFINITY;
    const fm_sdf_view g = fm_obstacles_sdf(m->obstacles);
    const int64_t vertices = 4 * (int64_t)n;
    const float least = grid_min_vertex(&g, verts, vertices);
    if (!(least < g.far)) return g.far; /* every vertex beyond the band: at least its width */
    const float near = least + EXACT_WITHIN_VOXELS * g.voxel;
    double exact = INFINITY;
#pragma omp parallel num_threads(fm_threads(0)) reduction(min : exact)
    {
        double best = INFINITY; /* this thread's: only a nearer vertex can change the minimum */
#pragma omp for schedule(dynamic, 4096)
        for (int64_t i = 0; i < vertices; i++) {
            const float *v = verts + 3 * i;
            const float gv = fm_sdf_sample(&g, v[0], v[1], v[2], NULL);
            if (!(gv <= near)) continue;
            const double p[3] = {v[0], v[1], v[2]};
            /* within a voxel of the surface the grid's sign may be wrong: the signed query there */
            best = fmin(best, gv <= g.voxel || !(best > 0) ? fm_obstacles_closest(m->obstacles, p, NULL, NULL)
                                                            : fm_obstacles_distance_within(m->obstacles, p, best));
        }
        exact = fmin(exact, best);
    }
    return exact;
}

/* Frame k's tets of agents first … end − 1 (mine, first's first) checked, with the inverted-tet
 * count and the vertices' clearance. On P ranks (d), each rank's share: the counts summed, the
 * clearance the least, the runaway message the lowest rank's (the first agent in id order, as on
 * one process). */
static fm_status check_frame(const fm_morph_model *m, const fm_dist *d, int64_t k, const float *mine, int64_t first,
                             int64_t end, fm_morph_run_stats *stats, fm_error *err)
{
    fm_status st = fm_frame_check_runaway_from(mine, 12, first, end - first, m->scene_lo, m->scene_hi, k, MORPH_SPEEDS, err);
    int64_t inverted = st == FM_OK ? fm_count_inverted_tets(mine, (size_t)(end - first)) : 0;
    double nearest = st == FM_OK ? -fm_morph_vertex_clearance(m, mine, (size_t)(end - first)) : -INFINITY;
    if ((st = fm_dist_agree(d, st, err)) != FM_OK) return st;
    fm_dist_sum_i64(d, &inverted, 1);
    fm_dist_max_f64(d, &nearest, 1); /* the least clearance: exact in any order */
    stats->inverted_tet_frames += inverted;
    stats->min_vertex_clearance = fmin(stats->min_vertex_clearance, -nearest);
    return FM_OK;
}

/* Frame k: the tet vertices (and phases), checked, written to the cache. */
static fm_status check_and_write(const fm_morph_model *m, const fm_morph_state *s, int64_t k, const float *verts,
                                 const uint8_t *phases, fm_cache_writer *cache, fm_morph_run_stats *stats, fm_error *err)
{
    fm_status st = check_frame(m, NULL, k, verts, 0, s->n, stats, err);
    return st == FM_OK && cache ? cache_frame(cache, verts, phases, err) : st;
}

/* The frame's buffers: on one process, or with the frame gathered on rank 0, every agent's tet and
 * phase by id; with the cache written by P ranks, the rank's share of them (from its first id) and
 * its own agents' tets in slot order (own), so that a rank holds about n / P of each. */
typedef struct frame_buffers {
    float *verts;
    uint8_t *phases;
    float *own;
    int64_t own_capacity; /* slots own holds */
} frame_buffers;

/* On P ranks: the frame gathered on rank 0, which checks and writes it; every rank returns the
 * outcome (a failed step's, else rank 0's). */
static fm_status emit_dist_frame(const fm_morph_model *m, fm_morph_state *s, int64_t k, float *verts, uint8_t *phases,
                                 fm_cache_writer *cache, fm_morph_run_stats *stats, fm_error *err)
{
    if (s->dist_status != FM_OK) return *err = s->dist_error, err->status = s->dist_status;
    fm_status st = fm_morph_dist_frame(m, s, verts, phases, err);
    if (st == FM_OK && fm_dist_rank(s->dist) == 0) st = check_and_write(m, s, k, verts, phases, cache, stats, err);
    st = fm_dist_agree(s->dist, st, err);
    fm_dist_bcast(s->dist, &stats->inverted_tet_frames, sizeof stats->inverted_tet_frames, 0);
    fm_dist_bcast(s->dist, &stats->min_vertex_clearance, sizeof stats->min_vertex_clearance, 0);
    return st;
}

/* On P ranks with the cache written in parallel: each rank checks and encodes its share of the
 * frame, rank 0 appends the blocks. */
static fm_status emit_shared_frame(const fm_morph_model *m, fm_morph_state *s, int64_t k, frame_buffers *f,
                                   fm_frame_share *share, fm_cache_writer *cache, fm_morph_run_stats *stats, fm_error *err)
{
    if (s->dist_status != FM_OK) return *err = s->dist_error, err->status = s->dist_status;
    fm_status st = fm_dist_agree(s->dist, fm_morph_own_room(s, &f->own, &f->own_capacity, err), err);
    float *verts = f->verts;
    uint8_t *phases = f->phases;
    if (st == FM_OK) st = fm_morph_dist_frame_share(m, s, share->begin, NULL, f->own, verts, phases, err); /* agreed by every rank */
    if (st == FM_OK) st = check_frame(m, s->dist, k, verts, fm_frame_share_first(share), fm_frame_share_end(share), stats, err);
    if (st != FM_OK) return st;
    const void *by_kind[CACHE_ATTR_KINDS] = {[FM_ATTR_TET_VERTICES] = verts, [FM_ATTR_PHASE] = phases};
    return fm_frame_share_write(share, s->dist, cache, by_kind, (uint32_t)k, &s->slabs->totals.bytes_sent, err);
}

/* Frame k: the tet vertices and phases, checked, written to the cache, with the inverted-tet count. */
static fm_status emit_frame(const fm_morph_model *m, fm_morph_state *s, int64_t k, frame_buffers *f,
                            fm_frame_share *share, fm_cache_writer *cache, fm_morph_run_stats *stats, fm_error *err)
{
    if (share->on) return emit_shared_frame(m, s, k, f, share, cache, stats, err);
    if (s->dist) return emit_dist_frame(m, s, k, f->verts, f->phases, cache, stats, err);
    fm_morph_tet_vertices(m, s, f->verts);
    fm_morph_phases(s, f->phases);
    return check_and_write(m, s, k, f->verts, f->phases, cache, stats, err);
}

void fm_morph_run_stats_free(fm_morph_run_stats *stats)
{
    free(stats->mde_fraction);
    stats->mde_fraction = NULL;
}

/* Records frame k's MDE fraction (FM Table I's last column, k >= 1) from the step counters. */
static fm_status record_mde(const fm_morph_state *s, int64_t k, int64_t *flying_before, int64_t *mde_before,
                            fm_morph_run_stats *stats, int64_t *capacity, fm_error *err)
{
    int64_t flying = s->flying_agent_steps - *flying_before, mde = s->mde_agent_steps - *mde_before;
    fm_status st = fm_frame_rows_room(&stats->mde_fraction, k, 1, capacity, err);
    if (st != FM_OK) return st;
    stats->mde_fraction[k - 1] = flying > 0 ? (double)mde / (double)flying : NAN;
    *flying_before = s->flying_agent_steps, *mde_before = s->mde_agent_steps;
    return FM_OK;
}

/* FM Table I's MDE column: the mean over the frames that had agents in phase 1, summed in frame
 * order (so a resumed run adds the same numbers in the same order). */
static double mde_mean(const fm_morph_run_stats *stats)
{
    double sum = 0;
    int64_t frames = 0;
    for (int64_t f = 0; f + 1 < stats->run.frames; f++)
        if (!isnan(stats->mde_fraction[f])) sum += stats->mde_fraction[f], frames++;
    return frames ? sum / (double)frames : 0.0;
}

/* Keeps list[0 .. *count) the (at most FM_MORPH_STRAGGLERS_LISTED) smallest ids seen, sorted. */
static void keep_straggler(fm_morph_straggler *list, int *count, fm_morph_straggler x)
{
    int i = *count;
    if (i == FM_MORPH_STRAGGLERS_LISTED) {
        if (list[i - 1].id < x.id) return;
        i--; /* x takes the largest one's place */
    } else {
        (*count)++;
    }
    for (; i > 0 && list[i - 1].id > x.id; i--) list[i] = list[i - 1];
    list[i] = x;
}

static double sphere_distance(const fm_morph_model *m, float x, float y, float z)
{
    const double dx = (double)x - m->sphere_c[0], dy = (double)y - m->sphere_c[1], dz = (double)z - m->sphere_c[2];
    return sqrt(dx * dx + dy * dy + dz * dz) - m->sphere_r;
}

/* Why a run stopped at its frame limit (issue 38): the agents not arrived, per phase, and the first
 * few by id with their distance outside the switch sphere. On P ranks each rank lists its own store's
 * and the ranks merge their lists by id, smallest first (collective; the waiting agents, ids from
 * s->launched on, are in no store and are added by rank 0). */
static void find_stragglers(const fm_morph_model *m, const fm_morph_state *s, fm_morph_run_stats *stats)
{
    fm_morph_straggler mine[FM_MORPH_STRAGGLERS_LISTED];
    int count = 0;
    int64_t per_phase[4] = {0, 0, 0, 0};
    for (int64_t a = 0; a < fm_morph_slots(s); a++) {
        const int phase = s->phase[a];
        if (phase != FM_PHASE_FLYING && phase != FM_PHASE_HOMING) continue;
        per_phase[phase]++;
        keep_straggler(mine, &count, (fm_morph_straggler){s->id[a], phase, sphere_distance(m, s->p[0][a], s->p[1][a], s->p[2][a])});
    }
    fm_dist_sum_i64(s->dist, per_phase, 4);
    per_phase[FM_PHASE_WAITING] = s->n - s->launched;
    if (fm_dist_rank(s->dist) == 0)
        for (int64_t id = s->launched; id < s->n && id < s->launched + FM_MORPH_STRAGGLERS_LISTED; id++)
            keep_straggler(mine, &count, (fm_morph_straggler){id, FM_PHASE_WAITING,
                                                             sphere_distance(m, m->src_c[0][id], m->src_c[1][id], m->src_c[2][id])});
    memcpy(stats->stragglers, per_phase, sizeof per_phase);
    stats->stragglers_listed = 0;
    for (int i = 0, next = 0; i < FM_MORPH_STRAGGLERS_LISTED; i++) { /* the smallest next id of any rank */
        int64_t best = next < count ? -mine[next].id : INT64_MIN;
        fm_dist_max_i64(s->dist, &best, 1);
        if (best == INT64_MIN) break;
        const int own = next < count && mine[next].id == -best;
        int64_t phase = own ? mine[next].phase : -1;
        double distance = own ? mine[next].sphere_distance : -INFINITY;
        fm_dist_max_i64(s->dist, &phase, 1);
        fm_dist_max_f64(s->dist, &distance, 1);
        stats->straggler[stats->stragglers_listed++] = (fm_morph_straggler){-best, (int)phase, distance};
        next += own;
    }
}

/* The end-state checks and totals of stats.json, from the last frame's tets of the store's agents. */
static void finish_stats(const fm_morph_model *m, const fm_morph_state *s, const frame_buffers *f, int shared,
                         fm_morph_run_stats *stats)
{
    stats->run.steps = s->step;
    stats->all_arrived = s->count[FM_PHASE_ARRIVED] == s->n;
    stats->stopped_at_frame_limit = !stats->all_arrived;
    stats->final_max_vertex_error = fm_morph_final_vertex_error(m, s, shared ? f->own : f->verts, shared);
    stats->target_tets_filled_once = fm_morph_targets_taken_once(s);
    stats->morph_fallbacks = s->morph_fallbacks;
    stats->detour_agent_steps = s->detour_agent_steps;
    stats->mde_fraction_mean = mde_mean(stats);
    stats->min_obstacle_clearance = s->min_clearance;
    find_stragglers(m, s, stats);
}

/* The tetra morph in the shared frame loop (frame_loop.h): its callbacks and what they carry. */
static fm_status morph_sync(void *sim, fm_error *err);
typedef struct morph_run {
    const fm_morph_model *m;
    fm_morph_state *s;
    fm_cache_writer *cache;
    const fm_run_control *c;
    fm_morph_run_stats *stats;
    frame_buffers frame;
    int64_t flying_before, mde_before, capacity; /* the MDE counters at the last frame, mde_fraction's room */
    fm_frame_share share;                        /* on P ranks: this rank's share of every frame */
} morph_run;

static void morph_step(void *sim)
{
    morph_run *r = sim;
    fm_morph_step(r->m, r->s);
}

/* A moving target goes on moving after the last tet arrived: its run ends at the frame limit. */
static int morph_finished(const void *sim)
{
    const morph_run *r = sim;
    return r->s->count[FM_PHASE_ARRIVED] == r->s->n && !r->m->motion;
}

/* Frame k: written, its MDE fraction recorded, the progress reported. */
static fm_status morph_frame(void *sim, int64_t k, fm_error *err)
{
    morph_run *r = sim;
    fm_status st = emit_frame(r->m, r->s, k, &r->frame, &r->share, r->cache, r->stats, err);
    if (st != FM_OK || k == 0) return st;
    st = record_mde(r->s, k, &r->flying_before, &r->mde_before, r->stats, &r->capacity, err);
    if (st == FM_OK && r->c->progress) {
        fm_morph_info info = fm_morph_get_info(r->s);
        r->c->progress(&info.run, k, r->c->progress_user);
    }
    return st;
}

/* The loop's checkpoint (the cache already flushed): the state and the statistics so far. */
static fm_status morph_save(void *sim, const char *path, fm_error *err)
{
    morph_run *r = sim;
    if (r->s->dist) return fm_morph_dist_checkpoint_save(path, r->m, r->s, r->stats, r->stats->run.frames, err);
    return fm_morph_checkpoint_save(path, r->m, r->s, r->stats, err);
}

/* Before a checkpoint on P ranks: every rank's blocks of the cache on disk. */
static fm_status morph_sync(void *sim, fm_error *err) { return fm_frame_share_sync(&((morph_run *)sim)->share, err); }

/* The frame's buffers (frame_buffers); a resumed run's hold its last frame, should it be complete. */
static fm_status alloc_frame(morph_run *r, fm_error *err)
{
    const fm_morph_state *s = r->s;
    const int64_t agents = r->share.on ? fm_frame_share_end(&r->share) - fm_frame_share_first(&r->share) : s->n;
    frame_buffers *f = &r->frame;
    f->verts = fm_alloc(sizeof(float) * 12 * (size_t)agents), f->phases = fm_alloc((size_t)agents);
    if (!f->verts || !f->phases) return fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame of %lld agents", (long long)agents);
    if (r->share.on && fm_morph_own_room(s, &f->own, &f->own_capacity, err) != FM_OK) return err->status;
    if (r->c->resume && r->share.on) fm_morph_tet_vertices_by_slot(r->m, s, f->own);
    else if (r->c->resume) fm_morph_tet_vertices(r->m, s, f->verts);
    return FM_OK;
}

fm_status fm_morph_run_controlled(const fm_morph_model *m, fm_morph_state *s, fm_cache_writer *cache, const fm_run_control *c,
                                  fm_morph_run_stats *stats, fm_error *err)
{
    if (!c->resume) memset(stats, 0, sizeof *stats), stats->min_vertex_clearance = INFINITY;
    morph_run r = {.m = m, .s = s, .cache = cache, .c = c, .stats = stats,
                   .flying_before = s->flying_agent_steps, .mde_before = s->mde_agent_steps};
    /* capacity 0: a resumed run's array holds exactly its frames so far */
    fm_status st = fm_frame_rows_room(&stats->mde_fraction, FM_MAX(stats->run.frames, 1), 1, &r.capacity, err);
    if ((st = fm_dist_agree(s->dist, st, err)) == FM_OK) st = fm_frame_share_start(&r.share, s->dist, cache, s->threads, c->resume, err);
    if (st == FM_OK) st = fm_dist_agree(s->dist, alloc_frame(&r, err), err);
    if (st == FM_OK) {
        fm_frame_share_commit(&r.share, cache);
        const fm_frame_loop loop = {&r, morph_step, morph_finished, morph_frame, morph_save, m->steps_per_frame,
                                    m->def.frame_limit, c, &stats->run, cache, s->dist, morph_sync};
        st = fm_frame_loop_run(&loop, err);
        finish_stats(m, s, &r.frame, r.share.on, stats);
    }
    fm_frame_share_free(&r.share);
    fm_free(r.frame.verts), fm_free(r.frame.phases), fm_free(r.frame.own);
    return st;
}

fm_status fm_morph_run(const fm_morph_model *m, fm_morph_state *s, fm_cache_writer *cache, fm_run_progress_fn progress,
                       void *user, fm_morph_run_stats *stats, fm_error *err)
{
    fm_run_control c = fm_default_run_control();
    c.progress = progress, c.progress_user = user;
    return fm_morph_run_controlled(m, s, cache, &c, stats, err);
}
