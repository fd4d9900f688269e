/* The tetra morph on P ranks (docs/scale-out.md): slabs, migration, halos, the frame gather.
 *
 * Space is cut into P slabs along the scene's longest axis: contiguous ranges of the cell key
 * along that axis, rank r owning cut[r] <= x < cut[r + 1]. Each rank's store holds the agents it
 * owns (launched there, or moved in), laid out as on one process; waiting agents are held by no
 * rank (they are the model's rest tets, launched by the rank whose slab holds their centroid).
 * Every step:
 *   - migration: an agent in flight whose centroid left the slab moves, with all of its state,
 *     to the owner of its new place (rest data are rebuilt from the model by id);
 *   - halo: each rank appends, after its active range, the flying agents of other ranks within
 *     d_min of its slab (position and id): the MDE walk (kernel_mde.c) then sees every neighbour it
 *     would see on one process, and sums their pushes in id order, so V_la is the same bits;
 *   - the rest of the step is per agent (fields, obstacles, moves), or global in id order (the
 *     hand-out, morph_step.c), or an integer or min reduction: the same for any P.
 * Every step the cuts move to the quantiles of the agents in flight, so each
 * rank gets the same share of the flock as it sweeps the scene. */
#include "morph.h"
#include "frame_share.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* An agent that changes rank: everything its store slot carries but the rest data. */
typedef struct agent_record {
    float p[3], v[3], p2[3], t2, tf, morph[FM_MORPH_FLOATS];
    float detour_best, detour_since;
    int64_t target;
    int32_t id;
    uint8_t phase, perm, morph_safe, detour_on;
    uint8_t settled; /* a resumed agent that arrived before the last re-sort (fm_morph_dist_adopt) */
} agent_record;

/* A neighbour of another rank, for this step's MDE walk. */
typedef struct ghost_record {
    float p[3];
    int32_t id;
} ghost_record;

/* The first cuts: quantiles of every source tet's centroid (the flock starts as the source). */
static void initial_cuts(const fm_morph_model *m, fm_slabs *d)
{
    double *bins = calloc(FM_SLAB_BINS, sizeof(double));
    if (!bins) return; /* the cuts stay: still correct, only less balanced */
    for (int64_t i = 0; i < m->n; i++) bins[fm_slabs_bin(d, m->src_c[d->axis][i])]++;
    fm_slabs_cut(d, bins, NULL);
    free(bins);
}

fm_status fm_morph_state_distribute(const fm_morph_model *m, fm_morph_state *s, const fm_dist *dist, fm_error *err)
{
    fm_slabs *d = fm_slabs_create(dist, m->scene_lo, m->scene_hi, m->def.d_min, err);
    if (!d) return err->status;
    initial_cuts(m, d);
    s->dist = dist, s->slabs = d;
    s->active_begin = s->active_end = 0; /* nothing launched: no slot holds an agent yet */
    fm_morph_state_fit(s); /* the rank's store grows with its share (docs/scale-out.md, "Memory") */
    return FM_OK;
}

fm_dist_totals fm_morph_dist_get_totals(const fm_morph_state *s)
{
    fm_dist_totals t = {0};
    return s && s->slabs ? s->slabs->totals : t; /* s: NULL for a shot's group that was never made */
}

/* Stage 1 on P ranks: agents id in [launched, due) leave the source; each rank takes those whose
 * rest centroid lies in its slab, in id order, after its active range. */
static void unpack_agent(const fm_morph_model *m, fm_morph_state *s, const agent_record *r, int64_t a);

/* Agent i as it leaves the source (or waits there): at its rest centroid, no target, the rest of
 * its state zero; rest data come from the model as for any agent that arrives in a store. */
static agent_record rest_record(const fm_morph_model *m, int64_t i, uint8_t phase)
{
    agent_record r = {.target = -1, .id = (int32_t)i, .phase = phase, .detour_best = INFINITY};
    for (int k = 0; k < 3; k++) r.p[k] = m->src_c[k][i];
    return r;
}

fm_status fm_morph_dist_launch(const fm_morph_model *m, fm_morph_state *s, int64_t due, fm_error *err)
{
    const fm_slabs *d = s->slabs;
    int64_t mine = 0;
    for (int64_t i = s->launched; i < due; i++) mine += fm_slabs_owner(d, m->src_c[d->axis][i], 0) == d->rank;
    fm_status st = fm_dist_agree(s->dist, fm_morph_state_reserve(s, s->active_end + mine, err), err);
    for (int64_t i = s->launched; st == FM_OK && i < due; i++) {
        if (fm_slabs_owner(d, m->src_c[d->axis][i], 0) != d->rank) continue;
        const agent_record r = rest_record(m, i, FM_PHASE_FLYING);
        unpack_agent(m, s, &r, s->active_end++);
    }
    return st;
}

static void pack_agent(const fm_morph_state *s, int64_t a, agent_record *r)
{
    memset(r, 0, sizeof *r);
    for (int k = 0; k < 3; k++) r->p[k] = s->p[k][a], r->v[k] = s->v[k][a], r->p2[k] = s->p2[k][a];
    r->t2 = s->t2[a], r->tf = s->tf[a], r->target = s->target[a], r->id = s->id[a];
    memcpy(r->morph, s->morph + FM_MORPH_FLOATS * a, sizeof r->morph);
    r->phase = s->phase[a], r->perm = s->perm[a], r->morph_safe = s->morph_safe[a];
    r->detour_best = s->detour_best[a], r->detour_since = s->detour_since[a], r->detour_on = s->detour_on[a];
}

static void unpack_agent(const fm_morph_model *m, fm_morph_state *s, const agent_record *r, int64_t a)
{
    for (int k = 0; k < 3; k++) s->p[k][a] = r->p[k], s->v[k][a] = r->v[k], s->p2[k][a] = r->p2[k];
    s->t2[a] = r->t2, s->tf[a] = r->tf, s->target[a] = r->target, s->id[a] = r->id;
    memcpy(s->morph + FM_MORPH_FLOATS * a, r->morph, sizeof r->morph);
    s->phase[a] = r->phase, s->perm[a] = r->perm, s->morph_safe[a] = r->morph_safe;
    s->detour_best[a] = r->detour_best, s->detour_since[a] = r->detour_since, s->detour_on[a] = r->detour_on;
    const size_t i = (size_t)r->id;
    for (int j = 0; j < 12; j++) s->rest_rel[j][a] = m->src_rel[12 * i + (size_t)j];
    s->rest_radius[a] = m->src_radius[i];
}

/* Slot `from`'s agent to slot `to`, every per-slot array. */
static void move_slot(fm_morph_state *s, int64_t from, int64_t to)
{
    for (int k = 0; k < 3; k++) s->p[k][to] = s->p[k][from], s->v[k][to] = s->v[k][from], s->p2[k][to] = s->p2[k][from];
    for (int j = 0; j < 12; j++) s->rest_rel[j][to] = s->rest_rel[j][from];
    s->rest_radius[to] = s->rest_radius[from], s->id[to] = s->id[from], s->phase[to] = s->phase[from];
    s->target[to] = s->target[from], s->t2[to] = s->t2[from], s->tf[to] = s->tf[from];
    memcpy(s->morph + FM_MORPH_FLOATS * to, s->morph + FM_MORPH_FLOATS * from, sizeof(float) * FM_MORPH_FLOATS);
    s->perm[to] = s->perm[from], s->morph_safe[to] = s->morph_safe[from];
    s->detour_best[to] = s->detour_best[from], s->detour_since[to] = s->detour_since[from];
    s->detour_on[to] = s->detour_on[from];
}

static int in_flight(uint8_t phase) { return phase == FM_PHASE_FLYING || phase == FM_PHASE_HOMING; }

/* Packs the leaving agents rank by rank (two passes: count, then fill) and fills each gap with the
 * last agent of the range: the cost is the leavers', not the store's (the order changes, which no
 * result depends on; the next re-sort restores the locality). */
static agent_record *pack_leaving(fm_morph_state *s, int64_t *leaving, fm_error *err)
{
    fm_slabs *d = s->slabs;
    const float *x = s->p[d->axis];
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    *leaving = 0;
    for (int64_t a = s->active_begin; a < s->active_end; a++) {
        if (!in_flight(s->phase[a])) continue;
        int r = fm_slabs_owner(d, x[a], d->rank);
        if (r != d->rank) d->count[r]++, (*leaving)++;
    }
    agent_record *out = fm_alloc(sizeof(agent_record) * (size_t)FM_MAX(*leaving, 1));
    if (!out) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld migrating agents", (long long)*leaving), NULL;
    int64_t *at = calloc((size_t)d->ranks, sizeof(int64_t));
    if (!at) return fm_free(out), fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    for (int r = 1; r < d->ranks; r++) at[r] = at[r - 1] + d->count[r - 1];
    for (int64_t a = s->active_begin; a < s->active_end;) {
        int r = in_flight(s->phase[a]) ? fm_slabs_owner(d, x[a], d->rank) : d->rank;
        if (r == d->rank) {
            a++;
            continue;
        }
        pack_agent(s, a, out + at[r]++);
        if (a != --s->active_end) move_slot(s, s->active_end, a); /* slot a is looked at again */
    }
    free(at);
    d->totals.migrated += *leaving;
    return out;
}

/* Agents in flight that left this rank's slab go to their new owners; arrivals in place stay. */
fm_status fm_morph_dist_migrate(const fm_morph_model *m, fm_morph_state *s, fm_error *err)
{
    int64_t leaving = 0, received = 0;
    agent_record *out = pack_leaving(s, &leaving, err);
    void *in;
    fm_status st = fm_slabs_send(s->slabs, s->dist, out ? FM_OK : err->status, out, sizeof(agent_record), &in, &received, err);
    if (st == FM_OK) st = fm_dist_agree(s->dist, fm_morph_state_reserve(s, s->active_end + received, err), err);
    for (int64_t k = 0; st == FM_OK && k < received; k++) unpack_agent(m, s, (const agent_record *)in + k, s->active_end++);
    fm_free(out), fm_free(in);
    return st;
}

/* This step's ghosts: the other ranks' flying agents within the halo of this slab, appended at
 * [active_end, active_end + ghosts) (position and id: what the MDE walk reads). */
fm_status fm_morph_dist_ghosts(fm_morph_state *s, int64_t *ghosts, fm_error *err)
{
    fm_slabs *d = s->slabs;
    const float *x = s->p[d->axis];
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    int64_t sending = 0, received = 0;
    for (int64_t a = s->active_begin; a < s->active_end; a++) /* count, then fill */
        if (s->phase[a] == FM_PHASE_FLYING && fm_slabs_in_halo(d, x[a]))
            for (int r = 0; r < d->ranks; r++) d->count[r] += r != d->rank && fm_slabs_near(d, r, x[a]);
    for (int r = 0; r < d->ranks; r++) sending += d->count[r];
    ghost_record *out = fm_alloc(sizeof(ghost_record) * (size_t)FM_MAX(sending, 1));
    int64_t *at = calloc((size_t)d->ranks, sizeof(int64_t));
    fm_status st = out && at ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld halo agents", (long long)sending);
    if (st == FM_OK) {
        for (int r = 1; r < d->ranks; r++) at[r] = at[r - 1] + d->count[r - 1];
        for (int64_t a = s->active_begin; a < s->active_end; a++) {
            if (s->phase[a] != FM_PHASE_FLYING || !fm_slabs_in_halo(d, x[a])) continue;
            for (int r = 0; r < d->ranks; r++)
                if (r != d->rank && fm_slabs_near(d, r, x[a]))
                    out[at[r]++] = (ghost_record){{s->p[0][a], s->p[1][a], s->p[2][a]}, s->id[a]};
        }
    }
    void *in;
    st = fm_slabs_send(d, s->dist, st, out, sizeof(ghost_record), &in, &received, err);
    if (st == FM_OK) st = fm_dist_agree(s->dist, fm_morph_state_reserve(s, s->active_end + received, err), err);
    *ghosts = 0;
    if (st == FM_OK) {
        const ghost_record *g = in;
        for (int64_t k = 0; k < received; k++) {
            const int64_t a = s->active_end + k;
            for (int c = 0; c < 3; c++) s->p[c][a] = g[k].p[c];
            s->id[a] = g[k].id, s->member[a] = 1;
        }
        *ghosts = received;
        d->totals.ghost_agent_steps += received;
    }
    fm_free(out), fm_free(in), free(at);
    return st;
}

/* Every step: the cuts to the quantiles of the agents in flight, each weighted
 * by its rank's measured cost per agent-step since the last cut (an agent near an obstacle or in a
 * dense part of the flock costs more), all ranks together; so the slabs follow the flock and the
 * cost (slabs.h). */
/* The cuts at the quantiles of the agents in flight, each weighing its rank's `weight`, and of the
 * agents [launched, due) about to launch, from the source (each rank counts a share of them), at
 * the mean weight of an agent in flight: summed over the ranks when `dist` is set. Without memory
 * the cuts stay: still correct, only less balanced. */
static void cut_at_flight(const fm_morph_model *m, fm_morph_state *s, int64_t due, double weight, const fm_dist *dist)
{
    fm_slabs *d = s->slabs;
    enum { WEIGHT, COUNT, FLIGHT, LAUNCH = FLIGHT + FM_SLAB_BINS, ALL = LAUNCH + FM_SLAB_BINS };
    double *h = calloc(ALL, sizeof(double));
    if (!h) return;
    const float *x = s->p[d->axis];
    for (int64_t a = s->active_begin; a < s->active_end; a++)
        if (in_flight(s->phase[a])) h[FLIGHT + fm_slabs_bin(d, x[a])] += weight, h[WEIGHT] += weight, h[COUNT]++;
    const int64_t launching = due - s->launched, ranks = dist ? d->ranks : 1, me = dist ? d->rank : 0;
    for (int64_t i = s->launched + launching * me / ranks; i < s->launched + launching * (me + 1) / ranks; i++)
        h[LAUNCH + fm_slabs_bin(d, m->src_c[d->axis][i])]++;
    fm_dist_sum_f64(dist, h, launching > 0 ? ALL : LAUNCH); /* every rank gets the same histograms: the same cuts */
    const double mean = h[COUNT] > 0 ? h[WEIGHT] / h[COUNT] : 1;
    for (int b = 0; b < FM_SLAB_BINS; b++) h[FLIGHT + b] += mean * h[LAUNCH + b];
    fm_slabs_cut(d, h + FLIGHT, NULL);
    free(h);
}

/* With this step's launches in the histogram: without them, the cuts fall around the few agents in
 * flight when a wave launches (rook at 10^6 agents launched at once: one rank took every agent and
 * held 1.4× the other's memory until they migrated). */
void fm_morph_dist_rebalance(const fm_morph_model *m, fm_morph_state *s, int64_t due)
{
    cut_at_flight(m, s, due, fm_slabs_take_weight(s->slabs), s->dist);
}

void fm_morph_dist_add_busy(fm_morph_state *s, double seconds)
{
    fm_slabs_add_busy(s->slabs, seconds, (double)(s->active_end - s->active_begin));
}

/* The load of this step: agents in flight on the busiest rank, and on all ranks together. */
void fm_morph_dist_record_load(fm_morph_state *s)
{
    int64_t mine = 0;
    for (int64_t a = s->active_begin; a < s->active_end; a++) mine += in_flight(s->phase[a]);
    fm_slabs_record_load(s->slabs, s->dist, mine);
}

/* One agent's tet in a frame, for the gather to rank 0. */
typedef struct frame_record {
    int32_t id;
    float v[12];
    uint8_t phase, pad[3];
} frame_record;

/* The frame on rank 0 in id order: each rank's agents gathered, the waiting ones (in no store)
 * added from the model. Rank 0's own agents are already in place (fm_morph_tet_vertices writes by
 * id) and are not sent; the other ranks' `verts` hold their own agents only. */
fm_status fm_morph_dist_frame(const fm_morph_model *m, fm_morph_state *s, float *verts, uint8_t *phases,
                              fm_error *err)
{
    fm_morph_tet_vertices(m, s, verts);
    const int root = fm_dist_rank(s->dist) == 0;
    const int64_t count = root ? 0 : s->active_end;
    frame_record *mine = fm_alloc(sizeof(frame_record) * (size_t)FM_MAX(count, 1));
    fm_status st = mine ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame of %lld agents", (long long)count);
    st = fm_dist_agree(s->dist, st, err);
    if (st != FM_OK) return fm_free(mine), st;
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < count; a++) {
        frame_record *r = mine + a;
        r->id = s->id[a], r->phase = s->phase[a];
        memcpy(r->v, verts + 12 * (size_t)s->id[a], sizeof r->v);
    }
    void *all = NULL;
    int64_t total = 0;
    st = fm_dist_gather(s->dist, mine, count, sizeof(frame_record), &all, &total, err);
    fm_free(mine);
    s->slabs->totals.bytes_sent += count * (int64_t)sizeof(frame_record);
    if (st != FM_OK || !root) return fm_free(all), st;
    fm_morph_phases(s, phases); /* rank 0's own */
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t k = 0; k < total; k++) { /* distinct ids: no two write one place */
        const frame_record *r = (const frame_record *)all + k;
        memcpy(verts + 12 * (size_t)r->id, r->v, sizeof r->v);
        phases[r->id] = r->phase;
    }
    for (int64_t i = s->launched; i < m->n; i++)
        fm_morph_waiting_tet(m, i, verts + 12 * (size_t)i), phases[i] = FM_PHASE_WAITING;
    fm_free(all);
    return FM_OK;
}

/* Agent id's row (its place in the frame) under the row map: the id itself without one. */
static int64_t row_of(const fm_morph_rows *rows, int64_t id)
{
    return !rows ? id : rows->row ? rows->row[id] : rows->row0 + id;
}

/* Agent id's tet (its own vertex order) in its row's vertex order. */
static void row_tet(const fm_morph_rows *rows, int64_t id, const float tet[12], float out[12])
{
    const uint8_t *perm = fm_even_permutations[rows && rows->perm ? rows->perm[id] : 0];
    for (int v = 0; v < 4; v++) memcpy(out + 3 * v, tet + 3 * perm[v], 3 * sizeof(float));
}

/* Row r of the share (r counted from its first row): its tet (in the row's vertex order), phase
 * and, under a row map, group. */
static void put_row(const fm_morph_rows *rows, int64_t r, const float tet[12], uint8_t phase, float *verts,
                    uint8_t *phases)
{
    memcpy(verts + 12 * (size_t)r, tet, 12 * sizeof(float));
    phases[r] = phase;
    if (rows) rows->groups[r] = rows->group;
}

/* The rank's own agents' tets (own, slot order) go to the ranks whose shares hold their rows: into
 * this rank's share (verts and phases from its first row) in place, to the others in rank order
 * (*recv gets theirs for this rank; count, then fill, as the migration packs). */
static fm_status exchange_share(fm_morph_state *s, const int64_t *begin, const fm_morph_rows *rows, const float *own,
                                float *verts, uint8_t *phases, void **recv, int64_t *received, fm_error *err)
{
    fm_slabs *d = s->slabs;
    const int64_t first = begin[d->rank];
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    for (int64_t a = 0; a < s->active_end; a++) d->count[fm_frame_share_owner(begin, d->ranks, row_of(rows, s->id[a]))]++;
    d->count[d->rank] = 0; /* its own share's are put in place */
    int64_t *at = malloc(sizeof(int64_t) * ((size_t)d->ranks + 1));
    if (at) fm_slabs_offsets(d, at);
    frame_record *out = at ? fm_alloc(sizeof(frame_record) * (size_t)FM_MAX(at[d->ranks], 1)) : NULL;
    fm_status st = out ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame's exchange");
    for (int64_t a = 0; st == FM_OK && a < s->active_end; a++) {
        const int64_t id = s->id[a], row = row_of(rows, id);
        const int r = fm_frame_share_owner(begin, d->ranks, row);
        float tet[12];
        row_tet(rows, id, own + 12 * (size_t)a, tet);
        if (r == d->rank) {
            put_row(rows, row - first, tet, s->phase[a], verts, phases);
            continue;
        }
        frame_record *f = out + at[r]++;
        f->id = (int32_t)row, f->phase = s->phase[a];
        memset(f->pad, 0, sizeof f->pad);
        memcpy(f->v, tet, sizeof f->v);
    }
    st = fm_slabs_send(d, s->dist, st, out, sizeof(frame_record), recv, received, err);
    free(at), fm_free(out);
    return st;
}

/* The agents still waiting at the source whose rows lie in this rank's share (first … end − 1):
 * their tets at rest, from the model. */
static void put_waiting(const fm_morph_model *m, const fm_morph_state *s, const fm_morph_rows *rows, int64_t first,
                        int64_t end, float *verts, uint8_t *phases)
{
    int64_t i = s->launched, stop = m->n; /* under a row map of a group's rows in any order: every one */
    if (!rows || !rows->row) {
        const int64_t row0 = rows ? rows->row0 : 0; /* rows row0 + id */
        i = FM_MAX(i, first - row0), stop = FM_MIN(stop, end - row0);
    }
    for (; i < stop; i++) {
        const int64_t row = row_of(rows, i);
        if (row < first || row >= end) continue;
        float rest[12], tet[12];
        fm_morph_waiting_tet(m, i, rest);
        row_tet(rows, i, rest, tet);
        put_row(rows, row - first, tet, FM_PHASE_WAITING, verts, phases);
    }
}

/* Every agent whose row lies in this rank's share of the frame (rows begin[rank] … begin[rank + 1]
 * − 1) in verts and phases from its first row: its own from the store, the other ranks' sent here,
 * the waiting ones from the model. */
fm_status fm_morph_dist_frame_share(const fm_morph_model *m, fm_morph_state *s, const int64_t *begin,
                                    const fm_morph_rows *rows, float *own, float *verts, uint8_t *phases, fm_error *err)
{
    const int me = fm_dist_rank(s->dist);
    const int64_t first = begin[me];
    fm_morph_tet_vertices_by_slot(m, s, own);
    void *recv = NULL;
    int64_t received = 0;
    fm_status st = exchange_share(s, begin, rows, own, verts, phases, &recv, &received, err);
    if (st != FM_OK) return fm_free(recv), st;
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t k = 0; k < received; k++) { /* distinct rows: no two write one place */
        const frame_record *r = (const frame_record *)recv + k;
        put_row(rows, r->id - first, r->v, r->phase, verts, phases);
    }
    fm_free(recv);
    put_waiting(m, s, rows, first, begin[me + 1], verts, phases);
    return FM_OK;
}

/* The slots this rank's agents take in the one-process store of a checkpoint: launched agents
 * [0, launched) in rank order, rank r's after the lower ranks' (*before of them). */
static fm_status slots_before(const fm_morph_state *s, fm_status st, int64_t *before, fm_error *err)
{
    const int32_t mine = (int32_t)s->active_end;
    int32_t *counts = NULL;
    int64_t ranks = 0, total = 0;
    *before = 0;
    if ((st = fm_dist_agree(s->dist, st, err)) == FM_OK) st = fm_dist_allgather_i32(s->dist, &mine, 1, &counts, &ranks, err);
    for (int64_t r = 0; st == FM_OK && r < ranks; r++) {
        if (r < fm_dist_rank(s->dist)) *before += counts[r];
        total += counts[r];
    }
    fm_free(counts);
    if (st == FM_OK && total != s->launched)
        st = fm_fail(err, FM_ERR_INTERNAL, "checkpoint: the ranks hold %lld agents, %lld were launched", (long long)total,
                     (long long)s->launched);
    return fm_dist_agree(s->dist, st, err);
}

/* On P ranks: every rank writes its part of one process's checkpoint (morph_checkpoint.c) at once:
 * its agents at the slots slots_before gives, and its share of the waiting agents [launched, n),
 * in id order, built as rest records in the slots after its own (free at a frame boundary: the
 * halo is rebuilt every step). Rank 0 writes the counters, with the active range one process has;
 * any P, or one process, resumes the file. */
fm_status fm_morph_dist_checkpoint_save(const char *path, const fm_morph_model *m, fm_morph_state *s,
                                        const fm_morph_run_stats *stats, int64_t frames, fm_error *err)
{
    const int64_t mine = s->active_end, begin = s->active_begin;
    const int me = fm_dist_rank(s->dist), ranks = fm_dist_size(s->dist);
    const int64_t waiting = s->n - s->launched;
    const int64_t from = s->launched + waiting * me / ranks, to = s->launched + waiting * (me + 1) / ranks;
    int64_t before = 0;
    fm_status st = slots_before(s, fm_morph_state_reserve(s, mine + to - from, err), &before, err);
    if (st != FM_OK) return st;
    for (int64_t i = from; i < to; i++) {
        const agent_record r = rest_record(m, i, FM_PHASE_WAITING);
        unpack_agent(m, s, &r, mine + (i - from));
    }
    const fm_ckpt_part parts[2] = {{before, mine, 0}, {from, to - from, mine}};
    s->active_begin = 0, s->active_end = s->launched; /* one process's, for rank 0's counters */
    st = fm_morph_checkpoint_write(path, m, s, stats, frames, parts, 2, err);
    s->active_begin = begin, s->active_end = mine;
    return st;
}

/* After every rank loaded its share of a checkpoint's slots, [first, first + count) of the file, into
 * slots [0, count) (morph_checkpoint.c): the cuts at the quantiles of the agents in flight over every
 * rank's share, and each launched agent to the rank whose slab holds it (a waiting one is no rank's:
 * it launches from the model). The records come in rank order, each rank's in slot order, so the
 * receiver keeps the file's order, the agents that arrived before the last re-sort first (the file's
 * [0, active_begin)). The hand-over is no step's traffic: the totals stay. */
fm_status fm_morph_dist_adopt(const fm_morph_model *m, fm_morph_state *s, int64_t first, int64_t count, fm_error *err)
{
    fm_slabs *d = s->slabs;
    const fm_dist_totals totals = d->totals;
    const int64_t mine = FM_MAX(0, FM_MIN(s->launched - first, count));
    const int64_t early = FM_MAX(0, FM_MIN(s->active_begin - first, mine));
    s->active_begin = 0, s->active_end = mine;
    cut_at_flight(NULL, s, s->launched, 1, s->dist); /* weight 1: no step was timed yet */
    const float *x = s->p[d->axis];
    memset(d->count, 0, sizeof(int64_t) * (size_t)d->ranks);
    for (int64_t a = 0; a < mine; a++) d->count[fm_slabs_owner(d, x[a], 0)]++;
    int64_t *at = malloc(sizeof(int64_t) * ((size_t)d->ranks + 1));
    if (at) fm_slabs_offsets(d, at);
    agent_record *out = at ? fm_alloc(sizeof(agent_record) * (size_t)FM_MAX(mine, 1)) : NULL;
    fm_status st = out ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld resumed agents", (long long)mine);
    for (int64_t a = 0; st == FM_OK && a < mine; a++) {
        agent_record *r = out + at[fm_slabs_owner(d, x[a], 0)]++;
        pack_agent(s, a, r);
        r->settled = a < early;
    }
    void *in = NULL;
    int64_t received = 0;
    st = fm_slabs_send(d, s->dist, st, out, sizeof(agent_record), &in, &received, err);
    if (st == FM_OK) st = fm_dist_agree(s->dist, fm_morph_state_reserve(s, received, err), err);
    int64_t settled = 0, a = 0;
    for (int64_t k = 0; st == FM_OK && k < received; k++) settled += ((const agent_record *)in)[k].settled;
    for (int64_t k = 0; st == FM_OK && k < received; k++) { /* the settled first, each kind in its order */
        const agent_record *r = (const agent_record *)in + k;
        unpack_agent(m, s, r, r->settled ? a++ : settled + k - a);
    }
    s->active_begin = settled, s->active_end = st == FM_OK ? received : 0;
    fm_morph_state_fit(s); /* the share was loaded: the rank keeps room for its slab's agents */
    d->totals = totals;
    free(at), fm_free(out), fm_free(in);
    return st;
}
