/* The tetra morph's memory estimate (memory.h, docs/limits.md): its model, agent store, frame and
 * preparation per agent, and the MDE grid when d_min > 0. */
#include "memory.h"
#include "morph.h"

/* Bytes per agent of each array, as allocated by morph_model.c, morph_state.c, morph_run.c, the cache writer and grid.c. */
static const double MODEL_PER_AGENT =
    sizeof(float) * (12 + 3 + 12 + 3 + 1) /* src_rel, src_c, tgt_f, tgt_c, src_radius */
    + sizeof(int64_t);                     /* src_index */
static const double STATE_PER_AGENT =
    sizeof(float) * (3 + 3 + 3 + 2 + FM_MORPH_FLOATS + 3) /* p, v, p2, t2 and tf, morph, vla */
    + 6                                                 /* phase, perm, morph_safe, entered, member, mde_needed */
    + sizeof(int64_t)                                   /* target */
    + sizeof(int32_t) + 16 + 2 * sizeof(uint32_t) + 2 * sizeof(int32_t) /* id; re-sort scratch, keys, slots */
    + sizeof(float) * (12 + 1)                          /* rest_rel, rest_radius: the model's, in store order */
    + (double)sizeof(block_counts) / FM_BLOCK;
/* Preprocessing holds both tet sets in double (subdivided to n), the two orders and the model with
 * its double targets (tgt, dropped once it is built). */
static const double PREP_PER_AGENT = 2 * 12 * sizeof(double) + 2 * sizeof(int64_t) + 12 * sizeof(double);
fm_memory_estimate fm_morph_memory_estimate(const fm_scene_def *def, int64_t n)
{
    fm_memory_estimate e = {0};
    double agents = (double)n;
    e.model = MODEL_PER_AGENT;
    e.state = STATE_PER_AGENT;
    e.frames = fm_memory_frames_per_agent(def, 12 * sizeof(float) + 1, 12 * sizeof(float)); /* tet vertices, phase */
    e.grid = def->d_min > 0 && n > 0 ? fm_memory_grid_bytes(n) / agents : 0;
    e.fixed = fm_memory_fixed_bytes(def);
    e.preprocess_per_agent = PREP_PER_AGENT + MODEL_PER_AGENT;
    fm_memory_total(&e, n);
    return e;
}


fm_status fm_morph_memory_check(const fm_scene_def *def, int64_t n, fm_error *err)
{
    const fm_memory_need need = {fm_morph_memory_estimate(def, n), def->d_min > 0 ? "MDE" : NULL,
                                 " or turn MDE off (mde.d_min 0)"};
    return fm_memory_check(def, n, &need, err);
}
