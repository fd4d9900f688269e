/* The shape flock on P ranks (docs/scale-out.md): slabs, migration, the boids' halo, the frame's
 * and the checkpoint's shares.
 *
 * A rank's store holds the agents whose position lies in its slab (slabs.h), in slots kept in
 * increasing id order (id[slot]), with their parameters by slot (fm_flock_params), so the step reads
 * them as one process reads its agents; it grows with the slab (fm_flock_state_reserve). Every step:
 *   - migration: an agent that left the slab moves, with all that carries it from one step to the
 *     next (position, velocity, orientation, phase, bind time, destination, leader, own Kalman
 *     covariance), to the owner of its new place, which merges it into its slots by id;
 *   - halo: the agents in flight within the largest perception radius of another slab go there as
 *     ghosts (id, position, velocity: what the boids read of a neighbour), merged into the slots by
 *     id with the rank-local phase FM_FLOCK_ELSEWHERE, which every stage of the step skips, and
 *     listed in the neighbour grid. The grid lists agents by cell, then by slot, so by id, and its
 *     table is the one process's (fm_grid_init_table): with every neighbour within the radius
 *     present, each agent sums the same neighbours in the same order as on one process: the same
 *     bits. The next migration drops the ghosts;
 *   - the rest is per agent (leaders, fields, the Kalman filter, the moves), replicated (the path,
 *     the shared covariance, the target), or an integer sum (the counts).
 * At a frame and a checkpoint each rank receives the agents of its share of the ids into a view
 * (fm_flock_state_view: arrays for those ids alone), so its share of the frame, the measures and the
 * checkpoint is one process's. Where the frame's pieces are not whole blocks of measures, rank 0's
 * share is every agent. */
#include "flock.h"
#include "frame_share.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* An arrived agent's share of a step's work against one in flight (no boids, no Kalman filter, no
 * fields): its weight in the balance. */
static const double ARRIVED_WEIGHT = 0.1;

/* What every record to another rank starts with: the receiver places the agent by it. */
typedef struct record_head {
    int32_t id;
    uint8_t phase, pad[3];
} record_head;

/* An agent that changes rank, or goes to a checkpoint's share: all that carries it to the next step
 * (100 bytes). */
typedef struct agent_record {
    record_head h;
    float p[3], v[3], orient[4], dest[3], leader[3], t_bind;
    double kalman_p[3];
} agent_record;

/* An agent of a frame's share: what the frame and its measures read (72 bytes). */
typedef struct frame_record {
    record_head h;
    float p[3], v[3], orient[4], dest[3], leader[3];
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
    for (int k = 0; k < 3; k++)
        r->p[k] = s->p[k][a], r->v[k] = s->v[k][a], r->dest[k] = s->dest[k][a], r->leader[k] = s->leader[k][a];
    memcpy(r->orient, s->orient + 4 * a, sizeof r->orient);
    r->h.id = (int32_t)fm_flock_id(s, a), r->h.phase = s->phase[a];
}

static void unpack_frame(fm_flock_state *s, int64_t a, const void *in)
{
    const frame_record *r = in;
    for (int k = 0; k < 3; k++)
        s->p[k][a] = r->p[k], s->v[k][a] = r->v[k], s->dest[k][a] = r->dest[k], s->leader[k][a] = r->leader[k];
    memcpy(s->orient + 4 * a, r->orient, sizeof r->orient);
    s->phase[a] = r->h.phase;
}

static void pack(const fm_flock_state *s, int64_t a, void *out)
{
    agent_record *r = out;
    memset(r, 0, sizeof *r);
    for (int k = 0; k < 3; k++)
        r->p[k] = s->p[k][a], r->v[k] = s->v[k][a], r->dest[k] = s->dest[k][a], r->leader[k] = s->leader[k][a];
    if (s->kalman_p) memcpy(r->kalman_p, s->kalman_p + 3 * a, sizeof r->kalman_p);
    memcpy(r->orient, s->orient + 4 * a, sizeof r->orient);
    r->t_bind = s->t_bind[a], r->h.id = (int32_t)fm_flock_id(s, a), r->h.phase = s->phase[a];
}

static void unpack(fm_flock_state *s, int64_t a, const void *in)
{
    const agent_record *r = in;
    for (int k = 0; k < 3; k++)
        s->p[k][a] = r->p[k], s->v[k][a] = r->v[k], s->dest[k][a] = r->dest[k], s->leader[k][a] = r->leader[k];
    if (s->kalman_p) memcpy(s->kalman_p + 3 * a, r->kalman_p, sizeof r->kalman_p);
    memcpy(s->orient + 4 * a, r->orient, sizeof r->orient);
    s->t_bind[a] = r->t_bind, s->phase[a] = r->h.phase;
}

/* The cuts at the quantiles of n agents in flight at x[id], which every rank holds alike (no sum
 * over the ranks). */
static void cut_at_all(fm_slabs *d, const float *x, int64_t n)
{
    double *bins = calloc(FM_SLAB_BINS, sizeof(double));
    if (!bins) return; /* the cuts stay: still correct, only less balanced */
    for (int64_t a = 0; a < n; a++) bins[fm_slabs_bin(d, x[a])] += 1.0;
    fm_slabs_cut(d, bins, NULL);
    free(bins);
}

/* The cuts at the quantiles of every rank's agents, each weighted by its phase times `weight`. */
static void cut_at_agents(fm_flock_state *s, double weight)
{
    fm_slabs *d = s->slabs;
    double *bins = calloc(FM_SLAB_BINS, sizeof(double));
    if (!bins) return;
    const float *x = s->p[d->axis];
    for (int64_t a = 0; a < s->slots; a++)
        if (is_mine(s->phase[a])) bins[fm_slabs_bin(d, x[a])] += weight * agent_weight(s->phase[a]);
    fm_slabs_cut(d, bins, s->dist);
    free(bins);
}

/* Of n agents at x[id] (alike on every rank), those of this rank's slab: how many. */
static int64_t count_mine(const fm_slabs *d, const float *x, int64_t n)
{
    int64_t mine = 0;
    for (int64_t a = 0; a < n; a++) mine += fm_slabs_owner(d, x[a], 0) == d->rank;
    return mine;
}

/* A rank's store for the agents of its slab at x[id] (every rank's alike): their ids in the slots,
 * with their parameters. */
static fm_flock_state *store_for_slab(const fm_flock_model *m, int threads, const fm_dist *dist, fm_slabs *d,
                                      const float *x, fm_error *err)
{
    const int64_t mine = count_mine(d, x, m->n);
    fm_flock_state *s = fm_flock_state_alloc(m, threads, dist, FM_MIN(m->n, mine + mine / 4 + 1024), err);
    if (!s) return fm_slabs_free(d), NULL;
    s->slabs = d, s->slots = 0;
    for (int64_t id = 0; id < m->n; id++) {
        if (fm_slabs_owner(d, x[id], 0) != d->rank) continue;
        s->id[s->slots] = (int32_t)id;
        fm_flock_params_copy(m, &s->prm, s->slots++, id);
    }
    return s;
}

fm_flock_state *fm_flock_state_create_distributed(const fm_flock_model *m, int threads, const fm_dist *dist,
                                                  fm_error *err)
{
    fm_slabs *d = fm_slabs_create(dist, m->scene_lo, m->scene_hi, m->max_radius, err);
    if (!d) return NULL;
    cut_at_all(d, m->start[d->axis], m->n); /* every agent starts on its source sample, in flight */
    fm_flock_state *s = store_for_slab(m, threads, dist, d, m->start[d->axis], err);
    if (s) fm_flock_state_start(m, s);
    return s;
}

fm_dist_totals fm_flock_dist_get_totals(const fm_flock_state *s)
{
    fm_dist_totals t = {0};
    return s && s->slabs ? s->slabs->totals : t;
}

/* Records another rank sent, of one kind: `count` of `size` bytes, the id at offset id_at; take()
 * writes one into its slot, which gets its parameters where `own` (an agent of this rank, not a
 * ghost). */
typedef struct arrivals {
    const void *records;
    int64_t count;
    size_t size, id_at;
    int own;
    void (*take)(fm_flock_state *, int64_t, const void *);
} arrivals;

/* An incoming agent: its id, its kind (arrivals) and place among their records, its new slot. */
typedef struct incoming {
    int32_t id, k;
    int64_t slot;
    int kind;
} incoming;

/* s->merge_buf for `count` incoming agents: kept between steps (grown by half), so the step makes no
 * allocation that the C library would keep in its heap. */
static incoming *incoming_room(fm_flock_state *s, int64_t count)
{
    const size_t bytes = sizeof(incoming) * (size_t)FM_MAX(count, 1);
    if (bytes > s->merge_bytes) {
        void *more = realloc(s->merge_buf, bytes + bytes / 2);
        if (!more) return NULL;
        s->merge_buf = more, s->merge_bytes = bytes + bytes / 2;
    }
    return s->merge_buf;
}

static int by_id(const void *a, const void *b)
{
    const int32_t x = ((const incoming *)a)->id, y = ((const incoming *)b)->id;
    return (x > y) - (x < y);
}

/* The incoming agents of every kind (their ids are distinct), sorted by id; their number. */
static int64_t list_incoming(incoming *in, const arrivals *kinds, int kind_count)
{
    int64_t count = 0;
    for (int c = 0; c < kind_count; c++)
        for (int64_t k = 0; k < kinds[c].count; k++, count++) {
            memcpy(&in[count].id, (const char *)kinds[c].records + kinds[c].size * (size_t)k + kinds[c].id_at,
                   sizeof(int32_t));
            in[count].k = (int32_t)k, in[count].kind = c;
        }
    qsort(in, (size_t)count, sizeof *in, by_id);
    return count;
}

/* The slots rebuilt, once: those with keep(phase) in their order, merged by id with the arrivals of
 * each kind, which their take() writes into their new slots; each gets its id and, for an agent of
 * this rank (own), its parameters. */
static fm_status merge_slots(const fm_flock_model *m, fm_flock_state *s, int (*keep)(uint8_t), const arrivals *kinds,
                             int kind_count, fm_error *err)
{
    int64_t kept = 0, arriving = 0;
    for (int64_t a = 0; a < s->slots; a++) kept += keep(s->phase[a]);
    for (int c = 0; c < kind_count; c++) arriving += kinds[c].count;
    if (kept == s->slots && arriving == 0) return FM_OK;
    incoming *in = incoming_room(s, arriving);
    fm_status st = in ? fm_flock_state_reserve(s, kept + arriving, err)
                      : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld incoming agents", (long long)arriving);
    if (st != FM_OK) return st;
    const int64_t count = list_incoming(in, kinds, kind_count);
    int32_t *from = s->move_from; /* a slot array: room for kept + count after the reserve */
    int64_t a = 0, j = 0, slots = 0;
    for (;;) { /* the merge by id: kept slot a, or incoming j (sorted) */
        while (a < s->slots && !keep(s->phase[a])) a++;
        if (a >= s->slots && j >= count) break;
        if (a < s->slots && (j >= count || s->id[a] < in[j].id)) from[slots++] = (int32_t)a++;
        else in[j++].slot = slots, from[slots++] = -1;
    }
    fm_flock_state_move_slots(s, from, slots);
    for (j = 0; j < count; j++) {
        const arrivals *c = &kinds[in[j].kind];
        c->take(s, in[j].slot, (const char *)c->records + c->size * (size_t)in[j].k);
        s->id[in[j].slot] = in[j].id;
        if (c->own) fm_flock_params_copy(m, &s->prm, in[j].slot, in[j].id);
    }
    return FM_OK;
}

/* During the exchange, the phase of a slot the merge drops: last step's ghosts, and agents that left
 * for a slab whose halo this one is not in (one that is stays here, as a ghost). */
enum { DROPPED = 0xFE };
static int kept_in_slots(uint8_t phase) { return phase != DROPPED; }
static int keep_all(uint8_t phase) { return (void)phase, 1; }

/* The step's records to send, grouped by rank. */
typedef struct exchange_out {
    int64_t *ghost_count;  /* per rank (the migrants' are d->count, which fm_slabs_send reads) */
    int64_t *migrant_at, *ghost_at; /* per rank, the next record's place (ranks + 1: the sum last) */
    agent_record *agent;   /* NULL while counting */
    ghost_record *ghost;
    int64_t kept_ghosts;   /* agents that left but stay here as ghosts */
} exchange_out;

/* Where this rank's agent a goes this step: to the owner of its slab (`owner`), and as a ghost to every
 * other slab whose halo holds it, if in flight (the halo as its owner sees it: every rank's ghosts
 * are its owner's, whether it moved or not). Counts them (o->agent NULL) or packs them; says
 * whether it stays here as a ghost. */
static int route_agent(fm_slabs *d, const fm_flock_state *s, int64_t a, int owner, exchange_out *o)
{
    const float x = s->p[d->axis][a];
    if (owner != d->rank) o->agent ? pack(s, a, o->agent + o->migrant_at[owner]++) : (void)d->count[owner]++;
    if (!in_flight(s->phase[a]) || (owner == d->rank && !fm_slabs_in_halo(d, x))) return 0;
    int ghost_here = 0;
    for (int r = 0; r < d->ranks; r++) {
        if (r == owner || !fm_slabs_near(d, r, x)) continue;
        if (r == d->rank) ghost_here = 1; /* it left, and this slab's halo still holds it */
        else if (!o->agent) o->ghost_count[r]++;
        else
            o->ghost[o->ghost_at[r]++] = (ghost_record){{s->p[0][a], s->p[1][a], s->p[2][a]},
                                                        {s->v[0][a], s->v[1][a], s->v[2][a]}, s->id[a]};
    }
    return ghost_here;
}

static void take_ghost(fm_flock_state *s, int64_t a, const void *in)
{
    const ghost_record *g = in;
    for (int c = 0; c < 3; c++) s->p[c][a] = g->p[c], s->v[c][a] = g->v[c];
    s->phase[a] = FM_FLOCK_ELSEWHERE;
}

/* The step's records (o): every agent of this rank routed (route_agent), counted, then packed; last
 * step's ghosts, and the agents that left for good, marked DROPPED for the merge. */
static fm_status pack_exchange(fm_flock_state *s, exchange_out *o, fm_error *err)
{
    fm_slabs *d = s->slabs;
    const int ranks = d->ranks;
    memset(d->count, 0, sizeof(int64_t) * (size_t)ranks);
    memset(o->ghost_count, 0, sizeof(int64_t) * (size_t)ranks);
    for (int64_t a = 0; a < s->slots; a++) {
        if (s->phase[a] == FM_FLOCK_ELSEWHERE) s->phase[a] = DROPPED; /* last step's ghost */
        else route_agent(d, s, a, fm_slabs_owner(d, s->p[d->axis][a], d->rank), o);
    }
    fm_slabs_offsets(d, o->migrant_at), fm_offsets(o->ghost_count, ranks, o->ghost_at);
    const int64_t leaving = o->migrant_at[ranks], ghosts = o->ghost_at[ranks];
    o->agent = fm_alloc(sizeof(agent_record) * (size_t)FM_MAX(leaving, 1));
    o->ghost = fm_alloc(sizeof(ghost_record) * (size_t)FM_MAX(ghosts, 1));
    if (!o->agent || !o->ghost)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld migrating and %lld halo agents", (long long)leaving,
                       (long long)ghosts);
    for (int64_t a = 0; a < s->slots; a++) {
        if (s->phase[a] == DROPPED) continue;
        const int owner = fm_slabs_owner(d, s->p[d->axis][a], d->rank);
        const int ghost_here = route_agent(d, s, a, owner, o);
        if (owner == d->rank) continue;
        s->phase[a] = ghost_here ? FM_FLOCK_ELSEWHERE : DROPPED;
        o->kept_ghosts += ghost_here;
    }
    d->totals.migrated += leaving;
    return FM_OK;
}

/* On P ranks, before the grid build: the cuts (every step: they follow the flock, as the morph's do,
 * and the agents cross them less often than cuts that jump every few steps), then the migration and
 * the halo in one pass and one merge of the slots. Each agent that left its slab goes, with all
 * that carries it, to its new owner; every agent in flight goes as a ghost to each other slab whose
 * halo holds it, chosen for its new owner, so the ghosts are those the owners after the migration
 * would send. The merge keeps the agents that stay and those that left but are ghosts here, drops
 * last step's ghosts, and takes the arrivals and the new ghosts. */
fm_status fm_flock_dist_exchange(const fm_flock_model *m, fm_flock_state *s, fm_error *err)
{
    fm_slabs *d = s->slabs;
    cut_at_agents(s, fm_slabs_weight(d, s->step));
    const size_t per_rank = (size_t)d->ranks + 1;
    int64_t *counts = malloc(sizeof(int64_t) * 3 * per_rank);
    exchange_out o = {0};
    if (counts) o.ghost_count = counts, o.migrant_at = counts + per_rank, o.ghost_at = counts + 2 * per_rank;
    fm_status st = counts ? pack_exchange(s, &o, err) : fm_fail(err, FM_ERR_MEMORY, "out of memory");
    void *agents_in = NULL, *ghosts_in = NULL;
    int64_t migrants = 0, ghosts = 0;
    st = fm_slabs_send(d, s->dist, st, o.agent, sizeof(agent_record), &agents_in, &migrants, err);
    if (st == FM_OK) {
        memcpy(d->count, o.ghost_count, sizeof(int64_t) * (size_t)d->ranks);
        st = fm_slabs_send(d, s->dist, st, o.ghost, sizeof(ghost_record), &ghosts_in, &ghosts, err);
    }
    const arrivals kinds[2] = {
        {agents_in, migrants, sizeof(agent_record), offsetof(agent_record, h.id), 1, unpack},
        {ghosts_in, ghosts, sizeof(ghost_record), offsetof(ghost_record, id), 0, take_ghost},
    };
    if (st == FM_OK) st = merge_slots(m, s, kept_in_slots, kinds, 2, err);
    if (st == FM_OK) d->totals.ghost_agent_steps += ghosts + o.kept_ghosts;
    fm_free(o.agent), fm_free(o.ghost), fm_free(agents_in), fm_free(ghosts_in), free(counts);
    return fm_dist_agree(s->dist, st, err);
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
 * there, as records of `size` bytes (count, then fill, as the migration packs), and puts those of its
 * own share into its view (with a grid where `grid`), with the run's counters: the share's agents
 * are then complete there. Returns the view, or NULL (every rank agrees). */
static fm_flock_state *share(fm_flock_state *s, const int64_t *begin, int grid, size_t size,
                             void (*put)(const fm_flock_state *, int64_t, void *),
                             void (*take)(fm_flock_state *, int64_t, const void *), fm_error *err)
{
    fm_slabs *d = s->slabs;
    const int64_t first = begin[d->rank], end = begin[d->rank + 1];
    fm_flock_state *view = fm_flock_state_view(s, first, end - first, grid, err);
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    for (int64_t a = 0; a < s->slots; a++)
        if (is_mine(s->phase[a])) d->count[fm_frame_share_owner(begin, d->ranks, s->id[a])]++;
    d->count[d->rank] = 0; /* those of this rank's share go straight into its view */
    int64_t *at = malloc(sizeof(int64_t) * ((size_t)d->ranks + 1));
    if (at) fm_slabs_offsets(d, at);
    char *out = at ? fm_alloc(size * (size_t)FM_MAX(at[d->ranks], 1) + size) : NULL; /* and one for this rank */
    fm_status st = view && out ? FM_OK : view ? fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame's exchange") : err->status;
    for (int64_t a = 0; st == FM_OK && a < s->slots; a++) {
        if (!is_mine(s->phase[a])) continue;
        const int r = fm_frame_share_owner(begin, d->ranks, s->id[a]);
        char *rec = out + size * (size_t)(r == d->rank ? at[d->ranks] : at[r]++);
        put(s, a, rec);
        if (r == d->rank) take(view, s->id[a] - first, rec);
    }
    void *in = NULL;
    int64_t received = 0;
    st = fm_slabs_send(d, s->dist, st, out, size, &in, &received, err);
    for (int64_t k = 0; st == FM_OK && k < received; k++) {
        const char *rec = (const char *)in + size * (size_t)k;
        take(view, ((const record_head *)rec)->id - first, rec);
    }
    if (st == FM_OK) {
        view->step = s->step, view->time = s->time, view->kalman = s->kalman, view->lag_sum = s->lag_sum;
        memcpy(view->count, s->count, sizeof view->count);
    }
    free(at), fm_free(out), fm_free(in);
    return st == FM_OK ? view : NULL;
}

/* Shares of the ids: every id on rank 0 (all), or runs of whole FM_BLOCK blocks, as even as they go. */
static fm_flock_state *share_by(fm_flock_state *s, int all, int grid, fm_error *err)
{
    const int ranks = fm_dist_size(s->dist);
    int64_t *begin = malloc(sizeof(int64_t) * ((size_t)ranks + 1));
    fm_status st = fm_dist_agree(s->dist, begin ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory"), err);
    if (st != FM_OK) return free(begin), NULL;
    const int64_t blocks = (s->n + FM_BLOCK - 1) / FM_BLOCK;
    for (int r = 0; r <= ranks; r++) begin[r] = all ? (r > 0 ? s->n : 0) : FM_MIN(FM_BLOCK * (blocks * r / ranks), s->n);
    fm_flock_state *view = share(s, begin, grid, sizeof(frame_record), pack_frame, unpack_frame, err);
    free(begin);
    return view;
}

/* Rank 0 gets every agent (the frame gathered, where the pieces are not whole blocks of measures):
 * a share of every id, with a grid for the measures where `grid`. */
fm_flock_state *fm_flock_dist_gather(fm_flock_state *s, int grid, fm_error *err)
{
    return share_by(s, 1, grid && fm_dist_rank(s->dist) == 0, err);
}

/* Each rank a run of whole FM_BLOCK blocks: for block sums without a frame (a shot group's end-state
 * distances, fm_flock_distance_blocks). */
fm_flock_state *fm_flock_dist_blocks(fm_flock_state *s, fm_error *err) { return share_by(s, 0, 0, err); }

/* The cache written in parallel (frame_share.h): this rank's share of the frame's agents. */
fm_flock_state *fm_flock_dist_share(fm_flock_state *s, const int64_t *begin, fm_error *err)
{
    return share(s, begin, 0, sizeof(frame_record), pack_frame, unpack_frame, err);
}

void fm_flock_dist_own_in_flight(fm_flock_state *s)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->slots; a++) s->member[a] = is_mine(s->phase[a]) && s->phase[a] != FM_PHASE_ARRIVED;
}

/* After a frame's measures: their grid is not the one this rank's next step builds (that lists its
 * own agents and the ghosts). */
void fm_flock_dist_release(fm_flock_state *s) { s->grid_current = 0; }

/* The slot of agent id here, or −1 (on P ranks slots by increasing id; one process re-sorted: its
 * slot_by_id). */
int64_t fm_flock_slot_of(const fm_flock_state *s, int64_t id)
{
    if (s->slot_by_id) return id >= 0 && id < s->n ? s->slot_by_id[id] : -1;
    if (!s->id) return id >= s->first && id < s->first + s->slots ? id - s->first : -1;
    int64_t lo = 0, hi = s->slots;
    while (lo < hi) {
        const int64_t mid = lo + (hi - lo) / 2;
        if (s->id[mid] < id) lo = mid + 1;
        else hi = mid;
    }
    return lo < s->slots && s->id[lo] == id ? lo : -1;
}

/* On P ranks: every rank takes the agents of its share of the pieces (fm_ckpt_share: the ids
 * begin[r] … begin[r + 1] − 1) into its view with all that a checkpoint saves of them, and writes
 * them at their place in one process's file, rank 0 the rest; any P, or one process, resumes it, and
 * the file is one process's, byte for byte. */
fm_status fm_flock_dist_checkpoint_save(const char *path, const fm_flock_model *m, fm_flock_state *s,
                                        const fm_flock_run_stats *stats, int64_t frames, fm_error *err)
{
    const int ranks = fm_dist_size(s->dist), me = fm_dist_rank(s->dist);
    int64_t *begin = malloc(sizeof(int64_t) * ((size_t)ranks + 1));
    fm_status st = fm_dist_agree(s->dist, begin ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory"), err);
    if (st != FM_OK) return free(begin), st;
    for (int r = 0; r < ranks; r++) begin[r] = fm_ckpt_share(s->n, m->def.cache_piece_agents, r, ranks).first;
    begin[ranks] = s->n;
    fm_flock_state *view = share(s, begin, 0, sizeof(agent_record), pack, unpack, err);
    fm_ckpt_part part = fm_ckpt_share(s->n, m->def.cache_piece_agents, me, ranks);
    part.at = 0; /* the view's element 0 is the share's first agent */
    if (view) view->look = s->look; /* the same on every rank (fm_flock_look_frame merges the ranks') */
    st = view ? fm_flock_checkpoint_write(path, m, view, s->dist, stats, frames, &part, 1, err) : err->status;
    free(begin);
    return fm_dist_agree(s->dist, st, err);
}

/* The agents of every rank's view (s->view: a share of the ids, as a checkpoint restored them): the
 * cuts at their quantiles, and each to the rank whose slab holds it, merged into its slots
 * (collective); the view is freed once packed. The hand-over is no step's traffic: the totals stay. */
fm_status fm_flock_dist_adopt(const fm_flock_model *m, fm_flock_state *s, fm_error *err)
{
    fm_flock_state *view = s->view;
    fm_slabs *d = s->slabs;
    const fm_dist_totals totals = d->totals;
    double *bins = calloc(FM_SLAB_BINS, sizeof(double));
    if (bins) {
        for (int64_t a = 0; a < view->slots; a++) bins[fm_slabs_bin(d, view->p[d->axis][a])] += agent_weight(view->phase[a]);
        fm_slabs_cut(d, bins, s->dist); /* summed over the ranks */
        free(bins);
    }
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    for (int64_t a = 0; a < view->slots; a++) d->count[fm_slabs_owner(d, view->p[d->axis][a], d->rank)]++;
    int64_t *at = malloc(sizeof(int64_t) * ((size_t)d->ranks + 1));
    if (at) fm_slabs_offsets(d, at);
    agent_record *out = at ? fm_alloc(sizeof(agent_record) * (size_t)FM_MAX(at[d->ranks], 1)) : NULL;
    fm_status st = out ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld resumed agents", (long long)view->slots);
    for (int64_t a = 0; st == FM_OK && a < view->slots; a++)
        pack(view, a, out + at[fm_slabs_owner(d, view->p[d->axis][a], d->rank)]++);
    s->step = view->step, s->time = view->time, s->kalman = view->kalman, s->lag_sum = view->lag_sum;
    memcpy(s->count, view->count, sizeof s->count);
    s->look = view->look;
    fm_flock_state_destroy(view), s->view = NULL; /* its agents are in the records */
    void *in = NULL;
    int64_t received = 0;
    st = fm_slabs_send(d, s->dist, st, out, sizeof(agent_record), &in, &received, err);
    s->slots = 0; /* the fresh store's agents give way to the restored ones */
    const arrivals restored = {in, received, sizeof(agent_record), offsetof(agent_record, h.id), 1, unpack};
    if (st == FM_OK) st = merge_slots(m, s, keep_all, &restored, 1, err);
    d->totals = totals;
    free(at), fm_free(out), fm_free(in);
    return fm_dist_agree(s->dist, st, err);
}

/* The restored phases of every rank's share against the counters (check_state counts a share's
 * phases only where it holds every agent). */
static fm_status check_counts(const fm_flock_state *view, const fm_dist *dist, const char *path, fm_error *err)
{
    int64_t count[4] = {0, 0, 0, 0};
    for (int64_t a = 0; a < view->slots; a++) count[view->phase[a]]++; /* in range: check_state */
    fm_dist_sum_i64(dist, count, 4);
    if (memcmp(count, view->count, sizeof count) == 0) return FM_OK;
    return fm_ckpt_damaged(path, "counters inconsistent with the agents", err);
}

/* On P ranks: every rank reads the file, keeping its share of the pieces (fm_ckpt_share, as the
 * ranks wrote it) in its view, and the agents go to their slabs' ranks. */
fm_status fm_flock_dist_checkpoint_load(fm_flock_state *s, const fm_flock_model *m,
                                        fm_status (*load)(fm_flock_state *view, const fm_ckpt_part *part, void *arg),
                                        void *arg, const char *path, fm_error *err)
{
    fm_ckpt_part part = fm_ckpt_share(s->n, m->def.cache_piece_agents, fm_dist_rank(s->dist), fm_dist_size(s->dist));
    part.at = 0; /* the view's element 0 is the share's first agent */
    fm_flock_state *view = fm_flock_state_view(s, part.first, part.count, 0, err);
    fm_status st = fm_dist_agree(s->dist, view ? load(view, &part, arg) : err->status, err);
    if (st == FM_OK) st = fm_dist_agree(s->dist, check_counts(view, s->dist, path, err), err);
    if (st == FM_OK) st = fm_flock_dist_adopt(m, s, err);
    return st;
}
