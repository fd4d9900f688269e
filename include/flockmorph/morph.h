/* flockmorph's tetra flock morph (FM; scene "mode": "tetra_morph", the default). The flow follows
 * MuJoCo's model/data split:
 *   fm_scene_def      parameters (scene.h)
 *   fm_morph_model    everything immutable after preprocessing: tets, orders, path, bounding sphere
 *   fm_morph_state    everything the step mutates: the agent store, the clock, counters
 *   fm_morph_step(model, state) advances one time step; fm_morph_tet_vertices() gives a frame, and
 *   fm_morph_run() steps and writes every frame to a cache (cache.h) under one fm_run_control (run.h). */
#ifndef FLOCKMORPH_MORPH_H
#define FLOCKMORPH_MORPH_H

#include "flockmorph/cache.h"
#include "flockmorph/run.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct fm_morph_model fm_morph_model;


fm_morph_model *fm_morph_model_build(const fm_scene_def *def, fm_progress_fn progress, void *user,
                         fm_error *err);
void fm_morph_model_destroy(fm_morph_model *model);

/* Radius-edge ratio (circumradius / shortest edge, what TetGen's -q bounds) over a tet set. */
typedef struct fm_morph_tet_quality {
    double bound;               /* the scene's tetgen.quality, the bound asked of TetGen */
    double max_ratio;           /* the largest ratio */
    double share_above;         /* fraction of the tets whose ratio exceeds the bound */
    double share_above_4;       /* fraction of the tets whose ratio exceeds 4.0 (issue 38's hard limit) */
    double median_ratio;        /* the (lower) median ratio */
} fm_morph_tet_quality;

typedef struct fm_morph_model_info {
    int64_t agents;             /* n */
    int64_t source_tets;        /* n1: TetGen's count before subdivision */
    int64_t target_tets;        /* n2 */
    int64_t source_refined_tets; /* TetGen's count under the volume bound chosen for about n tets, before the
                                    longest-edge splits (tetgen.subdivision "bisect"); source_tets when
                                    TetGen did not run again */
    int64_t target_refined_tets;
    double source_volume;       /* total volume of the source tets after subdivision */
    double target_volume;
    double source_centroid[3];  /* C_S */
    double target_centroid[3];  /* C_T */
    double sphere_center[3];    /* exact minimal bounding sphere of the target (phase switch) */
    double sphere_radius;
    int32_t key_points;         /* m + 2 key points Q_0..Q_{m+1} */
    int32_t path_routed;        /* stretches of the path rerouted round the obstacles (obstacles.route) */
    double detour_time;         /* obstacles.detour_time as used: seconds without progress near an obstacle
                                   before a tet takes the detour; 0 when tets never do */
    double time_step;           /* seconds per step */
    int32_t steps_per_frame;
    double launch_rate;         /* agents per second, after the default is applied */
    int fields_baked;           /* the style fields' noise is baked on style.grid (only where the grid
                                   resolves it: cells of at most a quarter of the noise scale) */
    double field_bake_error;    /* baked against direct, relative RMS at t = 0; NaN when not baked */
    double field_fade_distance; /* style.fade_distance as used: omega2 V_l fades to 0 over this distance
                                   outside the switch sphere; 0 when it does not fade */
    double field_fade_time;     /* style.fade_time as used: seconds of flight after which omega2 V_l
                                   fades out (over as long again); 0 when it never does */
    fm_morph_tet_quality source_quality;        /* the n source tets the agents are (after subdivision) */
    fm_morph_tet_quality target_quality;        /* the n target tets */
    fm_morph_tet_quality source_tetgen_quality; /* TetGen's n1 tets, before subdivision */
    fm_morph_tet_quality target_tetgen_quality; /* TetGen's n2 tets */
} fm_morph_model_info;

fm_morph_model_info fm_morph_model_get_info(const fm_morph_model *model);

/* Input the engine accepts but the paper does not expect (source and target overlapping, FM §4),
 * one message per warning, naming the scene file and key. The CLI prints them and lists them in
 * stats.json "warnings". */
int fm_morph_model_warning_count(const fm_morph_model *model);
const char *fm_morph_model_warning(const fm_morph_model *model, int i);

/* Target tet j's four vertices (12 floats, x y z per vertex) in world units. */
const float *fm_morph_model_target_tet(const fm_morph_model *model, int64_t j);

typedef struct fm_morph_state fm_morph_state;

/* threads <= 0 uses OpenMP's default. Results do not depend on the thread count. */
fm_morph_state *fm_morph_state_create(const fm_morph_model *model, int threads, fm_error *err);
void fm_morph_state_destroy(fm_morph_state *state);

void fm_morph_step(const fm_morph_model *model, fm_morph_state *state);

typedef struct fm_morph_info {
    fm_run_info run;           /* step, time, agents per fm_phase */
    int all_arrived;
    int64_t morph_fallbacks;   /* agents whose correspondence needed the safe A(t) form */
    int64_t flying_agent_steps;/* phase-1 agent-steps so far ... */
    int64_t mde_agent_steps;   /* ... and those among them that MDE pushed (FM §5.4) */
    int64_t detour_agent_steps; /* ... and those on a detour round an obstacle (issue 38) */
    double min_obstacle_clearance; /* smallest d_t - R_X seen in phase 1; +inf without obstacles */
} fm_morph_info;

fm_morph_info fm_morph_get_info(const fm_morph_state *state);

/* Writes every agent's tet, 12 floats per agent (4 vertices × xyz), agents in id order.
 * Computes the morph (FM §6) for agents in phase 2. */
void fm_morph_tet_vertices(const fm_morph_model *model, const fm_morph_state *state, float *out);

/* Target tet index each agent holds (-1 while it has none), agents in id order. */
void fm_morph_targets(const fm_morph_state *state, int64_t *out);

/* Each agent's fm_phase (one byte per agent), agents in id order. */
void fm_morph_phases(const fm_morph_state *state, uint8_t *out);

/* An agent that had not arrived when a run stopped at its frame limit (issue 38). */
enum { FM_MORPH_STRAGGLERS_LISTED = 8 };
typedef struct fm_morph_straggler {
    int64_t id;                     /* agent id (its launch rank, D1) */
    int phase;                      /* fm_phase: waiting, flying or homing */
    double sphere_distance;         /* its centroid's distance outside the switch sphere (< 0: inside) */
} fm_morph_straggler;

typedef struct fm_morph_run_stats {
    fm_run_totals run;              /* frames, steps, seconds stepping (fm_morph_step) and writing */
    int all_arrived;
    int stopped_at_frame_limit;
    int64_t inverted_tet_frames;    /* tet-frames with signed volume <= 0 */
    double final_max_vertex_error;  /* last frame vs the target tets (ground truth, double) */
    int target_tets_filled_once;    /* every target tet taken by exactly one agent */
    int64_t morph_fallbacks;
    int64_t detour_agent_steps;     /* phase-1 agent-steps on a detour round an obstacle (issue 38) */
    double *mde_fraction;           /* per frame after frame 0: MDE agent-steps / phase-1 agent-steps,
                                       NaN for frames with nobody in phase 1; free with fm_morph_run_stats_free */
    double mde_fraction_mean;       /* mean over the frames with agents in phase 1 (FM Table I) */
    double min_obstacle_clearance;  /* smallest d_t - R_X in phase 1; +inf without obstacles */
    double min_vertex_clearance;    /* smallest fm_morph_vertex_clearance over the frames written */
    int64_t stragglers[4];          /* agents not arrived at the end, per fm_phase (arrived: 0) */
    int stragglers_listed;          /* the first of them by id, at most FM_MORPH_STRAGGLERS_LISTED */
    fm_morph_straggler straggler[FM_MORPH_STRAGGLERS_LISTED];
} fm_morph_run_stats;

void fm_morph_run_stats_free(fm_morph_run_stats *stats);

/* Steps until every agent has arrived or def.frame_limit frames are written, writing each frame
 * to `cache` (may be NULL) and measuring the run. */
fm_status fm_morph_run(const fm_morph_model *model, fm_morph_state *state, fm_cache_writer *cache,
                 fm_run_progress_fn progress, void *user, fm_morph_run_stats *stats, fm_error *err);

/* fm_morph_run with checkpoints, a stop flag and resume. The cache and stats of a run stopped and resumed
 * any number of times are bitwise those of an uninterrupted run (timings aside). */
fm_status fm_morph_run_controlled(const fm_morph_model *model, fm_morph_state *state, fm_cache_writer *cache,
                            const fm_run_control *control, fm_morph_run_stats *stats, fm_error *err);

/* Writes the run's state and statistics after stats->frames frames to `path` (as PATH.partial,
 * fsync'ed, then renamed): docs/resume.md describes the file. */
fm_status fm_morph_checkpoint_save(const char *path, const fm_morph_model *model, const fm_morph_state *state,
                             const fm_morph_run_stats *stats, fm_error *err);

/* Restores a checkpoint into `state` (fresh from fm_morph_state_create for `model`) and `stats` (free
 * them with fm_morph_run_stats_free), after the checks of fm_checkpoint_check and a check that `model`
 * is the one it was written from (same tets after TetGen and subdivision, same obstacles). On
 * failure state is unusable and stats hold nothing to free. */
fm_status fm_morph_checkpoint_load(const char *path, const fm_morph_model *model, fm_morph_state *state, fm_morph_run_stats *stats,
                             fm_error *err);

/* The smallest signed distance (negative inside) from the scene's obstacles of any vertex of n tets
 * (n × 12 floats, e.g. a frame): measured exactly (Embree's closest point) at every vertex whose
 * distance-grid value is within two voxels of the smallest, so it is the true minimum. When every
 * vertex is beyond the grid's band (k_a plus the largest tet radius plus two voxels) it is the
 * band's width, a lower bound; +inf without obstacles. Does not depend on the thread count. */
double fm_morph_vertex_clearance(const fm_morph_model *model, const float *verts, size_t n);

/* ---------------------------------------------------------------- shots (docs/scene.md, "Groups")
 *
 * Several morphs in one shot: the groups of one scene file (fm_scene_load_group 0 .. count-1) on
 * one clock, written to one cache with a `group` attribute. A group starts `start` seconds into the
 * shot or after its `after` group has arrived; a group whose source is another's formed shape takes
 * over that group's agents (their cache rows) and flies on from where they stand; a group's
 * `avoid` list makes those groups' shapes obstacles to it (their target if it flies after them,
 * their source if before). Checkpoints and resume as fm_morph_run_controlled's (fm_shot_run). */
typedef struct fm_shot fm_shot;

fm_shot *fm_shot_build(const fm_scene_def *defs, int count, int threads, fm_progress_fn progress, void *user,
                       fm_error *err);
void fm_shot_destroy(fm_shot *shot);
void fm_shot_set_threads(fm_shot *shot, int threads); /* <= 0: OpenMP's default; results do not depend on it */
int fm_shot_groups(const fm_shot *shot);
int64_t fm_shot_rows(const fm_shot *shot);   /* agents in the cache: the n of each group from a mesh */
const fm_morph_model *fm_shot_model(const fm_shot *shot, int g);
const fm_morph_state *fm_shot_state(const fm_shot *shot, int g); /* NULL until fm_shot_run (on P ranks fm_shot_distribute) makes it */

typedef struct fm_shot_group_stats {
    int64_t agents;
    int all_arrived;
    double start_time, arrival_time;  /* seconds into the shot; NaN when it never started or arrived */
    double final_max_vertex_error;    /* as fm_morph_run_stats' (INFINITY unless all arrived) */
    int target_tets_filled_once;
    int64_t inverted_tet_frames;      /* over the frames it wrote */
    double min_vertex_clearance;      /* fm_morph_vertex_clearance against its own obstacles, over the frames it wrote */
    double min_obstacle_clearance;    /* smallest d_t - R_X its flying tets saw */
    double mde_fraction;              /* MDE agent-steps / flying agent-steps over its flight */
} fm_shot_group_stats;

typedef struct fm_shot_stats {
    fm_run_totals run;
    int64_t rows;
    int all_arrived;
    int64_t inverted_tet_frames;
    double min_vertex_clearance;      /* the smallest of the groups' */
    fm_shot_group_stats group[FM_MAX_GROUPS];
} fm_shot_stats;

/* Steps until every group has arrived or the frame limit, writing every frame to `cache` (may be
 * NULL; created with FM_ATTR_TET_VERTICES and any of FM_ATTR_ID, FM_ATTR_PHASE, FM_ATTR_GROUP).
 * control's stop flag, progress, checkpoints and resume are honoured as fm_morph_run_controlled's:
 * the checkpoint is control->checkpoint_path and, beside it, each group's state at the frames it
 * counts (PATH.f<F>.g<G>; docs/resume.md "Shots"). A resumed run (control->resume) continues the
 * shot and the stats fm_shot_checkpoint_load restored. */
fm_status fm_shot_run(fm_shot *shot, fm_cache_writer *cache, const fm_run_control *control, fm_shot_stats *stats,
                      fm_error *err);
/* Restores a shot saved by fm_shot_run (built from the same scene) and its statistics so far. */
fm_status fm_shot_checkpoint_load(fm_shot *shot, const char *path, fm_shot_stats *stats, fm_error *err);
/* fm_checkpoint_check for a shot's file, against its first group's scene (fm_scene_load_group 0). */
fm_status fm_shot_checkpoint_check(const char *path, const fm_scene_def *group0, fm_error *err);

/* Number of tets (n × 12 floats) with signed volume <= 0. */
int64_t fm_count_inverted_tets(const float *verts, size_t n);

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_MORPH_H */
