/* The shape flock's agent store (structure of arrays) and its frames: positions, velocities,
 * orientations (a frame aligned with the velocity, as a quaternion) and phases. */
#include "flock.h"
#include "fm_math.h"

#include <math.h>
#include <omp.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* Every member that carries the run from one step to the next (a checkpoint saves exactly these):
 * positions, velocities, orientations, phases, bind times, the destinations and the leaders (each
 * step differences them for their velocities), the Kalman covariance (shared, and the agents' own
 * when R varies over the run; a run without them saves that member empty), the counters and the
 * tracking lag's running sum. Not listed: what each step rebuilds before reading it (dest_v and
 * leader_v, by those differences; a static target's dest_v stays 0; acc, ext, w_homing, mesh_v,
 * eval, the grid, blocks), member (set from phase before each grid build) and the style fields, whose baked grid is a pure
 * function of time and seed. */
#define AGENT_ARRAY(member, bytes) {#member, offsetof(fm_flock_state, member), bytes, 1}
#define AGENT_XYZ(member) AGENT_ARRAY(member[0], sizeof(float)), AGENT_ARRAY(member[1], sizeof(float)), \
                          AGENT_ARRAY(member[2], sizeof(float))
#define SCALAR(member) {#member, offsetof(fm_flock_state, member), sizeof(((fm_flock_state *)0)->member), 0}
const fm_store_member fm_flock_state_members[] = {
    AGENT_XYZ(p), AGENT_XYZ(v), AGENT_ARRAY(orient, 4 * sizeof(float)), AGENT_ARRAY(phase, sizeof(uint8_t)),
    AGENT_ARRAY(t_bind, sizeof(float)), AGENT_XYZ(dest), AGENT_XYZ(leader), AGENT_ARRAY(kalman_p, 3 * sizeof(double)),
    SCALAR(step), SCALAR(time), SCALAR(kalman), SCALAR(count), SCALAR(lag_sum),
};
#undef AGENT_ARRAY
#undef AGENT_XYZ
#undef SCALAR
const int fm_flock_state_member_count = (int)(sizeof fm_flock_state_members / sizeof fm_flock_state_members[0]);

static int alloc_arrays(fm_flock_state *s, int deforming, int64_t nv, int own_kalman)
{
    size_t n = (size_t)s->n;
    int ok = (s->orient = fm_alloc(sizeof(float) * 4 * n)) && (s->phase = fm_alloc(n)) &&
             (s->t_bind = fm_alloc(sizeof(float) * n)) && (s->w_homing = fm_alloc(sizeof(float) * n)) &&
             (s->member = fm_alloc(n)) && (s->blocks = fm_alloc(sizeof(flock_block) * (n / FM_BLOCK + 1)));
    float **arrays[] = {s->p, s->v, s->dest, s->dest_v, s->leader, s->leader_v, s->acc, s->steer, s->ext};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; i++)
        for (int k = 0; k < 3; k++) ok = ok && (arrays[i][k] = fm_alloc(sizeof(float) * n));
    if (own_kalman) ok = ok && (s->kalman_p = fm_alloc(sizeof(double) * 3 * n)) && (s->r_scale = fm_alloc(sizeof(float) * n));
    if (ok && s->kalman_p) memset(s->kalman_p, 0, sizeof(double) * 3 * n); /* P starts at 0 */
    if (deforming) ok = ok && (s->mesh_v = fm_alloc(sizeof(double) * 3 * (size_t)nv)) && (s->eval = fm_alloc(sizeof(float) * 3 * n));
    return ok;
}

/* Agents start at rest on their source samples, facing their destinations. */
static void initial_state(const fm_flock_model *m, fm_flock_state *s)
{
    for (int64_t a = 0; a < s->n; a++) {
        float toward[3];
        for (int k = 0; k < 3; k++) {
            s->p[k][a] = s->leader[k][a] = m->start[k][a];
            s->dest[k][a] = m->dest0[k][a];
            toward[k] = m->dest0[k][a] - m->start[k][a];
        }
        s->orient[4 * a] = 1;
        fm_flock_update_orientation(s->orient + 4 * a, toward);
        s->phase[a] = FM_PHASE_FLYING;
        s->member[a] = 1;
    }
    s->count[FM_PHASE_FLYING] = s->n;
    if (!s->mesh_v) return;
    fm_flock_target_vertices(&m->target, &m->def.flock, 0, s->mesh_v); /* a deforming target at t = 0 */
    fm_samples_eval(&m->target.dest, s->mesh_v, m->target.mesh.tri, s->eval);
    for (int64_t a = 0; a < s->n; a++)
        for (int k = 0; k < 3; k++) s->dest[k][a] = s->eval[3 * a + k];
}

fm_flock_state *fm_flock_state_create(const fm_flock_model *m, int threads, fm_error *err)
{
    fm_flock_state *s = calloc(1, sizeof *s);
    if (!s) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    s->n = m->n;
    s->threads = fm_threads(threads);
    const fm_scene_def *def = &m->def;
    fm_status st = alloc_arrays(s, m->info.deforming, m->target.mesh.nv, def->flock.kalman_r_over != FM_KALMAN_R_FIXED)
                       ? FM_OK
                       : fm_fail(err, FM_ERR_MEMORY, "out of memory for the store of %lld agents", (long long)m->n);
    if (st == FM_OK && def->field_count > 0) {
        s->fields = fm_fields_create(def->fields, def->field_count, def->seed, m->fields.baked ? def->field_grid : NULL,
                                     m->scene_lo, m->scene_hi, err);
        if (!s->fields) st = err ? err->status : FM_ERR_INPUT;
    }
    if (st == FM_OK) st = fm_grid_init(&s->grid, s->n, err);
    if (st == FM_OK) st = fm_grid_init_velocities(&s->grid, err); /* the boids read neighbours' velocities */
    s->grid_ready = st == FM_OK;
    if (st != FM_OK) {
        fm_flock_state_destroy(s);
        return NULL;
    }
    fm_kalman_init(&s->kalman, m->dt, def->flock.kalman_q, def->flock.kalman_r_position, def->flock.kalman_r_velocity);
    initial_state(m, s);
    return s;
}

void fm_flock_state_destroy(fm_flock_state *s)
{
    if (!s) return;
    float **arrays[] = {s->p, s->v, s->dest, s->dest_v, s->leader, s->leader_v, s->acc, s->steer, s->ext};
    for (size_t i = 0; i < sizeof arrays / sizeof arrays[0]; i++)
        for (int k = 0; k < 3; k++) fm_free(arrays[i][k]);
    fm_free(s->orient), fm_free(s->phase), fm_free(s->t_bind), fm_free(s->w_homing), fm_free(s->member);
    fm_free(s->blocks), fm_free(s->mesh_v), fm_free(s->eval), fm_free(s->kalman_p), fm_free(s->r_scale);
    if (s->fields) fm_fields_destroy(s->fields);
    if (s->grid_ready) fm_grid_free(&s->grid);
    fm_slabs_free(s->slabs), fm_free(s->gathered);
    free(s);
}

fm_run_info fm_flock_get_info(const fm_flock_state *s)
{
    fm_run_info info = {.step = s->step, .time = s->time};
    memcpy(info.count, s->count, sizeof info.count);
    return info;
}

/* The agent's frame: x along v, y = unit(world Z x x), z = x cross y, so the agent stays upright;
 * flying straight up or down (no such y), y is the previous y made perpendicular to x. Unchanged
 * when v is 0. */
void fm_flock_update_orientation(float *q, const float v[3])
{
    double len = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
    if (!(len > 1e-12)) return;
    const double x[3] = {v[0] / len, v[1] / len, v[2] / len};
    double y[3] = {-x[1], x[0], 0}, ylen = sqrt(y[0] * y[0] + y[1] * y[1]);
    if (ylen < 1e-3) { /* near vertical: the previous frame's y, minus its part along x */
        const double w = q[0], i = q[1], j = q[2], k = q[3];
        const double prev[3] = {2 * (i * j - w * k), 1 - 2 * (i * i + k * k), 2 * (j * k + w * i)};
        double along = prev[0] * x[0] + prev[1] * x[1] + prev[2] * x[2];
        for (int c = 0; c < 3; c++) y[c] = prev[c] - along * x[c];
        ylen = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
        if (!(ylen > 1e-9)) return;
    }
    for (int c = 0; c < 3; c++) y[c] /= ylen;
    const double z[3] = {x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
    fm_mat3 r;
    for (int c = 0; c < 3; c++) r.m[c][0] = x[c], r.m[c][1] = y[c], r.m[c][2] = z[c];
    double out[4];
    fm_quat_from_rotation(r, out);
    for (int c = 0; c < 4; c++) q[c] = (float)out[c];
}

void fm_flock_frame(const fm_flock_state *s, float *position, float *velocity, float *orientation, uint8_t *phase)
{
    fm_flock_frame_range(s, 0, s->n, position, velocity, orientation, phase);
}

void fm_flock_frame_range(const fm_flock_state *s, int64_t begin, int64_t end, float *position, float *velocity,
                          float *orientation, uint8_t *phase)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = begin; a < end; a++)
        for (int k = 0; k < 3; k++) {
            if (position) position[3 * (a - begin) + k] = s->p[k][a];
            if (velocity) velocity[3 * (a - begin) + k] = s->v[k][a];
        }
    if (orientation) memcpy(orientation, s->orient + 4 * begin, sizeof(float) * 4 * (size_t)(end - begin));
    if (phase) memcpy(phase, s->phase + begin, (size_t)(end - begin));
}

void fm_flock_destinations(const fm_flock_state *s, float *out)
{
    for (int64_t a = 0; a < s->n; a++)
        for (int k = 0; k < 3; k++) out[3 * a + k] = s->dest[k][a];
}

/* Blocks [b0, b1): each one's sum and largest of the agents' distances to their destinations, in
 * pairs. */
static void distance_blocks(const fm_flock_state *s, int64_t b0, int64_t b1, double *pairs)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t b = b0; b < b1; b++) {
        double sum = 0, big = 0;
        for (int64_t a = b * FM_BLOCK; a < FM_MIN((b + 1) * FM_BLOCK, s->n); a++) {
            double d2 = 0;
            for (int k = 0; k < 3; k++) d2 += ((double)s->p[k][a] - s->dest[k][a]) * ((double)s->p[k][a] - s->dest[k][a]);
            sum += sqrt(d2), big = fmax(big, sqrt(d2));
        }
        pairs[2 * (b - b0)] = sum, pairs[2 * (b - b0) + 1] = big;
    }
}

/* Per-block sums combined in block order, so the mean does not depend on the thread count. */
void fm_flock_distance(const fm_flock_state *s, double *mean, double *max)
{
    fm_flock_distance_blocks(s, 0, s->n, NULL, mean, max);
}

/* On P ranks each rank sums the blocks of its share (whole FM_BLOCK blocks) and rank 0 combines
 * every block in block order: the one process's figures. */
void fm_flock_distance_blocks(const fm_flock_state *s, int64_t begin, int64_t end, const fm_dist *d, double *mean,
                              double *max)
{
    const int64_t b0 = begin / FM_BLOCK, b1 = (end + FM_BLOCK - 1) / FM_BLOCK;
    double *pairs = malloc(sizeof(double) * 2 * (size_t)FM_MAX(b1 - b0, 1));
    void *all = NULL;
    int64_t total = 0;
    fm_status st = fm_dist_agree(d, pairs ? FM_OK : FM_ERR_MEMORY, NULL);
    if (st == FM_OK) distance_blocks(s, b0, b1, pairs);
    if (st == FM_OK) st = fm_dist_gather(d, pairs, b1 - b0, 2 * sizeof(double), &all, &total, NULL);
    *mean = *max = NAN;
    if (st == FM_OK && fm_dist_rank(d) == 0) {
        const double *p = all;
        *mean = 0, *max = 0;
        for (int64_t b = 0; b < total; b++) *mean += p[2 * b], *max = fmax(*max, p[2 * b + 1]); /* block order */
        *mean /= (double)s->n;
    }
    fm_free(all), free(pairs);
}
