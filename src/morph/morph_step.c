/* fm_morph_step: one time step of the tetra flock morph (FM §5).
 *
 * The pipeline, in order:
 *   0. re-sort      every FM_RESORT_INTERVAL steps, the in-flight agents by position (resort.c)
 *   1. launch       agents whose launch time has come leave the source, in D1 order (eq 4)
 *   2. prepare      the style-field grid for this time (if baked and time-varying); the MDE
 *                   neighbour grid over the flying agents (counting sort)
 *   3. velocities   phase 1: V_grn = omega1 V_g (eq 3, with the path-width pull) + omega2 V_l
 *                   (eqs 5-6); the look-ahead test and V_oa (eqs 7-8); plus V_la from MDE (§5.4).
 *                   Phase 2 with avoidance on: aimed at the target, then eqs 7-8.
 *   4. move         phase 1 integrates and tests the phase switch; phase 2 flies its straight
 *                   line in closed form (eq 9), after a closed-form blend from the phase-1
 *                   velocity (phase2.blend_time, issue 38), or integrates when steered; arrivals
 *   5. hand-out     agents that entered phase 2 take the next target tet in D2 order, in
 *                   agent-id order (serial)
 *   6. morph setup  each new phase-2 agent gets its correspondence and A = RS (§6)
 * Stages 3, 4 and 6 run over fixed blocks of the active range (sim.h) on OpenMP threads. Stage 3 only reads
 * positions and stage 4 only moves an agent itself, with a barrier between them, so every agent
 * sees the same neighbours whatever the thread count; per-block counts are combined in block
 * order. */
#include "morph.h"
#include "kernels.h"
#include "kernel_avoid.h"
#include "kernel_detour.h"
#include "kernel_mde.h"

#include <math.h>
#include <stdlib.h>

/* The kernels name the phases themselves (kernels.h); they must be the engine's. */
_Static_assert((int)FM_KERNEL_FLYING == (int)FM_PHASE_FLYING, "kernel phase FLYING");
_Static_assert((int)FM_KERNEL_HOMING == (int)FM_PHASE_HOMING, "kernel phase HOMING");
_Static_assert((int)FM_KERNEL_ARRIVED == (int)FM_PHASE_ARRIVED, "kernel phase ARRIVED");

/* The agents launched once this step's launch is done: agent id i launches at i / rate. */
static int64_t due_agents(const fm_morph_model *m, const fm_morph_state *s)
{
    const int64_t due = (int64_t)floor(m->launch_rate * s->time) + 1;
    return FM_MAX(FM_MIN(due, s->n), s->launched);
}

/* Waiting agents are the slots from active_end on, in id order: launching moves the boundary (on P
 * ranks each rank takes its share: a failure to make room for it is every rank's). */
static fm_status launch_due_agents(const fm_morph_model *m, fm_morph_state *s)
{
    const int64_t due = due_agents(m, s);
    if (due <= s->launched) return FM_OK;
    int64_t count = due - s->launched;
    if (s->dist) {
        fm_status st = fm_morph_dist_launch(m, s, due, &s->dist_error);
        if (st != FM_OK) return st;
    } else {
        for (int64_t a = s->active_end; a < s->active_end + count; a++) s->phase[a] = FM_PHASE_FLYING;
        s->active_end += count;
    }
    s->count[FM_PHASE_WAITING] -= count;
    s->count[FM_PHASE_FLYING] += count;
    s->launched = due;
    return FM_OK;
}

/* Exact signed distance for the avoidance kernel (Embree through fm_obstacles_closest). */
static double exact_distance(const void *ctx, const double p[3], double normal[3])
{
    return fm_obstacles_closest((const fm_obstacles *)ctx, p, NULL, normal);
}

/* d_t from the grid, but exact (Embree) wherever the eq 8 look-ahead decides contact: within the
 * largest tet radius plus two voxels of the surface, since the grid errs by up to a voxel there. */
static fm_obstacle_view obstacle_view(const fm_morph_model *m)
{
    fm_sdf_view sdf = fm_obstacles_sdf(m->obstacles);
    const double *u = m->def.up, len = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    return (fm_obstacle_view){sdf, (float)m->def.k_a, (float)m->def.speed0, exact_distance, m->obstacles,
                              m->max_radius + 2.0f * sdf.voxel, {(float)(u[0] / len), (float)(u[1] / len), (float)(u[2] / len)}};
}

/* Issue 38's detour (kernel_detour.h): the navigation function, the clock's wait, progress of a grid
 * cell, back on the path within two cells, watched within k_a of an obstacle. */
static fm_detour_view detour_view(const fm_morph_model *m)
{
    const fm_nav *n = &m->nav;
    const fm_sdf_view u = {n->u, {n->n[0], n->n[1], n->n[2]}, {n->origin[0], n->origin[1], n->origin[2]}, n->h, INFINITY};
    fm_sdf_view g = u;
    g.d = n->g;
    return (fm_detour_view){u, g, fm_obstacles_sdf(m->obstacles), (float)m->detour_time, n->h, 2 * n->h,
                            (float)m->def.k_a, (float)(m->def.omega1 * m->def.speed0)};
}

static fm_detour_store detour_store(const fm_morph_state *s)
{
    return (fm_detour_store){s->detour_best, s->detour_since, s->detour_on};
}

/* The MDE grid's cell edge: at least d_min (the search reaches one cell), and no smaller than the
 * agents' spacing at rest, cbrt(source volume / n). With cells much smaller than the spacing, almost
 * every cell holds one agent or none and each of an agent's 9 rows is a random place in the table:
 * a cache miss each, whatever the store's order. With cells about the spacing, agents next to each
 * other in the (re-sorted) store share rows, and the walk trims the rows to those within d_min. */
float fm_morph_mde_cell(const fm_morph_model *m)
{
    double spacing = cbrt(m->info.source_volume / (double)m->n);
    return (float)fmax(m->def.d_min, spacing);
}

/* Stage 2: the neighbour grid over this step's flying agents, and the halo's `ghosts` after them
 * (their member flags already set). */
static void build_neighbour_grid(const fm_morph_model *m, fm_morph_state *s, int64_t ghosts)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->active_end; a++) s->member[a] = s->phase[a] == FM_PHASE_FLYING;
    fm_grid_build(&s->grid, (const float *const *)s->p, s->member, s->active_end + ghosts, fm_morph_mde_cell(m), s->threads);
}

/* Avoidance leaves d_t and R_X per agent for the contact step. The store borrows the re-sort's
 * scratch for them (16 bytes per agent, idle once the step's re-sort is done), so they cost no
 * memory. */
static fm_obstacle_scratch obstacle_scratch(const fm_morph_state *s)
{
    float *d_grid = s->sort_scratch;
    return (fm_obstacle_scratch){d_grid, d_grid + s->capacity};
}

static fm_radius_view radius_view(const fm_morph_model *m, const fm_morph_state *s)
{
    return (fm_radius_view){s->rest_radius, s->id, (float)m->def.shrink, (float)m->def.shrink_time, m->launch_rate};
}

/* MDE (FM §5.4): V_la gathered from the grid's neighbours and added to the flying agents. */
static int64_t add_mde(const fm_morph_model *m, fm_morph_state *s, int64_t begin, int64_t end)
{
    const fm_scene_def *def = &m->def;
    float push = (float)(def->mde_speed > 0 ? def->mde_speed : def->speed0);
    int64_t needed = fm_kernel_mde(&s->grid, (const float *const *)s->p, s->member, s->id, begin, end, (float)def->d_min,
                                   push, s->vla, s->mde_needed);
    for (int64_t a = begin; a < end; a++)
        if (s->member[a]) s->v[0][a] += s->vla[0][a], s->v[1][a] += s->vla[1][a], s->v[2][a] += s->vla[2][a];
    return needed;
}

static double smoothstep(double u) { return u <= 0 ? 0 : u >= 1 ? 1 : u * u * (3 - 2 * u); }

/* How much of omega2 V_l agent id at (x, y, z) keeps at time t (issue 38): near the target,
 * smoothstep(d / D), d its distance outside the switch sphere and D style.fade_distance (1 beyond D,
 * 0 on and inside the sphere); late, after T = style.fade_time of flight, times 1 - smoothstep(age / T
 * - 1) (0 from 2T on). Strong fields (FM Table I's creatures) otherwise hold a few per cent of the
 * flock for good in eddies where V_l cancels the global velocity. In double, one agent at a time:
 * the same bits at any thread count, SIMD level and rank count. */
static float field_fade(const fm_morph_model *m, const double sphere_c[3], float x, float y, float z, int64_t id, double t)
{
    double f = 1;
    if (m->field_fade > 0) {
        const double dx = (double)x - sphere_c[0], dy = (double)y - sphere_c[1], dz = (double)z - sphere_c[2];
        f = smoothstep((sqrt(dx * dx + dy * dy + dz * dz) - m->sphere_r) / m->field_fade);
    }
    if (m->field_fade_time > 0) { /* in flight since id / launch_rate (due_agents) */
        const double late = (t - (double)id / m->launch_rate) / m->field_fade_time - 1;
        if (late > 0) f *= 1 - smoothstep(late);
    }
    return (float)f;
}

/* omega2 V_l (FM eq 6), faded near the target: the fields' kernel writes V_l into the MDE scratch
 * (free until add_mde), then each flying agent adds its faded share; where the fade is 1 the sum is
 * bit for bit the unfaded one. */
static void add_faded_fields(const fm_morph_model *m, fm_morph_state *s, int64_t begin, int64_t end)
{
    float *const *vl = s->vla, *const *v = s->v, *const *p = s->p;
    double c[3] = {m->sphere_c[0], m->sphere_c[1], m->sphere_c[2]};
    for (int k = 0; k < 3 && m->motion; k++) c[k] += s->motion_now->offset[k]; /* the sphere travels with the target */
    for (int64_t a = begin; a < end; a++) vl[0][a] = vl[1][a] = vl[2][a] = 0.0f;
    fm_fields_add_block(s->fields, (const float *const *)p, s->phase, begin, end, s->time, (float)m->def.omega2, vl);
    for (int64_t a = begin; a < end; a++) {
        if (s->phase[a] != FM_PHASE_FLYING) continue;
        const float f = field_fade(m, c, p[0][a], p[1][a], p[2][a], s->id[a], s->time);
        v[0][a] += f * vl[0][a], v[1][a] += f * vl[1][a], v[2][a] += f * vl[2][a];
    }
}

/* A moving target (issue 38): each homing agent's target centroid at the step's end (prepared by
 * fm_morph_step) in the MDE scratch, idle between the fields and MDE and after MDE; the homing
 * kernels read it by slot (target NULL). */
static const float *const *moving_goals(const fm_morph_model *m, fm_morph_state *s, int64_t begin, int64_t end)
{
    for (int64_t a = begin; a < end; a++) {
        if (s->phase[a] != FM_PHASE_HOMING) continue;
        double t[12], c[3];
        fm_morph_motion_tet(m, s->motion_now, s->target[a], t, c);
        for (int k = 0; k < 3; k++) s->vla[k][a] = (float)c[k];
    }
    return (const float *const *)s->vla;
}

/* Stage 3 for one block: velocities from positions at the start of the step (FM eq 8). */
static void velocity_block(const fm_morph_model *m, fm_morph_state *s, int64_t begin, int64_t end, block_counts *bc)
{
    const fm_scene_def *def = &m->def;
    const fm_morph_motion_now *now = s->motion_now;
    float *const *key_q = now && now->key_q[0] ? now->key_q : m->key_q, *const *key_f = now && now->key_q[0] ? now->key_f : m->key_f;
    const fm_path_view path = {{key_q[0], key_q[1], key_q[2]}, {key_f[0], key_f[1], key_f[2]},
                               m->key_count, (float)(0.5 * def->path_width), (float)def->path_attraction};
    const float *const *p = (const float *const *)s->p;
    const float dt = (float)m->dt;
    fm_kernel_global_velocity(&path, p, s->phase, begin, end, (float)(def->omega1 * def->speed0), s->v);
    const int detours = m->obstacles && m->detour_time > 0;
    fm_detour_view dv;
    if (detours) { /* V_g of the agents on a detour: down the navigation function instead of f_i */
        dv = detour_view(m);
        fm_kernel_detour_velocity(&dv, p, s->phase, detour_store(s), begin, end, s->v);
    }
    if (s->fields && (m->field_fade > 0 || m->field_fade_time > 0)) add_faded_fields(m, s, begin, end);
    else if (s->fields) fm_fields_add_block(s->fields, p, s->phase, begin, end, s->time, (float)def->omega2, s->v);
    fm_obstacle_view o;
    fm_radius_view r;
    const fm_obstacle_scratch sc = obstacle_scratch(s);
    int steer_phase2 = m->obstacles && def->avoid_in_phase2;
    bc->clearance = INFINITY;
    if (m->obstacles) { /* V_grn -> V_oa where the look-ahead collides (eqs 7-8) */
        o = obstacle_view(m), r = radius_view(m, s);
        bc->clearance = fm_kernel_avoid(&o, &r, p, s->v, s->phase, FM_PHASE_FLYING, begin, end, s->time, dt, sc);
        if (detours) bc->detours = fm_kernel_detour_track(&dv, &path, sc, p, s->phase, detour_store(s), begin, end, s->time);
    }
    if (steer_phase2) {
        const int64_t *target = m->motion ? NULL : s->target;
        fm_kernel_homing_aim(p, s->v, s->phase, target, m->motion ? moving_goals(m, s, begin, end) : (const float *const *)m->tgt_c,
                             s->t2, begin, end, (float)def->speed0, s->time, dt, def->blend_time);
        fm_kernel_avoid(&o, &r, p, s->v, s->phase, FM_PHASE_HOMING, begin, end, s->time, dt, sc);
    }
    bc->flying = 0;
    for (int64_t a = begin; a < end; a++) bc->flying += s->phase[a] == FM_PHASE_FLYING;
    bc->mde = def->d_min > 0 ? add_mde(m, s, begin, end) : 0; /* + V_la */
    if (m->obstacles) fm_kernel_contact(&o, sc, p, s->v, s->phase, FM_PHASE_FLYING, begin, end, dt);
    if (steer_phase2) fm_kernel_contact(&o, sc, p, s->v, s->phase, FM_PHASE_HOMING, begin, end, dt);
}

/* Stage 4 for one block: each agent moves only itself. */
static void move_block(const fm_morph_model *m, fm_morph_state *s, int64_t begin, int64_t end, double t_end,
                       block_counts *bc)
{
    fm_sphere_view sphere = {{m->sphere_c[0], m->sphere_c[1], m->sphere_c[2]}, m->sphere_r};
    if (m->motion) /* the switch sphere travels with target_motion.path */
        for (int k = 0; k < 3; k++) sphere.c[k] = (float)(m->sphere_c[k] + s->motion_now->offset[k]);
    fm_sdf_view target_sdf;
    if (m->target_sdf) target_sdf = fm_obstacles_sdf(m->target_sdf);
    const float *const *v = (const float *const *)s->v, *const *tgt_c = (const float *const *)m->tgt_c;
    const int64_t *target = s->target;
    if (m->motion) tgt_c = moving_goals(m, s, begin, end), target = NULL;
    bc->entered = fm_kernel_integrate_flying(s->p, v, s->phase, begin, end, (float)m->dt, sphere,
                                             m->target_sdf ? &target_sdf : NULL,
                                             (float)m->def.switch_distance, s->entered);
    if (m->obstacles && m->def.avoid_in_phase2)
        bc->arrived = fm_kernel_homing_steered(s->p, v, s->phase, target, tgt_c, begin, end, (float)m->dt);
    else
        bc->arrived = fm_kernel_homing(s->p, s->v, s->phase, target, tgt_c, (const float *const *)s->p2,
                                       s->t2, s->tf, begin, end, t_end, m->def.blend_time);
}

/* Slot a takes target slot `slot` and enters phase 2 at t_end. */
static void take_target(const fm_morph_model *m, fm_morph_state *s, int64_t a, int64_t slot, double t_end)
{
    s->target[a] = slot;
    s->phase[a] = FM_PHASE_HOMING;
    s->t2[a] = (float)t_end;
    double d2 = 0, now[12], c[3];
    if (m->motion) fm_morph_motion_tet(m, s->motion_now, slot, now, c); /* where it is at t_end */
    for (int k = 0; k < 3; k++) {
        s->p2[k][a] = s->p[k][a];
        double d = (double)(m->motion ? (float)c[k] : m->tgt_c[k][slot]) - s->p[k][a];
        d2 += d * d;
    }
    s->tf[a] = (float)(sqrt(d2) / m->def.speed0); /* eq 9 */
}

static int by_value(const void *x, const void *y)
{
    const uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return (a > b) - (a < b);
}

/* This step's entries as (id << 32 | slot), in id order, in the re-sort's idle key scratch. */
static int64_t entries_by_id(fm_morph_state *s, const block_counts *bc, int64_t blocks, uint64_t *key)
{
    int64_t count = 0;
    for (int64_t b = 0; b < blocks; b++) {
        if (bc[b].entered == 0) continue;
        int64_t begin, end;
        fm_active_block(s, b, &begin, &end);
        for (int64_t a = begin; a < end; a++)
            if (s->entered[a]) key[count++] = (uint64_t)(uint32_t)s->id[a] << 32 | (uint64_t)a;
    }
    qsort(key, (size_t)count, sizeof *key, by_value);
    return count;
}

static int by_id(const void *x, const void *y)
{
    const int32_t a = *(const int32_t *)x, b = *(const int32_t *)y;
    return (a > b) - (a < b);
}

/* Stage 5 (FM §5.5): the k-th agent to enter phase 2 takes target slot k (D2 order); the agents
 * that enter in one step, of all ranks, take theirs in agent-id order, so the hand-out does not
 * depend on where an agent is stored. */
static fm_status hand_out_targets(const fm_morph_model *m, fm_morph_state *s, const block_counts *bc, int64_t blocks,
                                  double t_end)
{
    uint64_t *key = (uint64_t *)s->sort_keys; /* 2 uint32 a slot: room for a key a slot */
    const int64_t count = entries_by_id(s, bc, blocks, key);
    if (!s->dist) {
        for (int64_t k = 0; k < count; k++) take_target(m, s, (int64_t)(key[k] & 0xffffffffu), s->next_slot + k, t_end);
        s->next_slot += count;
        return FM_OK;
    }
    int32_t *mine = s->sort_slots, *all = NULL; /* idle after the re-sort too */
    for (int64_t k = 0; k < count; k++) mine[k] = (int32_t)(key[k] >> 32);
    int64_t total = 0;
    fm_status st = fm_dist_allgather_i32(s->dist, mine, count, &all, &total, &s->dist_error);
    if (st != FM_OK) return st;
    if (total > 0) qsort(all, (size_t)total, sizeof *all, by_id); /* all is NULL when no rank has an entry */
    for (int64_t k = 0; k < count; k++) { /* its place among every rank's entries */
        const int32_t *at = bsearch(&mine[k], all, (size_t)total, sizeof *all, by_id);
        take_target(m, s, (int64_t)(key[k] & 0xffffffffu), s->next_slot + (at - all), t_end);
    }
    s->next_slot += total;
    fm_free(all);
    return FM_OK;
}

static int64_t setup_morphs(const fm_morph_model *m, fm_morph_state *s, int64_t begin, int64_t end)
{
    int64_t fallbacks = 0;
    for (int64_t a = begin; a < end; a++) {
        if (!s->entered[a]) continue;
        const int64_t slot = s->target[a];
        float src[12], dst[12];
        fm_morph_state_rest_tet(s, a, src);
        for (int i = 0; i < 12; i++) dst[i] = m->tgt_f[12 * slot + i] - m->tgt_c[i % 3][slot];
        s->morph_safe[a] = (uint8_t)fm_morph_setup(src, dst,
                                                   s->morph + FM_MORPH_FLOATS * a, &s->perm[a]);
        fallbacks += s->morph_safe[a];
    }
    return fallbacks;
}

const char *const fm_stage_names[FM_STAGE_COUNT] = {"resort", "launch", "fields", "grid", "velocity", "move",
                                                     "handout", "morph"};

/* Adds the time since *t to stage k and restarts *t. */
static void lap(fm_morph_state *s, fm_stage k, double *t)
{
    double now = fm_seconds();
    s->stage_seconds[k] += now - *t;
    *t = now;
}

/* The step's counts, block by block in block order, then (on P ranks) summed over the ranks. */
static void combine_counts(fm_morph_state *s, const block_counts *bc, int64_t blocks)
{
    int64_t sum[6] = {0}; /* entered, arrived, fallbacks, flying, mde, detours */
    float clearance = INFINITY;
    for (int64_t b = 0; b < blocks; b++) {
        sum[0] += bc[b].entered, sum[1] += bc[b].arrived, sum[2] += bc[b].fallbacks;
        sum[3] += bc[b].flying, sum[4] += bc[b].mde, sum[5] += bc[b].detours;
        clearance = fminf(clearance, bc[b].clearance);
    }
    fm_dist_sum_i64(s->dist, sum, 6);
    fm_dist_min_f32(s->dist, &clearance, 1);
    s->count[FM_PHASE_FLYING] -= sum[0];
    s->count[FM_PHASE_HOMING] += sum[0] - sum[1];
    s->count[FM_PHASE_ARRIVED] += sum[1];
    s->morph_fallbacks += sum[2];
    s->flying_agent_steps += sum[3];
    s->mde_agent_steps += sum[4];
    s->detour_agent_steps += sum[5];
    s->min_clearance = fminf(s->min_clearance, clearance);
}

/* On P ranks, before the step proper: the cuts, then the agents that left the slab to their new
 * owners. The cuts follow the agents every step: the morph's flock sweeps along the slab axis, and
 * cuts kept for 8 steps let it pile into the slabs ahead (2 ranks at 3·10^5: 105 000 against
 * 195 000 agents before each re-cut at equal cost per agent; 16 ranks of 10^6 on 16 cores: the
 * busiest rank's work 2.04× the mean). A cut costs a 32 KiB allreduce. */
static fm_status distribute(const fm_morph_model *m, fm_morph_state *s)
{
    fm_morph_dist_rebalance(m, s, due_agents(m, s));
    return fm_morph_dist_migrate(m, s, &s->dist_error);
}

/* Every FM_RESORT_INTERVAL steps, and sooner when the agents launched since the last re-sort (in
 * launch order, appended to the active range) are more than an eighth of it: a launch of many
 * agents at once is then sorted at the next step instead of up to 7 steps later. No result depends
 * on the store's order, so neither does any on when it is sorted. */
static int resort_due(const fm_morph_state *s)
{
    const int64_t active = s->active_end - s->active_begin, unsorted = s->active_end - s->sorted_end;
    return s->step % FM_RESORT_INTERVAL == 0 || 8 * unsorted > active;
}

void fm_morph_step(const fm_morph_model *m, fm_morph_state *s)
{
    const double t_end = (double)(s->step + 1) * m->dt; /* no drift from summing dt */
    if (s->dist_status != FM_OK) return; /* every rank knows: the frame reports it */
    double t = fm_seconds();
    if (s->dist && (s->dist_status = distribute(m, s)) != FM_OK) return;
    if (resort_due(s)) fm_morph_state_resort(m, s);
    lap(s, FM_STAGE_RESORT, &t);
    if ((s->dist_status = launch_due_agents(m, s)) != FM_OK) return;
    const int64_t blocks = fm_active_blocks(s);
    int64_t ghosts = 0;
    if (s->dist && m->def.d_min > 0 && (s->dist_status = fm_morph_dist_ghosts(s, &ghosts, &s->dist_error)) != FM_OK)
        return;
    if (m->motion) fm_morph_motion_prepare(m, s->motion_now, t_end); /* the target at the step's end */
    lap(s, FM_STAGE_LAUNCH, &t);
    block_counts *bc = s->blocks; /* P ranks: after the store made room for this step's agents */
    if (s->fields) fm_fields_prepare(s->fields, s->time, s->threads);
    lap(s, FM_STAGE_FIELDS, &t);
    const double busy_from = t;
    if (m->def.d_min > 0) build_neighbour_grid(m, s, ghosts);
    lap(s, FM_STAGE_GRID, &t);
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t b = 0; b < blocks; b++) {
        int64_t begin, end;
        fm_active_block(s, b, &begin, &end);
        bc[b] = (block_counts){0, 0, 0, 0, 0, INFINITY, 0};
        velocity_block(m, s, begin, end, &bc[b]);
    }
    lap(s, FM_STAGE_VELOCITY, &t);
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t b = 0; b < blocks; b++) {
        int64_t begin, end;
        fm_active_block(s, b, &begin, &end);
        move_block(m, s, begin, end, t_end, &bc[b]);
    }
    lap(s, FM_STAGE_MOVE, &t);
    if (s->dist) fm_morph_dist_add_busy(s, t - busy_from);
    if ((s->dist_status = hand_out_targets(m, s, bc, blocks, t_end)) != FM_OK) return;
    lap(s, FM_STAGE_HANDOUT, &t);
#pragma omp parallel for num_threads(s->threads) schedule(dynamic, 1)
    for (int64_t b = 0; b < blocks; b++) {
        int64_t begin, end;
        fm_active_block(s, b, &begin, &end);
        if (bc[b].entered) bc[b].fallbacks = setup_morphs(m, s, begin, end);
    }
    lap(s, FM_STAGE_MORPH, &t);
    combine_counts(s, bc, blocks);
    if (s->dist) fm_morph_dist_record_load(s);
    s->time = t_end;
    s->step++;
}
