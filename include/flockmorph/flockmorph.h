/* flockmorph — turn one 3D shape into another as a flock.
 *
 * The public C API. One umbrella header; everything under src/ and kernels/ is internal.
 *
 * The flow follows MuJoCo's model/data split:
 *   fm_scene_def   parameters (from a scene file or fm_default_scene_def())
 *   fm_morph_model       everything immutable after preprocessing: tets, orders, path, bounding sphere
 *   fm_morph_state       everything the step mutates: the agent store, the clock, counters
 *   fm_morph_step(model, state) advances one time step; fm_morph_tet_vertices() gives a frame.
 *
 * Every fallible call takes an fm_error* and returns an fm_status (or NULL for constructors);
 * on failure err->message says what went wrong and names the file, line, key or element.
 */
#ifndef FLOCKMORPH_H
#define FLOCKMORPH_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FM_VERSION_STRING "0.1.0"

/* Status codes double as the CLI's exit codes. */
typedef enum fm_status {
    FM_OK = 0,
    FM_ERR_USAGE = 1,    /* bad command line */
    FM_ERR_INPUT = 2,    /* bad scene file, mesh or parameter */
    FM_ERR_IO = 3,       /* cannot read or write a file */
    FM_ERR_MEMORY = 4,   /* allocation failed */
    FM_ERR_INTERNAL = 5, /* a library failed in a way the input does not explain */
    FM_STOPPED = 6       /* not an error: fm_morph_run_controlled stopped on request after its checkpoint,
                            or fm_flock_run_controlled at a frame boundary (the CLI then exits 128
                            + the signal's number) */
} fm_status;

typedef struct fm_error {
    fm_status status;
    char message[2048];
} fm_error;

/* ---------------------------------------------------------------- scene */

#define FM_PATH_MAX 4096
#define FM_MAX_PATH_POINTS 256

typedef enum fm_curve { FM_CURVE_POLYLINE = 0, FM_CURVE_CATMULL_ROM = 1 } fm_curve;

/* A mesh placed in the world: x_world = R(rotate_deg) * (scale * x_file) + translate.
 * Rotations are applied about X, then Y, then Z, in degrees. */
typedef struct fm_mesh_ref {
    char path[FM_PATH_MAX];
    double translate[3];
    double scale;
    double rotate_deg[3];
} fm_mesh_ref;

#define FM_MAX_FIELDS 8
#define FM_MAX_OBSTACLES 16

typedef enum fm_field_kind {
    FM_FIELD_CURL_NOISE = 0, /* FM eq 5: curl of three Perlin potentials */
    FM_FIELD_WIND = 1,       /* mean wind plus time-varying curl-noise turbulence */
    FM_FIELD_GRAVITY = 2,    /* a constant velocity along `direction` */
    FM_FIELD_VORTEX = 3      /* SCF eqs 7-8: strength * (axis x (x - center)) */
} fm_field_kind;

/* One style field (FM §5.2). V_l is the sum of the scene's fields; V_grn = omega1 V_g + omega2 V_l
 * (FM eq 6). Each field is a function of position and time. */
typedef struct fm_field_def {
    fm_field_kind kind;
    double gain;          /* curl noise: magnitude of the potentials P (FM eq 5), units^2/s */
    double scale;         /* curl noise and wind turbulence: noise length scale, units */
    double direction[3];  /* wind: mean direction; gravity: direction (any length; normalised) */
    double speed;         /* wind: WindSpeed; gravity: its speed; units/s */
    double turbulence;    /* wind: magnitude of the turbulent potentials, units^2/s */
    double period;        /* wind: seconds for the turbulence to change (0: frozen) */
    double center[3];     /* vortex: Pos_center (SCF eq 7) */
    double axis[3];       /* vortex: rotation axis; SCF eq 8 is (0, 1, 0) */
    double strength;      /* vortex: d of SCF eq 8, 1/s */
} fm_field_def;

/* A field of the given kind with the documented defaults (docs/scene.md). */
fm_field_def fm_default_field_def(fm_field_kind kind);

typedef enum fm_phase_switch {
    FM_SWITCH_SPHERE = 0,   /* FM §5.5: inside the target's minimal bounding sphere */
    FM_SWITCH_DISTANCE = 1  /* beyond the paper (§8): the target's own signed distance < switch_distance */
} fm_phase_switch;

/* Which system a scene runs: the tetra flock morph (FM) or the shape-constrained flock (SCF). */
typedef enum fm_mode { FM_MODE_TETRA_MORPH = 0, FM_MODE_SHAPE_FLOCK = 1 } fm_mode;

#define FM_FUZZY_MAX_POINTS 16

/* A fuzzy weight curve (SCF Figure 6): the weight of one kind of force as a function of the agent's
 * distance to its destination, piecewise linear through count points (d strictly increasing,
 * w >= 0) and constant beyond the first and the last, so continuous everywhere. */
typedef struct fm_fuzzy_def {
    int32_t count;
    double d[FM_FUZZY_MAX_POINTS]; /* units */
    double w[FM_FUZZY_MAX_POINTS];
} fm_fuzzy_def;

/* The four weight curves, indexing fm_flock_def.fuzzy. */
typedef enum fm_fuzzy_force {
    FM_FUZZY_STEERING = 0, FM_FUZZY_HOMING = 1, FM_FUZZY_DAMPING = 2, FM_FUZZY_EXTERNAL = 3, FM_FUZZY_FORCES = 4
} fm_fuzzy_force;

/* One boids rule (SCF "Basic Steering Behaviors"); every agent draws its own values uniformly from
 * these [lo, hi] ranges. */
typedef struct fm_boid_rule_def {
    double radius_j[2];  /* J of SCF eq 6: the perception radius is r = J / sqrt(N) */
    double angle_deg[2]; /* perception angle: full opening of the cone around the heading, (0, 360] */
    double weight[2];
} fm_boid_rule_def;

typedef enum fm_flock_sampling {
    FM_FLOCK_SAMPLE_RANDOM = 0, FM_FLOCK_SAMPLE_MOSAIC = 1, FM_FLOCK_SAMPLE_STRATIFIED = 2
} fm_flock_sampling;
typedef enum fm_flock_match { FM_FLOCK_MATCH_RANDOM = 0, FM_FLOCK_MATCH_SPHERICAL = 1 } fm_flock_match;
/* The mosaic's dis_ij (SCF eqs 1-2): it both selects the neighbours and enters E_ij. */
typedef enum fm_mosaic_distance { FM_MOSAIC_EUCLIDEAN = 0, FM_MOSAIC_MANHATTAN = 1 } fm_mosaic_distance;
typedef enum fm_flock_arrival { FM_ARRIVAL_BIND = 0, FM_ARRIVAL_FLOAT = 1 } fm_flock_arrival;
typedef enum fm_deform_kind {
    FM_DEFORM_NONE = 0,     /* a static target */
    FM_DEFORM_WAVE = 1,     /* procedural: vertices move along their normals, a travelling sine wave */
    FM_DEFORM_PULSE = 2,    /* procedural: the target scales about its centre, breathing */
    FM_DEFORM_SEQUENCE = 3  /* a sequence of meshes with the target's connectivity */
} fm_deform_kind;

/* The shape-constrained flock's parameters (SCF; docs/shape-flock.md, docs/scene.md "shape_flock"). */
typedef struct fm_flock_def {
    fm_flock_sampling sampling;  /* how the source and target surfaces are sampled */
    fm_flock_match match;        /* agent-to-destination correspondence */
    /* surface mosaic sampling (docs/sampling.md; M the surface area, N = n) */
    int32_t mosaic_iterations;   /* eq 5 applications; 0 keeps the random start */
    fm_mosaic_distance mosaic_distance;
    double mosaic_k;             /* eq 1: neighbourhood A = k sqrt(M/N) */
    double mosaic_w;             /* eq 3: sigma = w sqrt(M/N) */
    double mosaic_step;          /* eq 5's delta t in units of sqrt(M/N) */
    /* stratified sampling */
    double stratified_lambda;    /* the density lambda e^(-lambda d), d in voxel edges */
    double stratified_oversample;/* occupied voxels per sample before minimum-distance elimination, >= 1 */
    double mass;                 /* m of eq 9; every force is divided by it */
    double max_speed[2];         /* MaxSpeed range, units/s */
    double max_force[2];         /* MaxForce range (bounds the boids steering force), units/s^2 * mass */
    fm_boid_rule_def separation, cohesion, alignment;
    double kalman_q;             /* spectral density of Q's acceleration noise, units^2/s^3 */
    double kalman_r_position;    /* R's position variance, units^2 (> 0) */
    double kalman_r_velocity;    /* R's velocity variance, units^2/s^2 (> 0) */
    fm_fuzzy_def fuzzy[FM_FUZZY_FORCES];
    double damping;              /* c of the damping force -m c (v - v_destination), 1/s */
    double external_gain;        /* acceleration per unit of style-field velocity, 1/s */
    double path_time;            /* seconds the leaders take along the path; 0 = path length / speed0 */
    double arrival_radius;       /* stepped steering within this distance of the destination; 0 = off */
    double arrival_time;         /* time constant of the stepped approach, s */
    double turn_rate_deg;        /* largest turn of the stepped approach, degrees/s */
    double bind_distance;        /* arrival: bind (or start floating) within this distance, units */
    fm_flock_arrival arrival_mode;
    double float_amplitude;      /* floating: largest offset from the destination, units */
    double float_period;         /* floating: seconds per oscillation */
    fm_deform_kind deform;
    double deform_amplitude;     /* wave: units along the normal; pulse: relative scale */
    double deform_period;        /* seconds per cycle */
    double deform_wavelength;    /* wave: units along deform_direction */
    double deform_direction[3];  /* wave: the direction it travels */
    char deform_sequence[FM_PATH_MAX]; /* sequence: printf pattern with one integer, "wave_%03d.obj" */
    int32_t deform_frames;       /* sequence: meshes 0 .. frames-1 */
    double deform_frame_rate;    /* sequence: meshes per second; the sequence loops */
} fm_flock_def;

/* Every parameter of a run; docs/scene.md documents each with its default and unit. */
typedef struct fm_scene_def {
    char scene_path[FM_PATH_MAX]; /* where it was read from (for messages); "" if built in code */
    fm_mode mode;               /* the tetra morph (default) or the shape-constrained flock */
    fm_mesh_ref source;
    fm_mesh_ref target;
    int64_t n;                  /* agents = tets after subdivision; 0 = max(n1, n2) (FM §4) */
    double tet_quality;         /* TetGen radius-edge bound (-q), default 2.0 */
    double tet_max_volume;      /* TetGen volume bound (-a), 0 = none */
    double speed0;              /* base speed, units per second (FM eq 3) */
    double omega1;              /* weight of the global velocity in V_grn (FM eq 6) */
    double frame_rate;          /* frames per second of animation time */
    double time_step;           /* seconds per step; must divide 1/frame_rate; 0 = 1/frame_rate */
    int32_t frame_limit;        /* stop after this many frames even if agents are still flying */
    double path_points[FM_MAX_PATH_POINTS][3]; /* user control points between C_S and C_T */
    int32_t path_point_count;
    int32_t path_key_points;    /* m: key points sampled on the curve (FM eq 3) */
    fm_curve path_curve;
    double launch_rate;         /* agents launched per second in D1 order; 0 = n / 2 s */
    double shrink;              /* linear scale a tet shrinks to when launched (FM §6: 1/2) */
    double shrink_time;         /* seconds the launch shrink takes */
    double morph_fraction;      /* fraction of phase 2 spent on A(t); the rest enlarges */
    /* style fields (FM §5.2) */
    double omega2;              /* weight of V_l (FM eq 6) */
    fm_field_def fields[FM_MAX_FIELDS];
    int32_t field_count;
    int32_t field_grid[3];      /* bake fields on this grid over the scene bounds; 0 = evaluate directly */
    /* obstacles (FM §5.3) */
    fm_mesh_ref obstacles[FM_MAX_OBSTACLES];
    int32_t obstacle_count;
    double k_a;                 /* influence range of eq 7, units */
    double obstacle_voxel;      /* signed-distance voxel size, units; 0 = automatic */
    int32_t avoid_in_phase2;    /* beyond the paper (§8): obstacle avoidance also in phase 2 */
    /* local avoidance, MDE (FM §5.4) */
    double d_min;               /* minimum distance between tet centroids, units; 0 = off */
    double mde_speed;           /* push speed of a pair at zero distance, units/s; 0 = speed0 */
    /* path width (FM §5.1) */
    double path_width;          /* agents farther than width/2 from the path are pulled back; 0 = off */
    double path_attraction;     /* pull speed per unit of distance outside the width, 1/s */
    /* phase switch */
    fm_phase_switch phase_switch;
    double switch_distance;     /* units, for FM_SWITCH_DISTANCE */
    uint64_t seed;              /* random seed */
    int32_t compression_level;  /* zstd level of the frame cache, 1..19 */
    int32_t cache_delta;        /* frame cache: XOR delta to the previous frame (lossless; default 1) */
    int32_t cache_key_interval; /* frame cache: frames from one whole frame to the next with delta */
    double cache_quantum;       /* frame cache: round positions to multiples of this; 0 = lossless */
    char cache_name[256];       /* file name of the cache inside the output directory */
    fm_flock_def flock;         /* mode FM_MODE_SHAPE_FLOCK only */
} fm_scene_def;

fm_scene_def fm_default_scene_def(void);

/* Reads and validates a JSON scene file. Relative mesh paths are resolved against the scene
 * file's directory. Unknown keys, wrong types and out-of-range values fail with
 * "FILE:LINE:COLUMN: ..." in err->message. */
fm_status fm_scene_load(const char *path, fm_scene_def *def, fm_error *err);

/* The same from a scene text in memory (len bytes, no NUL needed). `name` stands for the file in
 * messages and relative mesh paths are resolved against its directory. */
fm_status fm_scene_parse(const char *text, size_t len, const char *name, fm_scene_def *def,
                         fm_error *err);

/* Checks a definition built in code (fm_scene_load calls it too). */
fm_status fm_scene_validate(const fm_scene_def *def, fm_error *err);

/* ---------------------------------------------------------------- model */

typedef struct fm_morph_model fm_morph_model;

/* Progress of long preprocessing stages; may be NULL. fraction is in [0, 1]. */
typedef void (*fm_progress_fn)(const char *stage, double fraction, void *user);

fm_morph_model *fm_morph_model_build(const fm_scene_def *def, fm_progress_fn progress, void *user,
                         fm_error *err);
void fm_morph_model_destroy(fm_morph_model *model);

typedef struct fm_morph_model_info {
    int64_t agents;             /* n */
    int64_t source_tets;        /* n1: TetGen's count before subdivision */
    int64_t target_tets;        /* n2 */
    double source_volume;       /* total volume of the source tets after subdivision */
    double target_volume;
    double source_centroid[3];  /* C_S */
    double target_centroid[3];  /* C_T */
    double sphere_center[3];    /* exact minimal bounding sphere of the target (phase switch) */
    double sphere_radius;
    int32_t key_points;         /* m + 2 key points Q_0..Q_{m+1} */
    double time_step;           /* seconds per step */
    int32_t steps_per_frame;
    double launch_rate;         /* agents per second, after the default is applied */
} fm_morph_model_info;

fm_morph_model_info fm_morph_model_get_info(const fm_morph_model *model);

/* Input the engine accepts but the paper does not expect (source and target overlapping, FM §4),
 * one message per warning, naming the scene file and key. The CLI prints them and lists them in
 * stats.json "warnings". */
int fm_morph_model_warning_count(const fm_morph_model *model);
const char *fm_morph_model_warning(const fm_morph_model *model, int i);

/* Target tet j's four vertices (12 floats, x y z per vertex) in world units. */
const float *fm_morph_model_target_tet(const fm_morph_model *model, int64_t j);

/* ---------------------------------------------------------------- state */

typedef struct fm_morph_state fm_morph_state;

typedef enum fm_phase {
    FM_PHASE_WAITING = 0,  /* not launched yet, at rest in the source */
    FM_PHASE_FLYING = 1,   /* phase 1: following the path (FM eq 8) */
    FM_PHASE_HOMING = 2,   /* phase 2: flying straight to its target tet (FM eq 9) */
    FM_PHASE_ARRIVED = 3
} fm_phase;

/* threads <= 0 uses OpenMP's default. Results do not depend on the thread count. */
fm_morph_state *fm_morph_state_create(const fm_morph_model *model, int threads, fm_error *err);
void fm_morph_state_destroy(fm_morph_state *state);

void fm_morph_step(const fm_morph_model *model, fm_morph_state *state);

typedef struct fm_morph_info {
    int64_t step;
    double time;               /* seconds of animation time */
    int64_t count[4];          /* agents per fm_phase */
    int all_arrived;
    int64_t morph_fallbacks;   /* agents whose correspondence needed the safe A(t) form */
    int64_t flying_agent_steps;/* phase-1 agent-steps so far ... */
    int64_t mde_agent_steps;   /* ... and those among them that MDE pushed (FM §5.4) */
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

/* ---------------------------------------------------------------- cache */

/* The native frame cache (docs/cache-format.md): one zstd-compressed chunk per frame, an index
 * for random access. Written as PATH.partial and renamed to PATH only by finish(). */
typedef struct fm_cache_writer fm_cache_writer;

fm_cache_writer *fm_cache_writer_create(const char *path, uint64_t agents, double frame_rate,
                                        int compression_level, fm_error *err);
/* verts: agents × 12 floats. */
fm_status fm_cache_writer_add_frame(fm_cache_writer *w, const float *verts, fm_error *err);
/* Writes the index and renames PATH.partial to PATH; frees w. If anything failed (now or on the
 * writer thread: disk full, file-size limit), PATH.partial stays, readable by fm_cache_open up to
 * its last complete frame, and nothing is under PATH. */
fm_status fm_cache_writer_finish(fm_cache_writer *w, fm_error *err);
void fm_cache_writer_abort(fm_cache_writer *w);                       /* frees w, deletes file */

typedef struct fm_cache_reader fm_cache_reader;

/* Opens a cache for random access by frame. A cache without a valid index (the run was killed,
 * the file was cut short) is opened up to its last complete frame, and fm_cache_warning says so. */
fm_cache_reader *fm_cache_open(const char *path, fm_error *err);
/* "" for a complete cache; otherwise what was wrong and how many frames were recovered. */
const char *fm_cache_warning(const fm_cache_reader *r);
uint64_t fm_cache_agents(const fm_cache_reader *r);
uint32_t fm_cache_frames(const fm_cache_reader *r);
double fm_cache_frame_rate(const fm_cache_reader *r);
/* The tet vertices of one frame (agents × 12 floats); an error if the cache has no tet vertices. */
fm_status fm_cache_read_frame(fm_cache_reader *r, uint32_t frame, float *out, fm_error *err);
void fm_cache_close(fm_cache_reader *r);

/* ---------------------------------------------------------------- cache attributes (formats 2 and 3)
 *
 * A cache holds, per frame, one array per attribute, agents in id order. The tetra morph writes
 * tet vertices and phase; point flocks (the shape-constrained flock) write position, velocity and
 * orientation. fm_cache_writer_create above is the tetra morph's shorthand for
 * {FM_ATTR_TET_VERTICES} with default options. */
typedef enum fm_cache_attr {
    FM_ATTR_TET_VERTICES = 1, /* 12 × f32: 4 vertices × xyz */
    FM_ATTR_POSITION = 2,     /* 3 × f32 */
    FM_ATTR_VELOCITY = 3,     /* 3 × f32 */
    FM_ATTR_ORIENTATION = 4,  /* 4 × f32: unit quaternion w x y z, the agent's frame (x along velocity) */
    FM_ATTR_ID = 5,           /* 1 × u32: stable agent id */
    FM_ATTR_PHASE = 6         /* 1 × u8: fm_phase (tetra morph) or the flock's own phase */
} fm_cache_attr;

typedef enum fm_cache_scalar { FM_SCALAR_F32 = 1, FM_SCALAR_U32 = 2, FM_SCALAR_U8 = 3 } fm_cache_scalar;

typedef struct fm_cache_attr_info {
    fm_cache_attr attr;
    const char *name;        /* "tet_vertices", "position", ... as in docs/cache-format.md */
    int components;          /* values per agent */
    fm_cache_scalar scalar;
    size_t bytes_per_agent;  /* components × scalar size */
} fm_cache_attr_info;

/* Fixed facts about an attribute kind; NULL for an unknown one. */
const fm_cache_attr_info *fm_cache_attr_describe(fm_cache_attr attr);

typedef struct fm_cache_options {
    int compression_level;   /* zstd 1..19 (default 1) */
    int delta;               /* 1 (the default): every attribute stored as the XOR of its bits with
                                the previous frame's (lossless); every key_interval-th frame is
                                stored whole. 0: every frame whole */
    int key_interval;        /* frames from one whole frame to the next when delta is on (default 16):
                                random access decodes at most this many chunks */
    double quantum;          /* > 0: f32 attributes rounded to multiples of quantum and stored as
                                int32 multiples (lossy, error <= quantum / 2 before the read value's
                                own float rounding); 0: lossless (the default) */
} fm_cache_options;

fm_cache_options fm_default_cache_options(void);

fm_cache_writer *fm_cache_writer_create_attrs(const char *path, uint64_t agents, double frame_rate,
                                              const fm_cache_attr *attrs, int attr_count,
                                              const fm_cache_options *opts, fm_error *err);
/* data[i] points at agents × attribute i's values, in the order given to create_attrs. */
fm_status fm_cache_writer_add_frame_attrs(fm_cache_writer *w, const void *const *data, fm_error *err);
/* Reopens PATH.partial left by an interrupted run (format 3), checks its first `frames` chunks
 * (headers and crc32), drops anything after them, and continues writing with the attributes and
 * options of its header (checkpoint / resume). Given the same further frames the finished file is
 * byte-identical to an uninterrupted one. Fails, leaving the file alone, if fewer frames are
 * readable. */
fm_cache_writer *fm_cache_writer_resume(const char *path, uint32_t frames, fm_error *err);
uint32_t fm_cache_writer_frames(const fm_cache_writer *w); /* frames handed over so far */
/* Waits until every frame handed over so far is written, then flushes and fsyncs the file, so a
 * checkpoint taken after it can rely on those frames being on disk. */
fm_status fm_cache_writer_flush(fm_cache_writer *w, fm_error *err);
/* Stops without an index: frees w and keeps PATH.partial with every frame written so far, readable
 * by fm_cache_open up to its last complete frame and continued by fm_cache_writer_resume (a run
 * stopped by a signal, or one that failed: disk full, file-size limit). */
void fm_cache_writer_close_partial(fm_cache_writer *w);

int fm_cache_attr_count(const fm_cache_reader *r);
const fm_cache_attr_info *fm_cache_attr_at(const fm_cache_reader *r, int i);
int fm_cache_has_attr(const fm_cache_reader *r, fm_cache_attr attr);
/* Reads one attribute of one frame into out (agents × bytes_per_agent bytes, aligned for its
 * scalar type). With delta, a frame is rebuilt from the key frame before it; the last decoded frame
 * is kept, so reading frames in order decodes one chunk each. */
fm_status fm_cache_read_attr(fm_cache_reader *r, uint32_t frame, fm_cache_attr attr, void *out,
                             fm_error *err);
/* Sizes for `inspect`: the file, and the raw and compressed bytes of all frames. */
uint64_t fm_cache_file_bytes(const fm_cache_reader *r);
uint64_t fm_cache_raw_bytes(const fm_cache_reader *r);
uint64_t fm_cache_compressed_bytes(const fm_cache_reader *r);
uint64_t fm_cache_frame_bytes(const fm_cache_reader *r, uint32_t frame); /* one chunk; 0 past the end */
uint32_t fm_cache_version(const fm_cache_reader *r);                     /* 1, 2 or 3 */
/* The frame count the header states (format 3): 0 while the writer runs and in a partial file,
 * else equal to fm_cache_frames (fm_cache_open refuses a file where it differs from the index).
 * Formats 1 and 2 have none: 0. */
uint32_t fm_cache_header_frames(const fm_cache_reader *r);
/* The options the cache was written with (format 1: its level, no delta, no quantum). */
fm_cache_options fm_cache_get_options(const fm_cache_reader *r);

/* ---------------------------------------------------------------- run */

typedef struct fm_morph_run_stats {
    int64_t frames;                 /* frames written, frame 0 (the rest state) included */
    int64_t steps;
    double simulate_seconds;        /* time spent in fm_morph_step */
    double output_seconds;          /* time spent computing and writing frames */
    int all_arrived;
    int stopped_at_frame_limit;
    int64_t inverted_tet_frames;    /* tet-frames with signed volume <= 0 */
    double final_max_vertex_error;  /* last frame vs the target tets (ground truth, double) */
    int target_tets_filled_once;    /* every target tet taken by exactly one agent */
    int64_t morph_fallbacks;
    double *mde_fraction;           /* per frame after frame 0: MDE agent-steps / phase-1 agent-steps,
                                       NaN for frames with nobody in phase 1; free with fm_morph_run_stats_free */
    double mde_fraction_mean;       /* mean over the frames with agents in phase 1 (FM Table I) */
    double min_obstacle_clearance;  /* smallest d_t - R_X in phase 1; +inf without obstacles */
} fm_morph_run_stats;

void fm_morph_run_stats_free(fm_morph_run_stats *stats);

/* Called after every frame; may be NULL. */
typedef void (*fm_run_progress_fn)(const fm_morph_info *info, int64_t frame, void *user);

/* Steps until every agent has arrived or def.frame_limit frames are written, writing each frame
 * to `cache` (may be NULL) and measuring the run. */
fm_status fm_morph_run(const fm_morph_model *model, fm_morph_state *state, fm_cache_writer *cache,
                 fm_run_progress_fn progress, void *user, fm_morph_run_stats *stats, fm_error *err);

/* ---------------------------------------------------------------- checkpoint and resume */

/* Called by fm_morph_run_controlled at a frame boundary once the cache is flushed, so the cache's first
 * stats->frames frames are on disk; typically calls fm_morph_checkpoint_save. A failure ends the run. */
typedef fm_status (*fm_run_checkpoint_fn)(const fm_morph_model *model, const fm_morph_state *state, const fm_morph_run_stats *stats,
                                          void *user, fm_error *err);

typedef struct fm_run_control {
    fm_run_progress_fn progress;     /* after every frame; may be NULL */
    void *progress_user;
    int resume;                      /* 0: a new run (frame 0 is written first, stats start at zero);
                                        1: state and stats were restored by fm_morph_checkpoint_load and the
                                        run continues after frame stats->frames - 1 */
    fm_run_checkpoint_fn checkpoint; /* NULL: no checkpoints */
    void *checkpoint_user;
    int64_t checkpoint_every;        /* checkpoint every this many frames; 0: not by frame count */
    double checkpoint_seconds;       /* ... or when this much wall time passed since the last one
                                        (or the start); 0: not by time */
    volatile sig_atomic_t *stop;     /* may be NULL; read at every frame boundary: when non-zero, the
                                        run checkpoints there and returns FM_STOPPED (unless that
                                        frame already ends the run) */
} fm_run_control;

/* No checkpoints, no stop flag, a new run. */
fm_run_control fm_default_run_control(void);

/* fm_morph_run with checkpoints, a stop flag and resume. The cache and stats of a run stopped and resumed
 * any number of times are bitwise those of an uninterrupted run (timings aside). */
fm_status fm_morph_run_controlled(const fm_morph_model *model, fm_morph_state *state, fm_cache_writer *cache,
                            const fm_run_control *control, fm_morph_run_stats *stats, fm_error *err);

/* Writes the run's state and statistics after stats->frames frames to `path` (as PATH.partial,
 * fsync'ed, then renamed): docs/resume.md describes the file. */
fm_status fm_morph_checkpoint_save(const char *path, const fm_morph_model *model, const fm_morph_state *state,
                             const fm_morph_run_stats *stats, fm_error *err);

/* Checks a checkpoint file against a scene before the (long) model build: readable, undamaged
 * (checksum), this version's layout, written for the same scene parameters. FM_ERR_INPUT with a
 * message saying which, FM_ERR_IO if it cannot be read. */
fm_status fm_checkpoint_check(const char *path, const fm_scene_def *def, fm_error *err);

/* Restores a checkpoint into `state` (fresh from fm_morph_state_create for `model`) and `stats` (free
 * them with fm_morph_run_stats_free), after the checks of fm_checkpoint_check and a check that `model`
 * is the one it was written from (same tets after TetGen and subdivision, same obstacles). On
 * failure state is unusable and stats hold nothing to free. */
fm_status fm_morph_checkpoint_load(const char *path, const fm_morph_model *model, fm_morph_state *state, fm_morph_run_stats *stats,
                             fm_error *err);

/* Number of tets (n × 12 floats) with signed volume <= 0. */
int64_t fm_count_inverted_tets(const float *verts, size_t n);

/* ---------------------------------------------------------------- shape-constrained flock
 *
 * The second mode (scene "mode": "shape_flock"; SCF, docs/shape-flock.md): n point agents start on
 * samples of the source surface, each is given a sample of the target surface as its destination,
 * and they fly there as boids along the global path, homing through a Kalman filter and weighted by
 * fuzzy curves, then bind to (or float around) their destinations, which follow the target when it
 * deforms. The same model/state split as the tetra morph: the model is immutable, the state holds
 * the agent store. Agents use fm_phase: FM_PHASE_FLYING under forces, FM_PHASE_HOMING in the stepped
 * approach, FM_PHASE_ARRIVED bound or floating. */
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
    double path_time;          /* seconds the leaders take along their paths */
    double time_step;
    int32_t steps_per_frame;
    double max_radius;         /* the largest perception radius: the neighbour grid's cell */
    int deforming;             /* the target moves (fm_deform_kind != NONE) */
} fm_flock_model_info;

fm_flock_model_info fm_flock_model_get_info(const fm_flock_model *model);

/* Every agent's start C1 and its destination C2 at time 0, 3 floats per agent (either may be NULL). */
void fm_flock_model_endpoints(const fm_flock_model *model, float *c1, float *c2);

/* threads <= 0 uses OpenMP's default. Results do not depend on the thread count. */
fm_flock_state *fm_flock_state_create(const fm_flock_model *model, int threads, fm_error *err);
void fm_flock_state_destroy(fm_flock_state *state);

void fm_flock_step(const fm_flock_model *model, fm_flock_state *state);

typedef struct fm_flock_info {
    int64_t step;
    double time;
    int64_t count[4];          /* agents per fm_phase */
} fm_flock_info;

fm_flock_info fm_flock_get_info(const fm_flock_state *state);

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

typedef struct fm_flock_run_stats {
    int64_t frames;                 /* frames written, frame 0 included */
    int64_t steps;
    double simulate_seconds;        /* time spent in fm_flock_step */
    double output_seconds;          /* time spent computing and writing frames */
    int all_bound;                  /* every agent bound or floating at its destination */
    int stopped_at_frame_limit;
    double final_mean_distance;     /* to the destination, at the last frame */
    double final_max_distance;
    double bound_fraction;          /* agents in FM_PHASE_ARRIVED at the last frame */
    double tracking_lag;            /* deforming target: mean distance to the moving destination over
                                       the frames after path_time; NaN for a static target */
    int64_t tracking_frames;        /* frames that mean is taken over */
} fm_flock_run_stats;

typedef void (*fm_flock_progress_fn)(const fm_flock_info *info, int64_t frame, void *user);

/* Steps until every agent is bound (static targets only) or def.frame_limit frames are written,
 * writing each frame to `cache` (from fm_flock_cache_create; may be NULL). */
fm_status fm_flock_run(const fm_flock_model *model, fm_flock_state *state, fm_cache_writer *cache,
                       fm_flock_progress_fn progress, void *user, fm_flock_run_stats *stats, fm_error *err);

/* Called by fm_flock_run_controlled at a frame boundary once the cache is flushed (its first
 * stats->frames frames are on disk); typically calls fm_flock_checkpoint_save. A failure ends the run. */
typedef fm_status (*fm_flock_checkpoint_fn)(const fm_flock_model *model, const fm_flock_state *state,
                                            const fm_flock_run_stats *stats, void *user, fm_error *err);

/* As fm_run_control, for the shape flock. */
typedef struct fm_flock_run_control {
    fm_flock_progress_fn progress;   /* after every frame; may be NULL */
    void *progress_user;
    volatile sig_atomic_t *stop;     /* may be NULL; read at every frame boundary: when non-zero, the
                                        run checkpoints there (if it has a hook) and returns
                                        FM_STOPPED (unless that frame already ends it), every frame
                                        so far handed to the cache and `stats` filled in for them */
    int resume;                      /* 1: state and stats were restored by fm_flock_checkpoint_load */
    fm_flock_checkpoint_fn checkpoint; /* NULL: no checkpoints */
    void *checkpoint_user;
    int64_t checkpoint_every;        /* every this many frames; 0: not by frame count */
    double checkpoint_seconds;       /* ... or this much wall time; 0: not by time */
} fm_flock_run_control;

/* fm_flock_run with checkpoints, a stop flag and resume: the cache of a run stopped and resumed any
 * number of times is bitwise that of an uninterrupted run, and so are its stats (timings aside). */
fm_status fm_flock_run_controlled(const fm_flock_model *model, fm_flock_state *state, fm_cache_writer *cache,
                                  const fm_flock_run_control *control, fm_flock_run_stats *stats, fm_error *err);

/* The shape flock's checkpoint: the same file as fm_morph_checkpoint_save's (docs/resume.md) with the
 * flock's store and statistics. fm_checkpoint_check serves both modes. */
fm_status fm_flock_checkpoint_save(const char *path, const fm_flock_model *model, const fm_flock_state *state,
                                   const fm_flock_run_stats *stats, fm_error *err);
/* Restores it into `state` (fresh from fm_flock_state_create for `model`) and `stats`, after the
 * checks of fm_checkpoint_check and a check that `model` is the one it was written from. */
fm_status fm_flock_checkpoint_load(const char *path, const fm_flock_model *model, fm_flock_state *state,
                                   fm_flock_run_stats *stats, fm_error *err);

/* ---------------------------------------------------------------- export and preview */

/* Writes tets (n × 12 floats) in the format of path's extension: .ply (binary little-endian)
 * or .obj (4 triangles per tet), .vtu or .vdb (include/flockmorph/export.h, docs/export.md). */
fm_status fm_export_tets(const float *verts, size_t n, const char *path, fm_error *err);

/* The preview renderer (docs/render.md): Embree ray casting of tets (4 triangles each) or points
 * (spheres), Lambert shading with one key light and hard shadows, a ground plane under the bounds,
 * a colour per agent from a gradient over agent index, sRGB output. Every pixel is computed by one
 * thread from fixed rays, so the image does not depend on the thread count. */
typedef struct fm_render_opts {
    int width, height;      /* pixels, 1..16384 */
    double view_dir[3];     /* direction the camera looks along (any length) */
    double up[3];           /* the image's up direction (projected onto the image plane) */
    int perspective;        /* 0: orthographic; 1: perspective from a distance set by fov_deg */
    double fov_deg;         /* perspective: the bounding sphere fills this angle (default 40) */
    double margin;          /* fraction of the image left around the fitted bounds, [0, 0.5) */
    const double *bounds;   /* optional fixed [minx miny minz maxx maxy maxz] that the camera and
                               ground are fitted to (e.g. the whole animation's); NULL: the frame's */
    double world_up[3];     /* the ground lies under the bounds across world_up */
    double light_dir[3];    /* towards the key light (any length); zero: high above, from the camera's left */
    int ground;             /* 1: draw the ground plane (default), 0: background only */
    double point_radius;    /* points: sphere radius in world units; 0: fm_render_point_radius() */
    int samples;            /* samples per pixel along each axis, 1..8 (1: one ray per pixel) */
    int threads;            /* OpenMP threads; <= 0: OpenMP's default */
} fm_render_opts;

/* 960x540, the "persp" view, world up +Z, ground on, margin 0.05, 1 sample, automatic radius. */
fm_render_opts fm_default_render_opts(void);

/* Sets view_dir, up and perspective for a named view: "persp" (a 3/4 perspective view from the
 * front left, above), "front" (orthographic along +Y), "top" (along -Z) or "side" (along -X).
 * An unknown name is a usage error. */
fm_status fm_render_set_view(fm_render_opts *opts, const char *name, fm_error *err);

/* A sphere radius for points: 0.45 x the median distance from a sample of the points to their
 * nearest neighbour (so neighbouring spheres nearly touch). Non-finite points are ignored. */
double fm_render_point_radius(const float *positions, size_t n);

/* A renderer keeps its options and Embree device across frames (a video's frames share them). */
typedef struct fm_renderer fm_renderer;

fm_renderer *fm_renderer_create(const fm_render_opts *opts, fm_error *err);
void fm_renderer_destroy(fm_renderer *r);

/* Render tets (n x 12 floats) or points (n x 3 floats) into rgb: width x height x 3 bytes, rows top
 * to bottom, sRGB. Agent i (its index) gets colour i / (n - 1) of the gradient. Tets or points
 * with a non-finite coordinate are skipped. */
fm_status fm_renderer_draw_tets(fm_renderer *r, const float *verts, size_t n, unsigned char *rgb,
                                fm_error *err);
fm_status fm_renderer_draw_points(fm_renderer *r, const float *positions, size_t n,
                                  unsigned char *rgb, fm_error *err);

/* Writes an 8-bit RGB image (rows top to bottom) as PNG through PATH.partial and rename(). */
fm_status fm_write_png(const unsigned char *rgb, int width, int height, const char *path,
                       fm_error *err);

/* One-call forms: create a renderer, draw, write the PNG. */
fm_status fm_render_tets_png(const float *verts, size_t n, const fm_render_opts *opts,
                             const char *path, fm_error *err);
fm_status fm_render_points_png(const float *positions, size_t n, const fm_render_opts *opts,
                               const char *path, fm_error *err);

/* Video through the ffmpeg program (Debian package ffmpeg), H.264 in MP4: raw RGB frames are piped
 * to `ffmpeg -f rawvideo -pix_fmt rgb24 -s WxH -r FPS -i - -c:v libx264 -pix_fmt yuv420p`, which
 * writes PATH.partial; finish() waits for it and renames the file to PATH. A missing ffmpeg or
 * one that fails is an I/O error that quotes its stderr; no file is left under PATH then. */
typedef struct fm_video_writer fm_video_writer;

/* width and height must be even (yuv420p); fps > 0. */
fm_video_writer *fm_video_open(const char *path, int width, int height, double fps, fm_error *err);
/* rgb: width x height x 3 bytes. */
fm_status fm_video_add_frame(fm_video_writer *v, const unsigned char *rgb, fm_error *err);
fm_status fm_video_finish(fm_video_writer *v, fm_error *err); /* frees v */
void fm_video_abort(fm_video_writer *v);                       /* frees v, removes the partial file */

#ifdef __cplusplus
}
#endif

#include "flockmorph/export.h" /* the exporters: one frame as plain arrays to PLY, OBJ, VTK, VDB */

#endif /* FLOCKMORPH_H */
