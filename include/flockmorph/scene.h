/* flockmorph scenes: every parameter of a run (fm_scene_def, docs/scene.md), read from a JSON
 * scene file or built in code, and validated once. */
#ifndef FLOCKMORPH_SCENE_H
#define FLOCKMORPH_SCENE_H

#include "flockmorph/core.h"

#ifdef __cplusplus
extern "C" {
#endif

#define FM_PATH_MAX 4096
#define FM_MAX_PATH_POINTS 256
#define FM_MAX_MOTION_POINTS 64
/* The largest seed: 2^53 - 1, the largest integer that every JSON reader keeps exactly (jq and
 * JavaScript hold numbers as doubles, so a larger seed read back by them names another run). */
#define FM_SEED_MAX 9007199254740991ull

/* The files `flockmorph run` writes beside the cache in its output directory; output.cache may
 * not take one of these names (nor end in .partial, the name of a file being written). */
#define FM_OUTPUT_STATS "stats.json"
#define FM_OUTPUT_CHECKPOINT "checkpoint.fmck"
#define FM_OUTPUT_LOCK ".flockmorph.lock"
#define FM_OUTPUT_MANIFEST "wedge.json" /* what ran, with which overrides (docs/wedges.md) */
#define FM_OUTPUT_OBSTACLES "obstacles.ply" /* the placed obstacle meshes, when the scene has any */

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
#define FM_MAX_GROUPS 8

/* One morph of a shot (docs/scene.md, "Groups"). Times are seconds of animation time. */
typedef struct fm_group_def {
    char name[64];
    double start;                 /* from the shot's start, or from `after`'s arrival */
    int32_t after;                /* the earlier group whose last agent's arrival `start` counts from; -1: none */
    int32_t source_group;         /* the earlier group whose formed shape this one starts from (its agents
                                     fly on); -1: the source mesh */
    int32_t avoid[FM_MAX_GROUPS]; /* groups whose shape is an obstacle to this one's agents */
    int32_t avoid_count;
} fm_group_def;

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

/* How both shapes reach n tets (FM §4). */
typedef enum fm_subdivision {
    FM_SUBDIVIDE_BISECT = 0, /* issue 38: TetGen again under a volume bound for about n tets, then the
                                largest split at the midpoint of the longest edge (docs/limits.md) */
    FM_SUBDIVIDE_PAPER = 1   /* FM eqs 1-2: 1-to-4 centroid splits, then 1-to-3 and 1-to-2 */
} fm_subdivision;

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
    double radius[2];    /* the perception radius in spacings sqrt(A / N), A the mean of the source's and
                            the target's surface areas (the default) */
    double radius_j[2];  /* J of SCF eq 6: the perception radius is r = J / sqrt(N); used when by_j */
    int32_t by_j;        /* radius_j was given (the loader sets it; radius then may not be) */
    double angle_deg[2]; /* perception angle: full opening of the cone around the heading, (0, 360] */
    double weight[2];
} fm_boid_rule_def;

typedef enum fm_flock_sampling {
    FM_FLOCK_SAMPLE_RANDOM = 0, FM_FLOCK_SAMPLE_MOSAIC = 1, FM_FLOCK_SAMPLE_STRATIFIED = 2
} fm_flock_sampling;
/* Agents to destinations: random; spherical (both sets sampled, matched by direction); projected
 * (the target's points are the source's projected and relaxed, SCF's own method). */
typedef enum fm_flock_match {
    FM_FLOCK_MATCH_RANDOM = 0, FM_FLOCK_MATCH_SPHERICAL = 1, FM_FLOCK_MATCH_PROJECTED = 2
} fm_flock_match;

/* The mosaic's dis_ij (SCF eqs 1-2): it both selects the neighbours and enters E_ij. */
typedef enum fm_mosaic_distance { FM_MOSAIC_EUCLIDEAN = 0, FM_MOSAIC_MANHATTAN = 1 } fm_mosaic_distance;
/* What the Kalman filter's R is scaled over (SCF: R "adjusts how closely the agents follow the
 * virtual leaders"): nothing (R fixed), the agent's distance to its destination, or its leader's speed. */
typedef enum fm_kalman_r_over {
    FM_KALMAN_R_FIXED = 0, FM_KALMAN_R_OVER_DISTANCE = 1, FM_KALMAN_R_OVER_LEADER_SPEED = 2
} fm_kalman_r_over;
/* SCF Figure 6's two strategies: chosen by the target (a moving one tracks), or by the scene. */
typedef enum fm_fuzzy_strategy { FM_FUZZY_AUTO = 0, FM_FUZZY_STATIC = 1, FM_FUZZY_TRACKING = 2 } fm_fuzzy_strategy;
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
    fm_kalman_r_over kalman_r_over; /* R scaled per agent by kalman_r_scale over this; FIXED: not */
    fm_fuzzy_def kalman_r_scale; /* [x, scale] points, scale > 0, linear between, flat beyond */
    int32_t kalman_r_scale_velocity; /* the scale applies to R's velocity variance too (default: position only) */
    fm_fuzzy_def fuzzy[FM_FUZZY_FORCES];          /* SCF's static strategy (a static target) */
    fm_fuzzy_def fuzzy_tracking[FM_FUZZY_FORCES]; /* its tracking strategy (a deforming target) */
    fm_fuzzy_strategy fuzzy_strategy; /* which of the two runs (AUTO: tracking for a moving target) */
    double damping;              /* c of the damping force -m c (v - v_destination), 1/s */
    double external_gain;        /* acceleration per unit of style-field velocity, 1/s */
    double path_time;            /* seconds the leaders take along the path; 0 = path length / speed0 */
    double ease_in, ease_out;    /* seconds a leader takes to speed up from rest, and to slow to rest */
    double ease_spread;          /* seconds between the first leaders' start and the last's, front first */
    int32_t uncross;             /* projected or spherical match: swap destinations between nearby agents
                                    whose eq-11 paths cross (fm_match_uncross); 0 = the paper's match */
    double reform;               /* the last fraction of the path over which the formation turns from the
                                    source's layout into the target's; 0 = eq 11, over the whole path */
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
    /* a travelling target (target.path.*, docs/shape-flock.md "A target that travels"): the shape,
     * static or deforming, is carried along a route B, a cubic B-spline through these points, by
     * B(u) - B(0), turned about B(0) with the route's tangent when orient is set */
    double travel_points[FM_MAX_PATH_POINTS][3];
    int32_t travel_point_count;  /* 0: the target stays where it is placed; else >= 2 */
    double travel_start;         /* seconds when it sets off; < 0: when the last leader arrives */
    double travel_speed;         /* its cruise speed along the route, units/s; 0 = speed0 */
    double travel_ease;          /* seconds it takes to speed up from rest, and to slow to rest */
    int32_t travel_orient;       /* it turns with the route's tangent (a rotation-minimising frame) */
} fm_flock_def;

/* One change to a scene file's JSON before it is read (`flockmorph run --set KEY=VALUE`, a
 * wedge; docs/wedges.md). key is dotted, with list elements by their index ("mde.d_min",
 * "obstacles.meshes.0.scale"); missing groups are created. value is JSON text ("0.05", "true",
 * "[1, 2, 3]", "{\"type\": \"gravity\"}"; null removes the key, which then takes its default),
 * or any other text as a plain string. Messages about it start "--set KEY=VALUE", or
 * "ORIGIN: KEY=VALUE" when origin is not NULL. */
typedef struct fm_scene_override {
    const char *key, *value, *origin;
} fm_scene_override;

#define FM_MAX_OVERRIDES 64

/* An override as the loaded scene remembers it, so that errors found later (a mesh that does
 * not open, n too small) name it rather than the file's line. */
typedef struct fm_scene_override_note {
    char path[160];  /* the key as messages write it: "obstacles.meshes[0].scale" */
    char label[320]; /* what messages start with: "--set obstacles.meshes.0.scale=2" */
} fm_scene_override_note;

/* Every parameter of a run; docs/scene.md documents each with its default and unit. */
typedef struct fm_scene_def {
    char scene_path[FM_PATH_MAX]; /* where it was read from (for messages); "" if built in code */
    fm_mode mode;               /* the tetra morph (default) or the shape-constrained flock */
    fm_mesh_ref source;
    fm_mesh_ref target;
    int64_t n;                  /* agents = tets after subdivision; 0 = max(n1, n2) (FM §4) */
    double tet_quality;         /* TetGen radius-edge bound (-q), default 2.0 */
    double tet_max_volume;      /* TetGen volume bound (-a), 0 = none */
    int tet_subdivision;        /* fm_subdivision: how a shape with fewer than n tets gets n */
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
    double field_fade;          /* units: omega2 V_l fades to 0 over this distance outside the switch sphere
                                   (issue 38); 0 = the target's bounding-sphere radius, < 0 = no fade */
    double field_fade_time;     /* seconds: an agent still in phase 1 after this long in flight loses
                                   omega2 V_l over as long again; 0 = twice the path's length over
                                   omega1 speed0, < 0 = never */
    /* obstacles (FM §5.3) */
    fm_mesh_ref obstacles[FM_MAX_OBSTACLES];
    int32_t obstacle_count;
    double k_a;                 /* influence range of eq 7, units */
    double obstacle_voxel;      /* signed-distance voxel size, units; 0 = automatic */
    int32_t avoid_in_phase2;    /* beyond the paper (§8): obstacle avoidance also in phase 2 */
    int32_t path_route;         /* issue 38: the path is rerouted round the obstacles (inflated by the
                                   largest tet radius) where it crosses them; default 1 */
    double detour_time;         /* issue 38: seconds a tet near an obstacle may make no progress along
                                   the path before it takes the detour down the navigation function;
                                   0 = 8 k_a / (omega1 speed0), < 0 = never */
    double up[3];               /* the scene's up direction (any length, not zero; default +Z, glTF's
                                   is +Y): obstacle avoidance turns agents round an obstacle in the
                                   plane normal to it, so upright obstacles are passed at the side */
    /* local avoidance, MDE (FM §5.4) */
    double d_min;               /* minimum distance between tet centroids, units; 0 = off */
    double mde_speed;           /* push speed of a pair at zero distance, units/s; 0 = speed0 */
    /* path width (FM §5.1) */
    double path_width;          /* agents farther than width/2 from the path are pulled back; 0 = off */
    double path_attraction;     /* pull speed per unit of distance outside the width, 1/s */
    /* phase switch */
    fm_phase_switch phase_switch;
    double switch_distance;     /* units, for FM_SWITCH_DISTANCE */
    double blend_time;          /* beyond the paper (issue 38): seconds over which the phase-1 velocity
                                   blends into eq 9's V_2 after the switch; 0 = the hard switch */
    /* a target that moves (issue 38; docs/scene.md "target_motion"): a mesh sequence with the
       target mesh's connectivity that the target tets follow, and/or a path the target travels;
       both a pure function of the time since `start` */
    struct fm_target_motion_def {
        char sequence[FM_PATH_MAX];  /* printf pattern with one integer, as shape_flock.deform.sequence; "" = none */
        int32_t frames;              /* meshes 0 .. frames-1 */
        double frame_rate;           /* meshes per second, linear between them, looping */
        double start;                /* seconds before the target starts to move */
        double path[FM_MAX_MOTION_POINTS][3]; /* offsets from the rest placement, after [0, 0, 0] */
        int32_t path_count;
        double speed;                /* units per second along the path; it stops at the last point */
    } target_motion;
    uint64_t seed;              /* random seed, 0 ... FM_SEED_MAX */
    int32_t compression_level;  /* zstd level of the frame cache, 1..19 */
    int32_t cache_delta;        /* frame cache: XOR delta to the previous frame (lossless; default 1) */
    int32_t cache_key_interval; /* frame cache: frames from one whole frame to the next with delta */
    double cache_quantum;       /* frame cache: round positions to multiples of this; 0 = lossless */
    int32_t cache_piece_agents; /* frame cache: agents per piece (format 4), each compressed on its own */
    char cache_name[256];       /* file name of the cache inside the output directory */
    fm_flock_def flock;         /* mode FM_MODE_SHAPE_FLOCK only */
    /* a shot of several morphs (docs/scene.md, "Groups"): group_count > 0 when the file has a
       `groups` list. fm_scene_load then gives the shared values only (group_index -1), which no
       model is built from; fm_scene_load_group gives group g's whole definition (group_index g) */
    int32_t group_count;
    int32_t group_index;
    fm_group_def group;
    /* the overrides it was read with (fm_scene_load_overridden), in order; for messages only */
    fm_scene_override_note overrides[FM_MAX_OVERRIDES];
    int32_t override_count;
} fm_scene_def;

fm_scene_def fm_default_scene_def(void);

/* Group g of a scene with `groups` (0 <= g < group_count): the scene's top level with the group's
 * item laid over it (objects merged key by key, other values replaced), read and validated as a
 * scene is; errors name the key in the group's item ("FILE:LINE:COL: groups[1].speed0: ...") or
 * at the top level where the value comes from there. A group whose source is another group's
 * formed shape ("source": {"group": NAME}) gets that group's target as its source mesh. */
fm_status fm_scene_load_group(const char *path, const fm_scene_override *overrides, int count, int g,
                              fm_scene_def *def, fm_error *err);

/* The same from a scene text in memory (len bytes; name stands for the file, as in fm_scene_parse). */
fm_status fm_scene_parse_group(const char *text, size_t len, const char *name, const fm_scene_override *overrides,
                               int count, int g, fm_scene_def *def, fm_error *err);

/* Reads and validates a JSON scene file. Relative mesh paths are resolved against the scene
 * file's directory. Unknown keys, wrong types and out-of-range values fail with
 * "FILE:LINE:COLUMN: ..." in err->message. */
fm_status fm_scene_load(const char *path, fm_scene_def *def, fm_error *err);

/* The same from a scene text in memory (len bytes, no NUL needed). `name` stands for the file in
 * messages and relative mesh paths are resolved against its directory. */
fm_status fm_scene_parse(const char *text, size_t len, const char *name, fm_scene_def *def,
                         fm_error *err);

/* fm_scene_load of the file's JSON changed by `count` overrides, applied in order (a later one
 * wins), then validated exactly as a file is. An error in an overridden value, or in a key an
 * override created, names the override instead of FILE:LINE:COLUMN:
 * "--set mde.d_min=-1: mde.d_min: -1 is out of range: must be >= 0". */
fm_status fm_scene_load_overridden(const char *path, const fm_scene_override *overrides, int count,
                                   fm_scene_def *def, fm_error *err);

/* Checks a definition built in code (fm_scene_load calls it too). */
fm_status fm_scene_validate(const fm_scene_def *def, fm_error *err);

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_SCENE_H */
