/* The flock measures of a frame (include/flockmorph/flock.h, docs/stats.md "Flock measures"):
 * polarisation, nearest-neighbour distance, distance from the eq-12 path, speed, distance to the
 * destination, the fraction in flight, and the look (flock_look.c). Sums are taken per FM_BLOCK
 * block of agents on the threads and combined in block order, so the figures do not depend on the
 * thread count. */
#include "flock.h"

#include <math.h>
#include <stdlib.h>

const char *const fm_flock_measure_names[FM_FLOCK_MEASURES] = {"polarisation", "nn_distance", "leader_distance",
                                                               "speed", "destination_distance", "in_flight",
                                                               "persistence", "coherence", "smoothness"};

/* Nearest-neighbour queries a frame: the mean of 1,024 has a standard error near 1 % for the
 * nearest-neighbour distances of a flock (their CV is about 0.3). */
enum { NN_QUERIES = 1024 };

typedef struct measure_block {
    int64_t in_flight, moving;
    double unit[3], speed, leader, destination;
    double velocity[3]; /* of all agents (the look's mean velocity) */
} measure_block;

static double distance3(const float *const a[3], const float *const b[3], int64_t i)
{
    double d2 = 0;
    for (int k = 0; k < 3; k++) d2 += ((double)a[k][i] - b[k][i]) * ((double)a[k][i] - b[k][i]);
    return sqrt(d2);
}

/* Agent a's share of its block's sums. */
static void measure_agent(const fm_flock_state *s, int64_t a, measure_block *b)
{
    const float *const *p = (const float *const *)s->p;
    b->destination += distance3(p, (const float *const *)s->dest, a);
    for (int k = 0; k < 3; k++) b->velocity[k] += s->v[k][a];
    if (!s->member[a]) return;
    const double v[3] = {s->v[0][a], s->v[1][a], s->v[2][a]}, speed = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    b->speed += speed;
    if (speed > 0)
        for (int k = 0; k < 3; k++) b->unit[k] += v[k] / speed;
    b->moving += speed > 0;
    b->leader += distance3(p, (const float *const *)s->leader, a);
}

/* A nearest-neighbour query: the agent and its position (the ranks exchange them as 4 words). */
typedef struct nn_query {
    int32_t id;
    float x[3];
} nn_query;

/* The mean distance from each queried agent to its nearest neighbour in flight (s->member). The
 * first grid is the step's own (its cell, the agents in flight), so the next step keeps it. The
 * grid finds neighbours within its cell; agents with none ask again on a grid of four times the
 * cell, until all have one (at most 16 times: 4^16 cells reach past any scene a float holds), so an
 * isolated agent counts with its true distance. Summed in query order. On P ranks (d) each rank's
 * s->member holds its own agents in flight, each rank answers every query from them, and the least
 * squared distance over the ranks is the one process's: the same grid query over all the agents. */
static double mean_nn(const fm_flock_model *m, fm_flock_state *s, const fm_dist *d, const nn_query *query,
                      int64_t count, double *nn, double *best, int64_t *self)
{
    float cell = fm_flock_cell(m);
    int64_t pending = count;
    for (int64_t q = 0; q < count; q++) nn[q] = NAN, self[q] = fm_flock_slot_of(s, query[q].id); /* −1: not here */
    int passes = 0;
    for (; pending > 0 && passes <= 16; passes++, cell *= 4) {
        fm_grid_build_moving(&s->grid, (const float *const *)s->p, (const float *const *)s->v, s->member, s->slots, cell,
                             s->threads);
#pragma omp parallel for num_threads(s->threads) schedule(static)
        for (int64_t q = 0; q < count; q++) {
            double d2;
            best[q] = -INFINITY; /* negated: the ranks take the largest */
            if (isnan(nn[q]))
                best[q] = fm_grid_nearest(&s->grid, query[q].x, NULL, self[q], -1, &d2) >= 0 ? -d2 : -INFINITY;
        }
        fm_dist_max_f64(d, best, (int)count);
        pending = 0;
        for (int64_t q = 0; q < count; q++)
            if (isnan(nn[q]) && best[q] > -INFINITY) nn[q] = sqrt(-best[q]);
            else pending += isnan(nn[q]);
    }
    /* the first grid is the one the next step builds (its cell, the agents in flight): it keeps it */
    s->grid_current = !d && passes == 1;
    double sum = 0;
    int64_t found = 0;
    for (int64_t q = 0; q < count; q++)
        if (!isnan(nn[q])) sum += nn[q], found++;
    return found > 0 ? sum / (double)found : NAN;
}

/* out's measures of the blocks, and the mean velocity of all agents into mean_v. */
static void combine(const measure_block *blocks, int64_t count, int64_t n, double out[FM_FLOCK_MEASURES],
                    double mean_v[3])
{
    measure_block t = {0};
    for (int64_t i = 0; i < count; i++) { /* block order */
        const measure_block *b = &blocks[i];
        t.in_flight += b->in_flight, t.moving += b->moving;
        for (int k = 0; k < 3; k++) t.unit[k] += b->unit[k], t.velocity[k] += b->velocity[k];
        t.speed += b->speed, t.leader += b->leader, t.destination += b->destination;
    }
    const double flying = t.in_flight > 0 ? (double)t.in_flight : NAN;
    const double u = sqrt(t.unit[0] * t.unit[0] + t.unit[1] * t.unit[1] + t.unit[2] * t.unit[2]);
    out[FM_FLOCK_POLARISATION] = t.moving > 0 ? u / (double)t.moving : NAN;
    out[FM_FLOCK_LEADER_DISTANCE] = t.leader / flying;
    out[FM_FLOCK_SPEED] = t.speed / flying;
    out[FM_FLOCK_DESTINATION_DISTANCE] = n > 0 ? t.destination / (double)n : NAN;
    out[FM_FLOCK_IN_FLIGHT] = n > 0 ? (double)t.in_flight / (double)n : NAN;
    for (int k = 0; k < 3; k++) mean_v[k] = n > 0 ? t.velocity[k] / (double)n : NAN;
}

/* Blocks [b0, b1) of the agents in id order (a re-sorted store through fm_flock_slot_in_id_order):
 * s->member of their agents (in flight) and their in-flight counts. */
static void mark_blocks(fm_flock_state *s, int64_t b0, int64_t b1, measure_block *b)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t i = b0; i < b1; i++)
        for (int64_t j = i * FM_BLOCK; j < FM_MIN((i + 1) * FM_BLOCK, s->slots); j++) {
            const int64_t a = fm_flock_slot_in_id_order(s, j);
            s->member[a] = s->phase[a] != FM_PHASE_ARRIVED;
            b[i - b0].in_flight += s->member[a];
        }
}

/* Blocks [b0, b1) in id order, with `before` agents in flight ahead of them: each block's sums, and
 * every stride-th agent in flight, counted in id order from the first, asks for its nearest
 * neighbour: query[k − first_query] for its number k. */
static fm_status sum_blocks(const fm_flock_state *s, int64_t b0, int64_t b1, int64_t before, int64_t stride,
                            measure_block *b, nn_query *query, int64_t first_query)
{
    int64_t *first = malloc(sizeof(int64_t) * (size_t)FM_MAX(b1 - b0, 1));
    if (!first) return FM_ERR_MEMORY;
    for (int64_t i = b0; i < b1; i++) first[i - b0] = before, before += b[i - b0].in_flight;
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t i = b0; i < b1; i++) {
        int64_t rank = first[i - b0];
        for (int64_t j = i * FM_BLOCK; j < FM_MIN((i + 1) * FM_BLOCK, s->slots); j++) {
            const int64_t a = fm_flock_slot_in_id_order(s, j);
            measure_agent(s, a, &b[i - b0]);
            if (s->member[a] && rank % stride == 0)
                query[rank / stride - first_query] = (nn_query){(int32_t)fm_flock_id(s, a), {s->p[0][a], s->p[1][a], s->p[2][a]}};
            rank += s->member[a];
        }
    }
    free(first);
    return FM_OK;
}

void fm_flock_measure_frame(const fm_flock_model *m, fm_flock_state *s, double out[FM_FLOCK_MEASURES])
{
    fm_flock_measure_frame_look(m, s, &s->look, s->step / m->steps_per_frame, out);
}

void fm_flock_measure_frame_look(const fm_flock_model *m, fm_flock_state *s, fm_flock_look *look, int64_t frame,
                                 double out[FM_FLOCK_MEASURES])
{
    double mean_v[3] = {NAN, NAN, NAN};
    const int64_t n = s->n, blocks = (s->slots + FM_BLOCK - 1) / FM_BLOCK;
    measure_block *b = calloc((size_t)(blocks > 0 ? blocks : 1), sizeof *b);
    nn_query *query = malloc(sizeof(nn_query) * NN_QUERIES);
    double *nn = malloc(sizeof(double) * 2 * NN_QUERIES);
    int64_t *self = malloc(sizeof(int64_t) * NN_QUERIES);
    for (int i = 0; i < FM_FLOCK_MEASURES; i++) out[i] = NAN;
    if (b && query && nn && self) {
        mark_blocks(s, 0, blocks, b);
        int64_t total = 0;
        for (int64_t i = 0; i < blocks; i++) total += b[i].in_flight;
        const int64_t stride = total > NN_QUERIES ? (total + NN_QUERIES - 1) / NN_QUERIES : 1;
        if (sum_blocks(s, 0, blocks, 0, stride, b, query, 0) == FM_OK) {
            combine(b, blocks, n, out, mean_v);
            if (total >= 2)
                out[FM_FLOCK_NN_DISTANCE] = mean_nn(m, s, NULL, query, (total + stride - 1) / stride, nn, nn + NN_QUERIES, self);
            fm_flock_look_frame(m, s, NULL, look, frame, mean_v, total >= 2, out, NULL); /* s->member: in flight */
        }
    }
    free(b), free(query), free(nn), free(self);
}

/* The agents in flight on every rank's share, in rank order (so in id order), summed on all. */
static int64_t in_flight_before(const fm_dist *d, int64_t mine, int64_t *total)
{
    const int ranks = fm_dist_size(d), me = fm_dist_rank(d);
    int64_t *each = calloc((size_t)ranks, sizeof *each), before = 0;
    if (!each) return *total = -1, 0;
    each[me] = mine;
    fm_dist_sum_i64(d, each, ranks);
    *total = 0;
    for (int r = 0; r < ranks; r++) before += r < me ? each[r] : 0, *total += each[r];
    free(each);
    return before;
}

fm_status fm_flock_measure_frame_shared(const fm_flock_model *m, fm_flock_state *s, fm_flock_state *view,
                                        int64_t frame, double out[FM_FLOCK_MEASURES], fm_error *err)
{
    const fm_dist *d = s->dist;
    const int64_t blocks = (view->slots + FM_BLOCK - 1) / FM_BLOCK; /* the view starts on a block */
    measure_block *b = calloc((size_t)FM_MAX(blocks, 1), sizeof *b);
    nn_query *mine = malloc(sizeof(nn_query) * NN_QUERIES);
    double *nn = malloc(sizeof(double) * 2 * NN_QUERIES);
    int64_t *self = malloc(sizeof(int64_t) * NN_QUERIES);
    fm_status st = b && mine && nn && self ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for the flock measures");
    if ((st = fm_dist_agree(d, st, err)) != FM_OK) return free(b), free(mine), free(nn), free(self), st;
    mark_blocks(view, 0, blocks, b);
    int64_t flying = 0, total;
    for (int64_t i = 0; i < blocks; i++) flying += b[i].in_flight;
    const int64_t before = in_flight_before(d, flying, &total);
    const int64_t stride = total > NN_QUERIES ? (total + NN_QUERIES - 1) / NN_QUERIES : 1;
    const int64_t q0 = (before + stride - 1) / stride, q1 = (before + flying + stride - 1) / stride; /* this rank's queries */
    st = fm_dist_agree(d, total < 0 ? FM_ERR_MEMORY : sum_blocks(view, 0, blocks, before, stride, b, mine, q0), err);
    void *all = NULL;
    int32_t *queries = NULL;
    int64_t count = 0, words = 0;
    if (st == FM_OK) st = fm_dist_gather(d, b, blocks, sizeof *b, &all, &count, err);
    for (int i = 0; i < FM_FLOCK_MEASURES; i++) out[i] = NAN;
    double mean_v[3] = {NAN, NAN, NAN};
    if (st == FM_OK && fm_dist_rank(d) == 0) combine(all, count, s->n, out, mean_v);
    if (st == FM_OK && total >= 2)
        st = fm_dist_allgather_i32(d, (const int32_t *)mine, 4 * (q1 - q0), &queries, &words, err);
    if (st == FM_OK && total >= 2) {
        fm_flock_dist_own_in_flight(s); /* s->member: this rank's own agents in flight, not the ghosts */
        out[FM_FLOCK_NN_DISTANCE] = mean_nn(m, s, d, (const nn_query *)queries, words / 4, nn, nn + NN_QUERIES, self);
    }
    if (st == FM_OK) /* collective: the ranks' own agents answer the look's queries */
        st = fm_flock_look_frame(m, s, d, &s->look, frame, fm_dist_rank(d) == 0 ? mean_v : NULL, total >= 2, out, err);
    fm_free(all), fm_free(queries), free(b), free(mine), free(nn), free(self);
    return st;
}
