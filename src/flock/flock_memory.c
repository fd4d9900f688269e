/* The shape flock's memory estimate (memory.h, docs/limits.md): its model, store, frame and the
 * sampler's peak per agent, and the boids' neighbour grid, always. */
#include "flock.h"
#include "memory.h"

#include <math.h>

/* The shape flock (flock_model.c, flock_state.c, flock_run.c). The model: start and destination at
 * time 0 (6 floats), the boids parameters (3 rules x radius, angle, weight; max speed, force and
 * acceleration) and the destination's sample (a point, barycentrics, a triangle). */
static const double FLOCK_MODEL_PER_AGENT = sizeof(float) * (6 + 3 * FM_BOIDS_RULES + 3) + sizeof(float) * 6 + sizeof(int32_t);
/* The store: p, v, dest, dest_v, leader, leader_v, acc, steer, ext (3 floats each), the orientation, the
 * bind time and homing weight, phase and grid membership, the per-block counts. */
static const double FLOCK_STATE_PER_AGENT = sizeof(float) * (9 * 3 + 4 + 2) + 2 + (double)sizeof(flock_block) / FM_BLOCK;
/* R over the run: each agent's own Kalman covariance (3 doubles) and its factor of R (a float). */
static const double FLOCK_OWN_KALMAN_PER_AGENT = sizeof(double) * 3 + sizeof(float);
/* A deforming target's destinations, evaluated each step (3 floats). */
static const double FLOCK_DEFORM_PER_AGENT = sizeof(float) * 3;
/* The frame: position, velocity (3 floats), orientation (4: the largest attribute) and phase (1 byte). */
static const double FLOCK_FRAME = sizeof(float) * (3 + 3 + 4) + 1, FLOCK_LARGEST_ATTR = sizeof(float) * 4;
/* On P ranks: an agent of a frame's exchange by share (flock_dist.c's frame record). */
static const double FLOCK_SHARE_RECORD = 72;
/* On P ranks a rank holds its slab's agents and its halo's ghosts in a store with a quarter more
 * room (fm_flock_state_reserve). The cuts balance the work, not the agents: a rank of 2 held up to
 * 1.28 n / P (flock_suzanne_torus at 10^6 agents, 60 steps), so 1.7 n / P slots. Each slot also has
 * its agent's id, its parameters (the model's 15 floats: 3 rules x radius, angle, weight; max speed,
 * force and acceleration; the source sample) and the slots' moves' scratch (24 bytes and the old
 * slot, 4). */
static const double HELD_PER_SHARE = 1.7;
static const double FLOCK_SLOT_EXTRA = 2 * sizeof(int32_t) + sizeof(float) * (3 * FM_BOIDS_RULES + 3 + 3) + 24;
/* One process with the store re-sorted in space (flock_resort.c, the default) has the same per-slot
 * arrays, and each agent's slot (slot_by_id). */
static const double FLOCK_RESORT_EXTRA = FLOCK_SLOT_EXTRA + sizeof(int32_t);
/* The view of a frame's or a checkpoint's share (fm_flock_state_view): position, velocity,
 * destination, leader, orientation, bind time, phase, in-flight flag (and the own Kalman covariance). */
static const double FLOCK_VIEW = sizeof(float) * (4 * 3 + 4 + 1) + 2;

/* The peak of preprocessing, while the target is sampled: the model, the agent-sample match
 * (int64) and the source's samples (point, barycentrics, triangle), plus the sampler's own arrays
 * per sample (sample.c, sample_mosaic.c, sample_stratified.c), the larger of the source's and the
 * target's (match "projected" relaxes the target with the mosaic): the double points and triangles;
 * for mosaic also a float copy, the neighbour grid, the moved points and the Hilbert sort's keys
 * and copies; for stratified the candidates (point in double, triangle) and their elimination's
 * float copy, flags, neighbours, keys, heap and grid, 1.1 x oversample candidates per sample. */
static double flock_preprocess_per_agent(const fm_scene_def *def, int64_t n)
{
    const double samples = sizeof(float) * 6 + sizeof(int32_t), points = sizeof(double) * 3 + sizeof(int32_t);
    const double grid = n > 0 ? fm_memory_grid_bytes(n) / (double)n : 0;
    const double mosaic = points + sizeof(float) * 3 + grid + points + sizeof(fm_keyed) + points;
    double sampler = points; /* the larger of the source's and the target's sampler */
    if (def->flock.sampling == FM_FLOCK_SAMPLE_MOSAIC || def->flock.match == FM_FLOCK_MATCH_PROJECTED) sampler = mosaic;
    if (def->flock.sampling == FM_FLOCK_SAMPLE_STRATIFIED) {
        const double candidate = points + 4 /* padding */ + sizeof(float) * 3 + 1 + sizeof(int64_t) + sizeof(double) +
                                 sizeof(double) + sizeof(int64_t) + grid;
        sampler = fmax(sampler, points + 1.1 * FM_SAMPLE_OVERSAMPLE * candidate);
    }
    return FLOCK_MODEL_PER_AGENT + sizeof(int64_t) + samples + sampler;
}

fm_memory_estimate fm_flock_memory_estimate(const fm_scene_def *def, int64_t n)
{
    fm_memory_estimate e = {0};
    double agents = (double)n;
    const double ranks = fm_memory_ranks(), held = ranks > 1 ? HELD_PER_SHARE / ranks : 1;
    const int own_kalman = def->flock.kalman_r_over != FM_KALMAN_R_FIXED;
    /* on P ranks a machine holds one model, its first rank's (fm_flock_model_build_shared) */
    const int shared = ranks > 1;
    e.model = shared ? 0 : FLOCK_MODEL_PER_AGENT;
    e.shared = shared ? FLOCK_MODEL_PER_AGENT : 0;
    e.state = (FLOCK_STATE_PER_AGENT + (fm_flock_target_moves(&def->flock) ? FLOCK_DEFORM_PER_AGENT : 0) +
               (own_kalman ? FLOCK_OWN_KALMAN_PER_AGENT : 0) + (ranks > 1 ? FLOCK_SLOT_EXTRA : FLOCK_RESORT_EXTRA)) * held;
    /* On P ranks the frame is the rank's share n / P (frame_share.h): its arrays and view, its
     * encoder's stored and previous words and blocks (the frame with ids), and the exchange of the
     * share's agents (a record sent and one received). Rank 0's writer makes no frame buffers. */
    e.frames = ranks > 1 ? (FLOCK_FRAME + FLOCK_VIEW + (own_kalman ? sizeof(double) * 3 : 0) +
                            3 * (FLOCK_FRAME + sizeof(uint32_t)) + 2 * FLOCK_SHARE_RECORD) / ranks
                         : fm_memory_frames_per_agent(def, FLOCK_FRAME);
    /* The boids' neighbour grid, always, with its copy of the velocities (grid.h); on P ranks for the
     * rank's slots, its table the one process's (fm_grid_init_table). */
    const double listed = sizeof(fm_grid_quad) / 4.0 + sizeof(uint32_t) + sizeof(fm_grid_rec) + sizeof(uint32_t);
    const double table = fm_memory_grid_bytes(n) - agents * listed; /* as fm_memory_grid_bytes counts */
    const double per_slot = listed + sizeof(fm_grid_quad) / 4.0 + 3 * sizeof(float);
    e.grid = n > 0 ? (table + per_slot * ceil(agents * held)) / agents : 0;
    /* the look's history in the store (flock_look.c), twice: the store and a frame's view */
    e.fixed = fm_memory_fixed_bytes(def) + fm_memory_encoder_scratch_bytes(def, n, FLOCK_LARGEST_ATTR) +
              2 * (double)sizeof(fm_flock_look);
    e.preprocess_per_agent = flock_preprocess_per_agent(def, n);
    fm_memory_total(&e, n);
    return e;
}


fm_status fm_flock_memory_check(const fm_scene_def *def, int64_t n, fm_error *err)
{
    const fm_memory_need need = {fm_flock_memory_estimate(def, n), "boids'", NULL};
    return fm_memory_check(def, n, &need, err);
}
