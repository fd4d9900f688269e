/* The tetra morph's memory estimate (memory.h, docs/limits.md): its model, agent store, frame and
 * preparation per agent, and the MDE grid when d_min > 0. */
#include "memory.h"
#include "morph.h"

#include <math.h>

/* Bytes per agent of each array, as allocated by morph_model.c, morph_state.c, morph_run.c, the cache writer and grid.c. */
static const double MODEL_PER_AGENT =
    sizeof(float) * (12 + 3 + 12 + 3 + 1) /* src_rel, src_c, tgt_f, tgt_c, src_radius */
    + sizeof(int64_t);                     /* src_index */
static const double STATE_PER_AGENT =
    sizeof(float) * (3 + 3 + 3 + 2 + FM_MORPH_FLOATS + 3 + 2) /* p, v, p2, t2 and tf, morph, vla, detour clock */
    + 7                                                 /* phase, perm, morph_safe, entered, member, mde_needed,
                                                           detour_on */
    + sizeof(int64_t)                                   /* target */
    + sizeof(int32_t) + 16 + 2 * sizeof(uint32_t) + 2 * sizeof(int32_t) /* id; re-sort scratch, keys, slots */
    + sizeof(float) * (12 + 1)                          /* rest_rel, rest_radius: the model's, in store order */
    + (double)sizeof(block_counts) / FM_BLOCK;
/* A moving target's sequence (morph_motion.c): each target-tet vertex's triangle and (b1, b2, h),
 * held by every rank. */
static const double MOTION_PER_AGENT = 4 * (sizeof(int32_t) + 3 * sizeof(double));

/* The preparation's peak (morph_model.c), as the source half of the model is stored: both tet sets
 * in double (subdivided to n), D1 and its sort keys, and that half (src_rel, src_c, src_index). The
 * target half comes after the source tets are freed, without the double targets (a shot's group
 * keeps them: 96 more, not counted). */
static const double PREP_PER_AGENT = 2 * 12 * sizeof(double) + sizeof(int64_t) + 16 + sizeof(float) * (12 + 3) + sizeof(int64_t);

/* On P ranks a rank holds its slab's agents, the busiest rank at most about 1.2 n / P (measured
 * load_imbalance 1.01-1.18), in a store with a quarter more room (fm_morph_state_reserve). */
static const double HELD_PER_SHARE = 1.5;
/* ... and the frame: its own agents' tets in slot order (held) with the exchange that hands them to
 * the shares (a 56-byte record sent and one received), and its share n / P of the cache's frame
 * (tets and phases) with its encoder's stored words, previous words (delta) and blocks. */
static const double OWN_TETS = sizeof(float) * 12 + 2 * 56, SHARE_FRAME = 4 * (sizeof(float) * 12 + 1);

fm_memory_estimate fm_morph_memory_estimate(const fm_scene_def *def, int64_t n)
{
    fm_memory_estimate e = {0};
    const double ranks = fm_memory_ranks(), held = ranks > 1 ? HELD_PER_SHARE / ranks : 1;
    const int64_t mine = (int64_t)ceil((double)n * held); /* the agents a rank's store holds */
    /* on P ranks a machine holds one model, its first rank's (fm_morph_model_build_shared) */
    const int shared = ranks > 1;
    e.model = (shared ? 0 : MODEL_PER_AGENT) + (def->target_motion.sequence[0] ? MOTION_PER_AGENT : 0);
    e.shared = shared ? MODEL_PER_AGENT : 0;
    e.state = STATE_PER_AGENT * held;
    e.frames = ranks > 1 ? OWN_TETS * held + SHARE_FRAME / ranks
                         : fm_memory_frames_per_agent(def, 12 * sizeof(float) + 1); /* tet vertices, phase */
    e.grid = def->d_min > 0 && n > 0 ? fm_memory_grid_bytes(mine) / (double)n : 0;
    e.fixed = fm_memory_fixed_bytes(def) + fm_memory_encoder_scratch_bytes(def, n, 12 * sizeof(float));
    e.preprocess_per_agent = PREP_PER_AGENT;
    fm_memory_total(&e, n);
    return e;
}


fm_status fm_morph_memory_check(const fm_scene_def *def, int64_t n, fm_error *err)
{
    const fm_memory_need need = {fm_morph_memory_estimate(def, n), def->d_min > 0 ? "MDE" : NULL,
                                 " or turn MDE off (mde.d_min 0)"};
    return fm_memory_check(def, n, &need, err);
}
