/* The look of the flock in numbers, per frame (docs/stats.md "Flock measures", docs/shape-flock.md
 * "The look in numbers"): tools/flock-look.py's three figures, measured while the run goes on.
 *
 * A fixed sample of FM_LOOK_AGENTS agents (ids j n / S, j = 0 .. S - 1, S = min(n, FM_LOOK_AGENTS))
 * stands for the flock. Every frame its positions go into a ring (fm_flock_look, in the store, so a
 * checkpoint keeps it); every FM_LOOK_EVERY-th frame f (and at f - L, L = round(frame rate)) its
 * agents in flight get their K = 6 nearest neighbours among all the agents in flight, ids by
 * (distance, id); every FM_LOOK_EVERY-th frame f then gives:
 *   persistence  the share of each sample agent's 6 nearest at f - L still among its 6 nearest at f
 *                (flock-look's persistence at mid-flight frame f - L);
 *   coherence    the mean cosine between a sample agent's velocity fluctuation (its velocity minus
 *                the mean of all agents') and its 6 nearest neighbours' (flock-look's at frame f,
 *                with the engine's velocities instead of central differences);
 *   smoothness   each sample agent's acceleration autocorrelation at a lag of 4 frames over the
 *                2 W frames lo .. lo + 2 W - 1, lo = f - 2 W - 4, W = floor(frame rate), its mean
 *                acceleration over lo .. f - 1 taken out (flock-look's at mid-flight frame
 *                f - W - 4), averaged over the agents whose acceleration is not constant.
 * Other frames, and frame rates above FM_LOOK_MAX_SECOND, give NaN.
 *
 * The neighbours come from the measures' grid over the agents in flight (cell = the largest
 * perception radius, or wider where mean_nn needed it), 2 cells each way; a neighbour list is complete
 * once its 6th is within 2 cells, else it is asked again on a grid of 4 times the cell (as mean_nn's). On P ranks each rank answers every query from
 * its own agents and the lists are merged by (distance, id), and the sample's positions and
 * velocities are the maximum over the ranks of what each holds (its own, -inf elsewhere): every
 * figure is one process's, bit for bit. */
#include "flock.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A query looks REACH cells each way (5^3 cells): the grid's cell is at least the largest
 * perception radius, and 6 neighbours are nearly always within 2 of it, so the measures' own grid
 * answers without a build of its own; the few that are not ask FAR cells each way on it, and only
 * then a wider grid is built. */
enum { REACH = 2, FAR = 5 };

/* A neighbour candidate of a query: squared distance, agent id (-1: none), its velocity. */
typedef struct look_cand {
    double d2;
    int32_t id;
    float v[3];
} look_cand;

/* The sample this frame: positions, velocities and whether in flight, by sample index. */
typedef struct look_sample {
    int64_t count;
    double p[FM_LOOK_AGENTS][3], v[FM_LOOK_AGENTS][3];
    double flying[FM_LOOK_AGENTS];
} look_sample;

static int64_t sample_id(int64_t n, int64_t count, int64_t j) { return j * n / count; }

static int before(double d2, int32_t id, const look_cand *c) { return d2 < c->d2 || (d2 == c->d2 && id < c->id); }

/* c[0 .. K) sorted by (d2, id): x in its place if it is among the K smallest. */
static void keep_nearest(look_cand *c, look_cand x)
{
    if (!before(x.d2, x.id, &c[FM_LOOK_K - 1])) return;
    int i = FM_LOOK_K - 1;
    for (; i > 0 && before(x.d2, x.id, &c[i - 1]); i--) c[i] = c[i - 1];
    c[i] = x;
}

static void clear(look_cand *c)
{
    for (int i = 0; i < FM_LOOK_K; i++) c[i] = (look_cand){INFINITY, -1, {0, 0, 0}};
}

/* The sample's positions, velocities and flight from the agents here (s: all of them, or on P ranks
 * this rank's own), the maximum over the ranks. */
static void read_sample(const fm_flock_state *s, const fm_dist *d, look_sample *x)
{
    const int64_t n = s->n, count = n < FM_LOOK_AGENTS ? n : FM_LOOK_AGENTS;
    x->count = count;
    for (int64_t j = 0; j < count; j++) {
        const int64_t a = fm_flock_slot_of(s, sample_id(n, count, j));
        const int here = a >= 0 && s->phase[a] != FM_FLOCK_ELSEWHERE;
        for (int k = 0; k < 3; k++) x->p[j][k] = here ? s->p[k][a] : -INFINITY, x->v[j][k] = here ? s->v[k][a] : -INFINITY;
        x->flying[j] = here ? s->phase[a] != FM_PHASE_ARRIVED : -INFINITY;
    }
    fm_dist_max_f64(d, &x->p[0][0], (int)(3 * count));
    fm_dist_max_f64(d, &x->v[0][0], (int)(3 * count));
    fm_dist_max_f64(d, x->flying, (int)count);
}

static int slot_order(const void *a, const void *b)
{
    const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* The slots of the (2 reach + 1)^3 cells around q, each once (hashing may map cells to one slot),
 * in increasing order; returns their count. */
static int reach_slots(const fm_grid *g, const double q[3], int reach, uint32_t *slots)
{
    const int32_t cx = fm_grid_coord(fm_grid_scaled(g, (float)q[0])), cy = fm_grid_coord(fm_grid_scaled(g, (float)q[1])),
                  cz = fm_grid_coord(fm_grid_scaled(g, (float)q[2]));
    int count = 0;
    for (int dz = -reach; dz <= reach; dz++)
        for (int dy = -reach; dy <= reach; dy++)
            for (int dx = -reach; dx <= reach; dx++) slots[count++] = fm_grid_slot(g, cx + dx, cy + dy, cz + dz);
    qsort(slots, (size_t)count, sizeof *slots, slot_order);
    int unique = 0;
    for (int i = 0; i < count; i++)
        if (unique == 0 || slots[i] != slots[unique - 1]) slots[unique++] = slots[i];
    return unique;
}

/* This rank's candidates within `cells` cells of the grid for the pending queries: every agent
 * within cells * cell of the query lies in those cells (grid.h, fm_grid_scaled). */
static void local_candidates(const fm_flock_state *s, const look_sample *x, const uint8_t *pending, int cells,
                             look_cand *out)
{
    const fm_grid *g = &s->grid;
    const double reach = (double)cells * g->cell, reach2 = reach * reach;
    const int64_t n = s->n;
#pragma omp parallel for num_threads(s->threads) schedule(dynamic, 16)
    for (int64_t j = 0; j < x->count; j++) {
        look_cand *c = out + FM_LOOK_K * j;
        clear(c);
        if (!pending[j]) continue;
        const int32_t self = (int32_t)sample_id(n, x->count, j);
        uint32_t slots[(2 * FAR + 1) * (2 * FAR + 1) * (2 * FAR + 1)];
        const int count = reach_slots(g, x->p[j], cells, slots);
        for (int r = 0; r < count; r++)
            for (int32_t e = g->start[slots[r]]; e < g->start[slots[r] + 1]; e++) {
                const fm_grid_quad *q = &g->quad[e >> 2];
                const int lane = e & 3;
                const int64_t a = q->i[lane];
                const int32_t id = (int32_t)fm_flock_id(s, a);
                const double dx = q->x[lane] - x->p[j][0], dy = q->y[lane] - x->p[j][1], dz = q->z[lane] - x->p[j][2];
                const double d2 = dx * dx + dy * dy + dz * dz;
                if (id == self || d2 > reach2) continue;
                keep_nearest(c, (look_cand){d2, id, {s->v[0][a], s->v[1][a], s->v[2][a]}});
            }
    }
}

/* The 6 nearest agents in flight of every sample agent in flight, ids (-1: fewer than 6 found) into
 * ids and their velocities into nv; s->member lists this rank's agents in flight, and with
 * grid_fresh s->grid is a grid of them built this frame (mean_nn's last), which is asked first.
 * Returns the status of the ranks' exchange. */
static fm_status neighbours(const fm_flock_model *m, fm_flock_state *s, const fm_dist *d, const look_sample *x,
                            int32_t (*ids)[FM_LOOK_K], float (*nv)[FM_LOOK_K][3], int grid_fresh, fm_error *err)
{
    const int64_t count = x->count;
    look_cand *mine = malloc(sizeof *mine * FM_LOOK_K * (size_t)count), *best = malloc(sizeof *best * FM_LOOK_K * (size_t)count);
    uint8_t pending[FM_LOOK_AGENTS];
    fm_status st = fm_dist_agree(d, mine && best ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for the look"), err);
    int64_t left = 0;
    for (int64_t j = 0; j < count; j++) pending[j] = x->flying[j] > 0, left += pending[j];
    for (int64_t j = 0; st == FM_OK && j < count; j++) clear(best + FM_LOOK_K * j);
    float cell = grid_fresh ? s->grid.cell : fm_flock_cell(m);
    /* pass 0: REACH cells on the fresh grid; 1: FAR cells on it; then wider grids */
    for (int pass = 0; st == FM_OK && left > 0 && pass <= 16; pass++) {
        if (pass >= 2 || !grid_fresh) {
            if (pass >= 2) cell *= 4;
            fm_grid_build_moving(&s->grid, (const float *const *)s->p, (const float *const *)s->v, s->member, s->slots,
                                 cell, s->threads);
            s->grid_current = 0, grid_fresh = 1; /* not the grid the next step builds */
        }
        local_candidates(s, x, pending, pass == 1 ? FAR : REACH, mine);
        void *all = NULL;
        int64_t total = 0;
        if (d) st = fm_dist_allgather(d, mine, FM_LOOK_K * count, sizeof *mine, &all, &total, err);
        const look_cand *got = d ? all : mine;
        const int64_t ranks = d ? total / (FM_LOOK_K * count) : 1;
        left = 0;
        for (int64_t j = 0; st == FM_OK && j < count; j++) {
            if (!pending[j]) continue;
            look_cand *c = best + FM_LOOK_K * j;
            clear(c);
            for (int64_t r = 0; r < ranks; r++) /* rank order; the merge's result does not depend on it */
                for (int i = 0; i < FM_LOOK_K; i++) {
                    const look_cand *y = got + (r * count + j) * FM_LOOK_K + i;
                    if (y->id >= 0) keep_nearest(c, *y);
                }
            pending[j] = c[FM_LOOK_K - 1].id < 0; /* fewer than 6 within reach: ask a wider grid */
            left += pending[j];
        }
        fm_free(all);
    }
    for (int64_t j = 0; st == FM_OK && j < count; j++) {
        const look_cand *c = best + FM_LOOK_K * j;
        const int whole = x->flying[j] > 0 && c[FM_LOOK_K - 1].id >= 0;
        for (int i = 0; i < FM_LOOK_K; i++) {
            ids[j][i] = whole ? c[i].id : -1;
            for (int k = 0; k < 3; k++) nv[j][i][k] = c[i].v[k];
        }
    }
    free(mine), free(best);
    return st;
}

/* Persistence: the neighbour lists of frames `then` and `now` (ring entries), sample agents with both. */
static double persistence(const int32_t (*then)[FM_LOOK_K], const int32_t (*now)[FM_LOOK_K], int64_t count)
{
    double sum = 0;
    int64_t agents = 0;
    for (int64_t j = 0; j < count; j++) {
        if (then[j][0] < 0 || now[j][0] < 0) continue;
        int same = 0;
        for (int a = 0; a < FM_LOOK_K; a++)
            for (int b = 0; b < FM_LOOK_K; b++) same += then[j][a] == now[j][b];
        sum += (double)same / FM_LOOK_K, agents++;
    }
    return agents > 0 ? sum / (double)agents : NAN;
}

static void unit_fluctuation(const double v[3], const double mean[3], double u[3])
{
    double dv[3] = {v[0] - mean[0], v[1] - mean[1], v[2] - mean[2]};
    const double len = fmax(sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]), 1e-12);
    for (int k = 0; k < 3; k++) u[k] = dv[k] / len;
}

static double coherence(const look_sample *x, const int32_t (*ids)[FM_LOOK_K], const float (*nv)[FM_LOOK_K][3],
                        const double mean[3])
{
    double sum = 0;
    int64_t pairs = 0;
    for (int64_t j = 0; j < x->count; j++) {
        if (ids[j][0] < 0) continue;
        double u[3], w[3];
        unit_fluctuation(x->v[j], mean, u);
        for (int i = 0; i < FM_LOOK_K; i++) {
            const double v[3] = {nv[j][i][0], nv[j][i][1], nv[j][i][2]};
            unit_fluctuation(v, mean, w);
            sum += u[0] * w[0] + u[1] * w[1] + u[2] * w[2], pairs++;
        }
    }
    return pairs > 0 ? sum / (double)pairs : NAN;
}

/* Smoothness at frame f from the ring (frames f - 2W - LAG - 1 .. f all in it). */
static double smoothness(const fm_flock_look *look, int64_t f, int64_t w, double fps, int64_t count)
{
    const int64_t lo = f - 2 * w - FM_LOOK_LAG, frames = 2 * w + FM_LOOK_LAG; /* accelerations at lo .. f - 1 */
    double sum = 0;
    int64_t agents = 0;
    for (int64_t j = 0; j < count; j++) {
        double a[2 * FM_LOOK_MAX_SECOND + FM_LOOK_LAG][3], mean[3] = {0, 0, 0};
        for (int64_t t = 0; t < frames; t++) {
            const float *p0 = look->p[(lo + t - 1) % FM_LOOK_HISTORY][j], *p1 = look->p[(lo + t) % FM_LOOK_HISTORY][j],
                        *p2 = look->p[(lo + t + 1) % FM_LOOK_HISTORY][j];
            for (int k = 0; k < 3; k++) a[t][k] = ((double)p2[k] - 2 * (double)p1[k] + p0[k]) * fps * fps;
        }
        for (int64_t t = 0; t < frames; t++)
            for (int k = 0; k < 3; k++) mean[k] += a[t][k];
        for (int k = 0; k < 3; k++) mean[k] /= (double)frames;
        double num = 0, s0 = 0, s1 = 0;
        for (int64_t t = 0; t < 2 * w; t++)
            for (int k = 0; k < 3; k++) {
                const double b0 = a[t][k] - mean[k], b1 = a[t + FM_LOOK_LAG][k] - mean[k];
                num += b0 * b1, s0 += b0 * b0, s1 += b1 * b1;
            }
        const double den = sqrt(s0 * s1);
        if (den > 0) sum += num / den, agents++;
    }
    return agents > 0 ? sum / (double)agents : NAN;
}

fm_status fm_flock_look_frame(const fm_flock_model *m, fm_flock_state *s, const fm_dist *d, fm_flock_look *look,
                              int64_t f, const double mean_v[3], int grid_fresh, double out[FM_FLOCK_MEASURES],
                              fm_error *err)
{
    out[FM_FLOCK_PERSISTENCE] = out[FM_FLOCK_COHERENCE] = out[FM_FLOCK_SMOOTHNESS] = NAN;
    const double fps = m->def.frame_rate;
    const int64_t lag = (int64_t)llround(fps), w = (int64_t)fps; /* flock-look.py's round(fps) and int(fps) */
    if (f < 1 || lag > FM_LOOK_MAX_SECOND || w < 1) return FM_OK;
    look_sample *x = malloc(sizeof *x);
    int32_t (*ids)[FM_LOOK_K] = malloc(sizeof *ids * FM_LOOK_AGENTS);
    float (*nv)[FM_LOOK_K][3] = malloc(sizeof *nv * FM_LOOK_AGENTS);
    fm_status st = fm_dist_agree(d, x && ids && nv ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for the look"), err);
    if (st == FM_OK) read_sample(s, d, x);
    const int64_t count = st == FM_OK ? x->count : 0, at = f % FM_LOOK_HISTORY;
    for (int64_t j = 0; j < count; j++)
        for (int k = 0; k < 3; k++) look->p[at][j][k] = (float)x->p[j][k];
    if (st == FM_OK) look->p_frame[at] = f + 1;
    const int measured = f % FM_LOOK_EVERY == 0, ahead = (f + lag) % FM_LOOK_EVERY == 0;
    if (st == FM_OK && (measured || ahead)) {
        if (d) fm_flock_dist_own_in_flight(s);
        st = neighbours(m, s, d, x, ids, nv, grid_fresh, err);
        const int64_t slot = f % (FM_LOOK_MAX_SECOND + 1);
        if (st == FM_OK) memcpy(look->nb[slot], ids, sizeof *ids * (size_t)count), look->nb_frame[slot] = f + 1;
    }
    if (st == FM_OK && measured) {
        out[FM_FLOCK_COHERENCE] = mean_v ? coherence(x, (const int32_t (*)[FM_LOOK_K])ids, (const float (*)[FM_LOOK_K][3])nv, mean_v)
                                         : NAN;
        const int64_t then = (f - lag) % (FM_LOOK_MAX_SECOND + 1);
        if (f >= lag && look->nb_frame[then] == f - lag + 1)
            out[FM_FLOCK_PERSISTENCE] = persistence((const int32_t (*)[FM_LOOK_K])look->nb[then],
                                                    (const int32_t (*)[FM_LOOK_K])ids, count);
        int whole = f >= 2 * w + FM_LOOK_LAG + 1;
        for (int64_t t = f - 2 * w - FM_LOOK_LAG - 1; whole && t <= f; t++) whole = look->p_frame[t % FM_LOOK_HISTORY] == t + 1;
        if (whole) out[FM_FLOCK_SMOOTHNESS] = smoothness(look, f, w, fps, count);
    }
    free(x), free(ids), free(nv);
    return st;
}
