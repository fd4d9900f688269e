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
    SCALAR(step), SCALAR(time), SCALAR(kalman), SCALAR(count), SCALAR(lag_sum), SCALAR(look),
};
#undef AGENT_ARRAY
#undef AGENT_XYZ
#undef SCALAR
const int fm_flock_state_member_count = (int)(sizeof fm_flock_state_members / sizeof fm_flock_state_members[0]);

/* Every per-slot array, with its bytes a slot, whether it carries the agent from one step to the
 * next (moved with it when a rank's slots are rebuilt or the store is re-sorted: flock_resort.c;
 * the others are each step's scratch) and
 * which stores have it: allocated, resized and freed together (a new array is one line here). */
enum { IN_ALL, IN_STEPPED, IN_OWN_KALMAN, IN_STEPPED_OWN_KALMAN, IN_DEFORMING, IN_OWN_SLOTS };
typedef struct slot_array {
    size_t offset; /* of the array's pointer in fm_flock_state */
    size_t bytes;  /* per slot */
    int carried, in;
} slot_array;
#define SLOTS(member, bytes, carried, in) {offsetof(fm_flock_state, member), bytes, carried, in}
#define XYZ(member, carried, in) SLOTS(member[0], 4, carried, in), SLOTS(member[1], 4, carried, in), SLOTS(member[2], 4, carried, in)
static const slot_array SLOT_ARRAYS[] = {
    XYZ(p, 1, IN_ALL), XYZ(v, 1, IN_ALL), XYZ(dest, 1, IN_ALL), XYZ(leader, 1, IN_ALL),
    SLOTS(orient, 16, 1, IN_ALL), SLOTS(phase, 1, 1, IN_ALL), SLOTS(t_bind, 4, 1, IN_ALL),
    SLOTS(kalman_p, 24, 1, IN_OWN_KALMAN), SLOTS(member, 1, 0, IN_ALL),
    XYZ(dest_v, 0, IN_STEPPED), XYZ(leader_v, 0, IN_STEPPED), XYZ(acc, 0, IN_STEPPED), XYZ(steer, 0, IN_STEPPED),
    XYZ(ext, 0, IN_STEPPED), SLOTS(w_homing, 4, 0, IN_STEPPED), SLOTS(r_scale, 4, 0, IN_STEPPED_OWN_KALMAN),
    SLOTS(eval, 12, 0, IN_DEFORMING), SLOTS(id, 4, 1, IN_OWN_SLOTS), SLOTS(move_from, 4, 0, IN_OWN_SLOTS),
    XYZ(prm.radius, 1, IN_OWN_SLOTS), XYZ(prm.cos_half, 1, IN_OWN_SLOTS), XYZ(prm.weight, 1, IN_OWN_SLOTS),
    SLOTS(prm.max_speed, 4, 1, IN_OWN_SLOTS), SLOTS(prm.max_force, 4, 1, IN_OWN_SLOTS), SLOTS(prm.max_accel, 4, 1, IN_OWN_SLOTS),
    XYZ(prm.start, 1, IN_OWN_SLOTS),
};
#undef SLOTS
#undef XYZ
enum { SLOT_ARRAY_COUNT = sizeof SLOT_ARRAYS / sizeof SLOT_ARRAYS[0], SLOT_BYTES_MAX = 24 };

static void **slot_array_at(fm_flock_state *s, int i) { return (void **)((char *)s + SLOT_ARRAYS[i].offset); }

/* Whether the store has ids and parameters of its own by slot, and the slots' moves' scratch: on P
 * ranks, and on one process with the re-sort. */
static int has_own_slots(const fm_flock_state *s) { return s->dist != NULL || s->resort_every > 0; }

/* Whether store s has array i. A share's view (flock_dist.c) has only what a frame, its measures and
 * a checkpoint read. */
static int has_array(const fm_flock_state *s, int view, int i)
{
    switch (SLOT_ARRAYS[i].in) {
    case IN_ALL: return 1;
    case IN_STEPPED: return !view;
    case IN_OWN_KALMAN: return s->own_kalman;
    case IN_STEPPED_OWN_KALMAN: return !view && s->own_kalman;
    case IN_DEFORMING: return !view && s->deforming;
    default: return !view && has_own_slots(s);
    }
}

/* Every array of s at `capacity` slots, the first `keep` copied over, one array at a time (a resize
 * needs one array's bytes more, not the store's). On failure every array still holds min(old, new
 * capacity) slots, which the store then says it has. */
static fm_status resize_arrays(fm_flock_state *s, int view, int64_t capacity, int64_t keep)
{
    const int64_t least = FM_MIN(s->cap, capacity);
    if (!view) {
        flock_block *blocks = fm_alloc(sizeof(flock_block) * ((size_t)capacity / FM_BLOCK + 1));
        if (!blocks) return s->cap = least, FM_ERR_MEMORY;
        fm_free(s->blocks), s->blocks = blocks;
    }
    if (has_own_slots(s) && !view) {
        void *scratch = fm_alloc(SLOT_BYTES_MAX * (size_t)FM_MAX(capacity, 1));
        if (!scratch) return s->cap = least, FM_ERR_MEMORY;
        fm_free(s->scratch), s->scratch = scratch;
    }
    for (int i = 0; i < SLOT_ARRAY_COUNT; i++) {
        if (!has_array(s, view, i)) continue;
        void **a = slot_array_at(s, i), *fresh = fm_alloc(SLOT_ARRAYS[i].bytes * (size_t)FM_MAX(capacity, 1));
        if (!fresh) return s->cap = least, FM_ERR_MEMORY;
        if (*a && keep > 0) memcpy(fresh, *a, SLOT_ARRAYS[i].bytes * (size_t)keep);
        fm_free(*a), *a = fresh;
    }
    s->cap = capacity;
    return FM_OK;
}

/* With the re-sort off, on one process the model's parameters are the slots' (a slot is an agent). */
static void params_of_model(const fm_flock_model *m, fm_flock_params *prm)
{
    for (int r = 0; r < FM_BOIDS_RULES; r++)
        prm->radius[r] = m->radius[r], prm->cos_half[r] = m->cos_half[r], prm->weight[r] = m->weight[r];
    for (int k = 0; k < 3; k++) prm->start[k] = m->start[k];
    prm->max_speed = m->max_speed, prm->max_force = m->max_force, prm->max_accel = m->max_accel;
}

void fm_flock_params_copy(const fm_flock_model *m, fm_flock_params *prm, int64_t slot, int64_t id)
{
    for (int r = 0; r < FM_BOIDS_RULES; r++)
        prm->radius[r][slot] = m->radius[r][id], prm->cos_half[r][slot] = m->cos_half[r][id],
        prm->weight[r][slot] = m->weight[r][id];
    for (int k = 0; k < 3; k++) prm->start[k][slot] = m->start[k][id];
    prm->max_speed[slot] = m->max_speed[id], prm->max_force[slot] = m->max_force[id];
    prm->max_accel[slot] = m->max_accel[id];
}

/* Agent `id` in slot a, at rest on its source sample, facing its destination (dest: where its
 * destination is at time 0). */
static void initial_agent(const fm_flock_model *m, fm_flock_state *s, int64_t a, int64_t id, const float dest[3])
{
    float toward[3];
    for (int k = 0; k < 3; k++) {
        s->p[k][a] = s->leader[k][a] = m->start[k][id];
        s->dest[k][a] = dest[k];
        toward[k] = m->dest0[k][id] - m->start[k][id];
    }
    s->orient[4 * a] = 1;
    fm_flock_update_orientation(s->orient + 4 * a, toward);
    s->phase[a] = FM_PHASE_FLYING;
    s->member[a] = 1;
}

/* A deforming target's destination of agent `id` at the time of s->mesh_v (as fm_samples_eval). */
void fm_flock_destination_of(const fm_flock_model *m, const fm_flock_state *s, int64_t id, float out[3])
{
    const fm_samples *d = &m->target.dest;
    const int32_t *f = m->target.mesh.tri + 3 * (int64_t)d->tri[id];
    const float *b = d->bary + 3 * id;
    for (int k = 0; k < 3; k++)
        out[k] = (float)((double)b[0] * s->mesh_v[3 * (int64_t)f[0] + k] + (double)b[1] * s->mesh_v[3 * (int64_t)f[1] + k] +
                         (double)b[2] * s->mesh_v[3 * (int64_t)f[2] + k]);
}

/* Agents start at rest on their source samples, facing their destinations: slots [0, s->slots),
 * agent id(a) each (every agent on one process). */
void fm_flock_state_start(const fm_flock_model *m, fm_flock_state *s)
{
    if (s->mesh_v) fm_flock_target_vertices(&m->target, &m->def.flock, 0, s->mesh_v); /* a deforming target at t = 0 */
    for (int64_t a = 0; a < s->slots; a++) {
        const int64_t id = fm_flock_id(s, a);
        float dest[3] = {m->dest0[0][id], m->dest0[1][id], m->dest0[2][id]};
        if (s->mesh_v) fm_flock_destination_of(m, s, id, dest);
        initial_agent(m, s, a, id, dest);
    }
    s->count[FM_PHASE_FLYING] = s->n;
}

/* On one process with the re-sort: slot a holds agent a, with its parameters. */
static fm_status own_slots_in_id_order(const fm_flock_model *m, fm_flock_state *s, fm_error *err)
{
    if (!(s->slot_by_id = fm_alloc(sizeof(int32_t) * (size_t)FM_MAX(s->n, 1))))
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the store's order of %lld agents", (long long)s->n);
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->n; a++) {
        s->id[a] = s->slot_by_id[a] = (int32_t)a;
        fm_flock_params_copy(m, &s->prm, a, a);
    }
    return FM_OK;
}

/* The neighbour grid for `capacity` agents, with the entry-order copies the boids read (positions and
 * velocities). Its rows are laid out by position (grid.h), not hashed: a flock moves as one, so a
 * store sorted by the grid's slot (flock_resort.c) stays in nearly the grid's order while it flies,
 * where hashed rows shuffle it as soon as it crosses a cell (y or z); the boids then read each agent's
 * parameters in order instead of at random. Fitted to the flock's box, no two of its cells share a
 * slot. The slots change only the walk's order, never a sum's bits (kernel_boids.h). */
static fm_status flock_grid_init(fm_flock_state *s, int64_t capacity, fm_error *err)
{
    fm_status st = fm_grid_init_table(&s->grid, capacity, s->dist ? s->n : 0, err);
    if (st == FM_OK) st = fm_grid_init_velocities(&s->grid, err);
    s->grid.linear_rows = FM_GRID_ROWS_FITTED;
    return st;
}

/* The store without its agents: slots for `slots` agents (ids: on P ranks filled by the caller),
 * the fields, the grid (its table one process's for n agents on P ranks: grid.h). */
fm_flock_state *fm_flock_state_alloc(const fm_flock_model *m, int threads, const fm_dist *dist, int64_t slots,
                                     fm_error *err)
{
    fm_flock_state *s = calloc(1, sizeof *s);
    if (!s) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    const fm_scene_def *def = &m->def;
    s->n = m->n, s->slots = slots, s->dist = dist;
    s->threads = fm_threads(threads);
    if ((s->resort_every = dist ? 0 : fm_flock_resort_interval(err)) < 0) return free(s), NULL;
    s->own_kalman = def->flock.kalman_r_over != FM_KALMAN_R_FIXED, s->deforming = m->info.deforming;
    fm_status st = resize_arrays(s, 0, slots, 0) == FM_OK
                       ? FM_OK
                       : fm_fail(err, FM_ERR_MEMORY, "out of memory for the store of %lld agents", (long long)slots);
    if (!has_own_slots(s)) params_of_model(m, &s->prm);
    else if (st == FM_OK && !dist) st = own_slots_in_id_order(m, s, err);
    if (st == FM_OK && s->deforming && !(s->mesh_v = fm_alloc(sizeof(double) * 3 * (size_t)m->target.mesh.nv)))
        st = fm_fail(err, FM_ERR_MEMORY, "out of memory for the target's vertices");
    if (st == FM_OK && def->field_count > 0) {
        s->fields = fm_fields_create(def->fields, def->field_count, def->seed, m->fields.baked ? def->field_grid : NULL,
                                     m->scene_lo, m->scene_hi, err);
        if (!s->fields) st = err ? err->status : FM_ERR_INPUT;
    }
    if (st == FM_OK) st = flock_grid_init(s, s->cap, err);
    s->grid_ready = st == FM_OK;
    if (st != FM_OK) {
        fm_flock_state_destroy(s);
        return NULL;
    }
    fm_kalman_init(&s->kalman, m->dt, def->flock.kalman_q, def->flock.kalman_r_position, def->flock.kalman_r_velocity);
    s->kalman.scale_velocity = def->flock.kalman_r_scale_velocity;
    return s;
}

fm_flock_state *fm_flock_state_create(const fm_flock_model *m, int threads, fm_error *err)
{
    fm_flock_state *s = fm_flock_state_alloc(m, threads, NULL, m->n, err);
    if (s) fm_flock_state_start(m, s);
    return s;
}

/* Slots for `slots` agents and a quarter more (and 1024), at most n: a rank's store grows with its
 * slab at amortised cost. */
static int64_t with_room(const fm_flock_state *s, int64_t slots) { return FM_MIN(s->n, slots + slots / 4 + 1024); }

fm_status fm_flock_state_reserve(fm_flock_state *s, int64_t slots, fm_error *err)
{
    if (slots <= s->cap) return FM_OK;
    const int64_t capacity = with_room(s, slots);
    if (resize_arrays(s, 0, capacity, s->slots) != FM_OK)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for a store of %lld agents (this process holds %lld)",
                       (long long)capacity, (long long)s->slots);
    /* The grid is rebuilt every step: the old one goes first, so the two are never held together (a
     * failure stops the run, every rank agreeing: flock_dist.c). */
    if (s->grid_ready) fm_grid_free(&s->grid), s->grid_ready = 0;
    fm_status st = flock_grid_init(s, capacity, err);
    if (st != FM_OK) fm_grid_free(&s->grid);
    s->grid_ready = st == FM_OK;
    return st;
}

/* The slots rebuilt (P ranks): new slot k holds old slot from[k] (>= 0), or for from[k] = -1 nothing
 * yet (the caller writes it); `slots` of them. Only the carried arrays move. */
/* A slot's element of each size the arrays have: the gather below copies it as one value (a memcpy of
 * a size known only at run time is a call per slot). */
typedef struct { uint32_t w[4]; } bytes16;
typedef struct { uint64_t w[3]; } bytes24;
#define GATHER(type, to, a, from, slots, threads)                                                      \
    do {                                                                                               \
        type *restrict to_ = (type *)(to);                                                            \
        const type *restrict a_ = (const type *)(a);                                                  \
        _Pragma("omp parallel for num_threads(threads) schedule(static)")                              \
        for (int64_t k = 0; k < (slots); k++)                                                          \
            if ((from)[k] >= 0) to_[k] = a_[(from)[k]];                                                \
    } while (0)

/* to[k] = a[from[k]] for from[k] >= 0, for `slots` slots of `bytes` each. */
static void gather_slots(void *to, const void *a, size_t bytes, const int32_t *from, int64_t slots, int threads)
{
    switch (bytes) {
    case 1: GATHER(uint8_t, to, a, from, slots, threads); break;
    case 4: GATHER(uint32_t, to, a, from, slots, threads); break;
    case 16: GATHER(bytes16, to, a, from, slots, threads); break;
    case 24: GATHER(bytes24, to, a, from, slots, threads); break;
    default: /* a size with no case of its own: correct, only slower */
#pragma omp parallel for num_threads(threads) schedule(static)
        for (int64_t k = 0; k < slots; k++)
            if (from[k] >= 0) memcpy((char *)to + bytes * (size_t)k, (const char *)a + bytes * (size_t)from[k], bytes);
    }
}
#undef GATHER

void fm_flock_state_move_slots(fm_flock_state *s, const int32_t *from, int64_t slots)
{
    for (int i = 0; i < SLOT_ARRAY_COUNT; i++) {
        if (!SLOT_ARRAYS[i].carried || !has_array(s, 0, i)) continue;
        const size_t bytes = SLOT_ARRAYS[i].bytes;
        char *a = *slot_array_at(s, i);
        gather_slots(s->scratch, a, bytes, from, slots, s->threads);
        fm_copy_parallel(a, s->scratch, bytes * (size_t)slots, s->threads);
    }
    s->slots = slots;
}

/* A share's view (flock_dist.c): ids first … first + count − 1, the arrays a frame, its measures and
 * a checkpoint read; with a grid where asked (rank 0 measuring a gathered frame as one process
 * does). Kept in s->view between frames, remade when the share changes. */
fm_flock_state *fm_flock_state_view(fm_flock_state *s, int64_t first, int64_t count, int grid, fm_error *err)
{
    fm_flock_state *v = s->view;
    if (v && v->first == first && v->slots == count && v->grid_ready == grid) return v;
    fm_flock_state_destroy(v);
    s->view = v = calloc(1, sizeof *v);
    if (!v) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    v->n = s->n, v->first = first, v->slots = count, v->threads = s->threads;
    v->own_kalman = s->own_kalman, v->deforming = s->deforming;
    fm_status st = resize_arrays(v, 1, count, 0);
    if (st != FM_OK) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame's share of %lld agents", (long long)count);
    if (st == FM_OK && grid && (st = fm_grid_init(&v->grid, count, err)) == FM_OK)
        v->grid_ready = 1, st = fm_grid_init_velocities(&v->grid, err);
    if (st != FM_OK) return fm_flock_state_destroy(v), s->view = NULL;
    return v;
}

void fm_flock_state_destroy(fm_flock_state *s)
{
    if (!s) return;
    for (int i = 0; i < SLOT_ARRAY_COUNT; i++) {
        if (!has_own_slots(s) && SLOT_ARRAYS[i].in == IN_OWN_SLOTS) continue; /* the model's own, on one process */
        fm_free(*slot_array_at(s, i));
    }
    fm_free(s->slot_by_id), fm_free(s->blocks), fm_free(s->mesh_v), fm_free(s->scratch), free(s->merge_buf);
    if (s->fields) fm_fields_destroy(s->fields);
    if (s->grid_ready) fm_grid_free(&s->grid);
    fm_slabs_free(s->slabs);
    fm_flock_state_destroy(s->view);
    free(s);
}

fm_run_info fm_flock_get_info(const fm_flock_state *s)
{
    fm_run_info info = {.step = s->step, .time = s->time};
    memcpy(info.count, s->count, sizeof info.count);
    return info;
}

void fm_flock_frame(const fm_flock_state *s, float *position, float *velocity, float *orientation, uint8_t *phase)
{
    fm_flock_frame_range(s, 0, s->slots, position, velocity, orientation, phase);
}

/* Agent id's values from slot a into element o of the frame's arrays. */
static inline void frame_agent(const fm_flock_state *s, int64_t a, int64_t o, float *position, float *velocity,
                               float *orientation, uint8_t *phase)
{
    for (int k = 0; k < 3; k++) {
        if (position) position[3 * o + k] = s->p[k][a];
        if (velocity) velocity[3 * o + k] = s->v[k][a];
    }
    if (orientation) memcpy(orientation + 4 * o, s->orient + 4 * a, sizeof(float) * 4);
    if (phase) phase[o] = s->phase[a];
}

/* In id order (the cache's frames are): a re-sorted store's slots are read in store order and each
 * agent written at its id (a scatter touches each agent's 4 output runs, where a gather through
 * slot_by_id would touch its 8 input arrays at random). */
void fm_flock_frame_range(const fm_flock_state *s, int64_t begin, int64_t end, float *position, float *velocity,
                          float *orientation, uint8_t *phase)
{
    if (s->sorted) {
#pragma omp parallel for num_threads(s->threads) schedule(static)
        for (int64_t a = 0; a < s->slots; a++) {
            const int64_t i = s->id[a];
            if (i >= begin && i < end) frame_agent(s, a, i - begin, position, velocity, orientation, phase);
        }
        return;
    }
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t i = begin; i < end; i++) frame_agent(s, i, i - begin, position, velocity, orientation, phase);
}

void fm_flock_destinations(const fm_flock_state *s, float *out)
{
    for (int64_t i = 0; i < s->slots; i++)
        for (int k = 0; k < 3; k++) out[3 * i + k] = s->dest[k][fm_flock_slot_in_id_order(s, i)];
}

/* Blocks [b0, b1) of the agents in id order: each one's sum and largest of the agents' distances to
 * their destinations, in pairs. */
static void distance_blocks(const fm_flock_state *s, int64_t b0, int64_t b1, double *pairs)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t b = b0; b < b1; b++) {
        double sum = 0, big = 0;
        for (int64_t i = b * FM_BLOCK; i < FM_MIN((b + 1) * FM_BLOCK, s->slots); i++) {
            const int64_t a = fm_flock_slot_in_id_order(s, i);
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
    fm_flock_distance_blocks(s, 0, s->slots, NULL, mean, max);
}

/* On P ranks each rank sums the blocks of its share's view (flock_dist.c: whole FM_BLOCK blocks) and
 * rank 0 combines every block in block order: the one process's figures. */
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
