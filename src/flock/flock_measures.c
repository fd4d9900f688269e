/* The flock measures of a frame (include/flockmorph/flock.h, docs/stats.md "Flock measures"):
 * polarisation, nearest-neighbour distance, distance from the eq-12 path, speed, distance to the
 * destination, the fraction in flight. Sums are taken per FM_BLOCK block of agents on the threads
 * and combined in block order, so the figures do not depend on the thread count. */
#include "flock.h"

#include <math.h>
#include <stdlib.h>

const char *const fm_flock_measure_names[FM_FLOCK_MEASURES] = {"polarisation", "nn_distance", "leader_distance",
                                                               "speed", "destination_distance", "in_flight"};

/* Nearest-neighbour queries a frame: the mean of 1,024 has a standard error near 1 % for the
 * nearest-neighbour distances of a flock (their CV is about 0.3). */
enum { NN_QUERIES = 1024 };

typedef struct measure_block {
    int64_t in_flight, moving;
    double unit[3], speed, leader, destination;
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
    if (!s->member[a]) return;
    const double v[3] = {s->v[0][a], s->v[1][a], s->v[2][a]}, speed = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    b->speed += speed;
    if (speed > 0)
        for (int k = 0; k < 3; k++) b->unit[k] += v[k] / speed;
    b->moving += speed > 0;
    b->leader += distance3(p, (const float *const *)s->leader, a);
}

/* The mean distance from each queried agent to its nearest neighbour in flight (s->member). The
 * first grid is the step's own (its cell, the agents in flight), so the next step keeps it. The
 * grid finds neighbours within its cell; agents with none ask again on a grid of four times the
 * cell, until all have one (at most 16 times: 4^16 cells reach past any scene a float holds), so an
 * isolated agent counts with its true distance. Summed in query order. */
static double mean_nn(const fm_flock_model *m, fm_flock_state *s, const int64_t *query, int64_t count, double *nn)
{
    float cell = m->max_radius > 0 ? m->max_radius : 1.0f;
    int64_t pending = count;
    for (int64_t q = 0; q < count; q++) nn[q] = NAN;
    int passes = 0;
    for (; pending > 0 && passes <= 16; passes++, cell *= 4) {
        fm_grid_build_moving(&s->grid, (const float *const *)s->p, (const float *const *)s->v, s->member, s->n, cell,
                             s->threads);
        pending = 0;
#pragma omp parallel for num_threads(s->threads) schedule(static) reduction(+ : pending)
        for (int64_t q = 0; q < count; q++) {
            if (!isnan(nn[q])) continue;
            const int64_t a = query[q];
            const float x[3] = {s->p[0][a], s->p[1][a], s->p[2][a]};
            double d2;
            if (fm_grid_nearest(&s->grid, x, NULL, a, -1, &d2) >= 0) nn[q] = sqrt(d2);
            else pending++;
        }
    }
    /* the first grid is the one the next step builds (its cell, the agents in flight): it keeps it */
    s->grid_current = passes == 1;
    double sum = 0;
    int64_t found = 0;
    for (int64_t q = 0; q < count; q++)
        if (!isnan(nn[q])) sum += nn[q], found++;
    return found > 0 ? sum / (double)found : NAN;
}

static void combine(const measure_block *blocks, int64_t count, int64_t n, double out[FM_FLOCK_MEASURES])
{
    measure_block t = {0};
    for (int64_t i = 0; i < count; i++) { /* block order */
        const measure_block *b = &blocks[i];
        t.in_flight += b->in_flight, t.moving += b->moving;
        for (int k = 0; k < 3; k++) t.unit[k] += b->unit[k];
        t.speed += b->speed, t.leader += b->leader, t.destination += b->destination;
    }
    const double flying = t.in_flight > 0 ? (double)t.in_flight : NAN;
    const double u = sqrt(t.unit[0] * t.unit[0] + t.unit[1] * t.unit[1] + t.unit[2] * t.unit[2]);
    out[FM_FLOCK_POLARISATION] = t.moving > 0 ? u / (double)t.moving : NAN;
    out[FM_FLOCK_LEADER_DISTANCE] = t.leader / flying;
    out[FM_FLOCK_SPEED] = t.speed / flying;
    out[FM_FLOCK_DESTINATION_DISTANCE] = n > 0 ? t.destination / (double)n : NAN;
    out[FM_FLOCK_IN_FLIGHT] = n > 0 ? (double)t.in_flight / (double)n : NAN;
}

void fm_flock_measure_frame(const fm_flock_model *m, fm_flock_state *s, double out[FM_FLOCK_MEASURES])
{
    const int64_t n = s->n, blocks = (n + FM_BLOCK - 1) / FM_BLOCK;
    measure_block *b = calloc((size_t)(blocks > 0 ? blocks : 1), sizeof *b);
    int64_t *first = malloc(sizeof(int64_t) * (size_t)(blocks > 0 ? blocks : 1)), *query = malloc(sizeof(int64_t) * NN_QUERIES);
    double *nn = malloc(sizeof(double) * NN_QUERIES);
    for (int i = 0; i < FM_FLOCK_MEASURES; i++) out[i] = NAN;
    if (b && first && query && nn) {
#pragma omp parallel for num_threads(s->threads) schedule(static)
        for (int64_t i = 0; i < blocks; i++)
            for (int64_t a = i * FM_BLOCK; a < FM_MIN((i + 1) * FM_BLOCK, n); a++) {
                s->member[a] = s->phase[a] != FM_PHASE_ARRIVED;
                b[i].in_flight += s->member[a];
            }
        int64_t total = 0;
        for (int64_t i = 0; i < blocks; i++) first[i] = total, total += b[i].in_flight;
        /* every stride-th agent in flight, counted in id order, asks for its nearest neighbour */
        const int64_t stride = total > NN_QUERIES ? (total + NN_QUERIES - 1) / NN_QUERIES : 1;
#pragma omp parallel for num_threads(s->threads) schedule(static)
        for (int64_t i = 0; i < blocks; i++) {
            int64_t rank = first[i];
            for (int64_t a = i * FM_BLOCK; a < FM_MIN((i + 1) * FM_BLOCK, n); a++) {
                measure_agent(s, a, &b[i]);
                if (s->member[a] && rank % stride == 0) query[rank / stride] = a;
                rank += s->member[a];
            }
        }
        combine(b, blocks, n, out);
        if (total >= 2) out[FM_FLOCK_NN_DISTANCE] = mean_nn(m, s, query, (total + stride - 1) / stride, nn);
    }
    free(b), free(first), free(query), free(nn);
}
