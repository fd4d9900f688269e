/* The agent store (structure of arrays) and the frame: every tet's four vertices (FM §6). */
#include "morph.h"
#include "kernel_synth.h"

#include <math.h>
#include <omp.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* Every member of the store that carries the run from one step to the next; a checkpoint saves
 * exactly these (checkpoint.c), so a new per-agent array or evolving counter is one line here.
 * Not listed: the scratch each step rebuilds before reading it (entered, member, vla, mde_needed,
 * grid, blocks), and the style fields, whose baked grid is a pure function of time and seed. */
#define AGENT_ARRAY(member, bytes) {#member, offsetof(fm_morph_state, member), bytes, 1}
#define SCALAR(member) {#member, offsetof(fm_morph_state, member), sizeof(((fm_morph_state *)0)->member), 0}
const fm_store_member fm_morph_state_members[] = {
    AGENT_ARRAY(p[0], sizeof(float)), AGENT_ARRAY(p[1], sizeof(float)), AGENT_ARRAY(p[2], sizeof(float)),
    AGENT_ARRAY(v[0], sizeof(float)), AGENT_ARRAY(v[1], sizeof(float)), AGENT_ARRAY(v[2], sizeof(float)),
    AGENT_ARRAY(phase, sizeof(uint8_t)),
    AGENT_ARRAY(target, sizeof(int64_t)),
    AGENT_ARRAY(t2, sizeof(float)),
    AGENT_ARRAY(p2[0], sizeof(float)), AGENT_ARRAY(p2[1], sizeof(float)), AGENT_ARRAY(p2[2], sizeof(float)),
    AGENT_ARRAY(tf, sizeof(float)),
    AGENT_ARRAY(morph, sizeof(float) * FM_MORPH_FLOATS),
    AGENT_ARRAY(perm, sizeof(uint8_t)),
    AGENT_ARRAY(morph_safe, sizeof(uint8_t)),
    AGENT_ARRAY(detour_best, sizeof(float)), AGENT_ARRAY(detour_since, sizeof(float)),
    AGENT_ARRAY(detour_on, sizeof(uint8_t)),
    AGENT_ARRAY(id, sizeof(int32_t)), SCALAR(active_begin), SCALAR(active_end),
    SCALAR(step), SCALAR(time), SCALAR(launched), SCALAR(next_slot), SCALAR(count),
    SCALAR(morph_fallbacks), SCALAR(mde_agent_steps), SCALAR(detour_agent_steps), SCALAR(flying_agent_steps), SCALAR(min_clearance),
};
const int fm_morph_state_member_count = (int)(sizeof fm_morph_state_members / sizeof fm_morph_state_members[0]);

/* Every per-slot array of the store, with its bytes per slot: allocated, resized and freed together
 * (a new array is one line here). */
typedef struct slot_array {
    size_t offset; /* of the array's pointer in fm_morph_state */
    size_t bytes;  /* per slot */
} slot_array;
#define SLOTS(member, bytes) {offsetof(fm_morph_state, member), bytes}
static const slot_array SLOT_ARRAYS[] = {
    SLOTS(p[0], 4), SLOTS(p[1], 4), SLOTS(p[2], 4), SLOTS(v[0], 4), SLOTS(v[1], 4), SLOTS(v[2], 4),
    SLOTS(p2[0], 4), SLOTS(p2[1], 4), SLOTS(p2[2], 4),
    SLOTS(rest_rel[0], 4), SLOTS(rest_rel[1], 4), SLOTS(rest_rel[2], 4), SLOTS(rest_rel[3], 4),
    SLOTS(rest_rel[4], 4), SLOTS(rest_rel[5], 4), SLOTS(rest_rel[6], 4), SLOTS(rest_rel[7], 4),
    SLOTS(rest_rel[8], 4), SLOTS(rest_rel[9], 4), SLOTS(rest_rel[10], 4), SLOTS(rest_rel[11], 4),
    SLOTS(rest_radius, 4), SLOTS(id, 4), SLOTS(phase, 1), SLOTS(target, 8), SLOTS(t2, 4), SLOTS(tf, 4),
    SLOTS(morph, 4 * FM_MORPH_FLOATS), SLOTS(perm, 1), SLOTS(morph_safe, 1), SLOTS(entered, 1),
    SLOTS(detour_best, 4), SLOTS(detour_since, 4), SLOTS(detour_on, 1),
    SLOTS(member, 1), SLOTS(mde_needed, 1), SLOTS(vla[0], 4), SLOTS(vla[1], 4), SLOTS(vla[2], 4),
    SLOTS(sort_scratch, 16), SLOTS(sort_keys, 2 * sizeof(uint32_t)), SLOTS(sort_slots, 2 * sizeof(int32_t)),
};
enum { SLOT_ARRAY_COUNT = sizeof SLOT_ARRAYS / sizeof SLOT_ARRAYS[0] };

static void **slot_array_at(fm_morph_state *s, int i) { return (void **)((char *)s + SLOT_ARRAYS[i].offset); }

/* Every per-slot array at `capacity` slots, the first `keep` (<= capacity) slots copied over. One
 * array at a time, so a resize needs one array's bytes more, not the store's. On failure the arrays
 * done so far are resized: every array still holds min(old, new capacity) slots, which the store
 * then says it has. */
static fm_status resize_arrays(fm_morph_state *s, int64_t capacity, int64_t keep)
{
    const int64_t least = FM_MIN(s->capacity, capacity);
    block_counts *blocks = fm_alloc(sizeof(block_counts) * ((size_t)capacity / FM_BLOCK + 1));
    if (!blocks) return s->capacity = least, FM_ERR_MEMORY;
    fm_free(s->blocks), s->blocks = blocks;
    for (int i = 0; i < SLOT_ARRAY_COUNT; i++) {
        void **a = slot_array_at(s, i), *fresh = fm_alloc(SLOT_ARRAYS[i].bytes * (size_t)FM_MAX(capacity, 1));
        if (!fresh) return s->capacity = least, FM_ERR_MEMORY;
        if (*a && keep > 0) memcpy(fresh, *a, SLOT_ARRAYS[i].bytes * (size_t)keep);
        fm_free(*a), *a = fresh;
    }
    s->capacity = capacity;
    return FM_OK;
}

static void free_arrays(fm_morph_state *s)
{
    for (int i = 0; i < SLOT_ARRAY_COUNT; i++) fm_free(*slot_array_at(s, i)), *slot_array_at(s, i) = NULL;
    fm_free(s->blocks), s->blocks = NULL;
}

/* The MDE grid for up to capacity agents (a rank's own and its halo's): made before the old one is
 * freed, so a failure leaves the old one (large enough after a shrink; a failed growth stops the run). */
static fm_status size_grid(fm_morph_state *s, int64_t capacity, fm_error *err)
{
    fm_grid fresh;
    fm_status st = fm_grid_init(&fresh, capacity, err);
    if (st != FM_OK) return st;
    if (s->grid_ready) fm_grid_free(&s->grid);
    s->grid = fresh, s->grid_ready = 1;
    /* The store is Morton-sorted and MDE sums by id, not in the grid's order: rows by position
     * keep the walk's lookups near each other in memory and change no result. */
    s->grid.linear_rows = FM_GRID_ROWS_THIRDS;
    return FM_OK;
}

/* Resizes the store to `capacity` slots, keeping its agents (and the grid with it). */
static fm_status resize_store(fm_morph_state *s, int64_t capacity, fm_error *err)
{
    if (resize_arrays(s, capacity, FM_MIN(fm_morph_slots(s), capacity)) != FM_OK)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for a store of %lld agents (this process holds %lld)",
                       (long long)capacity, (long long)fm_morph_slots(s));
    return s->grid_ready ? size_grid(s, capacity, err) : FM_OK;
}

/* Slots for `slots` agents and a quarter more (and 1024): a rank's store grows and shrinks with its
 * slab at amortised cost. */
static int64_t with_room(const fm_morph_state *s, int64_t slots) { return FM_MIN(s->n, slots + slots / 4 + 1024); }

fm_status fm_morph_state_reserve(fm_morph_state *s, int64_t slots, fm_error *err)
{
    if (slots <= s->capacity) /* a loaded checkpoint's store may have outgrown the grid */
        return s->grid_ready && s->grid.capacity < s->capacity ? size_grid(s, s->capacity, err) : FM_OK;
    return resize_store(s, with_room(s, slots), err);
}

void fm_morph_state_fit(fm_morph_state *s)
{
    const int64_t fit = with_room(s, fm_morph_slots(s));
    if (fit < s->capacity) resize_store(s, fit, NULL); /* without memory the store stays as large as it was */
}

/* The parts of the store only some scenes need: style fields and the MDE grid. */
static fm_status create_velocity_model(const fm_morph_model *m, fm_morph_state *s, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    if (def->field_count > 0) {
        s->fields = fm_fields_create(def->fields, def->field_count, def->seed, m->fields.baked ? def->field_grid : NULL,
                                     m->scene_lo, m->scene_hi, err);
        if (!s->fields) return err ? err->status : FM_ERR_INPUT;
    }
    return def->d_min > 0 ? size_grid(s, s->capacity, err) : FM_OK;
}

/* A store of `capacity` slots holding no agent yet, every agent waiting. */
static fm_morph_state *create_empty(const fm_morph_model *m, int threads, int64_t capacity, fm_error *err)
{
    fm_morph_state *s = calloc(1, sizeof *s);
    if (!s) {
        fm_fail(err, FM_ERR_MEMORY, "out of memory");
        return NULL;
    }
    s->n = m->n;
    if (m->n > INT32_MAX) {
        free(s);
        fm_fail(err, FM_ERR_INPUT, "n = %lld agents: the store holds at most %d", (long long)m->n, INT32_MAX);
        return NULL;
    }
    s->threads = fm_threads(threads);
    if (resize_arrays(s, capacity, 0) != FM_OK) {
        fm_morph_state_destroy(s);
        fm_fail(err, FM_ERR_MEMORY, "out of memory for the store of %lld agents", (long long)capacity);
        return NULL;
    }
    if (create_velocity_model(m, s, err) != FM_OK || (m->motion && !(s->motion_now = fm_morph_motion_now_create(m, err)))) {
        fm_morph_state_destroy(s);
        return NULL;
    }
    s->count[FM_PHASE_WAITING] = s->n;
    s->min_clearance = INFINITY;
    for (int64_t a = 0; a < capacity; a++) s->detour_best[a] = INFINITY, s->detour_since[a] = 0, s->detour_on[a] = 0;
    return s;
}

fm_morph_state *fm_morph_state_create(const fm_morph_model *m, int threads, fm_error *err)
{
    fm_morph_state *s = create_empty(m, threads, m->n, err);
    if (!s) return NULL;
    for (int k = 0; k < 3; k++) memcpy(s->p[k], m->src_c[k], sizeof(float) * (size_t)s->n);
    for (int64_t a = 0; a < s->n; a++) s->target[a] = -1, s->id[a] = (int32_t)a;
    fm_morph_state_fill_rest(m, s);
    return s;
}

fm_morph_state *fm_morph_state_create_distributed(const fm_morph_model *m, int threads, const fm_dist *dist, fm_error *err)
{
    fm_morph_state *s = create_empty(m, threads, FM_MIN(m->n, 1024), err); /* it grows with the rank's agents */
    if (s && fm_morph_state_distribute(m, s, dist, err) != FM_OK) fm_morph_state_destroy(s), s = NULL;
    return s;
}

void fm_morph_state_destroy(fm_morph_state *s)
{
    if (!s) return;
    free_arrays(s);
    if (s->fields) fm_fields_destroy(s->fields);
    if (s->grid_ready) fm_grid_free(&s->grid);
    fm_slabs_free(s->slabs);
    fm_morph_motion_now_free(s->motion_now);
    free(s);
}

void fm_morph_state_fill_rest(const fm_morph_model *m, fm_morph_state *s)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->n; a++) {
        const size_t i = (size_t)s->id[a];
        for (int j = 0; j < 12; j++) s->rest_rel[j][a] = m->src_rel[12 * i + (size_t)j];
        s->rest_radius[a] = m->src_radius[i];
    }
}

fm_morph_info fm_morph_get_info(const fm_morph_state *s)
{
    fm_morph_info info = {.run = {.step = s->step, .time = s->time}, .morph_fallbacks = s->morph_fallbacks,
                          .flying_agent_steps = s->flying_agent_steps, .mde_agent_steps = s->mde_agent_steps,
                          .detour_agent_steps = s->detour_agent_steps,
                          .min_obstacle_clearance = s->min_clearance};
    memcpy(info.run.count, s->count, sizeof info.run.count);
    info.all_arrived = s->count[FM_PHASE_ARRIVED] == s->n;
    return info;
}

void fm_morph_targets(const fm_morph_state *s, int64_t *out)
{
    for (int64_t a = 0; a < fm_morph_slots(s); a++) out[s->id[a]] = s->target[a];
}

void fm_morph_phases(const fm_morph_state *s, uint8_t *out)
{
    for (int64_t a = 0; a < fm_morph_slots(s); a++) out[s->id[a]] = s->phase[a]; /* slot order in, id order out */
}

/* out[i] = c + scale * M * rel[i] for the four vertices (M row-major, NULL = identity). */
static void place_tet(const float *c, double scale, const double *mat, const float *rel, float *out)
{
    for (int i = 0; i < 4; i++) {
        const float *r = rel + 3 * i;
        for (int k = 0; k < 3; k++) {
            double x = mat ? mat[3 * k] * r[0] + mat[3 * k + 1] * r[1] + mat[3 * k + 2] * r[2] : r[k];
            out[3 * i + k] = (float)(c[k] + scale * x);
        }
    }
}

/* Target tet slot's vertices relative to its centroid, in the agent's vertex order. */
static void target_relative(const fm_morph_model *m, int64_t slot, const uint8_t *perm, float *rel)
{
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++)
            rel[3 * i + k] = m->tgt_f[12 * slot + 3 * perm[i] + k] - m->tgt_c[k][slot];
}

/* A moving target's tet (m->motion) for slot a's agent, in its vertex order, at the state's time. */
static void moving_target_tet(const fm_morph_model *m, const fm_morph_state *s, int64_t a, double out[12])
{
    double t[12], c[3];
    fm_morph_motion_tet(m, s->motion_now, s->target[a], t, c);
    const uint8_t *perm = fm_even_permutations[s->perm[a]];
    for (int i = 0; i < 4; i++) memcpy(out + 3 * i, t + 3 * perm[i], 3 * sizeof(double));
}

/* A moving target (issue 38): the homing tet's shape takes on the target tet's deformation (its
 * vertices relative to its centroid now, less at rest) by the fraction u of the flight, at the tet's
 * scale, so it lands on the deformed tet exactly as the static one lands on the rest tet. */
static void add_deformation(const fm_morph_model *m, const fm_morph_state *s, int64_t a, double u, double scale, float *out)
{
    double now[12], c[3] = {0, 0, 0};
    moving_target_tet(m, s, a, now);
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++) c[k] += 0.25 * now[3 * i + k];
    float rest[12];
    target_relative(m, s->target[a], fm_even_permutations[s->perm[a]], rest);
    for (int j = 0; j < 12; j++) out[j] = (float)(out[j] + u * scale * (now[j] - c[j % 3] - rest[j]));
}

/* Phase 2 shape (FM §6): A(t) on the shrunk tet for the first morph_fraction of the flight, then
 * the shrunk target tet enlarges to full size as it reaches its place. */
static void homing_tet(const fm_morph_model *m, const fm_morph_state *s, int64_t a, double time, float *out)
{
    const fm_scene_def *def = &m->def;
    const int32_t i = s->id[a];
    float rest[12];
    fm_morph_state_rest_tet(s, a, rest);
    double launch = (double)i / m->launch_rate, tf = s->tf[a];
    double u = tf > 0 ? (time - s->t2[a]) / tf : 1.0;
    u = u < 0 ? 0 : u > 1 ? 1 : u;
    const float c[3] = {s->p[0][a], s->p[1][a], s->p[2][a]};
    double um = def->morph_fraction;
    float rel[12];
    target_relative(m, s->target[a], fm_even_permutations[s->perm[a]], rel);
    if (u < um) {
        double full[9], mat[9];
        fm_morph_affine(rest, rel, full);
        fm_morph_matrix(s->morph + FM_MORPH_FLOATS * a, s->morph_safe[a], full, u / um, mat);
        place_tet(c, fm_shrink_scale(def, time - launch), mat, rest, out);
        return;
    }
    double sm = fm_shrink_scale(def, s->t2[a] + um * tf - launch), e = um < 1 ? (u - um) / (1 - um) : 1;
    place_tet(c, sm + e * (1 - sm), NULL, rel, out);
}

/* A moving target (issue 38), over what agent_tet wrote for a static one: an arrived tet is the
 * target tet where it is now; a homing one takes on its deformation by the fraction u of its flight,
 * at homing_tet's scale then. */
static void ride_moving_target(const fm_morph_model *m, const fm_morph_state *s, int64_t a, float *out)
{
    if (s->phase[a] == FM_PHASE_ARRIVED) {
        double t[12];
        moving_target_tet(m, s, a, t);
        for (int j = 0; j < 12; j++) out[j] = (float)t[j];
        return;
    }
    if (s->phase[a] != FM_PHASE_HOMING) return;
    const fm_scene_def *def = &m->def;
    const double launch = (double)s->id[a] / m->launch_rate, tf = s->tf[a], um = def->morph_fraction;
    double u = tf > 0 ? (s->time - s->t2[a]) / tf : 1.0;
    u = u < 0 ? 0 : u > 1 ? 1 : u;
    const double sm = fm_shrink_scale(def, s->t2[a] + um * tf - launch);
    const double scale = u < um ? fm_shrink_scale(def, s->time - launch) : sm + (um < 1 ? (u - um) / (1 - um) : 1) * (1 - sm);
    add_deformation(m, s, a, u, scale, out);
}

/* An agent's tet in any phase but phase 1 (the synthesis kernel, kernel_synth.h, has those). */
static void agent_tet(const fm_morph_model *m, const fm_morph_state *s, int64_t a, float *out)
{
    switch (s->phase[a]) {
    case FM_PHASE_WAITING: /* at rest: the store's p and rest_rel are the model's, as on P ranks */
        fm_morph_waiting_tet(m, s->id[a], out);
        break;
    case FM_PHASE_HOMING:
        homing_tet(m, s, a, s->time, out);
        break;
    default: { /* arrived: exactly the target tet, in this agent's vertex order */
        const uint8_t *perm = fm_even_permutations[s->perm[a]];
        for (int i = 0; i < 4; i++) memcpy(out + 3 * i, m->tgt_f + 12 * s->target[a] + 3 * perm[i], 3 * sizeof(float));
    }
    }
}

void fm_morph_waiting_tet(const fm_morph_model *m, int64_t id, float out[12])
{
    const float c[3] = {m->src_c[0][id], m->src_c[1][id], m->src_c[2][id]};
    place_tet(c, 1.0, NULL, m->src_rel + 12 * id, out);
}

/* The store's tets, written at 12 id (by_slot 0) or at 12 slot (by_slot 1). */
static void store_tets(const fm_morph_model *m, const fm_morph_state *s, int by_slot, float *out)
{
    fm_synth_view flying = {{s->p[0], s->p[1], s->p[2]}, {0}, s->id, s->time, m->launch_rate, m->def.shrink,
                            m->def.shrink_time, by_slot};
    for (int j = 0; j < 12; j++) flying.rest[j] = s->rest_rel[j];
    if (m->motion) fm_morph_motion_prepare(m, s->motion_now, s->time); /* serial, before the threads read it */
    const int64_t slots = fm_morph_slots(s), blocks = (slots + FM_BLOCK - 1) / FM_BLOCK;
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t b = 0; b < blocks; b++) {
        int64_t begin = b * FM_BLOCK, end = FM_MIN((b + 1) * FM_BLOCK, slots);
        fm_kernel_flying_tets(&flying, s->phase, FM_PHASE_FLYING, begin, end, out);
        for (int64_t a = begin; a < end; a++)
            if (s->phase[a] != FM_PHASE_FLYING) agent_tet(m, s, a, out + fm_synth_place(&flying, a));
        for (int64_t a = begin; a < end && m->motion; a++) ride_moving_target(m, s, a, out + fm_synth_place(&flying, a));
    }
}

/* Slot order in, id order out: each tet is written where its agent id says. */
void fm_morph_tet_vertices(const fm_morph_model *m, const fm_morph_state *s, float *out) { store_tets(m, s, 0, out); }

void fm_morph_tet_vertices_by_slot(const fm_morph_model *m, const fm_morph_state *s, float *out) { store_tets(m, s, 1, out); }

fm_status fm_morph_own_room(const fm_morph_state *s, float **own, int64_t *capacity, fm_error *err)
{
    if (fm_morph_slots(s) <= *capacity) return FM_OK;
    fm_free(*own);
    *own = fm_alloc(sizeof(float) * 12 * (size_t)s->capacity);
    *capacity = *own ? s->capacity : 0;
    return *own ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for the tets of %lld agents", (long long)s->capacity);
}
