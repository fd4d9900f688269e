/* The shape-constrained flock (SCF): the internal layout of fm_flock_model and fm_flock_state.
 *
 * It shares the machinery of the wings below (docs/architecture.md): SoA arrays from fm_alloc indexed by slot (on
 * one process re-sorted in space every few steps, flock_resort.c, id[] naming each slot's agent; on P ranks a
 * rank's agents in id order, flock_dist.c), FM_BLOCK blocks on OpenMP threads with per-block counts combined in block order, the counting-sort
 * neighbour grid (grid.h), the style fields (fields.h: SCF eqs 7-8's vortex, wind), the obstacle
 * distance field (obstacles.h), the cache and the frame loop (frame_loop.h). Why its store is not
 * fm_morph_state: docs/architecture.md, "What the two modes share". */
#ifndef FM_FLOCK_H
#define FM_FLOCK_H

#include "checkpoint.h"
#include "dist.h"
#include "fields.h"
#include "flock_bspline.h"
#include "flock_fuzzy.h"
#include "flock_kalman.h"
#include "grid.h"
#include "kernel_boids.h"
#include "kernel_orient.h"
#include "memory.h"
#include "obstacles.h"
#include "path_route.h"
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
    /* travelling (target.path.points; route.count 0: it stays): the shape at time t is carried by
     * B(u) - B(0) and turned about B(0) by F(u) F(0)^T, u the route's eased arc-length fraction */
    fm_bspline route;      /* B through target.path.points, by arc length */
    double *route_normal;  /* the rotation-minimising frame's normal at each of route.arc's samples */
    double route_start;    /* seconds when it sets off (fm_flock_target_set_start) */
    double route_time;     /* seconds from setting off to stopping */
    double route_ease;     /* each speed ramp, as a fraction of route_time */
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
    double route_margin;           /* obstacles.route: R's clearance beyond k_a (flock_model.c route_path) */
    double path_time;              /* each leader's time along its path, eased in and out */
    double ease_in, ease_out;      /* the ramps, as fractions of path_time (their sum <= 1) */
    double ease_spread;            /* seconds from the first leaders' start to the last's */
    double ease_axis[3], ease_lo, ease_inv_range; /* delay = spread (1 - (axis . C1 - lo) inv_range) */
    /* per-agent parameters, drawn from the scene's ranges */
    float *radius[FM_BOIDS_RULES], *cos_half[FM_BOIDS_RULES], *weight[FM_BOIDS_RULES];
    float *max_speed, *max_force;
    float *max_accel;              /* MaxForce / mass: bounds each force's acceleration */
    float max_radius;              /* the neighbour grid's cell */
    fm_fuzzy fuzzy[FM_FUZZY_FORCES];
    int tracking;                  /* SCF Figure 6's tracking strategy runs (else the static one) */
    fm_fuzzy r_scale;              /* R's factor over def.flock.kalman_r_over (unused when R is fixed) */
    fm_field_plan fields;          /* whether the state bakes the style fields (fields.h) */
    char warning[1024];            /* fm_flock_model_warning 0: the fields' plan, located */
    fm_obstacles *obstacles;       /* NULL without obstacles */
    double scene_lo[3], scene_hi[3]; /* source, target and path, padded: the style-field grid spans them */
    const fm_flock_model *from;    /* during the build only: a shot's group starting from this one's shape */
    fm_dist_shared *shared;        /* on P ranks (fm_flock_model_build_shared): the segment the machine's
                                      ranks share, which holds the arrays of n above; NULL: each its own */
};

/* Agent a's path fraction at time t: its leader's arc-length fraction along R~, eased in and out and
 * delayed by its place in the source (flock_model.c set_ease). 1 from the leader's arrival on.
 * *blend: the formation's blend f at t (fm_path_map_blend; shape_flock.layout, shape_flock.reform),
 * 1 from the arrival on. */
double fm_flock_leader(const fm_flock_model *m, const float *const start[3], int64_t a, double t, double *blend);

/* When the last leader reaches its destination: path_time + ease_spread (0 without a path). */
double fm_flock_leaders_end(const fm_flock_model *m);

/* On P ranks: the first rank of each machine builds the model (the sampling, the preparation's
 * peak) and puts its arrays of n (100 bytes an agent) in memory the machine's ranks share; the
 * others copy its scalars and build the target's deformation, the path and the obstacles' grid
 * (fm_dist_build_shared: without shared memory each builds its own). Collective (docs/scale-out.md);
 * a failure on any rank is every rank's. */
fm_flock_model *fm_flock_model_build_shared(const fm_scene_def *def, const fm_dist *dist, fm_progress_fn progress,
                                            void *user, fm_error *err);
/* A shot's group from `from`'s formed shape (fm_flock_model_build_from_shape), the same way. */
fm_flock_model *fm_flock_model_build_from_shape_shared(const fm_scene_def *def, const fm_flock_model *from,
                                                       const fm_dist *dist, fm_progress_fn progress, void *user,
                                                       fm_error *err);

/* What a build keeps for the next build of an edited scene (flockmorph studio: docs/studio.md, "An
 * edit and the model"): the samples of both surfaces and the match, the obstacles' distance grids and
 * the path routed round them, each with what it was made from. A build given a keep samples and
 * matches again only where those inputs differ (the placed source and target meshes byte for byte,
 * n, seed and the keys of shape_flock's sampling and match), which a path, speed, boids, fuzzy or
 * style edit leaves; makes a grid again only where the placed obstacle meshes, its reach or
 * obstacles.voxel differ (fm_kept_grid), and routes R again only where its route grid or its key
 * (fm_route_key: O1, O2, the route's box, margin and obstacle boxes, the path keys) differ. Everything
 * else is built as always, and the model is the same bytes either way. */
typedef struct fm_flock_keep {
    int has;
    fm_mesh source, target;     /* the placed source mesh and the target at time 0, sampled */
    int64_t n;
    uint64_t seed;
    fm_flock_def flock;         /* the shape_flock keys it was made with (sampling, mosaic, match, uncross) */
    fm_samples src, tgt;        /* the samples */
    int64_t *match;             /* agent a's target sample */
    fm_kept_grid grid;          /* m->obstacles (reach k_a: eq 7's push) */
    fm_kept_grid route_grid;    /* the route's own (reach 2 k_a + the margin: route_setup) */
    int has_route, routed;      /* R was routed on route_grid from route_key; routed: through these points */
    fm_route_key route_key;
    double *route_points;
    int32_t route_count;
    int reused;                 /* the last build did not sample or match again */
    int grid_reused;            /* ... m->obstacles was the keep's (0 without obstacles) */
    int route_reused;           /* ... R routed round the obstacles was the keep's */
    const volatile sig_atomic_t *cancel; /* the studio's flag (NULL: none): where an edit sets it, the
                                            build stops at its next stage boundary with FM_STOPPED,
                                            nothing kept half-made (flock_model.c build) */
} fm_flock_keep;

/* fm_flock_model_build, keeping in *keep (zeroed at first) the samples and the match it makes, and
 * reusing the kept ones where they fit. */
fm_flock_model *fm_flock_model_build_keeping(const fm_scene_def *def, fm_flock_keep *keep, fm_progress_fn progress,
                                             void *user, fm_error *err);
void fm_flock_keep_clear(fm_flock_keep *keep);

/* A group of a shot that starts from the shape `from` formed (flock_shot.c): its agents are from's,
 * starting on from's destinations (a static target that binds). */
fm_flock_model *fm_flock_model_build_from_shape(const fm_scene_def *def, const fm_flock_model *from,
                                                fm_progress_fn progress, void *user, fm_error *err);
/* The same, keeping in *keep as fm_flock_model_build_keeping does: its source samples are from's
 * destinations, so the kept samples and match fit while those are the same bytes (and the target,
 * n, seed and sampling keys are as they were). */
fm_flock_model *fm_flock_model_build_from_shape_keeping(const fm_scene_def *def, const fm_flock_model *from,
                                                        fm_flock_keep *keep, fm_progress_fn progress, void *user,
                                                        fm_error *err);

/* The look's history (flock_look.c): a fixed sample's positions over the last frames and its
 * neighbour lists over the last second, kept in the store so that a checkpoint keeps them and a
 * resumed run measures what an uninterrupted one does. Frame rates above FM_LOOK_MAX_SECOND frames
 * a second have no look. */
enum { FM_LOOK_AGENTS = 256, FM_LOOK_K = 6, FM_LOOK_LAG = 4, FM_LOOK_EVERY = 4, FM_LOOK_MAX_SECOND = 60,
       FM_LOOK_HISTORY = 2 * FM_LOOK_MAX_SECOND + FM_LOOK_LAG + 2 };
typedef struct fm_flock_look {
    int64_t p_frame[FM_LOOK_HISTORY];                    /* frame + 1 each entry of p holds; 0: none */
    float p[FM_LOOK_HISTORY][FM_LOOK_AGENTS][3];         /* the sample's positions, ring by frame */
    int64_t nb_frame[FM_LOOK_MAX_SECOND + 1];            /* frame + 1 each entry of nb holds; 0: none */
    int32_t nb[FM_LOOK_MAX_SECOND + 1][FM_LOOK_AGENTS][FM_LOOK_K]; /* neighbour ids, -1: not in flight */
} fm_flock_look;

/* Per-block results of a step, combined in block order. */
typedef struct flock_block {
    int64_t count[4];  /* agents per fm_phase after the step */
} flock_block;

/* Each agent's parameters drawn by the model, by slot (flock_state.c): copies for the store's slots,
 * which move with their agents (the re-sort on one process, the migration on P ranks), so the step
 * and the kernels read them as they read the store; with the re-sort off (FM_FLOCK_RESORT=0) on one
 * process the model's own arrays (a slot is an agent id). */
typedef struct fm_flock_params {
    float *radius[FM_BOIDS_RULES], *cos_half[FM_BOIDS_RULES], *weight[FM_BOIDS_RULES];
    float *max_speed, *max_force, *max_accel;
    float *start[3]; /* C1: the source sample */
} fm_flock_params;

struct fm_flock_state {
    int64_t n;                     /* agents of the run */
    int64_t slots;                 /* entries of the per-slot arrays in use: n on one process */
    int64_t cap;                   /* entries the per-slot arrays hold */
    int64_t first;                 /* a share's view (flock_dist.c): the id of slot 0; else 0 */
    int32_t *id;                   /* each slot's agent (on P ranks increasing); NULL: slot a is agent first + a */
    int resort_every;              /* one process: the store re-sorted in space every this many steps
                                      (flock_resort.c; FM_FLOCK_RESORT); 0: in id order, id NULL */
    int sorted;                    /* the slots are not in id order (since the last re-sort) */
    int32_t *slot_by_id;           /* one process with the re-sort: each agent's slot (n entries) */
    int64_t step;
    double time;
    int threads;
    int own_kalman, deforming;     /* which optional arrays the store has (kalman_p and r_scale; eval) */
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
    fm_flock_params prm;
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
    fm_flock_look look;            /* the look's history (flock_look.c) */
    /* On P ranks (flock_dist.c; NULL on one process): the slots hold this rank's agents (those of
     * its slab) and, during a step, the ghosts of its halo (phase FM_FLOCK_ELSEWHERE), all by id. */
    const fm_dist *dist;
    fm_slabs *slabs;
    fm_status dist_status;         /* a failed exchange (agreed by every rank): the step stops, the frame reports it */
    fm_error dist_error;
    void *scratch;                 /* the slots' moves: one array's worth (cap entries of the largest) */
    int32_t *move_from;            /* the slots' moves: each new slot's old one (flock_dist.c merge_slots, flock_resort.c) */
    void *merge_buf;               /* merge_slots' incoming agents, kept between steps */
    size_t merge_bytes;
    struct fm_flock_state *view;   /* a frame's or a checkpoint's share of the ids, complete (flock_dist.c) */
};

/* On P ranks, the phase of a ghost, an agent another rank computes: no stage of the step handles it. */
#define FM_FLOCK_ELSEWHERE 0xFF

/* The agent in slot a. */
static inline int64_t fm_flock_id(const fm_flock_state *s, int64_t a) { return s->id ? s->id[a] : s->first + a; }

/* The slot of the store's i-th agent in id order (agent first + i): the frames, the measures' block
 * sums and the destinations read a re-sorted store through it, so they see one in id order. */
static inline int64_t fm_flock_slot_in_id_order(const fm_flock_state *s, int64_t i)
{
    return s->sorted ? s->slot_by_id[i] : i;
}

/* The neighbour grid's cell: the largest perception radius (1 without boids). */
static inline float fm_flock_cell(const fm_flock_model *m) { return m->max_radius > 0 ? m->max_radius : 1.0f; }

/* flock_resort.c: the store sorted in space (slots by their cell's slot in the next grid build, bound
 * agents last), every per-slot array carried along; back in id order for good (a checkpoint's load);
 * in id order for a moment (a checkpoint's save: begin returns whether it moved them, for end, which
 * puts every agent back in its slot, so a run's order, and its bytes, do not depend on when it saves).
 * One process only. */
enum { FM_FLOCK_RESORT_INTERVAL = 8 };
/* FM_FLOCK_RESORT, else FM_FLOCK_RESORT_INTERVAL; -1 (err set) for a value that is no interval */
int fm_flock_resort_interval(fm_error *err);
void fm_flock_state_resort(const fm_flock_model *m, fm_flock_state *s);
void fm_flock_state_in_id_order(fm_flock_state *s);
int fm_flock_state_id_order_begin(fm_flock_state *s);
void fm_flock_state_id_order_end(fm_flock_state *s, int begun);
/* flock_step.c: s->member[a] = agent a is listed by the step's neighbour grid (on its way: flying or
 * homing; on P ranks the ghosts too). */
void fm_flock_mark_members(fm_flock_state *s);

/* flock_state.c: the store without its agents, for `slots` agents (dist: a rank's, with ids and
 * parameters by slot, which the caller fills); room for `slots` (a quarter more, at most n); the
 * slots moved (new slot k from old slot from[k], or -1: written by the caller); a share's view
 * (flock_dist.c); agent id's parameters into slot `slot`; a deforming target's destination of agent
 * id at the time of s->mesh_v. */
fm_flock_state *fm_flock_state_alloc(const fm_flock_model *m, int threads, const fm_dist *dist, int64_t slots,
                                     fm_error *err);
fm_status fm_flock_state_reserve(fm_flock_state *s, int64_t slots, fm_error *err);
void fm_flock_state_move_slots(fm_flock_state *s, const int32_t *from, int64_t slots);
fm_flock_state *fm_flock_state_view(fm_flock_state *s, int64_t first, int64_t count, int grid, fm_error *err);
void fm_flock_state_start(const fm_flock_model *m, fm_flock_state *s); /* the agents of the slots at rest */
void fm_flock_params_copy(const fm_flock_model *m, fm_flock_params *prm, int64_t slot, int64_t id);
void fm_flock_destination_of(const fm_flock_model *m, const fm_flock_state *s, int64_t id, float out[3]);

/* flock_state.c: the members a checkpoint saves (checkpoint.h), in file order. */
extern const fm_store_member fm_flock_state_members[];
extern const int fm_flock_state_member_count;

/* flock_target.c: the target's vertices at time t (nv * 3 doubles) */
fm_status fm_flock_target_build(fm_flock_target *t, const fm_scene_def *def, fm_error *err);
void fm_flock_target_free(fm_flock_target *t);
void fm_flock_target_vertices(const fm_flock_target *t, const fm_flock_def *def, double time, double *out);
/* A travelling target's start: target.path.start, or the leaders' end when that is < 0. */
void fm_flock_target_set_start(fm_flock_target *t, const fm_flock_def *def, double leaders_end);
/* When a travelling target stops (0 for one that does not travel). */
double fm_flock_target_travel_end(const fm_flock_target *t);
/* [lo, hi] grown to hold the shape anywhere along its route (a sphere about B(0) swept along it). */
void fm_flock_target_grow_bounds(const fm_flock_target *t, double lo[3], double hi[3]);
/* flock_model.c: the leaders' eased fraction of the way at normalised time x (raised-cosine speed
 * ramps of e_in and e_out, e_in + e_out <= 1), which the travelling target shares. */
double fm_flock_eased(double x, double e_in, double e_out);

/* flock_memory.c: the shape flock's bytes for n agents (docs/limits.md), and the refusal of a run
 * that does not fit (memory.h). */
fm_memory_estimate fm_flock_memory_estimate(const fm_scene_def *def, int64_t n);
fm_status fm_flock_memory_check(const fm_scene_def *def, int64_t n, fm_error *err);

/* flock_dist.c: the shape flock on P ranks (docs/scale-out.md). create_distributed makes one rank's
 * store (its slab's agents at rest); adopt makes it the slab's agents of every rank's s->view (each a
 * share of the agents, as a checkpoint restored them: collective), and frees the view. Per step: exchange (the migration and the
 * ghosts) before the grid build; after_step at
 * the end. At a frame: gather (rank 0's view then holds every agent) or share (each rank's view its
 * share of the ids), release after the frame. */
fm_flock_state *fm_flock_state_create_distributed(const fm_flock_model *m, int threads, const fm_dist *dist,
                                                  fm_error *err);
fm_status fm_flock_dist_adopt(const fm_flock_model *m, fm_flock_state *s, fm_error *err);
fm_dist_totals fm_flock_dist_get_totals(const fm_flock_state *s);
fm_status fm_flock_dist_exchange(const fm_flock_model *m, fm_flock_state *s, fm_error *err);
void fm_flock_dist_after_step(fm_flock_state *s, double busy_seconds);
fm_flock_state *fm_flock_dist_gather(fm_flock_state *s, int grid, fm_error *err);
fm_flock_state *fm_flock_dist_blocks(fm_flock_state *s, fm_error *err); /* whole FM_BLOCK blocks a rank */
int64_t fm_flock_slot_of(const fm_flock_state *s, int64_t id); /* −1: not here */
/* flock_state.c: agents begin … end − 1 of a frame (fm_flock_frame's arrays, in id order from
 * agent begin at index 0); the mean and
 * largest distance to the destinations over the blocks of [begin, end) (whole FM_BLOCK blocks),
 * on P ranks (d) every rank's share summed on rank 0 in block order (NaN elsewhere). */
void fm_flock_frame_range(const fm_flock_state *s, int64_t begin, int64_t end, float *position, float *velocity,
                          float *orientation, uint8_t *phase);
void fm_flock_distance_blocks(const fm_flock_state *s, int64_t begin, int64_t end, const fm_dist *d, double *mean,
                              double *max);
/* flock_measures.c: fm_flock_measure_frame of frame `frame` on P ranks from their shares (each
 * rank's view from fm_flock_dist_share or fm_flock_dist_blocks: runs of whole FM_BLOCK blocks); out
 * on rank 0; the look's history in s. */
fm_status fm_flock_measure_frame_shared(const fm_flock_model *m, fm_flock_state *s, fm_flock_state *view,
                                        int64_t frame, double out[FM_FLOCK_MEASURES], fm_error *err);
/* fm_flock_measure_frame of frame `frame` with the look's history in `look` (s may be a view that
 * holds every agent, on rank 0). */
void fm_flock_measure_frame_look(const fm_flock_model *m, fm_flock_state *s, fm_flock_look *look, int64_t frame,
                                 double out[FM_FLOCK_MEASURES]);
/* flock_look.c: the look's three figures of frame f into out (NaN unless f is a multiple of
 * FM_LOOK_EVERY and its history is there), its history advanced. s: every agent, or on P ranks (d)
 * this rank's store; s->member its agents in flight (on P ranks set here); grid_fresh: s->grid is a
 * grid of them built this frame (mean_nn's); mean_v: the mean velocity of all agents (NULL: no
 * coherence, on ranks other than 0). Collective on P ranks. */
fm_status fm_flock_look_frame(const fm_flock_model *m, fm_flock_state *s, const fm_dist *d, fm_flock_look *look,
                              int64_t f, const double mean_v[3], int grid_fresh, double out[FM_FLOCK_MEASURES],
                              fm_error *err);

/* The cache written in parallel: this rank's share of the ids (begin[rank] … begin[rank + 1] − 1)
 * complete in its view (returned; NULL on failure, which every rank agrees), from every rank;
 * release after the frame. */
fm_flock_state *fm_flock_dist_share(fm_flock_state *s, const int64_t *begin, fm_error *err);
/* s->member: this rank's own agents in flight (its slab's), not the ghosts. */
void fm_flock_dist_own_in_flight(fm_flock_state *s);
void fm_flock_dist_release(fm_flock_state *s);
/* Checkpoints on P ranks: each rank writes the agents of its share of the pieces, rank 0 the rest. */
fm_status fm_flock_checkpoint_write(const char *path, const fm_flock_model *m, const fm_flock_state *s,
                                    const fm_dist *dist, const fm_flock_run_stats *stats, int64_t frames,
                                    const fm_ckpt_part *parts, int part_count, fm_error *err);
/* On P ranks: each rank's share of the pieces read into its view by load(view, part, arg) (the whole
 * file checked), then every agent to the rank whose slab holds it. */
fm_status fm_flock_dist_checkpoint_load(fm_flock_state *s, const fm_flock_model *m,
                                        fm_status (*load)(fm_flock_state *view, const fm_ckpt_part *part, void *arg),
                                        void *arg, const char *path, fm_error *err);
fm_status fm_flock_dist_checkpoint_save(const char *path, const fm_flock_model *m, fm_flock_state *s,
                                        const fm_flock_run_stats *stats, int64_t frames, fm_error *err);
/* A shot's group (flock_shot.c): the state alone, without statistics, at `frames` frames (on P
 * ranks collective, as fm_flock_dist_checkpoint_save); its load (on P ranks each rank keeps its slab's). */
fm_status fm_flock_group_checkpoint_save(const char *path, const fm_flock_model *m, fm_flock_state *s, int64_t frames,
                                         fm_error *err);
fm_status fm_flock_group_checkpoint_load(const char *path, const fm_flock_model *m, fm_flock_state *s, int64_t *frames,
                                         fm_error *err);

/* flock_shot.c: a shot on P ranks: every group's state one rank's share; each writing group
 * gathered on rank 0 at a frame. */
/* fm_flock_shot_build on P ranks: every group's model one a machine (fm_flock_model_build_shared);
 * collective. dist NULL: fm_flock_shot_build. */
fm_flock_shot *fm_flock_shot_build_on(const fm_scene_def *defs, int count, const fm_dist *dist, fm_progress_fn progress,
                                      void *user, fm_error *err);
fm_status fm_flock_shot_distribute(fm_flock_shot *s, const fm_dist *dist, fm_error *err);
/* fm_flock_shot_build on one process, group g's model built keeping in keeps[g] (count of them, zeroed
 * at first): the studio's runs of an edited shot. */
fm_flock_shot *fm_flock_shot_build_keeping(const fm_scene_def *defs, int count, fm_flock_keep *keeps,
                                           fm_progress_fn progress, void *user, fm_error *err);
const fm_flock_state *fm_flock_shot_state(const fm_flock_shot *s, int g);

#endif
