/* flockmorph's shape-constrained flock (SCF; scene "mode": "shape_flock", docs/shape-flock.md):
 * n point agents start on samples of the source surface, each is given a sample of the target
 * surface as its destination,
 * and they fly there as boids along the global path, homing through a Kalman filter and weighted by
 * fuzzy curves, then bind to (or float around) their destinations, which follow the target when it
 * deforms. The same model/state split as the tetra morph: the model is immutable, the state holds
 * the agent store. Agents use fm_phase: FM_PHASE_FLYING under forces, FM_PHASE_HOMING in the stepped
 * approach, FM_PHASE_ARRIVED bound or floating. */
#ifndef FLOCKMORPH_FLOCK_H
#define FLOCKMORPH_FLOCK_H

#include "flockmorph/cache.h"
#include "flockmorph/run.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct fm_flock_model fm_flock_model;
typedef struct fm_flock_state fm_flock_state;

/* Requires def->mode == FM_MODE_SHAPE_FLOCK and def->n > 0. */
fm_flock_model *fm_flock_model_build(const fm_scene_def *def, fm_progress_fn progress, void *user,
                                     fm_error *err);
void fm_flock_model_destroy(fm_flock_model *model);

typedef struct fm_flock_model_info {
    int64_t agents;
    double source_center[3];   /* O1: the mean of the source samples */
    double target_center[3];   /* O2: the mean of the target samples (at time 0) */
    double path_length;        /* of the B-spline from O1 to O2 */
    double path_time;          /* seconds each leader takes along its path, eased in and out */
    double leaders_end;        /* seconds until the last leader arrives: path_time + shape_flock.ease.spread */
    double time_step;
    int32_t steps_per_frame;
    double max_radius;         /* the largest perception radius: the neighbour grid's cell */
    int deforming;             /* the target moves: it deforms (fm_deform_kind != NONE) or travels */
    double travel_length;      /* a travelling target's route (target.path.points): its length (0: none), */
    double travel_start, travel_end; /* and when it sets off and stops, s (NaN without a route) */
    int fields_baked;          /* as fm_morph_model_info's */
    double field_bake_error;
} fm_flock_model_info;

fm_flock_model_info fm_flock_model_get_info(const fm_flock_model *model);

/* Accepted but unusual input, one message per warning naming the scene file and key (as
 * fm_morph_model_warning): a style.grid too coarse for the noise, which is then evaluated directly. */
int fm_flock_model_warning_count(const fm_flock_model *model);
const char *fm_flock_model_warning(const fm_flock_model *model, int i);

/* Every agent's start C1 and its destination C2 at time 0, 3 floats per agent (either may be NULL). */
void fm_flock_model_endpoints(const fm_flock_model *model, float *c1, float *c2);

/* threads <= 0 uses OpenMP's default. Results do not depend on the thread count. */
fm_flock_state *fm_flock_state_create(const fm_flock_model *model, int threads, fm_error *err);
void fm_flock_state_destroy(fm_flock_state *state);

void fm_flock_step(const fm_flock_model *model, fm_flock_state *state);

/* The step, the time and the agents per fm_phase. */
fm_run_info fm_flock_get_info(const fm_flock_state *state);

/* The current frame, agents in id order; any output may be NULL. position and velocity: 3 floats
 * per agent; orientation: 4 floats (w x y z), the frame with x along the velocity and z toward world
 * +Z (kept while the agent is at rest); phase: one fm_phase byte. */
void fm_flock_frame(const fm_flock_state *state, float *position, float *velocity, float *orientation,
                    uint8_t *phase);

/* The current destinations, 3 floats per agent. */
void fm_flock_destinations(const fm_flock_state *state, float *out);

/* Mean and largest distance of the agents to their current destinations. */
void fm_flock_distance(const fm_flock_state *state, double *mean, double *max);

/* A cache with the flock's attributes: position, velocity, orientation and phase. */
fm_cache_writer *fm_flock_cache_create(const char *path, const fm_flock_model *model,
                                       const fm_cache_options *opts, fm_error *err);

/* The flock measures of a frame (docs/stats.md, "Flock measures"), what a user tunes against. Over
 * the agents in flight (not bound): polarisation, the norm of the mean unit velocity (1: all fly the
 * same way); the mean nearest-neighbour distance (among agents in flight, from up to 1,024 of them
 * spread evenly over the ids; NaN with fewer than 2 in flight); the mean distance from the agent's
 * own eq-12 path point (its virtual leader); the mean speed. Over all agents: the mean distance to
 * the destination. And the fraction of agents in flight. NaN where no agent is in flight. And the
 * look (tools/flock-look.py's figures, every FM_LOOK_EVERY-th frame on a fixed sample of up to 256
 * agents, NaN on the others): neighbour persistence over 1 s, neighbour coherence and acceleration
 * smoothness at a lag of 4 frames, each ending at the frame (src/flock/flock_look.c says how). */
typedef enum fm_flock_measure {
    FM_FLOCK_POLARISATION = 0,
    FM_FLOCK_NN_DISTANCE = 1,
    FM_FLOCK_LEADER_DISTANCE = 2,
    FM_FLOCK_SPEED = 3,
    FM_FLOCK_DESTINATION_DISTANCE = 4,
    FM_FLOCK_IN_FLIGHT = 5,
    FM_FLOCK_PERSISTENCE = 6,
    FM_FLOCK_COHERENCE = 7,
    FM_FLOCK_SMOOTHNESS = 8,
    FM_FLOCK_MEASURES = 9
} fm_flock_measure;

/* Their names in stats.json: "polarisation", "nn_distance", "leader_distance", "speed",
 * "destination_distance", "in_flight", "persistence", "coherence", "smoothness". */
extern const char *const fm_flock_measure_names[FM_FLOCK_MEASURES];

/* The measures of the state's current positions into out[FM_FLOCK_MEASURES]. The same for any
 * thread count. Rebuilds the state's neighbour grid (the next step rebuilds it anyway). */
void fm_flock_measure_frame(const fm_flock_model *model, fm_flock_state *state, double out[FM_FLOCK_MEASURES]);

typedef struct fm_flock_run_stats {
    fm_run_totals run;              /* frames, steps, seconds stepping (fm_flock_step) and writing */
    int all_bound;                  /* every agent bound or floating at its destination */
    int stopped_at_frame_limit;
    double final_mean_distance;     /* to the destination, at the last frame */
    double final_max_distance;
    double bound_fraction;          /* agents in FM_PHASE_ARRIVED at the last frame */
    double tracking_lag;            /* deforming target: mean distance to the moving destination over
                                       the frames after leaders_end; NaN for a static target */
    int64_t tracking_frames;        /* frames that mean is taken over */
    double *measures;               /* per frame after frame 0, FM_FLOCK_MEASURES each: row k - 1 is
                                       frame k's (malloc'ed; fm_flock_run_stats_free) */
    double measures_mean[FM_FLOCK_MEASURES];       /* over the frames with agents in flight */
    double measures_mid_flight[FM_FLOCK_MEASURES]; /* at the frame nearest half the path time */
} fm_flock_run_stats;

/* Frees stats->measures (and sets it to NULL); stats from a run or a checkpoint load. */
void fm_flock_run_stats_free(fm_flock_run_stats *stats);


/* Steps until every agent is bound (static targets only) or def.frame_limit frames are written,
 * writing each frame to `cache` (from fm_flock_cache_create; may be NULL). */
fm_status fm_flock_run(const fm_flock_model *model, fm_flock_state *state, fm_cache_writer *cache,
                       fm_run_progress_fn progress, void *user, fm_flock_run_stats *stats, fm_error *err);

/* fm_flock_run with checkpoints, a stop flag and resume: the cache of a run stopped and resumed any
 * number of times is bitwise that of an uninterrupted run, and so are its stats (timings aside). */
fm_status fm_flock_run_controlled(const fm_flock_model *model, fm_flock_state *state, fm_cache_writer *cache,
                                  const fm_run_control *control, fm_flock_run_stats *stats, fm_error *err);

/* The shape flock's checkpoint: the same file as fm_morph_checkpoint_save's (docs/resume.md) with the
 * flock's store and statistics. fm_checkpoint_check serves both modes. */
fm_status fm_flock_checkpoint_save(const char *path, const fm_flock_model *model, const fm_flock_state *state,
                                   const fm_flock_run_stats *stats, fm_error *err);
/* Restores it into `state` (fresh from fm_flock_state_create for `model`) and `stats`, after the
 * checks of fm_checkpoint_check and a check that `model` is the one it was written from. */
fm_status fm_flock_checkpoint_load(const char *path, const fm_flock_model *model, fm_flock_state *state,
                                   fm_flock_run_stats *stats, fm_error *err);

/* ---------------------------------------------------------------- shots (docs/scene.md, "Groups")
 *
 * A shape flock that "transforms among different static shapes" (SCF): the groups of one scene file
 * (fm_scene_load_group 0 .. count-1) on one clock, written to one cache with a `group` attribute. A
 * group from a mesh adds its n agents; a group whose source is another's formed shape ("source":
 * {"group": A}) takes over A's agents (the same rows), starting where A bound them, once A has bound
 * them all and `start` seconds later. A's target must be static and bind. */
typedef struct fm_flock_shot fm_flock_shot;

fm_flock_shot *fm_flock_shot_build(const fm_scene_def *defs, int count, fm_progress_fn progress, void *user,
                                   fm_error *err);
void fm_flock_shot_destroy(fm_flock_shot *shot);
void fm_flock_shot_set_threads(fm_flock_shot *shot, int threads); /* <= 0: OpenMP's default */
int fm_flock_shot_groups(const fm_flock_shot *shot);
int64_t fm_flock_shot_rows(const fm_flock_shot *shot);
const fm_flock_model *fm_flock_shot_model(const fm_flock_shot *shot, int g);

typedef struct fm_flock_shot_group_stats {
    int64_t agents;
    int all_bound;                  /* every agent bound (a static target that binds) */
    double start_time, bound_time;  /* seconds into the shot; NaN when it never started or bound all */
    double final_mean_distance;     /* to the destination, at the last frame */
    double final_max_distance;
    double bound_fraction;
    double measures_mean[FM_FLOCK_MEASURES]; /* its flock measures' mean over the frames it had agents in flight */
} fm_flock_shot_group_stats;

typedef struct fm_flock_shot_stats {
    fm_run_totals run;
    int64_t rows;
    int all_bound;                  /* every group bound all its agents */
    fm_flock_shot_group_stats group[FM_MAX_GROUPS];
    int groups;                     /* the groups measured */
    double *measures;               /* per frame after frame 0, groups * FM_FLOCK_MEASURES each: row k - 1
                                       is frame k's, group g's measures from g * FM_FLOCK_MEASURES, NaN
                                       where it has not started or has bound all (malloc'ed;
                                       fm_flock_shot_stats_free) */
} fm_flock_shot_stats;

/* Frees stats->measures (and sets it to NULL). */
void fm_flock_shot_stats_free(fm_flock_shot_stats *stats);

/* Steps until every group has bound its agents or the frame limit, writing every frame to `cache`
 * (may be NULL; created with FM_ATTR_POSITION and any of FM_ATTR_VELOCITY, FM_ATTR_ORIENTATION,
 * FM_ATTR_ID, FM_ATTR_PHASE, FM_ATTR_GROUP). control's stop flag, progress, checkpoints and resume
 * are honoured as fm_shot_run's (the groups' states beside the checkpoint, docs/resume.md "Shots"). */
fm_status fm_flock_shot_run(fm_flock_shot *shot, fm_cache_writer *cache, const fm_run_control *control,
                            fm_flock_shot_stats *stats, fm_error *err);
/* Restores a shot saved by fm_flock_shot_run (built from the same scene) and its statistics so far. */
fm_status fm_flock_shot_checkpoint_load(fm_flock_shot *shot, const char *path, fm_flock_shot_stats *stats,
                                        fm_error *err);
/* fm_checkpoint_check for a shape-flock shot's file, against its first group's scene. */
fm_status fm_flock_shot_checkpoint_check(const char *path, const fm_scene_def *group0, fm_error *err);

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_FLOCK_H */
