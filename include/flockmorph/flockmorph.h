/* flockmorph — turn one 3D shape into another as a flock.
 *
 * The public C API. One umbrella header; everything under src/ and kernels/ is internal.
 *
 * The flow follows MuJoCo's model/data split:
 *   fm_scene_def   parameters (from a scene file or fm_default_scene_def())
 *   fm_model       everything immutable after preprocessing: tets, orders, path, bounding sphere
 *   fm_state       everything the step mutates: the agent store, the clock, counters
 *   fm_step(model, state) advances one time step; fm_state_tet_vertices() gives a frame.
 *
 * Every fallible call takes an fm_error* and returns an fm_status (or NULL for constructors);
 * on failure err->message says what went wrong and names the file, line, key or element.
 */
#ifndef FLOCKMORPH_H
#define FLOCKMORPH_H

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
    FM_ERR_INTERNAL = 5  /* a library failed in a way the input does not explain */
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

/* Every parameter of a run; docs/scene.md documents each with its default and unit. */
typedef struct fm_scene_def {
    char scene_path[FM_PATH_MAX]; /* where it was read from (for messages); "" if built in code */
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
    char cache_name[256];       /* file name of the cache inside the output directory */
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

typedef struct fm_model fm_model;

/* Progress of long preprocessing stages; may be NULL. fraction is in [0, 1]. */
typedef void (*fm_progress_fn)(const char *stage, double fraction, void *user);

fm_model *fm_model_build(const fm_scene_def *def, fm_progress_fn progress, void *user,
                         fm_error *err);
void fm_model_destroy(fm_model *model);

typedef struct fm_model_info {
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
} fm_model_info;

fm_model_info fm_model_get_info(const fm_model *model);

/* Target tet j's four vertices (12 floats, x y z per vertex) in world units. */
const float *fm_model_target_tet(const fm_model *model, int64_t j);

/* ---------------------------------------------------------------- state */

typedef struct fm_state fm_state;

typedef enum fm_phase {
    FM_PHASE_WAITING = 0,  /* not launched yet, at rest in the source */
    FM_PHASE_FLYING = 1,   /* phase 1: following the path (FM eq 8) */
    FM_PHASE_HOMING = 2,   /* phase 2: flying straight to its target tet (FM eq 9) */
    FM_PHASE_ARRIVED = 3
} fm_phase;

/* threads <= 0 uses OpenMP's default. Results do not depend on the thread count. */
fm_state *fm_state_create(const fm_model *model, int threads, fm_error *err);
void fm_state_destroy(fm_state *state);

void fm_step(const fm_model *model, fm_state *state);

typedef struct fm_state_info {
    int64_t step;
    double time;               /* seconds of animation time */
    int64_t count[4];          /* agents per fm_phase */
    int all_arrived;
    int64_t morph_fallbacks;   /* agents whose correspondence needed the safe A(t) form */
    int64_t flying_agent_steps;/* phase-1 agent-steps so far ... */
    int64_t mde_agent_steps;   /* ... and those among them that MDE pushed (FM §5.4) */
    double min_obstacle_clearance; /* smallest d_t - R_X seen in phase 1; +inf without obstacles */
} fm_state_info;

fm_state_info fm_state_get_info(const fm_state *state);

/* Writes every agent's tet, 12 floats per agent (4 vertices × xyz), agents in id order.
 * Computes the morph (FM §6) for agents in phase 2. */
void fm_state_tet_vertices(const fm_model *model, const fm_state *state, float *out);

/* Target tet index each agent holds (-1 while it has none), agents in id order. */
void fm_state_targets(const fm_state *state, int64_t *out);

/* ---------------------------------------------------------------- cache */

/* The native frame cache (docs/cache-format.md): one zstd-compressed chunk per frame, an index
 * for random access. Written as PATH.partial and renamed to PATH only by finish(). */
typedef struct fm_cache_writer fm_cache_writer;

fm_cache_writer *fm_cache_writer_create(const char *path, uint64_t agents, double frame_rate,
                                        int compression_level, fm_error *err);
/* verts: agents × 12 floats. */
fm_status fm_cache_writer_add_frame(fm_cache_writer *w, const float *verts, fm_error *err);
fm_status fm_cache_writer_finish(fm_cache_writer *w, fm_error *err); /* frees w */
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

/* ---------------------------------------------------------------- cache attributes (format 2)
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
    int compression_level;   /* zstd 1..19 */
    int delta;               /* 1: f32 attributes stored as the XOR of their bits with the previous
                                frame's (lossless); every key_interval-th frame is stored whole */
    int key_interval;        /* frames between whole frames when delta is on (default 16) */
    double quantum;          /* > 0: f32 attributes rounded to multiples of quantum (lossy, error
                                <= quantum / 2, documented); 0: lossless (the default) */
} fm_cache_options;

fm_cache_options fm_default_cache_options(void);

fm_cache_writer *fm_cache_writer_create_attrs(const char *path, uint64_t agents, double frame_rate,
                                              const fm_cache_attr *attrs, int attr_count,
                                              const fm_cache_options *opts, fm_error *err);
/* data[i] points at agents × attribute i's values, in the order given to create_attrs. */
fm_status fm_cache_writer_add_frame_attrs(fm_cache_writer *w, const void *const *data, fm_error *err);
/* Reopens PATH.partial left by an interrupted run, keeps its first `frames` frames, drops anything
 * after them, and continues writing (checkpoint / resume). Fails if fewer frames are readable. */
fm_cache_writer *fm_cache_writer_resume(const char *path, uint32_t frames, fm_error *err);
uint32_t fm_cache_writer_frames(const fm_cache_writer *w); /* frames handed over so far */

int fm_cache_attr_count(const fm_cache_reader *r);
const fm_cache_attr_info *fm_cache_attr_at(const fm_cache_reader *r, int i);
int fm_cache_has_attr(const fm_cache_reader *r, fm_cache_attr attr);
/* Reads one attribute of one frame into out (agents × bytes_per_agent bytes). */
fm_status fm_cache_read_attr(fm_cache_reader *r, uint32_t frame, fm_cache_attr attr, void *out,
                             fm_error *err);
/* Sizes for `inspect`: the file, and the raw and compressed bytes of all frames. */
uint64_t fm_cache_file_bytes(const fm_cache_reader *r);
uint64_t fm_cache_raw_bytes(const fm_cache_reader *r);
uint64_t fm_cache_compressed_bytes(const fm_cache_reader *r);

/* ---------------------------------------------------------------- run */

typedef struct fm_run_stats {
    int64_t frames;                 /* frames written, frame 0 (the rest state) included */
    int64_t steps;
    double simulate_seconds;        /* time spent in fm_step */
    double output_seconds;          /* time spent computing and writing frames */
    int all_arrived;
    int stopped_at_frame_limit;
    int64_t inverted_tet_frames;    /* tet-frames with signed volume <= 0 */
    double final_max_vertex_error;  /* last frame vs the target tets (ground truth, double) */
    int target_tets_filled_once;    /* every target tet taken by exactly one agent */
    int64_t morph_fallbacks;
    double *mde_fraction;           /* per frame after frame 0: MDE agent-steps / phase-1 agent-steps,
                                       NaN for frames with nobody in phase 1; free with fm_run_stats_free */
    double mde_fraction_mean;       /* mean over the frames with agents in phase 1 (FM Table I) */
    double min_obstacle_clearance;  /* smallest d_t - R_X in phase 1; +inf without obstacles */
} fm_run_stats;

void fm_run_stats_free(fm_run_stats *stats);

/* Called after every frame; may be NULL. */
typedef void (*fm_run_progress_fn)(const fm_state_info *info, int64_t frame, void *user);

/* Steps until every agent has arrived or def.frame_limit frames are written, writing each frame
 * to `cache` (may be NULL) and measuring the run. */
fm_status fm_run(const fm_model *model, fm_state *state, fm_cache_writer *cache,
                 fm_run_progress_fn progress, void *user, fm_run_stats *stats, fm_error *err);

/* Number of tets (n × 12 floats) with signed volume <= 0. */
int64_t fm_count_inverted_tets(const float *verts, size_t n);

/* ---------------------------------------------------------------- export and preview */

/* Writes tets (n × 12 floats) as a triangle mesh, 4 triangles per tet; the format comes from
 * the extension: .ply (binary little-endian) or .obj. */
fm_status fm_export_tets(const float *verts, size_t n, const char *path, fm_error *err);

typedef struct fm_render_opts {
    int width, height;      /* pixels */
    double view_dir[3];     /* direction the camera looks along (world units) */
    double up[3];           /* world up */
    double margin;          /* fraction of the image left around the fitted bounds */
    const double *bounds;   /* optional fixed [minx miny minz maxx maxy maxz]; NULL fits the tets */
} fm_render_opts;

fm_render_opts fm_default_render_opts(void);

/* Orthographic, z-buffered, flat Lambert-shaded rendering of the tets' faces to a PNG. */
fm_status fm_render_tets_png(const float *verts, size_t n, const fm_render_opts *opts,
                             const char *path, fm_error *err);

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_H */
