/* fm_flock_step: one time step of the shape-constrained flock (SCF "Local Force Model", "Fuzzy
 * Control Logic", "Global Path Control").
 *
 * The pipeline, from t to t + dt:
 *   1. target     a deforming target's vertices at t + dt; each destination follows its triangle
 *                 (barycentric coordinates), its velocity by difference
 *   2. leaders    each agent's virtual leader at t + dt: its path R~ (eq 12) at its own eased, delayed
 *                 arc-length fraction (fm_flock_leader), which ends on the destination
 *   3. prepare    the Kalman covariance and gain (shared; with R over the run each agent's own
 *                 is advanced in stage 4); the style-field grid; the neighbour grid
 *                 over the agents not bound (counting sort, cell = the largest perception radius)
 *   4. forces     for agents under forces (FM_PHASE_FLYING): the boids steering, in the grid's
 *                 order (each agent its own neighbours, so the order changes no bit); then the fuzzy weights of their distance
 *                 to the destination (the static or the tracking strategy's curves) weigh the boids
 *                 steering, damping and external forces, each bounded by MaxForce (their
 *                 acceleration u), and the homing force of eq 9 from the Kalman posterior, bounded
 *                 by MaxForce after its weight; the boids get what homing leaves of MaxForce
 *   5. move       forces: v' = v + a dt, |v'| <= MaxSpeed, x += (v + v') dt / 2 (x + v dt + a dt^2 / 2
 *                 as eq 9 assumes, unless MaxSpeed cuts), then stepped steering once within
 *                 arrival.radius; stepped: turn toward the destination at a bounded rate and close
 *                 in at a pace that slows with the distance, at most MaxSpeed, binding within
 *                 bind_distance; bound: on the destination, or floating around it; then the
 *                 orientation
 * Stages 4 and 5 run over fixed blocks of agents on OpenMP threads with a barrier between them:
 * stage 4 only reads positions and velocities, stage 5 only moves an agent itself, so every agent
 * sees the same neighbours whatever the thread count; per-block counts are combined in block order. */
#include "flock.h"
#include "kernel_forces.h"
#include "kernel_leader.h"
#include "kernel_sdf.h"

#include <math.h>
#include <string.h>

static const double TWO_PI = 6.283185307179586;

/* Stage 1: destinations at time t (deforming targets only; a static target keeps dest0). On P ranks
 * those of this rank's agents, by id. */
static void update_destinations(const fm_flock_model *m, fm_flock_state *s, double t)
{
    fm_flock_target_vertices(&m->target, &m->def.flock, t, s->mesh_v);
    if (!s->id) fm_samples_eval(&m->target.dest, s->mesh_v, m->target.mesh.tri, s->eval);
    const float inv_dt = (float)(1.0 / m->dt);
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->slots; a++) {
        if (s->phase[a] == FM_FLOCK_ELSEWHERE) continue;
        if (s->id) fm_flock_destination_of(m, s, s->id[a], s->eval + 3 * a);
        for (int k = 0; k < 3; k++) {
            float now = s->eval[3 * a + k];
            s->dest_v[k][a] = (now - s->dest[k][a]) * inv_dt;
            s->dest[k][a] = now;
        }
    }
}

/* Stage 2 for agent a: its leader at time t, on its own eased path fraction u (fm_flock_leader;
 * r = R(u)), and its velocity by difference. */
static void leader_of(const fm_flock_model *m, fm_flock_state *s, double t, int64_t a)
{
    const double inv_dt = 1.0 / m->dt;
    double f;
    const double u = fm_flock_leader(m, (const float *const *)s->prm.start, a, t, &f);
    double z[3];
    if (u >= 1) {
        for (int k = 0; k < 3; k++) z[k] = s->dest[k][a];
    } else {
        double r[3];
        const double c1[3] = {s->prm.start[0][a], s->prm.start[1][a], s->prm.start[2][a]};
        const double c2[3] = {s->dest[0][a], s->dest[1][a], s->dest[2][a]};
        fm_bspline_eval_table(&m->path, u, r);
        fm_path_map_blend(r, m->o1, m->o2, c1, c2, u, f, z);
    }
    for (int k = 0; k < 3; k++) {
        s->leader_v[k][a] = (float)((z[k] - s->leader[k][a]) * inv_dt);
        s->leader[k][a] = (float)z[k];
    }
}

/* What the leaders' lanes (kernel_leader.h) need of the model at time t. */
static fm_leader_view leader_view(const fm_flock_model *m, double t)
{
    fm_leader_view w = {t, 1.0 / m->dt, m->path_time, {m->ease_axis[0], m->ease_axis[1], m->ease_axis[2]}, m->ease_lo,
                        m->ease_inv_range, m->ease_spread, m->ease_in, m->ease_out,
                        1.0 / (1.0 - 0.5 * (m->ease_in + m->ease_out)), m->def.flock.reform, m->path.arc,
                        FM_BSPLINE_ARC_SAMPLES, {0}, {0}, 0};
    for (int k = 0; k < 3; k++) {
        w.o1[k] = m->o1[k], w.o2[k] = m->o2[k];
        w.oo += (m->o2[k] - m->o1[k]) * (m->o2[k] - m->o1[k]); /* as fm_path_map_blend sums it */
    }
    return w;
}

/* Stage 2 for one block: whole groups of agents in SIMD lanes where there is a path (the same bits),
 * the agents on an ease ramp and the rest one by one. */
static void leaders_block(const fm_flock_model *m, fm_flock_state *s, double t, int64_t begin, int64_t end)
{
    int64_t a = begin, left[FM_BLOCK], left_count = 0;
    if (m->path_time > 0 && end - begin <= FM_BLOCK) {
        const fm_leader_view w = leader_view(m, t);
        a = fm_kernel_leaders(&w, s->phase, FM_FLOCK_ELSEWHERE, (const float *const *)s->prm.start,
                              (const float *const *)s->dest, s->leader, s->leader_v, begin, end, left, &left_count);
    }
    for (int64_t i = 0; i < left_count; i++) leader_of(m, s, t, left[i]);
    for (; a < end; a++)
        if (s->phase[a] != FM_FLOCK_ELSEWHERE) leader_of(m, s, t, a); /* another rank's (flock_dist.c) */
}

static float distance_to_destination(const fm_flock_state *s, int64_t a)
{
    float d[3] = {s->dest[0][a] - s->p[0][a], s->dest[1][a] - s->p[1][a], s->dest[2][a] - s->p[2][a]};
    return sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

/* Obstacles (shared with the tetra morph, beyond SCF, which has none): within k_a of an obstacle an
 * agent is pushed out along grad d_t, up to its MaxForce at the surface. */
static void add_obstacle_push(const fm_flock_model *m, fm_flock_state *s, int64_t a, float *acc)
{
    fm_sdf_view sdf = fm_obstacles_sdf(m->obstacles);
    float g[3], k_a = (float)m->def.k_a;
    float d = fm_sdf_sample(&sdf, s->p[0][a], s->p[1][a], s->p[2][a], g);
    if (!(d < k_a)) return;
    float push = s->prm.max_force[a] / (float)m->def.flock.mass * fminf(1.0f, 1.0f - d / k_a);
    for (int k = 0; k < 3; k++) acc[k] += push * g[k];
}

/* |x| <= limit for a 3-vector, by truncation (Reynolds's truncate). */
static void truncate3(float x[3], float limit)
{
    const float len2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    if (len2 > limit * limit)
        for (int k = 0; k < 3; k++) x[k] *= limit / sqrtf(len2);
}

/* R's factor for the agent this step: the curve over its distance d to the destination or over its
 * leader's speed (SCF: a larger R follows the leader more loosely). Over the distance, an agent
 * that has fallen behind its leader counts as no farther than the leader's distance plus the
 * curve's first x: once its leader has arrived it is held as tightly as an agent that close, and
 * closes in at the homing force's pace instead of creeping in under a loose hold. */
static float r_scale(const fm_flock_model *m, const fm_flock_state *s, int64_t a, float d)
{
    if (m->def.flock.kalman_r_over == FM_KALMAN_R_OVER_DISTANCE) {
        const float e[3] = {s->dest[0][a] - s->leader[0][a], s->dest[1][a] - s->leader[1][a], s->dest[2][a] - s->leader[2][a]};
        const float leader_d = sqrtf(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
        return fm_fuzzy_eval(&m->r_scale, fminf(d, leader_d + m->r_scale.d[0]));
    }
    const float lv[3] = {s->leader_v[0][a], s->leader_v[1][a], s->leader_v[2][a]};
    return fm_fuzzy_eval(&m->r_scale, sqrtf(lv[0] * lv[0] + lv[1] * lv[1] + lv[2] * lv[2]));
}

/* The fuzzy-weighted forces besides homing (SCF "Fuzzy Control Logic"), each bounded by MaxForce:
 * the boids steering (already, kernel_boids.h) into s->steer, and u, the acceleration of them all
 * (boids, damping relative to the destination, the fields of eqs 7-8 and obstacles), into s->acc. */
static void other_forces(const fm_flock_model *m, fm_flock_state *s, int64_t a)
{
    const fm_flock_def *f = &m->def.flock;
    const float d = distance_to_destination(s, a), max_accel = s->prm.max_accel[a], inv_mass = (float)(1.0 / f->mass);
    const float w_steer = fm_fuzzy_eval(&m->fuzzy[FM_FUZZY_STEERING], d);
    const float w_damp = fm_fuzzy_eval(&m->fuzzy[FM_FUZZY_DAMPING], d);
    const float w_ext = fm_fuzzy_eval(&m->fuzzy[FM_FUZZY_EXTERNAL], d);
    s->w_homing[a] = fm_fuzzy_eval(&m->fuzzy[FM_FUZZY_HOMING], d);
    if (s->r_scale) s->r_scale[a] = r_scale(m, s, a, d);
    float damp[3], ext[3] = {0, 0, 0}, acc[3];
    for (int k = 0; k < 3; k++) {
        /* the static strategy slows the agent down (SCF: "slowing down the agent nearby its
         * destination"); the tracking one damps its velocity relative to its moving destination
         * (on a static target the two are the same bits: its velocity is 0) */
        damp[k] = -(float)f->damping * (m->tracking ? s->v[k][a] - s->dest_v[k][a] : s->v[k][a]);
        if (s->fields) ext[k] = (float)f->external_gain * s->ext[k][a];
    }
    truncate3(damp, max_accel), truncate3(ext, max_accel);
    for (int k = 0; k < 3; k++) {
        s->steer[k][a] *= w_steer * inv_mass;
        acc[k] = s->steer[k][a] + w_damp * damp[k] + w_ext * ext[k];
    }
    if (m->obstacles) add_obstacle_push(m, s, a, acc);
    for (int k = 0; k < 3; k++) s->acc[k][a] = acc[k];
}

/* Homing h first, the boids with what is left of MaxForce (Reynolds's prioritised allocation): an
 * agent far from its leader, whose h reaches MaxForce, is not held there by its neighbours. */
static void combine_forces(fm_flock_state *s, int64_t a)
{
    const float h[3] = {s->ext[0][a], s->ext[1][a], s->ext[2][a]};
    float b[3] = {s->steer[0][a], s->steer[1][a], s->steer[2][a]};
    const float budget = fmaxf(0.0f, s->prm.max_accel[a] - sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]));
    truncate3(b, budget);
    for (int k = 0; k < 3; k++) s->acc[k][a] += h[k] + b[k] - s->steer[k][a];
}

/* Stage 4a: the boids steering F_steer of every agent under forces, into s->steer, in the grid's
 * order (fm_kernel_boids_listed: SIMD over the candidates, without meeting every neighbourhood cold;
 * its sums are exact, so the order gives the same bits). Every agent under forces is listed; each
 * writes only its own entries, so the chunks may go to the threads in any order. */
static void boids_pass(const fm_flock_model *m, fm_flock_state *s)
{
    const fm_flock_params *q = &s->prm;
    const float top_speed = (float)fmax(m->def.flock.max_speed[0], m->def.flock.max_speed[1]);
    const fm_boids_view boids = {{q->radius[0], q->radius[1], q->radius[2]}, {q->cos_half[0], q->cos_half[1], q->cos_half[2]},
                                 {q->weight[0], q->weight[1], q->weight[2]}, q->max_speed, q->max_force, m->max_radius,
                                 top_speed};
    const int64_t entries = s->grid.count, chunks = (entries + FM_BLOCK - 1) / FM_BLOCK;
#pragma omp parallel for num_threads(s->threads) schedule(dynamic, 1)
    for (int64_t c = 0; c < chunks; c++)
        fm_kernel_boids_listed(&s->grid, &boids, s->phase, FM_PHASE_FLYING, c * FM_BLOCK, FM_MIN((c + 1) * FM_BLOCK, entries),
                               s->steer);
}

static fm_weight_curve curve_of(const fm_fuzzy *c) { return (fm_weight_curve){c->count, c->d, c->w, c->slope}; }

/* What the forces' lanes (kernel_forces.h) need of the model and the store. */
static void forces_lanes(const fm_flock_model *m, fm_flock_state *s, fm_forces_view *w, fm_forces_arrays *x)
{
    const fm_flock_def *f = &m->def.flock;
    *w = (fm_forces_view){curve_of(&m->fuzzy[FM_FUZZY_STEERING]), curve_of(&m->fuzzy[FM_FUZZY_DAMPING]),
                          curve_of(&m->fuzzy[FM_FUZZY_EXTERNAL]), curve_of(&m->fuzzy[FM_FUZZY_HOMING]), curve_of(&m->r_scale),
                          f->kalman_r_over == FM_KALMAN_R_OVER_DISTANCE, m->tracking, s->fields != NULL,
                          (float)(1.0 / f->mass), (float)f->damping, (float)f->external_gain};
    *x = (fm_forces_arrays){.phase = s->phase, .sel = FM_PHASE_FLYING, .max_accel = s->prm.max_accel,
                            .w_homing = s->w_homing, .r_scale = s->r_scale};
    for (int k = 0; k < 3; k++) {
        x->p[k] = s->p[k], x->v[k] = s->v[k], x->dest[k] = s->dest[k], x->dest_v[k] = s->dest_v[k];
        x->leader[k] = s->leader[k], x->leader_v[k] = s->leader_v[k];
        x->steer[k] = s->steer[k], x->ext[k] = s->ext[k], x->acc[k] = s->acc[k];
    }
}

/* The obstacles' push on an agent whose other forces the lanes gave (other_forces adds it last). */
static void push_from_obstacles(const fm_flock_model *m, fm_flock_state *s, int64_t a)
{
    float acc[3] = {s->acc[0][a], s->acc[1][a], s->acc[2][a]};
    add_obstacle_push(m, s, a, acc);
    for (int k = 0; k < 3; k++) s->acc[k][a] = acc[k];
}

/* Stage 4b for one block: the acceleration of every agent under forces (FM_PHASE_FLYING); whole
 * groups of agents in SIMD lanes (the same bits), the rest one by one. */
static void forces_block(const fm_flock_model *m, fm_flock_state *s, int64_t begin, int64_t end)
{
    const float *const *p = (const float *const *)s->p, *const *v = (const float *const *)s->v;
    if (s->fields) {
        for (int k = 0; k < 3; k++) memset(s->ext[k] + begin, 0, sizeof(float) * (size_t)(end - begin));
        fm_fields_add_block(s->fields, p, s->phase, begin, end, s->time, 1.0f, s->ext);
    }
    fm_forces_view w;
    fm_forces_arrays x;
    forces_lanes(m, s, &w, &x);
    int64_t a = fm_kernel_other_forces(&w, &x, begin, end);
    if (m->obstacles)
        for (int64_t b = begin; b < a; b++)
            if (s->phase[b] == FM_PHASE_FLYING) push_from_obstacles(m, s, b);
    for (; a < end; a++)
        if (s->phase[a] == FM_PHASE_FLYING) other_forces(m, s, a);
    /* w_homing F_h / m (eq 9) into ext (read above): the Kalman filter predicts with u = acc and
     * updates with the leader */
    const fm_kalman_agents own = {s->kalman_p, s->r_scale};
    fm_kalman_homing(&s->kalman, s->kalman_p ? &own : NULL, begin, end, s->phase, FM_PHASE_FLYING, p, v, (const float *const *)s->leader,
                     (const float *const *)s->leader_v, s->w_homing, s->prm.max_accel, (const float *const *)s->acc, s->ext);
    for (a = fm_kernel_combine_forces(&x, begin, end); a < end; a++)
        if (s->phase[a] == FM_PHASE_FLYING) combine_forces(s, a);
}

/* Under forces, the paper's kinematics (eq 9 assumes them): for a constant a over the step,
 * v' = v + a dt and x' = x + (v + v') dt / 2 = x + v dt + a dt^2 / 2. MaxSpeed bounds v' before the
 * move, so the agent moves as under the constant acceleration (v' - v) / dt that reaches the bounded
 * v': |x' - x| / dt <= MaxSpeed (|v| and |v'| are), and v' is the velocity it ends the step with.
 * Returns the new phase. */
static uint8_t move_flying(const fm_flock_model *m, fm_flock_state *s, int64_t a, float dt)
{
    float v1[3];
    for (int k = 0; k < 3; k++) v1[k] = s->v[k][a] + s->acc[k][a] * dt;
    truncate3(v1, s->prm.max_speed[a]);
    for (int k = 0; k < 3; k++) {
        s->p[k][a] += 0.5f * (s->v[k][a] + v1[k]) * dt;
        s->v[k][a] = v1[k];
    }
    const float radius = (float)m->def.flock.arrival_radius;
    return radius > 0 && distance_to_destination(s, a) < radius ? FM_PHASE_HOMING : FM_PHASE_FLYING;
}

/* Rotates unit h toward unit d by at most `turn` radians, in their plane; returns the new h. */
static void turn_toward(float h[3], const float d[3], float turn)
{
    float c = h[0] * d[0] + h[1] * d[1] + h[2] * d[2];
    float e[3] = {d[0] - c * h[0], d[1] - c * h[1], d[2] - c * h[2]};
    float elen = sqrtf(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    float angle = acosf(fmaxf(-1.0f, fminf(1.0f, c)));
    if (angle <= turn || !(elen > 1e-6f)) {
        if (angle <= turn || c > 0) memcpy(h, d, 3 * sizeof(float));
        else { /* straight away from it: turn about any axis perpendicular to h */
            float p[3] = {-h[1], h[0], 0};
            if (fabsf(h[2]) > 0.9f) p[0] = 0, p[1] = -h[2], p[2] = h[1];
            float plen = sqrtf(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            for (int k = 0; k < 3; k++) h[k] = cosf(turn) * h[k] + sinf(turn) * p[k] / plen;
        }
        return;
    }
    for (int k = 0; k < 3; k++) h[k] = cosf(turn) * h[k] + sinf(turn) * e[k] / elen;
}

static void bind(fm_flock_state *s, int64_t a, float dt)
{
    for (int k = 0; k < 3; k++) s->v[k][a] = (s->dest[k][a] - s->p[k][a]) / dt, s->p[k][a] = s->dest[k][a];
    s->t_bind[a] = (float)(s->time + dt);
}

/* SCF's stepped steering: "by setting up a local coordinate frame for every one, we rotate and move
 * it in a right pace to navigate it smoothly toward the target position". In the destination's
 * frame the agent's heading turns toward it by at most turn_rate dt, and it closes in at speed
 * min(MaxSpeed, distance / arrival.time, with a finite-time end below) times the cosine left between
 * heading and direction (so a
 * wrong heading turns first and never orbits), binding once within bind_distance or within reach
 * of this step; |v| <= MaxSpeed. Returns the new phase. */
static uint8_t move_stepped(const fm_flock_model *m, fm_flock_state *s, int64_t a, float dt)
{
    const fm_flock_def *f = &m->def.flock;
    float to[3] = {s->dest[0][a] - s->p[0][a], s->dest[1][a] - s->p[1][a], s->dest[2][a] - s->p[2][a]};
    float dist = sqrtf(to[0] * to[0] + to[1] * to[1] + to[2] * to[2]);
    float rel[3] = {s->v[0][a] - s->dest_v[0][a], s->v[1][a] - s->dest_v[1][a], s->v[2][a] - s->dest_v[2][a]};
    float speed = sqrtf(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]);
    if (dist <= (float)f->bind_distance) return bind(s, a, dt), FM_PHASE_ARRIVED;
    float dir[3] = {to[0] / dist, to[1] / dist, to[2] / dist}, h[3];
    for (int k = 0; k < 3; k++) h[k] = speed > 0 ? rel[k] / speed : dir[k];
    turn_toward(h, dir, (float)(f->turn_rate_deg * 3.14159265358979323846 / 180) * dt);
    /* At most dist / T (the speed halves every T ln 2, never within 3 frames) and no faster than
     * the agent comes in (entering the radius does not kick it), but at least a constant
     * deceleration of R / (10 T^2) onto the destination, which stops it there in finite time instead
     * of an exponential tail (ln(R / bind_distance) T: 1.5 s at the defaults) in which nothing
     * visible moves. */
    const float T = (float)f->arrival_time, R = (float)f->arrival_radius;
    const float finish = sqrtf(0.2f * R * dist) / T;
    /* an agent that comes in faster than dist / T slows as under the constant deceleration that
     * stops it on the destination, v^2 = speed^2 (1 - speed dt / dist), not at once: the switch from
     * the forces does not kick it (SCF: "smoothly reach the destination") */
    const float stopping = speed * sqrtf(fmaxf(0.0f, 1.0f - speed * dt / dist));
    float pace = fminf(s->prm.max_speed[a], fmaxf(finish, fminf(speed, fmaxf(dist / T, stopping))));
    pace *= fmaxf(0.0f, h[0] * dir[0] + h[1] * dir[1] + h[2] * dir[2]);
    if (pace * dt >= dist) return bind(s, a, dt), FM_PHASE_ARRIVED;
    float v[3] = {s->dest_v[0][a] + pace * h[0], s->dest_v[1][a] + pace * h[1], s->dest_v[2][a] + pace * h[2]};
    truncate3(v, s->prm.max_speed[a]); /* a destination faster than MaxSpeed is not caught up with */
    for (int k = 0; k < 3; k++) {
        s->v[k][a] = v[k];
        s->p[k][a] += v[k] * dt;
    }
    return FM_PHASE_HOMING;
}

/* Bound: on the destination; floating: around it, a smooth per-agent Lissajous offset that grows
 * from 0 at binding to float_amplitude; at most MaxSpeed either way. */
static void move_bound(const fm_flock_model *m, fm_flock_state *s, int64_t a, float dt)
{
    const fm_flock_def *f = &m->def.flock;
    float offset[3] = {0, 0, 0};
    if (f->arrival_mode == FM_ARRIVAL_FLOAT) {
        static const double freq[3] = {1.0, 1.31, 0.77};
        double tau = s->time + dt - s->t_bind[a], ramp = 1 - exp(-tau / f->float_period);
        for (int k = 0; k < 3; k++) {
            double phase = TWO_PI * fm_random_unit(m->def.seed, 100 + (uint64_t)k, (uint64_t)fm_flock_id(s, a));
            offset[k] = (float)(f->float_amplitude * ramp * sin(TWO_PI * freq[k] * tau / f->float_period + phase));
        }
    }
    float step[3], len2 = 0;
    for (int k = 0; k < 3; k++) step[k] = s->dest[k][a] + offset[k] - s->p[k][a], len2 += step[k] * step[k];
    /* MaxSpeed holds for bound agents too: on a destination faster than it, the agent trails behind
     * (still bound) and closes up as soon as the destination slows */
    const float most = s->prm.max_speed[a] * dt;
    const float scale = len2 > most * most ? most / sqrtf(len2) : 1.0f;
    for (int k = 0; k < 3; k++) {
        s->v[k][a] = step[k] * scale / dt;
        s->p[k][a] += step[k] * scale;
    }
}

/* Stage 5 for one block: each agent moves only itself; those under forces in whole groups of SIMD
 * lanes (the same bits). An agent homing or bound never comes back under forces, so they move first. */
static void move_block(const fm_flock_model *m, fm_flock_state *s, int64_t begin, int64_t end, flock_block *bc)
{
    const float dt = (float)m->dt;
    memset(bc, 0, sizeof *bc);
    for (int64_t a = begin; a < end; a++) {
        const uint8_t phase = s->phase[a];
        if (phase == FM_PHASE_HOMING) s->phase[a] = move_stepped(m, s, a, dt);
        else if (phase != FM_PHASE_FLYING && phase != FM_FLOCK_ELSEWHERE) move_bound(m, s, a, dt);
    }
    fm_forces_view w;
    fm_forces_arrays x;
    forces_lanes(m, s, &w, &x);
    for (int64_t a = fm_kernel_move_flying(&x, s->p, s->v, s->phase, s->prm.max_speed, dt, (float)m->def.flock.arrival_radius,
                                           FM_PHASE_HOMING, begin, end);
         a < end; a++)
        if (s->phase[a] == FM_PHASE_FLYING) s->phase[a] = move_flying(m, s, a, dt);
    for (int64_t a = begin; a < end; a++)
        if (s->phase[a] != FM_FLOCK_ELSEWHERE) bc->count[s->phase[a]]++;
    fm_kernel_orient_along(s->orient, (const float *const *)s->v, s->phase, FM_FLOCK_ELSEWHERE, begin, end);
}

/* The neighbour grid lists the agents still on their way: a bound agent is part of the shape, not
 * of the flock, and one that arrives late must not be held off its destination by the separation
 * from those already there. On P ranks, this rank's and the ghosts (phase FM_FLOCK_ELSEWHERE, which
 * only ghosts have in the step). */
void fm_flock_mark_members(fm_flock_state *s)
{
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t a = 0; a < s->slots; a++)
        s->member[a] = s->phase[a] == FM_PHASE_FLYING || s->phase[a] == FM_PHASE_HOMING || s->phase[a] == FM_FLOCK_ELSEWHERE;
}

/* The neighbour grid of this step: the agents on their way, on P ranks with the ghosts. */
static void build_grid(const fm_flock_model *m, fm_flock_state *s)
{
    if (s->grid_current) return; /* the frame's measures built this very grid (flock_measures.c) */
    fm_flock_mark_members(s);
    fm_grid_build_moving(&s->grid, (const float *const *)s->p, (const float *const *)s->v, s->member, s->slots,
                         fm_flock_cell(m), s->threads);
}

void fm_flock_step(const fm_flock_model *m, fm_flock_state *s)
{
    if (s->dist_status != FM_OK) return; /* every rank knows: the frame reports it */
    if (s->dist && (s->dist_status = fm_flock_dist_exchange(m, s, &s->dist_error)) != FM_OK) return;
    if (s->resort_every > 0 && s->step % s->resort_every == 0) fm_flock_state_resort(m, s); /* one process */
    const double t_end = (double)(s->step + 1) * m->dt; /* no drift from summing dt */
    if (m->info.deforming) update_destinations(m, s, t_end);
    fm_kalman_advance(&s->kalman);
    if (s->fields) fm_fields_prepare(s->fields, s->time, s->threads);
    build_grid(m, s);
    s->grid_current = 0;
    const double busy_from = s->dist ? fm_seconds() : 0;
    const int64_t blocks = (s->slots + FM_BLOCK - 1) / FM_BLOCK; /* after the migration */
    boids_pass(m, s);
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t b = 0; b < blocks; b++) {
        const int64_t begin = b * FM_BLOCK, end = FM_MIN((b + 1) * FM_BLOCK, s->slots);
        leaders_block(m, s, t_end, begin, end);
        forces_block(m, s, begin, end);
    }
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t b = 0; b < blocks; b++)
        move_block(m, s, b * FM_BLOCK, FM_MIN((b + 1) * FM_BLOCK, s->slots), &s->blocks[b]);
    memset(s->count, 0, sizeof s->count);
    for (int64_t b = 0; b < blocks; b++) /* combine in block order */
        for (int i = 0; i < 4; i++) s->count[i] += s->blocks[b].count[i];
    if (s->dist) fm_flock_dist_after_step(s, fm_seconds() - busy_from);
    s->time = t_end;
    s->step++;
}
