/* The shape-constrained flock (SCF): the internal layout of fm_flock_model and fm_flock_state.
 *
 * It shares the machinery of the wings below (docs/architecture.md): SoA arrays from fm_alloc indexed by agent id, FM_BLOCK
 * blocks on OpenMP threads with per-block counts combined in block order, the counting-sort
 * neighbour grid (grid.h), the style fields (fields.h: SCF eqs 7-8's vortex, wind), the obstacle
 * distance field (obstacles.h), the cache and the frame loop (frame_loop.h). Why its store is not
 * fm_morph_state: docs/architecture.md, "What the two modes share". */
#ifndef FM_FLOCK_H
#define FM_FLOCK_H

#include "checkpoint.h"
#include "fields.h"
#include "flock_bspline.h"
#include "flock_fuzzy.h"
#include "flock_kalman.h"
#include "grid.h"
#include "kernel_boids.h"
#include "memory.h"
#include "obstacles.h"
#include "sample.h"
#include "scene_internal.h"
#include "slabs.h"

#include <stdint.h>

/* The target surface over time. Every agent's destination is a point of it given by a triangle and
 * barycentric coordinates (SCF: samples are drawn once, on the first shape, and follow the vertices
 * of a deforming one). */
typedef struct fm_flock_target {
    fm_deform_kind kind;
    fm_mesh mesh;          /* the placed target at rest */
    double *normals;       /* wave: unit vertex normals, 3 per vertex */
    double center[3];      /* pulse: the centre it scales about (mean of the vertices) */
    double *frames;        /* sequence: deform_frames vertex arrays, 3 * nv doubles each */
    int32_t *file_vertex;  /* sequence: the welded vertex of each of the target file's vertices as read */
    int64_t file_count;
    fm_samples dest;       /* agent a's destination: dest.tri[a], dest.bary[3a..], dest.p at rest */
} fm_flock_target;

struct fm_flock_model {
    fm_scene_def def;
    fm_flock_model_info info;
    int64_t n;
    double dt;
    int32_t steps_per_frame;
    float *start[3];               /* C1: the agent's source sample */
    float *dest0[3];               /* C2 at time 0 */
    fm_flock_target target;
    fm_bspline path;               /* R from O1 to O2, by arc length */
    double o1[3], o2[3];
    double path_time;
    /* per-agent parameters, drawn from the scene's ranges */
    float *radius[FM_BOIDS_RULES], *cos_half[FM_BOIDS_RULES], *weight[FM_BOIDS_RULES];
    float *max_speed, *max_force;
    float *max_accel;              /* MaxForce / mass: bounds each force's acceleration */
    float max_radius;              /* the neighbour grid's cell */
    fm_fuzzy fuzzy[FM_FUZZY_FORCES];
    fm_fuzzy r_scale;              /* R's factor over def.flock.kalman_r_over (unused when R is fixed) */
    fm_field_plan fields;          /* whether the state bakes the style fields (fields.h) */
    char warning[1024];            /* fm_flock_model_warning 0: the fields' plan, located */
    fm_obstacles *obstacles;       /* NULL without obstacles */
    double scene_lo[3], scene_hi[3]; /* source, target and path, padded: the style-field grid spans them */
    const fm_flock_model *from;    /* during the build only: a shot's group starting from this one's shape */
};

/* A group of a shot that starts from the shape `from` formed (flock_shot.c): its agents are from's,
 * starting on from's destinations (a static target that binds). */
fm_flock_model *fm_flock_model_build_from_shape(const fm_scene_def *def, const fm_flock_model *from,
                                                fm_progress_fn progress, void *user, fm_error *err);

/* Per-block results of a step, combined in block order. */
typedef struct flock_block {
    int64_t count[4];  /* agents per fm_phase after the step */
} flock_block;

struct fm_flock_state {
    int64_t n;
    int64_t step;
    double time;
    int threads;
    float *p[3], *v[3];
    float *orient;                 /* 4 per agent: w x y z */
    uint8_t *phase;                /* fm_phase: FLYING forces, HOMING stepped approach, ARRIVED bound */
    float *t_bind;                 /* when the agent bound (floating offsets start there) */
    float *dest[3], *dest_v[3];    /* the destination at the end of the step and its velocity */
    float *leader[3], *leader_v[3];/* the virtual leader (Kalman measurement) and its velocity */
    float *acc[3];                 /* scratch: the step's acceleration */
    float *steer[3];               /* scratch: the weighted boids steering (before it shares MaxForce with homing) */
    float *ext[3];                 /* scratch: the style fields at the agent, then the homing acceleration */
    float *w_homing;               /* scratch: the homing weight */
    double *mesh_v;                /* deforming: the target's vertices at the current time */
    float *eval;                   /* deforming: destinations, 3 per agent (fm_samples_eval) */
    uint8_t *member;               /* every agent is listed in the grid */
    fm_kalman kalman;              /* the covariance and gain, shared by all agents (flock_kalman.h) */
    double *kalman_p;              /* R over the run: each agent's own covariance, 3 per agent; else NULL */
    float *r_scale;                /* R over the run: scratch, the agent's factor of R this step */
    fm_fields *fields;
    fm_grid grid;
    int grid_ready;
    int grid_current;              /* the grid is the one the next step would build (fm_flock_measure_frame) */
    flock_block *blocks;
    int64_t count[4];
    double lag_sum;                /* fm_flock_run: the tracking lag's sum over its frames so far */
    /* On P ranks (flock_dist.c; NULL on one process): this rank computes the agents of its slab;
     * the others have phase FM_FLOCK_ELSEWHERE here. */
    const fm_dist *dist;
    fm_slabs *slabs;
    fm_status dist_status;         /* a failed exchange (agreed by every rank): the step stops, the frame reports it */
    fm_error dist_error;
    void *gathered;                /* rank 0 during a frame: the records received (fm_flock_dist_gather) */
    int64_t gathered_count;
    size_t gathered_size;          /* bytes a record */
};

/* On P ranks, the phase of an agent another rank computes: no stage of the step handles it. */
#define FM_FLOCK_ELSEWHERE 0xFF

/* flock_state.c: the members a checkpoint saves (checkpoint.h), in file order. */
extern const fm_store_member fm_flock_state_members[];
extern const int fm_flock_state_member_count;

/* flock_target.c: the target's vertices at time t (nv * 3 doubles) */
fm_status fm_flock_target_build(fm_flock_target *t, const fm_scene_def *def, fm_error *err);
void fm_flock_target_free(fm_flock_target *t);
void fm_flock_target_vertices(const fm_flock_target *t, const fm_flock_def *def, double time, double *out);

/* flock_memory.c: the shape flock's bytes for n agents (docs/limits.md), and the refusal of a run
 * that does not fit (memory.h). */
fm_memory_estimate fm_flock_memory_estimate(const fm_scene_def *def, int64_t n);
fm_status fm_flock_memory_check(const fm_scene_def *def, int64_t n, fm_error *err);

/* flock_dist.c: the shape flock on P ranks (docs/scale-out.md). distribute makes s (fresh from
 * fm_flock_state_create) one rank's share; adopt does the same after every rank loaded the same
 * checkpoint. Per step: migrate before mark_flock, ghosts after it, after_step at the end. At a
 * frame: gather (rank 0 then holds every agent), release after the frame. */
fm_status fm_flock_state_distribute(const fm_flock_model *m, fm_flock_state *s, const fm_dist *dist, fm_error *err);
void fm_flock_dist_adopt(fm_flock_state *s);
fm_dist_totals fm_flock_dist_get_totals(const fm_flock_state *s);
fm_status fm_flock_dist_migrate(fm_flock_state *s, fm_error *err);
fm_status fm_flock_dist_ghosts(fm_flock_state *s, fm_error *err);
void fm_flock_dist_after_step(fm_flock_state *s, double busy_seconds);
fm_status fm_flock_dist_gather(fm_flock_state *s, fm_error *err);
/* flock_state.c: agents begin … end − 1 of a frame (fm_flock_frame's arrays, in id order from
 * agent begin at index 0); the mean and
 * largest distance to the destinations over the blocks of [begin, end) (whole FM_BLOCK blocks),
 * on P ranks (d) every rank's share summed on rank 0 in block order (NaN elsewhere). */
void fm_flock_frame_range(const fm_flock_state *s, int64_t begin, int64_t end, float *position, float *velocity,
                          float *orientation, uint8_t *phase);
void fm_flock_distance_blocks(const fm_flock_state *s, int64_t begin, int64_t end, const fm_dist *d, double *mean,
                              double *max);
/* flock_measures.c: fm_flock_measure_frame on P ranks from their shares (ids begin[r] … begin[r + 1]
 * − 1, runs of whole FM_BLOCK blocks, complete on their ranks: fm_flock_dist_share); out on rank 0. */
fm_status fm_flock_measure_frame_shared(const fm_flock_model *m, fm_flock_state *s, const int64_t *begin,
                                        double out[FM_FLOCK_MEASURES], fm_error *err);

/* The cache written in parallel: this rank's share of the ids (begin[rank] … begin[rank + 1] − 1)
 * complete in its arrays, from every rank; release after the frame. */
fm_status fm_flock_dist_share(fm_flock_state *s, const int64_t *begin, fm_error *err);
/* s->member: this rank's own agents in flight (its slab's), not the share's agents it received. */
void fm_flock_dist_own_in_flight(fm_flock_state *s);
void fm_flock_dist_release(fm_flock_state *s);
/* Checkpoints on P ranks: each rank writes the agents of its share of the pieces, rank 0 the rest. */
fm_status fm_flock_checkpoint_write(const char *path, const fm_flock_model *m, const fm_flock_state *s,
                                    const fm_flock_run_stats *stats, int64_t frames, const fm_ckpt_part *parts,
                                    int part_count, fm_error *err);
fm_status fm_flock_dist_checkpoint_save(const char *path, const fm_flock_model *m, fm_flock_state *s,
                                        const fm_flock_run_stats *stats, int64_t frames, fm_error *err);
/* A shot's group (flock_shot.c): the state alone, without statistics, at `frames` frames (on P
 * ranks collective, as fm_flock_dist_checkpoint_save); its load, on P ranks then adopt. */
fm_status fm_flock_group_checkpoint_save(const char *path, const fm_flock_model *m, fm_flock_state *s, int64_t frames,
                                         fm_error *err);
fm_status fm_flock_group_checkpoint_load(const char *path, const fm_flock_model *m, fm_flock_state *s, int64_t *frames,
                                         fm_error *err);

/* flock_shot.c: a shot on P ranks: every group's state one rank's share; each writing group
 * gathered on rank 0 at a frame. */
fm_status fm_flock_shot_distribute(fm_flock_shot *s, const fm_dist *dist, fm_error *err);
const fm_flock_state *fm_flock_shot_state(const fm_flock_shot *s, int g);

/* flock_state.c */
void fm_flock_update_orientation(float *q, const float v[3]);

#endif
