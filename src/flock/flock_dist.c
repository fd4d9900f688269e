/* The shape flock on P ranks (docs/scale-out.md): slabs, migration, the boids' halo, the frame's
 * and the checkpoint's shares.
 *
 * Every rank keeps the one-process store (arrays indexed by agent id, as flock_state.c lays them
 * out) and computes only the agents whose position lies in its slab (slabs.h); an agent of another
 * rank has the rank-local phase FM_FLOCK_ELSEWHERE there, which every stage of the step skips, as
 * it skips a phase it does not handle. Every step:
 *   - migration: an agent that left the slab moves, with all that carries it from one step to the
 *     next (position, velocity, orientation, phase, bind time, leader, own Kalman covariance), to
 *     the owner of its new place; the destinations are computed by every rank for every agent, so
 *     they need not move;
 *   - halo: the agents in flight within the largest perception radius of another slab go there as
 *     ghosts (id, position, velocity: what the boids read of a neighbour), written in place and
 *     listed in the neighbour grid. The grid lists agents by cell, then by id, and the boids walk
 *     it in that order; with every neighbour within the radius present, each agent sums the same
 *     neighbours in the same order as on one process: the same bits;
 *   - the rest is per agent (leaders, fields, the Kalman filter, the moves), replicated (the path,
 *     the shared covariance, the target), or an integer sum (the counts).
 * At a frame and a checkpoint each rank receives the agents of its share of the ids into its arrays
 * (or, for a frame whose pieces are not whole blocks of measures, rank 0 receives every agent), so
 * its share of the frame, the measures and the checkpoint is one process's; then it marks them
 * elsewhere again. */
#include "flock.h"
#include "frame_share.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { RECUT_INTERVAL = 8 }; /* steps between two cuts */

/* An arrived agent's share of a step's work against one in flight (no boids, no Kalman filter, no
 * fields): its weight in the balance. */
static const double ARRIVED_WEIGHT = 0.1;

/* What every record to another rank starts with: rank 0 finds the agents it received by it. */
typedef struct record_head {
    int32_t id;
    uint8_t phase, pad[3];
} record_head;

/* An agent that changes rank, or goes to rank 0 for a checkpoint: all that carries it to the next
 * step (88 bytes). */
typedef struct agent_record {
    record_head h;
    float p[3], v[3], orient[4], leader[3], t_bind;
    double kalman_p[3];
} agent_record;

/* An agent in a frame on rank 0: what the frame and its measures read (60 bytes). */
typedef struct frame_record {
    record_head h;
    float p[3], v[3], orient[4], leader[3];
} frame_record;

/* A neighbour of another rank, for this step's boids. */
typedef struct ghost_record {
    float p[3], v[3];
    int32_t id;
} ghost_record;

static int is_mine(uint8_t phase) { return phase != FM_FLOCK_ELSEWHERE; }
static int in_flight(uint8_t phase) { return phase == FM_PHASE_FLYING || phase == FM_PHASE_HOMING; }

static double agent_weight(uint8_t phase) { return phase == FM_PHASE_ARRIVED ? ARRIVED_WEIGHT : 1.0; }

static void pack_frame(const fm_flock_state *s, int64_t a, void *out)
{
    frame_record *r = out;
    memset(r, 0, sizeof *r);
    for (int k = 0; k < 3; k++) r->p[k] = s->p[k][a], r->v[k] = s->v[k][a], r->leader[k] = s->leader[k][a];
    memcpy(r->orient, s->orient + 4 * a, sizeof r->orient);
    r->h.id = (int32_t)a, r->h.phase = s->phase[a];
}

static void unpack_frame(fm_flock_state *s, const void *in)
{
    const frame_record *r = in;
    const int64_t a = r->h.id;
    for (int k = 0; k < 3; k++) s->p[k][a] = r->p[k], s->v[k][a] = r->v[k], s->leader[k][a] = r->leader[k];
    memcpy(s->orient + 4 * a, r->orient, sizeof r->orient);
    s->phase[a] = r->h.phase;
}

static void pack(const fm_flock_state *s, int64_t a, void *out)
{
    agent_record *r = out;
    memset(r, 0, sizeof *r);
    for (int k = 0; k < 3; k++) r->p[k] = s->p[k][a], r->v[k] = s->v[k][a], r->leader[k] = s->leader[k][a];
    if (s->kalman_p) memcpy(r->kalman_p, s->kalman_p + 3 * a, sizeof r->kalman_p);
    memcpy(r->orient, s->orient + 4 * a, sizeof r->orient);
    r->t_bind = s->t_bind[a], r->h.id = (int32_t)a, r->h.phase = s->phase[a];
}

static void unpack(fm_flock_state *s, const void *in)
{
    const agent_record *r = in;
    const int64_t a = r->h.id;
    for (int k = 0; k < 3; k++) s->p[k][a] = r->p[k], s->v[k][a] = r->v[k], s->leader[k][a] = r->leader[k];
    if (s->kalman_p) memcpy(s->kalman_p + 3 * a, r->kalman_p, sizeof r->kalman_p);
    memcpy(s->orient + 4 * a, r->orient, sizeof r->orient);
    s->t_bind[a] = r->t_bind, s->phase[a] = r->h.phase;
}

/* The cuts at the quantiles of the agents this rank computes (every agent when all is set: every
 * rank then holds the same store and needs no sum), each weighted by its phase times `weight`. */
static void cut_at_agents(fm_flock_state *s, double weight, int all)
{
    fm_slabs *d = s->slabs;
    double *bins = calloc(FM_SLAB_BINS, sizeof(double));
    if (!bins) return; /* the cuts stay: still correct, only less balanced */
    const float *x = s->p[d->axis];
    for (int64_t a = 0; a < s->n; a++)
        if (all || is_mine(s->phase[a])) bins[fm_slabs_bin(d, x[a])] += weight * agent_weight(s->phase[a]);
    fm_slabs_cut(d, bins, all ? NULL : s->dist);
    free(bins);
}

/* Every rank holds every agent (a fresh state, or a loaded checkpoint): the cuts at their
 * quantiles, and the agents of other slabs marked elsewhere. */
static void keep_my_slab(fm_flock_state *s)
{
    cut_at_agents(s, 1, 1);
    const fm_slabs *d = s->slabs;
    for (int64_t a = 0; a < s->n; a++)
        if (fm_slabs_owner(d, s->p[d->axis][a], 0) != d->rank) s->phase[a] = FM_FLOCK_ELSEWHERE;
}

fm_status fm_flock_state_distribute(const fm_flock_model *m, fm_flock_state *s, const fm_dist *dist, fm_error *err)
{
    s->slabs = fm_slabs_create(dist, m->scene_lo, m->scene_hi, m->max_radius, err);
    if (!s->slabs) return err->status;
    s->dist = dist;
    keep_my_slab(s);
    return FM_OK;
}

void fm_flock_dist_adopt(fm_flock_state *s) { keep_my_slab(s); }

fm_dist_totals fm_flock_dist_get_totals(const fm_flock_state *s)
{
    fm_dist_totals t = {0};
    return s->slabs ? s->slabs->totals : t;
}

/* The records of this rank's agents that `go` sends elsewhere, grouped by rank (d->count). */
static agent_record *pack_leaving(fm_flock_state *s, int64_t *leaving, fm_error *err)
{
    fm_slabs *d = s->slabs;
    const float *x = s->p[d->axis];
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    *leaving = 0;
    for (int64_t a = 0; a < s->n; a++) {
        if (!is_mine(s->phase[a])) continue;
        const int r = fm_slabs_owner(d, x[a], d->rank);
        if (r != d->rank) d->count[r]++, (*leaving)++;
    }
    agent_record *out = fm_alloc(sizeof(agent_record) * (size_t)FM_MAX(*leaving, 1));
    int64_t *at = malloc(sizeof(int64_t) * (size_t)(d->ranks + 1));
    if (!out || !at) {
        fm_free(out), free(at);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld migrating agents", (long long)*leaving), NULL;
    }
    fm_slabs_offsets(d, at);
    for (int64_t a = 0; a < s->n && *leaving > 0; a++) {
        if (!is_mine(s->phase[a])) continue;
        const int r = fm_slabs_owner(d, x[a], d->rank);
        if (r == d->rank) continue;
        pack(s, a, out + at[r]++);
        s->phase[a] = FM_FLOCK_ELSEWHERE;
    }
    free(at);
    d->totals.migrated += *leaving;
    return out;
}

static fm_status migrate(fm_flock_state *s, fm_error *err)
{
    int64_t leaving = 0, received = 0;
    agent_record *out = pack_leaving(s, &leaving, err);
    void *in;
    fm_status st = fm_slabs_send(s->slabs, s->dist, out ? FM_OK : err->status, out, sizeof(agent_record), &in, &received, err);
    for (int64_t k = 0; st == FM_OK && k < received; k++) unpack(s, (const agent_record *)in + k);
    fm_free(out), fm_free(in);
    return st;
}

/* Before the grid build: the cuts (every RECUT_INTERVAL steps) and the migration. */
fm_status fm_flock_dist_migrate(fm_flock_state *s, fm_error *err)
{
    if (s->step % RECUT_INTERVAL == 0) cut_at_agents(s, fm_slabs_take_weight(s->slabs), 0);
    return migrate(s, err);
}

/* Whether this rank's agent a goes to rank r as a ghost. */
static int ghost_for(const fm_slabs *d, int r, float x) { return r != d->rank && fm_slabs_near(d, r, x); }

/* This step's ghosts: the other ranks' agents in flight within the halo of this slab, written in
 * place (position, velocity) and made members of the grid (after mark_flock). */
fm_status fm_flock_dist_ghosts(fm_flock_state *s, fm_error *err)
{
    fm_slabs *d = s->slabs;
    const float *x = s->p[d->axis];
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    int64_t sending = 0, received = 0;
    for (int64_t a = 0; a < s->n; a++) /* count, then fill */
        if (in_flight(s->phase[a]) && fm_slabs_in_halo(d, x[a]))
            for (int r = 0; r < d->ranks; r++) d->count[r] += ghost_for(d, r, x[a]);
    for (int r = 0; r < d->ranks; r++) sending += d->count[r];
    ghost_record *out = fm_alloc(sizeof(ghost_record) * (size_t)FM_MAX(sending, 1));
    int64_t *at = malloc(sizeof(int64_t) * (size_t)(d->ranks + 1));
    fm_status st = out && at ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld halo agents", (long long)sending);
    if (st == FM_OK) {
        fm_slabs_offsets(d, at);
        for (int64_t a = 0; a < s->n; a++) {
            if (!in_flight(s->phase[a]) || !fm_slabs_in_halo(d, x[a])) continue;
            for (int r = 0; r < d->ranks; r++)
                if (ghost_for(d, r, x[a]))
                    out[at[r]++] = (ghost_record){{s->p[0][a], s->p[1][a], s->p[2][a]}, {s->v[0][a], s->v[1][a], s->v[2][a]},
                                                  (int32_t)a};
        }
    }
    void *in;
    st = fm_slabs_send(d, s->dist, st, out, sizeof(ghost_record), &in, &received, err);
    if (st == FM_OK) {
        const ghost_record *g = in;
        for (int64_t k = 0; k < received; k++) {
            const int64_t a = g[k].id;
            for (int c = 0; c < 3; c++) s->p[c][a] = g[k].p[c], s->v[c][a] = g[k].v[c];
            s->member[a] = 1;
        }
        d->totals.ghost_agent_steps += received;
    }
    fm_free(out), fm_free(in), free(at);
    return st;
}

/* After the step: the counts over all ranks, the load, and the time its work took for the balance. */
void fm_flock_dist_after_step(fm_flock_state *s, double busy_seconds)
{
    double weight = 0;
    for (int i = 0; i < 4; i++) weight += (double)s->count[i] * agent_weight((uint8_t)i);
    fm_slabs_add_busy(s->slabs, busy_seconds, weight);
    fm_slabs_record_load(s->slabs, s->dist, s->count[FM_PHASE_FLYING] + s->count[FM_PHASE_HOMING]);
    fm_dist_sum_i64(s->dist, s->count, 4);
}


/* Every rank sends its agents whose ids lie in another rank's share (begin[r] … begin[r + 1] − 1)
 * there, as records of `size` bytes (count, then fill, as the migration packs), and takes those of
 * its own share into its arrays with their phases (s->gathered keeps them, for
 * fm_flock_dist_release). The share's agents are then complete here. */
static fm_status share(fm_flock_state *s, const int64_t *begin, size_t size,
                       void (*put)(const fm_flock_state *, int64_t, void *), void (*take)(fm_flock_state *, const void *),
                       fm_error *err)
{
    fm_slabs *d = s->slabs;
    const int64_t mine_begin = begin[d->rank], mine_end = begin[d->rank + 1];
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    for (int64_t a = 0; a < s->n; a++)
        if (is_mine(s->phase[a]) && (a < mine_begin || a >= mine_end)) d->count[fm_frame_share_owner(begin, d->ranks, a)]++;
    int64_t *at = malloc(sizeof(int64_t) * ((size_t)d->ranks + 1));
    if (at) fm_slabs_offsets(d, at);
    char *out = at ? fm_alloc(size * (size_t)FM_MAX(at[d->ranks], 1)) : NULL;
    fm_status st = out ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame's exchange");
    for (int64_t a = 0; st == FM_OK && a < s->n; a++)
        if (is_mine(s->phase[a]) && (a < mine_begin || a >= mine_end))
            put(s, a, out + size * (size_t)at[fm_frame_share_owner(begin, d->ranks, a)]++);
    void *in;
    int64_t received = 0;
    st = fm_slabs_send(d, s->dist, st, out, size, &in, &received, err);
    for (int64_t k = 0; st == FM_OK && k < received; k++) take(s, (const char *)in + size * (size_t)k);
    s->gathered = in, s->gathered_count = st == FM_OK ? received : 0, s->gathered_size = size;
    free(at), fm_free(out);
    return st;
}

/* Rank 0 gets every agent (the frame gathered, where the pieces are not whole blocks of measures):
 * a share of every id. */
fm_status fm_flock_dist_gather(fm_flock_state *s, fm_error *err)
{
    const int ranks = fm_dist_size(s->dist);
    int64_t *begin = malloc(sizeof(int64_t) * ((size_t)ranks + 1));
    fm_status st = fm_dist_agree(s->dist, begin ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory"), err);
    if (st != FM_OK) return free(begin), st;
    begin[0] = 0;
    for (int r = 1; r <= ranks; r++) begin[r] = s->n;
    st = share(s, begin, sizeof(frame_record), pack_frame, unpack_frame, err);
    free(begin);
    return st;
}

/* The cache written in parallel (frame_share.h): this rank's share of the frame's agents. */
fm_status fm_flock_dist_share(fm_flock_state *s, const int64_t *begin, fm_error *err)
{
    return share(s, begin, sizeof(frame_record), pack_frame, unpack_frame, err);
}

void fm_flock_dist_own_in_flight(fm_flock_state *s)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->n; a++) s->member[a] = is_mine(s->phase[a]) && s->phase[a] != FM_PHASE_ARRIVED;
    for (int64_t k = 0; k < s->gathered_count; k++)
        s->member[((const record_head *)((const char *)s->gathered + s->gathered_size * (size_t)k))->id] = 0;
}

/* Rank 0 after the frame: the agents it received are elsewhere again; the measures' grid is not
 * the one this rank's next step builds (that lists its own agents and the ghosts). */
void fm_flock_dist_release(fm_flock_state *s)
{
    for (int64_t k = 0; k < s->gathered_count; k++) {
        const record_head *h = (const record_head *)((const char *)s->gathered + s->gathered_size * (size_t)k);
        s->phase[h->id] = FM_FLOCK_ELSEWHERE;
    }
    fm_free(s->gathered);
    s->gathered = NULL, s->gathered_count = 0;
    s->grid_current = 0;
}

/* On P ranks: every rank takes the agents of its share of the pieces (fm_ckpt_share: the ids
 * begin[r] … begin[r + 1] − 1) with all that a checkpoint saves of them, and writes them at their
 * place in one process's file, rank 0 the rest; any P, or one process, resumes it, and the file is
 * one process's, byte for byte. */
fm_status fm_flock_dist_checkpoint_save(const char *path, const fm_flock_model *m, fm_flock_state *s,
                                        const fm_flock_run_stats *stats, int64_t frames, fm_error *err)
{
    const int ranks = fm_dist_size(s->dist), me = fm_dist_rank(s->dist);
    int64_t *begin = malloc(sizeof(int64_t) * ((size_t)ranks + 1));
    fm_status st = fm_dist_agree(s->dist, begin ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory"), err);
    if (st != FM_OK) return free(begin), st;
    for (int r = 0; r < ranks; r++) begin[r] = fm_ckpt_share(s->n, m->def.cache_piece_agents, r, ranks).first;
    begin[ranks] = s->n;
    st = share(s, begin, sizeof(agent_record), pack, unpack, err);
    const fm_ckpt_part part = fm_ckpt_share(s->n, m->def.cache_piece_agents, me, ranks);
    if (st == FM_OK) st = fm_flock_checkpoint_write(path, m, s, stats, frames, &part, 1, err);
    fm_flock_dist_release(s);
    free(begin);
    return fm_dist_agree(s->dist, st, err);
}
