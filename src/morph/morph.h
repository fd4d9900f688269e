/* The prepared model and the agent store (internal layout of fm_morph_model and fm_morph_state). */
#ifndef FM_MORPH_H
#define FM_MORPH_H

#include "checkpoint.h"
#include "dist.h"
#include "geom.h"
#include "fields.h"
#include "fm_internal.h"
#include "grid.h"
#include "memory.h"
#include "obstacles.h"
#include "path_route.h"
#include "scene_internal.h"
#include "slabs.h"

#include <stdint.h>

enum { FM_RESORT_INTERVAL = 8 }; /* steps between spatial re-sorts of the store */
enum { FM_MODEL_MAX_WARNINGS = 8 };

/* morph_motion.c: a target that moves (issue 38), built for every rank from the model (NULL: static). */
typedef struct fm_morph_motion fm_morph_motion;
/* The moving target at one time: a pure function of it, cached in the state (fm_morph_motion_prepare). */
typedef struct fm_morph_motion_now {
    double time;             /* when prepared; NaN: not yet */
    double offset[3];        /* target_motion.path's translation */
    double *v;               /* sequence: the surface's vertices (3 a vertex) */
    double *frame;           /* sequence: each triangle's edges b - a, c - a and N / sqrt|N| (9 a triangle) */
    float *key_q[3], *key_f[3]; /* path: the key points with the offset (FM eq 3), NULL without a path */
} fm_morph_motion_now;
/* morph_path.c: key points Q_0..Q_{m+1} from C_S through the control points to C_T (FM §5.1). */
typedef struct fm_path {
    double *q;      /* 3 per key point */
    int32_t count;  /* m + 2 */
} fm_path;
fm_status fm_path_build(const fm_scene_def *def, const double cs[3], const double ct[3],
                        fm_path *out, fm_error *err);
void fm_path_free(fm_path *path);

/* fm_path_build, then rerouted round the obstacles where it crosses them (route may be NULL: none).
 * A rerouted path gets one key point per r_soft of its length, up to twice path.key_points + 2. */
fm_status fm_path_build_routed(const fm_scene_def *def, const double cs[3], const double ct[3], fm_path_route *route,
                               fm_path *out, fm_error *err);

/* Immutable after fm_morph_model_build. Agent a is the source tet with the a-th smallest D1 (its launch
 * rank); target slot k is the target tet with the k-th smallest D2 (its hand-out rank). */
struct fm_morph_model {
    fm_scene_def def;
    fm_morph_model_info info;
    int64_t n;
    float *src_rel;          /* 12 per agent: rest vertices minus rest centroid */
    float *src_c[3];         /* rest centroid, SoA */
    double *tgt;             /* 12 per slot: target tet vertices in double, kept after the build only
                                for a shot's group that another group starts from (96 bytes an
                                agent: the run reads tgt_f); NULL otherwise */
    float *tgt_f;            /* 12 per slot: the same in float, written once an agent arrives */
    float *tgt_c[3];         /* target tet centroids, SoA */
    float *key_q[3];         /* path key points Q_i, SoA */
    float *key_f[3];         /* unit direction f_i from Q_i to Q_{i+1} (FM eq 3) */
    int32_t key_count;
    float sphere_c[3];
    float sphere_r;
    int64_t *src_index;      /* each agent's source tet before the launch order (D1) sorted them */
    float *src_radius;       /* R_X at rest: radius of each source tet's minimal bounding sphere */
    float max_radius;        /* the largest R_X */
    fm_field_plan fields;    /* whether the state bakes the style fields (fields.h) */
    double field_fade;       /* style.fade_distance resolved (its default: sphere_r); 0: no fade */
    double field_fade_time;  /* style.fade_time resolved (its default: 2 path length / (omega1 speed0)); 0: never */
    fm_obstacles *obstacles; /* FM §5.3 d_t (OpenVDB grid + Embree); NULL without obstacles */
    fm_obstacles *target_sdf;/* the target's own signed distance, for FM_SWITCH_DISTANCE */
    fm_nav nav;              /* issue 38's navigation function round the obstacles (path_route.c); its
                                arrays are meaningful only when detour_time > 0 */
    double detour_time;      /* obstacles.detour_time resolved; 0: no detours */
    double scene_lo[3], scene_hi[3]; /* bounds of source, target and path: the field grid spans them */
    double dt;
    int32_t steps_per_frame;
    double launch_rate;
    char warnings[FM_MODEL_MAX_WARNINGS][1024]; /* accepted but unusual input (fm_morph_model_warning) */
    int warning_count;
    fm_dist_shared *shared;  /* on P ranks (fm_morph_model_build_shared): the segment the machine's
                                ranks share, which holds the arrays above; NULL: each its own */
    fm_morph_motion *motion; /* target_motion (issue 38); NULL: the target stands still. Each rank its own */
};

fm_status fm_morph_motion_build(fm_morph_model *m, fm_error *err); /* after tgt_f and the path */
void fm_morph_motion_destroy(fm_morph_motion *mo);
void fm_morph_motion_hash(const fm_morph_motion *mo, fm_hash *h); /* for a checkpoint's model hash */
fm_morph_motion_now *fm_morph_motion_now_create(const fm_morph_model *m, fm_error *err);
void fm_morph_motion_now_free(fm_morph_motion_now *now);
/* now at `time` (nothing to do if it is already): the path's offset, the moved key points, the
 * deformed surface. Serial; the reads below are thread-safe. */
void fm_morph_motion_prepare(const fm_morph_model *m, fm_morph_motion_now *now, double time);
/* Target slot's tet at now's time (12 doubles, the slot's own vertex order) and its centroid. */
void fm_morph_motion_tet(const fm_morph_model *m, const fm_morph_motion_now *now, int64_t slot, double out[12], double c[3]);

/* On P ranks: the first rank of each machine builds the model (TetGen, the preparation's peak) and
 * puts its arrays (132 bytes an agent) in memory that the machine's ranks share; the others copy
 * its scalars and build only their distance grids (fm_dist_build_shared: without shared memory
 * each builds its own). Collective (docs/scale-out.md); a failure on any rank is every rank's. */
fm_morph_model *fm_morph_model_build_shared(const fm_scene_def *def, const fm_dist *dist, fm_progress_fn progress,
                                            void *user, fm_error *err);

/* A group of a shot (morph_shot.c). With `from`, it starts from that group's formed shape: its
 * source tets are from's target tets (from->tgt, which from was built keeping), slot j as source
 * tet j, and its n is from's. keep_targets: keep m->tgt for a later group that starts from this one
 * (the shot frees it once every group is built: fm_morph_model_drop_targets). */
fm_morph_model *fm_morph_model_build_group(const fm_scene_def *def, const fm_morph_model *from, int keep_targets,
                                           fm_progress_fn progress, void *user, fm_error *err);
/* The same on P ranks, one model a machine (fm_morph_model_build_shared): only the first rank of a
 * machine holds tgt (it builds the groups). */
fm_morph_model *fm_morph_model_build_group_shared(const fm_scene_def *def, const fm_morph_model *from, int keep_targets,
                                                  const fm_dist *dist, fm_progress_fn progress, void *user, fm_error *err);
void fm_morph_model_drop_targets(fm_morph_model *m);

/* What a build keeps for the next build of an edited scene (flockmorph studio: docs/studio.md, "An
 * edit and the model"): for each shape, TetGen's tets of the placed mesh and the tets at n, with the
 * inputs each was made from. A build given a keep makes neither again where those inputs are the
 * same (the placed mesh byte for byte, tetgen.quality and tetgen.max_volume; then
 * tetgen.subdivision and n), which is what a path, speed, style or MDE edit leaves; everything
 * after it is built as always except the obstacles' grid and the routed path (fm_kept_route). The model is the same bytes either
 * way: TetGen and the subdivision are functions of those inputs alone. */
typedef struct fm_kept_tets {
    int has_tetgen, has_at_n;
    fm_mesh mesh;               /* the placed mesh TetGen was given, */
    double quality, max_volume; /* with tetgen.quality and tetgen.max_volume */
    fm_tets tetgen;             /* TetGen's tets of it */
    int subdivision;            /* tetgen.subdivision and */
    int64_t n;                  /* the agents the tets at n were made for */
    fm_tets at_n;
    int64_t refined;            /* the refined count (fm_morph_model_info) */
} fm_kept_tets;

/* The obstacles' distance grid with the placed meshes, reach and obstacles.voxel it was made from
 * (fm_obstacles_grid), and the routed path and its navigation function with the key they were made
 * from and the grid. A build makes the grid again only where a mesh, the reach (k_a plus the largest
 * tet radius) or the voxel changed, and the route only where that or its key changed: a speed0,
 * style, MDE or launch edit keeps both. */
typedef struct fm_kept_route {
    fm_kept_grid grid;              /* reach: k_a plus the largest tet radius */
    int has_path, has_nav;
    fm_route_key key;
    fm_path path;
    int routed, unroutable;
    fm_nav nav;                     /* detours on: the model's copy */
} fm_kept_route;

typedef struct fm_morph_keep {
    fm_kept_tets shape[2]; /* source, target */
    fm_kept_route route;
    int reused;            /* the last build made none of them again (TetGen nor subdivision) */
    int grid_reused;       /* ... the obstacles' grid was the keep's (0 without obstacles) */
    int route_reused;      /* ... the routed path and navigation function were the keep's */
    const volatile sig_atomic_t *cancel; /* the studio's flag (NULL: none): where an edit sets it, the build
                                            stops at its next stage boundary with FM_STOPPED, nothing kept
                                            half-made (morph_model.c build) */
} fm_morph_keep;

/* fm_morph_model_build, keeping in *keep (zeroed at first) what it makes and reusing what fits. */
fm_morph_model *fm_morph_model_build_keeping(const fm_scene_def *def, fm_morph_keep *keep, fm_progress_fn progress,
                                             void *user, fm_error *err);
/* A shot's group (fm_morph_model_build_group), keeping in *keep the same way: its target's tets, and
 * its source's unless it starts from another group's shape (those tets are from's). */
fm_morph_model *fm_morph_model_build_group_keeping(const fm_scene_def *def, const fm_morph_model *from, int keep_targets,
                                                   fm_morph_keep *keep, fm_progress_fn progress, void *user,
                                                   fm_error *err);
void fm_morph_keep_clear(fm_morph_keep *keep);
/* stats.json's end-state checks (morph_run.c), for a shot's groups too. */
/* verts: the store's tets by agent id, or (by_slot) in slot order; NULL (no room for them) gives infinity. */
double fm_morph_final_vertex_error(const fm_morph_model *m, const fm_morph_state *s, const float *verts, int by_slot);
int fm_morph_targets_taken_once(const fm_morph_state *s);


/* Per-agent morph parameters (FM §6), set when the agent enters phase 2. */
enum { FM_MORPH_FLOATS = 4 }; /* rotation axis n (3) and angle theta of A = RS */

typedef struct block_counts {
    int64_t entered, arrived, fallbacks;
    int64_t flying, mde;      /* agents in phase 1, and of those the ones MDE pushed */
    float clearance;          /* smallest d_t - R_X in phase 1 */
    int64_t detours;          /* agents on a detour (issue 38) after this step */
} block_counts;

/* Stages of fm_morph_step, timed into fm_morph_state.stage_seconds for the benchmarks. */
typedef enum fm_stage {
    FM_STAGE_RESORT, FM_STAGE_LAUNCH, FM_STAGE_FIELDS, FM_STAGE_GRID, FM_STAGE_VELOCITY, FM_STAGE_MOVE,
    FM_STAGE_HANDOUT, FM_STAGE_MORPH, FM_STAGE_COUNT
} fm_stage;
extern const char *const fm_stage_names[FM_STAGE_COUNT];

/* Everything the step mutates. Arrays are 64-byte aligned and indexed by store slot; id[slot] is
 * the agent's id (its launch rank, the index of the model's per-agent arrays). Every
 * FM_RESORT_INTERVAL steps the in-flight agents are re-sorted by position (morph_resort.c: with MDE
 * by the slot of their cell in the MDE grid, so the grid lists them in store order; without, by the
 * Morton code of their position), so neighbours in space are neighbours in memory. The slots are laid out as
 *
 *     [0, active_begin)            arrived before the last re-sort
 *     [active_begin, active_end)   in flight (and agents that arrived since the last re-sort)
 *     [active_end, n)              waiting to launch, in id order
 *
 * so the step only visits the active range: idle agents cost nothing. */
struct fm_morph_state {
    int64_t n;
    int64_t capacity;        /* slots the per-slot arrays hold: n on one process; on P ranks this
                                rank's agents and halo, grown as they come (fm_morph_state_reserve) */
    int32_t *id;             /* agent id of each slot */
    int64_t active_begin, active_end;
    int64_t step;
    double time;
    int threads;
    float *p[3];             /* tet centroid */
    float *rest_rel[12];     /* the model's src_rel of the slot's agent (SoA, rebuilt from id by
                                fm_morph_state_fill_rest, moved by the re-sort): the step and the synthesis
                                read it in store order instead of gathering it by id */
    float *rest_radius;      /* the same for src_radius (R_X at rest) */
    float *v[3];             /* velocity of the last step; in phase 2 with the switch blend
                                (phase2.blend_time > 0, not steered), the velocity it entered phase 2
                                with (V_1), from which the closed form is evaluated (kernels.h) */
    uint8_t *phase;          /* fm_phase */
    int64_t *target;         /* target slot, -1 before phase 2 */
    float *t2;               /* time the agent entered phase 2 */
    float *p2[3];            /* centroid when it entered phase 2 */
    float *tf;               /* eq 9 flight time to its target */
    float *morph;            /* FM_MORPH_FLOATS per agent */
    uint8_t *perm;           /* vertex correspondence: index into fm_even_permutations */
    uint8_t *morph_safe;     /* 1: uses the always-invertible A(t) form (see morph.c) */
    float *detour_best;      /* issue 38's detour clock (kernel_detour.h): the least navigation value since
                                the clock last started, INFINITY when the agent is not watched */
    float *detour_since;     /* the time it was reached */
    uint8_t *detour_on;      /* 1: on a detour down the navigation function */
    uint8_t *entered;        /* scratch: entered the target sphere this step */
    void *sort_scratch;      /* scratch for the re-sort: 16 bytes per agent; the velocity stage
                                borrows 8 of them for the obstacle kernels (morph_step.c) */
    uint32_t *sort_keys;     /* scratch: 2 × capacity keys and 2 × capacity slots */
    int32_t *sort_slots;
    int64_t launched;        /* agents with id < launched have left the source */
    int64_t sorted_end;      /* active_end right after the last re-sort: the agents launched since
                                sit unsorted after it (fm_morph_step re-sorts early when they are many) */
    int64_t next_slot;       /* target slots handed out so far */
    int64_t count[4];        /* agents per phase */
    int64_t morph_fallbacks;
    block_counts *blocks;    /* per-block scratch, one per FM_BLOCK agents */
    fm_fields *fields;       /* style fields (FM §5.2), NULL without any; owns the baked grid */
    fm_grid grid;            /* neighbour grid for MDE (FM §5.4), built when d_min > 0 */
    int grid_ready;          /* grid initialised (to be freed) */
    uint8_t *member;         /* scratch: flying this step (the grid's members) */
    float *vla[3];           /* scratch: MDE velocities */
    uint8_t *mde_needed;     /* scratch */
    int64_t detour_agent_steps; /* phase-1 agent-steps on a detour (issue 38), since the start */
    int64_t mde_agent_steps; /* since the last frame: phase-1 agent-steps that needed MDE ... */
    int64_t flying_agent_steps; /* ... out of all phase-1 agent-steps */
    float min_clearance;     /* smallest d_t - R_X seen in phase 1 (INFINITY without obstacles) */
    double stage_seconds[FM_STAGE_COUNT]; /* wall time per stage, summed over steps */
    /* On P ranks (morph_dist.c; NULL on one process): the store holds this rank's agents only,
     * [0, active_end); waiting agents are in no store; the step's halo follows the active range. */
    const fm_dist *dist;
    fm_slabs *slabs;
    fm_status dist_status;   /* a failed exchange (agreed by every rank): the step stops, the frame reports it */
    fm_error dist_error;
    /* A moving target (m->motion): where it is at the time last prepared (the step's end; a frame
     * prepares its own time), a cache of a pure function of time, so it is in no checkpoint.
     * Writable through a const state: the frame's writers prepare it. NULL: static target. */
    fm_morph_motion_now *motion_now;
};

/* The slots that hold agents: all n on one process, this rank's [0, active_end) on P ranks. */
static inline int64_t fm_morph_slots(const fm_morph_state *s)
{
    return s->dist ? s->active_end : s->n;
}

/* Agent id's tet at rest in the source (a waiting agent's frame), from the model. */
void fm_morph_waiting_tet(const fm_morph_model *m, int64_t id, float out[12]);

/* morph_dist.c: the tetra morph on P ranks (docs/scale-out.md). */
/* morph_state.c: one rank's store on P ranks, as fm_morph_state_create then fm_morph_state_distribute
 * make it, without the n slots in between (docs/limits.md: memory on P ranks). */
fm_morph_state *fm_morph_state_create_distributed(const fm_morph_model *m, int threads, const fm_dist *dist, fm_error *err);
/* Makes s (fresh from fm_morph_state_create) one rank's share of the run: slabs cut at the source's
 * quantiles, an empty store. */
fm_status fm_morph_state_distribute(const fm_morph_model *m, fm_morph_state *s, const fm_dist *dist, fm_error *err);
fm_dist_totals fm_morph_dist_get_totals(const fm_morph_state *s);
fm_status fm_morph_dist_launch(const fm_morph_model *m, fm_morph_state *s, int64_t due, fm_error *err);
fm_status fm_morph_dist_migrate(const fm_morph_model *m, fm_morph_state *s, fm_error *err);
fm_status fm_morph_dist_ghosts(fm_morph_state *s, int64_t *ghosts, fm_error *err);
void fm_morph_dist_rebalance(const fm_morph_model *m, fm_morph_state *s, int64_t due); /* before agents < due launch */
void fm_morph_dist_record_load(fm_morph_state *s);
void fm_morph_dist_add_busy(fm_morph_state *s, double seconds); /* the step's own work, for the balance */
/* Checkpoints on P ranks: one file of one process's layout, written by every rank at once (any P
 * resumes it); each rank loads its share of the file's slots (fm_ckpt_share), and adopt sends every
 * launched agent of it to the rank whose slab holds it (collective). */
fm_status fm_morph_checkpoint_write(const char *path, const fm_morph_model *m, const fm_morph_state *s,
                                    const fm_morph_run_stats *stats, int64_t frames, const fm_ckpt_part *parts,
                                    int part_count, fm_error *err);
fm_status fm_morph_dist_checkpoint_save(const char *path, const fm_morph_model *m, fm_morph_state *s,
                                        const fm_morph_run_stats *stats, int64_t frames, fm_error *err);
/* A shot's group (morph_shot.c): the state alone, without statistics, at `frames` frames (on P
 * ranks collective, as fm_morph_dist_checkpoint_save); its load, on P ranks each rank's slab's agents. */
fm_status fm_morph_group_checkpoint_save(const char *path, const fm_morph_model *m, fm_morph_state *s, int64_t frames,
                                         fm_error *err);
fm_status fm_morph_group_checkpoint_load(const char *path, const fm_morph_model *m, fm_morph_state *s, int64_t *frames,
                                         fm_error *err);
fm_status fm_morph_dist_adopt(const fm_morph_model *m, fm_morph_state *s, int64_t first, int64_t count, fm_error *err);
fm_status fm_morph_dist_frame(const fm_morph_model *m, fm_morph_state *s, float *verts, uint8_t *phases, fm_error *err);
/* Where a state's agents go in a frame of rows (a shot's, morph_shot.c): agent i is row row0 + i
 * in its own vertex order, or (row set) row row[i] with its vertices in the even permutation
 * perm[i] (fm_even_permutations); the frame's rows of the state get `group` in groups. */
typedef struct fm_morph_rows {
    int64_t row0;
    const int64_t *row;
    const uint8_t *perm;
    uint8_t group;
    uint8_t *groups; /* from the share's first row, as verts and phases */
} fm_morph_rows;
/* The cache written by P ranks in parallel: this rank's share of the frame's rows, begin[rank] …
 * begin[rank + 1] − 1, complete in verts and phases (in row order from begin[rank]), from every
 * rank's store; the rows are the ids (rows NULL) or a shot's rows. own (12 floats a store slot)
 * gets the rank's own agents' tets in slot order. */
fm_status fm_morph_dist_frame_share(const fm_morph_model *m, fm_morph_state *s, const int64_t *begin,
                                    const fm_morph_rows *rows, float *own, float *verts, uint8_t *phases, fm_error *err);

/* morph_shot.c: a shot on P ranks (docs/scale-out.md): every group's state made as the rank's
 * share (fm_morph_state_create_distributed), before the run; each rank encodes its share of the
 * frames' rows. */
/* fm_shot_build on P ranks: every group's model one a machine (fm_morph_model_build_group_shared);
 * collective. dist NULL: fm_shot_build. */
fm_shot *fm_shot_build_on(const fm_scene_def *defs, int count, int threads, const fm_dist *dist, fm_progress_fn progress,
                          void *user, fm_error *err);
fm_status fm_shot_distribute(fm_shot *s, const fm_dist *dist, fm_error *err);
/* fm_shot_build on one process, group g's model built keeping in keeps[g] (count of them, zeroed at
 * first; fm_morph_model_build_group_keeping): the studio's runs of an edited shot, where a group whose
 * meshes, tetgen keys and n are as they were reuses its tets. */
fm_shot *fm_shot_build_keeping(const fm_scene_def *defs, int count, int threads, fm_morph_keep *keeps,
                               fm_progress_fn progress, void *user, fm_error *err);

/* morph_state.c: room for `slots` agents in the store (P ranks: before agents arrive); an
 * allocation failure leaves the store as it was. */
fm_status fm_morph_state_reserve(fm_morph_state *s, int64_t slots, fm_error *err);
/* The store shrunk to its agents and some room (P ranks: after a rank kept its share). */
void fm_morph_state_fit(fm_morph_state *s);
/* morph_state.c: the tets of the store's agents in slot order (12 floats a slot of fm_morph_slots). */
void fm_morph_tet_vertices_by_slot(const fm_morph_model *m, const fm_morph_state *s, float *out);
/* *own (fm_alloc'd, *capacity slots of 12 floats) as large as the store, which grows as the rank's
 * agents come: for fm_morph_tet_vertices_by_slot. */
fm_status fm_morph_own_room(const fm_morph_state *s, float **own, int64_t *capacity, fm_error *err);
/* morph_state.c: rest_rel and rest_radius from the model by id[] (after creation and a checkpoint load). */
void fm_morph_state_fill_rest(const fm_morph_model *m, fm_morph_state *s);
/* The rest vertices of slot a's tet relative to its centroid (12 floats). */
static inline void fm_morph_state_rest_tet(const fm_morph_state *s, int64_t a, float out[12])
{
    for (int j = 0; j < 12; j++) out[j] = s->rest_rel[j][a];
}

/* morph_resort.c: re-sorts the active range by position (arrivals first, then in flight: by MDE grid
 * slot, or by Morton code when d_min is 0); keeps every agent's id and state. */
void fm_morph_state_resort(const fm_morph_model *m, fm_morph_state *s);

/* morph_step.c: the MDE grid's cell edge (d_min > 0). */
float fm_morph_mde_cell(const fm_morph_model *m);

/* Slots of scheduler block b of the active range. */
static inline int64_t fm_active_blocks(const fm_morph_state *s)
{
    return (s->active_end - s->active_begin + FM_BLOCK - 1) / FM_BLOCK;
}
static inline void fm_active_block(const fm_morph_state *s, int64_t b, int64_t *begin, int64_t *end)
{
    *begin = s->active_begin + b * FM_BLOCK;
    *end = FM_MIN(*begin + FM_BLOCK, s->active_end);
}

/* morph_state.c: the table of every member a checkpoint saves (checkpoint.h), in file order. */
extern const fm_store_member fm_morph_state_members[];
extern const int fm_morph_state_member_count;



/* morph_order.c: FM eq 4. order[k] = index of the tet with the k-th smallest key (ties by index). */
fm_status fm_order_d1(const fm_tets *src, const fm_path *path, int64_t *order, fm_error *err);
fm_status fm_order_d2(const fm_tets *dst, const fm_path *path, int64_t *order, fm_error *err);

/* morph_memory.c: the tetra morph's bytes for n agents (docs/limits.md), and the refusal of a run
 * that does not fit (memory.h). */
fm_memory_estimate fm_morph_memory_estimate(const fm_scene_def *def, int64_t n);
fm_status fm_morph_memory_check(const fm_scene_def *def, int64_t n, fm_error *err);

/* morph_tet.c */
extern const uint8_t fm_even_permutations[12][4];
/* The index of the even permutation p with p[i] = inner[outer[i]]. */
uint8_t fm_compose_even_permutations(uint8_t outer, uint8_t inner);
/* Chooses the correspondence and A = RS for one agent: src and dst are 12 floats each, relative
 * to their centroids, both positively oriented. Returns 1 if the safe form had to be used. */
int fm_morph_setup(const float *src, const float *dst, float *morph, uint8_t *perm);
/* A (row-major) mapping src onto dst, both 12 floats relative to their centroids, dst already in
 * the agent's vertex order. */
void fm_morph_affine(const float *src, const float *dst, double a[9]);
/* A(t) (row-major) from the stored n, theta and A (FM §6: (1-t)I + t R(n, t theta) S with
 * S = R(n, theta)^T A, or the safe form). */
void fm_morph_matrix(const float *morph, int safe, const double a[9], double t, double out[9]);
/* Linear scale of a tet `tau` seconds after its launch (FM §6 shrink). */
double fm_shrink_scale(const fm_scene_def *def, double tau);

#endif
