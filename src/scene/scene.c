/* Scene files (JSON through jansson) and parameter validation.
 *
 * One table lists every numeric and string parameter with its key, type, range and place in
 * fm_scene_def; the loader and fm_scene_validate both walk it, so a range is written once.
 * Errors name FILE:LINE:COLUMN (found by json_locate.c, since jansson keeps no positions after
 * parsing) and the key. */
#define _POSIX_C_SOURCE 200809L
#include "fm_internal.h"
#include "json_locate.h"
#include "scene_groups.h"
#include "scene_internal.h"
#include "scene_override.h"

#include <jansson.h>

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A fuzzy curve through count [d, w] points. */
static fm_fuzzy_def fuzzy_curve(int count, const double (*pts)[2])
{
    fm_fuzzy_def c = {.count = count};
    for (int i = 0; i < count; i++) c.d[i] = pts[i][0], c.w[i] = pts[i][1];
    return c;
}

/* The shape flock's defaults (docs/scene.md "shape_flock"). Radii: SCF's J ranges divided by 3 (on
 * a surface of area A a radius J / sqrt(N) sees about pi J^2 / A agents whatever N: ~150 with the
 * paper's J on our 10-unit meshes, ~20 with these); angles and weights as SCF implies them
 * (separation widest, alignment narrowest). */
/* SCF Figure 6's two strategies (docs/shape-flock.md, "Fuzzy curves"): far from the destination
 * (6 units and more) the boids govern, homing holds the agent only loosely to its leader. Closing in,
 * the static strategy lets damping grow ("slowing down the agent nearby its destination"), the
 * tracking one lowers the steering and external weights further and raises homing sooner. */
static void default_fuzzy(fm_fuzzy_def *fixed, fm_fuzzy_def *tracking)
{
    static const double steering[3][2] = {{0, 0.05}, {1, 0.2}, {6, 1}}, homing[4][2] = {{0, 1}, {1, 0.8}, {3, 0.2}, {6, 0.03}};
    static const double damping[3][2] = {{0, 1}, {1, 1}, {3, 0}}, external[2][2] = {{0, 0.1}, {3, 1}};
    static const double t_steering[3][2] = {{0, 0.02}, {2, 0.2}, {6, 1}}, t_homing[3][2] = {{0, 1}, {2, 0.8}, {6, 0.03}};
    static const double t_damping[3][2] = {{0, 0.5}, {1, 0.5}, {3, 0}}, t_external[3][2] = {{0, 0.02}, {2, 0.1}, {6, 1}};
    fixed[FM_FUZZY_STEERING] = fuzzy_curve(3, steering), fixed[FM_FUZZY_HOMING] = fuzzy_curve(4, homing);
    fixed[FM_FUZZY_DAMPING] = fuzzy_curve(3, damping), fixed[FM_FUZZY_EXTERNAL] = fuzzy_curve(2, external);
    tracking[FM_FUZZY_STEERING] = fuzzy_curve(3, t_steering), tracking[FM_FUZZY_HOMING] = fuzzy_curve(3, t_homing);
    tracking[FM_FUZZY_DAMPING] = fuzzy_curve(3, t_damping), tracking[FM_FUZZY_EXTERNAL] = fuzzy_curve(3, t_external);
}

static fm_flock_def fm_default_flock_def(void)
{
    fm_flock_def f = {
        .sampling = FM_FLOCK_SAMPLE_MOSAIC, .match = FM_FLOCK_MATCH_PROJECTED, .mass = 1,
        .mosaic_iterations = FM_SAMPLE_MOSAIC_ITERATIONS, .mosaic_distance = FM_MOSAIC_EUCLIDEAN,
        .mosaic_k = FM_SAMPLE_MOSAIC_K, .mosaic_w = FM_SAMPLE_MOSAIC_W, .mosaic_step = FM_SAMPLE_MOSAIC_STEP,
        .stratified_lambda = FM_SAMPLE_LAMBDA, .stratified_oversample = FM_SAMPLE_OVERSAMPLE,
        .max_speed = {12, 18}, .max_force = {40, 80},
        /* radii in spacings: J / sqrt(A) of the J below (a third of SCF's) on the cylinder -> sphere
           example (A = 330); about 7 others within 1.5 spacings (docs/shape-flock.md) */
        .separation = {.radius = {1.2, 2.0}, .radius_j = {20, 40}, .angle_deg = {240, 300}, .weight = {0.8, 1.2}},
        .cohesion = {.radius = {0.55, 1.1}, .radius_j = {10, 40}, .angle_deg = {240, 300}, .weight = {0.1, 0.2}},
        .alignment = {.radius = {1.1, 2.2}, .radius_j = {20, 40}, .angle_deg = {300, 360}, .weight = {4, 6}},
        /* R over the distance to the destination (SCF: R sets how closely the agents follow their
           leaders): 8 units and more from it, 30 times r_position, so homing holds the agent's place
           loosely and the boids shape the flock while it keeps its leader's velocity; within 2 units
           r_position itself, as tight as a fixed R (docs/shape-flock.md, "R over the flight") */
        .kalman_q = 1, .kalman_r_position = 1, .kalman_r_velocity = 1,
        .kalman_r_over = FM_KALMAN_R_OVER_DISTANCE, .kalman_r_scale = {.count = 2, .d = {2, 8}, .w = {1, 30}},
        .damping = 3, .external_gain = 1, .ease_in = 1, .ease_out = 2.5, .ease_spread = 0.75, .reform = 0, .uncross = 1,
        .arrival_radius = 0.6, .arrival_time = 0.5, .turn_rate_deg = 720, .bind_distance = 0.002,
        .arrival_mode = FM_ARRIVAL_BIND, .float_amplitude = 0.05, .float_period = 2,
        .deform = FM_DEFORM_NONE, .deform_amplitude = 0.5, .deform_period = 2, .deform_wavelength = 5,
        .deform_direction = {1, 0, 0}, .deform_frame_rate = 24,
        .travel_start = -1, .travel_ease = 1, .travel_orient = 1,
    };
    default_fuzzy(f.fuzzy, f.fuzzy_tracking);
    return f;
}

fm_scene_def fm_default_scene_def(void)
{
    fm_scene_def d;
    memset(&d, 0, sizeof d);
    d.source.scale = d.target.scale = 1.0;
    d.up[2] = 1.0;
    d.tet_quality = 2.0;
    d.speed0 = 10.0;
    d.omega1 = 1.0;
    d.frame_rate = 24.0;
    d.frame_limit = 10000;
    d.path_key_points = 32;
    d.path_curve = FM_CURVE_POLYLINE;
    d.shrink = 0.5;
    d.shrink_time = 0.25;
    d.morph_fraction = 0.75;
    d.blend_time = 0.25; /* issue 38: 6 frames at 24 fps turn the switch's kink into a curve */
    d.seed = 1;
    d.group_index = -1;
    d.group.after = d.group.source_group = -1;
    d.compression_level = 1; /* zstd level 1: twice as fast as 3 on frames, about 10 % larger */
    d.cache_delta = 1; /* lossless, and it pays: docs/performance.md, "Cache writer" */
    d.cache_key_interval = 16;
    d.cache_piece_agents = 65536;
    d.omega2 = 1.0;
    d.k_a = 1.0;
    d.path_route = 1;
    d.path_attraction = 1.0;
    strcpy(d.cache_name, "frames.fmc");
    d.flock = fm_default_flock_def();
    d.target_motion.frame_rate = 24;
    d.target_motion.speed = 1;
    return d;
}

typedef enum param_type {
    P_DOUBLE, P_INT32, P_INT64, P_UINT64, P_BOOL, P_VEC3, P_INT3, P_MESH, P_NAME, P_CURVE, P_SWITCH,
    P_FIELD_KIND, P_POINTS, P_FIELDS, P_OBSTACLES,
    P_ENUM,     /* one of param.names (a NULL-terminated list), stored as an int-sized enum */
    P_RANGE,    /* [lo, hi] (or one number for both), each in range, lo <= hi */
    P_FUZZY,    /* a fuzzy weight curve: [[d, w], ...], d increasing */
    P_PATTERN   /* a mesh file name pattern, resolved like P_MESH but optional */
} param_type;

enum { OPEN_MIN = 1, OPEN_MAX = 2, POSITIVE_WEIGHTS = 4 /* P_FUZZY: the curve's values are > 0 */ };

/* Bounds that keep a run from blowing up (issue 42; docs/scene.md, "Ranges"), each far beyond any
 * sane scene: speed0 10^6 units/s crosses a 10-unit scene (the meshes' usual size) 4000 times a
 * frame at 24 fps; below 1/100 fps one step (time.time_step 0) lasts over 100 s; a mass of 10^-6
 * keeps the largest force's acceleration (shape_flock.max_force 10^12 / 10^-6) far inside the
 * float range of the step's velocities. Before, speed0 10^9, 10^-9 fps and a mass of 10^-300 ran
 * until the state ran away (the runaway check still catches what a bound cannot: speed0 10^6 in a
 * scene of one unit). */
#define FM_SPEED0_MAX 1e6
#define FM_FRAME_RATE_MIN 0.01
#define FM_FLOCK_MASS_MIN 1e-6

typedef struct param {
    const char *key;    /* dotted: "time.frame_rate" */
    param_type type;
    size_t offset;
    double min, max;
    int open;           /* OPEN_MIN / OPEN_MAX: that bound itself is excluded */
} param;

/* The values of each P_ENUM key, NULL-terminated. */
static const char *const MODE_NAMES[] = {"tetra_morph", "shape_flock", NULL};
static const char *const SAMPLING_NAMES[] = {"random", "mosaic", "stratified", NULL};
static const char *const MATCH_NAMES[] = {"random", "spherical", "projected", NULL};
static const char *const DISTANCE_NAMES[] = {"euclidean", "manhattan", NULL};
static const char *const ARRIVAL_NAMES[] = {"bind", "float", NULL};
static const char *const R_OVER_NAMES[] = {"none", "distance", "leader_speed", NULL};
static const char *const STRATEGY_NAMES[] = {"auto", "static", "tracking", NULL};
static const char *const DEFORM_NAMES[] = {"none", "wave", "pulse", "sequence", NULL};
static const char *const SUBDIVISION_NAMES[] = {"bisect", "paper", NULL};
static const struct { const char *key; const char *const *names; } ENUM_NAMES[] = {
    {"mode", MODE_NAMES}, {"shape_flock.sampling", SAMPLING_NAMES}, {"shape_flock.match", MATCH_NAMES},
    {"shape_flock.arrival.mode", ARRIVAL_NAMES}, {"shape_flock.deform.type", DEFORM_NAMES},
    {"shape_flock.mosaic.distance", DISTANCE_NAMES}, {"shape_flock.kalman.r_scale.over", R_OVER_NAMES},
    {"shape_flock.fuzzy.strategy", STRATEGY_NAMES},
    {"tetgen.subdivision", SUBDIVISION_NAMES},
};

static const char *const *enum_names(const param *p)
{
    for (size_t i = 0; i < sizeof ENUM_NAMES / sizeof ENUM_NAMES[0]; i++)
        if (!strcmp(ENUM_NAMES[i].key, p->key)) return ENUM_NAMES[i].names;
    return MODE_NAMES; /* not reached: every P_ENUM key is listed */
}

/* Keys (or groups of keys) of the tetra morph alone; "shape_flock" holds the flock's alone. A key of
 * the other mode is an error rather than silently ignored. */
static const char *const TETRA_ONLY[] = {"tetgen", "omega1", "path.key_points", "path.curve", "path.width",
                                         "path.attraction", "launch_rate", "morph", "style.omega2", "style.fade_distance",
                                         "style.fade_time",
                                         "obstacles.in_phase2", "obstacles.detour_time", "mde",
                                         "phase2", "up", "target_motion"};

static int has_prefix(const char *key, const char *group)
{
    size_t len = strlen(group);
    return !strncmp(key, group, len) && (key[len] == 0 || key[len] == '.');
}

static int applies(const param *p, fm_mode mode)
{
    if (has_prefix(p->key, "shape_flock") || has_prefix(p->key, "target.path")) return mode == FM_MODE_SHAPE_FLOCK;
    for (size_t i = 0; i < sizeof TETRA_ONLY / sizeof TETRA_ONLY[0]; i++)
        if (has_prefix(p->key, TETRA_ONLY[i])) return mode == FM_MODE_TETRA_MORPH;
    return 1;
}

/* The sampling method a key of the group "shape_flock.mosaic" or "shape_flock.stratified" belongs
 * to, as named in SAMPLING_NAMES; -1 for any other key. Such a key with another method is an error,
 * as a key of the other mode is. */
static int sampling_of(const param *p)
{
    if (has_prefix(p->key, "shape_flock.mosaic")) return FM_FLOCK_SAMPLE_MOSAIC;
    if (has_prefix(p->key, "shape_flock.stratified")) return FM_FLOCK_SAMPLE_STRATIFIED;
    return -1;
}

#define OFF(field) offsetof(fm_scene_def, field)
static const param PARAMS[] = {
    {"mode", P_ENUM, OFF(mode), 0, 0, 0}, /* first: the keys read after it are checked against it */
    {"source.mesh", P_MESH, OFF(source.path), 0, 0, 0},
    {"source.translate", P_VEC3, OFF(source.translate), -1e9, 1e9, 0},
    {"source.scale", P_DOUBLE, OFF(source.scale), 0, 1e9, 1},
    {"source.rotate_deg", P_VEC3, OFF(source.rotate_deg), -3600, 3600, 0},
    {"target.mesh", P_MESH, OFF(target.path), 0, 0, 0},
    {"target.translate", P_VEC3, OFF(target.translate), -1e9, 1e9, 0},
    {"target.scale", P_DOUBLE, OFF(target.scale), 0, 1e9, 1},
    {"target.rotate_deg", P_VEC3, OFF(target.rotate_deg), -3600, 3600, 0},
    {"target.path.points", P_POINTS, OFF(flock.travel_points), -1e9, 1e9, 0},
    {"target.path.start", P_DOUBLE, OFF(flock.travel_start), -1, 1e9, 0},
    {"target.path.speed", P_DOUBLE, OFF(flock.travel_speed), 0, 1e9, 0},
    {"target.path.ease", P_DOUBLE, OFF(flock.travel_ease), 0, 1e9, 0},
    {"target.path.orient", P_BOOL, OFF(flock.travel_orient), 0, 0, 0},
    {"n", P_INT64, OFF(n), 0, 1e9, 0},
    {"tetgen.quality", P_DOUBLE, OFF(tet_quality), 1.1, 100, 0},
    {"tetgen.max_volume", P_DOUBLE, OFF(tet_max_volume), 0, 1e30, 0},
    {"tetgen.subdivision", P_ENUM, OFF(tet_subdivision), 0, 0, 0},
    {"speed0", P_DOUBLE, OFF(speed0), 0, FM_SPEED0_MAX, OPEN_MIN}, /* bounds: docs/scene.md, "Ranges" */
    {"omega1", P_DOUBLE, OFF(omega1), 0, 1e3, 1},
    {"time.frame_rate", P_DOUBLE, OFF(frame_rate), FM_FRAME_RATE_MIN, 1e4, 0},
    {"time.time_step", P_DOUBLE, OFF(time_step), 0, 1e3, 0},
    {"time.frame_limit", P_INT32, OFF(frame_limit), 1, 1e7, 0},
    {"path.points", P_POINTS, OFF(path_points), -1e9, 1e9, 0},
    {"path.key_points", P_INT32, OFF(path_key_points), 1, 1e5, 0},
    {"path.curve", P_CURVE, OFF(path_curve), 0, 0, 0},
    {"launch_rate", P_DOUBLE, OFF(launch_rate), 0, 1e12, 0},
    {"morph.shrink", P_DOUBLE, OFF(shrink), 0, 1, 1},
    {"morph.shrink_time", P_DOUBLE, OFF(shrink_time), 0, 1e6, 0},
    {"morph.morph_fraction", P_DOUBLE, OFF(morph_fraction), 0, 1, OPEN_MIN | OPEN_MAX},
    {"seed", P_UINT64, OFF(seed), 0, 0, 0},
    {"output.cache", P_NAME, OFF(cache_name), 0, 0, 0},
    {"output.compression_level", P_INT32, OFF(compression_level), -7, 19, 0}, /* 0 is refused below */
    {"output.delta", P_BOOL, OFF(cache_delta), 0, 0, 0},
    {"output.key_interval", P_INT32, OFF(cache_key_interval), 1, 65536, 0},
    {"output.quantum", P_DOUBLE, OFF(cache_quantum), 0, 1e6, 0},
    {"output.piece_agents", P_INT32, OFF(cache_piece_agents), 256, 1 << 30, 0},
    {"style.omega2", P_DOUBLE, OFF(omega2), 0, 1e3, 0},
    {"style.fade_distance", P_DOUBLE, OFF(field_fade), -1, 1e9, 0},
    {"style.fade_time", P_DOUBLE, OFF(field_fade_time), -1, 1e9, 0},
    {"style.grid", P_INT3, OFF(field_grid), 0, 2048, 0},
    {"style.fields", P_FIELDS, OFF(fields), 0, 0, 0},
    {"obstacles.meshes", P_OBSTACLES, OFF(obstacles), 0, 0, 0},
    {"obstacles.k_a", P_DOUBLE, OFF(k_a), 0, 1e9, OPEN_MIN},
    {"obstacles.voxel", P_DOUBLE, OFF(obstacle_voxel), 0, 1e9, 0},
    {"obstacles.in_phase2", P_BOOL, OFF(avoid_in_phase2), 0, 0, 0},
    {"obstacles.route", P_BOOL, OFF(path_route), 0, 0, 0},
    {"obstacles.detour_time", P_DOUBLE, OFF(detour_time), -1, 1e6, 0},
    {"up", P_VEC3, OFF(up), -1e9, 1e9, 0},
    {"mde.d_min", P_DOUBLE, OFF(d_min), 0, 1e9, 0},
    {"mde.speed", P_DOUBLE, OFF(mde_speed), 0, 1e9, 0},
    {"path.width", P_DOUBLE, OFF(path_width), 0, 1e9, 0},
    {"path.attraction", P_DOUBLE, OFF(path_attraction), 0, 1e6, 0},
    {"phase2.switch", P_SWITCH, OFF(phase_switch), 0, 0, 0},
    {"phase2.switch_distance", P_DOUBLE, OFF(switch_distance), -1e9, 1e9, 0},
    {"phase2.blend_time", P_DOUBLE, OFF(blend_time), 0, 1e6, 0},
    {"target_motion.sequence", P_PATTERN, OFF(target_motion.sequence), 0, 0, 0},
    {"target_motion.frames", P_INT32, OFF(target_motion.frames), 0, 1e6, 0},
    {"target_motion.frame_rate", P_DOUBLE, OFF(target_motion.frame_rate), 0, 1e6, OPEN_MIN},
    {"target_motion.start", P_DOUBLE, OFF(target_motion.start), 0, 1e9, 0},
    {"target_motion.path", P_POINTS, OFF(target_motion.path), -1e9, 1e9, 0},
    {"target_motion.speed", P_DOUBLE, OFF(target_motion.speed), 0, 1e9, OPEN_MIN},
    {"shape_flock.sampling", P_ENUM, OFF(flock.sampling), 0, 0, 0}, /* before the two groups below */
    {"shape_flock.mosaic.iterations", P_INT32, OFF(flock.mosaic_iterations), 0, 1e5, 0},
    {"shape_flock.mosaic.distance", P_ENUM, OFF(flock.mosaic_distance), 0, 0, 0},
    {"shape_flock.mosaic.k", P_DOUBLE, OFF(flock.mosaic_k), 0, 16, OPEN_MIN},
    {"shape_flock.mosaic.w", P_DOUBLE, OFF(flock.mosaic_w), 0, 16, OPEN_MIN},
    {"shape_flock.mosaic.step", P_DOUBLE, OFF(flock.mosaic_step), 0, 4, OPEN_MIN},
    {"shape_flock.stratified.lambda", P_DOUBLE, OFF(flock.stratified_lambda), 0, 100, OPEN_MIN},
    {"shape_flock.stratified.oversample", P_DOUBLE, OFF(flock.stratified_oversample), 1, 16, 0},
    {"shape_flock.match", P_ENUM, OFF(flock.match), 0, 0, 0},
    {"shape_flock.mass", P_DOUBLE, OFF(flock.mass), FM_FLOCK_MASS_MIN, 1e9, 0},
    {"shape_flock.max_speed", P_RANGE, OFF(flock.max_speed), 0, 1e9, OPEN_MIN},
    {"shape_flock.max_force", P_RANGE, OFF(flock.max_force), 0, 1e12, 0},
    {"shape_flock.separation.radius", P_RANGE, OFF(flock.separation.radius), 0, 1e6, 0},
    {"shape_flock.separation.radius_j", P_RANGE, OFF(flock.separation.radius_j), 0, 1e9, 0},
    {"shape_flock.separation.angle", P_RANGE, OFF(flock.separation.angle_deg), 0, 360, OPEN_MIN},
    {"shape_flock.separation.weight", P_RANGE, OFF(flock.separation.weight), 0, 1e6, 0},
    {"shape_flock.cohesion.radius", P_RANGE, OFF(flock.cohesion.radius), 0, 1e6, 0},
    {"shape_flock.cohesion.radius_j", P_RANGE, OFF(flock.cohesion.radius_j), 0, 1e9, 0},
    {"shape_flock.cohesion.angle", P_RANGE, OFF(flock.cohesion.angle_deg), 0, 360, OPEN_MIN},
    {"shape_flock.cohesion.weight", P_RANGE, OFF(flock.cohesion.weight), 0, 1e6, 0},
    {"shape_flock.alignment.radius", P_RANGE, OFF(flock.alignment.radius), 0, 1e6, 0},
    {"shape_flock.alignment.radius_j", P_RANGE, OFF(flock.alignment.radius_j), 0, 1e9, 0},
    {"shape_flock.alignment.angle", P_RANGE, OFF(flock.alignment.angle_deg), 0, 360, OPEN_MIN},
    {"shape_flock.alignment.weight", P_RANGE, OFF(flock.alignment.weight), 0, 1e6, 0},
    {"shape_flock.kalman.q", P_DOUBLE, OFF(flock.kalman_q), 0, 1e12, 0},
    {"shape_flock.kalman.r_position", P_DOUBLE, OFF(flock.kalman_r_position), 0, 1e12, OPEN_MIN},
    {"shape_flock.kalman.r_velocity", P_DOUBLE, OFF(flock.kalman_r_velocity), 0, 1e12, OPEN_MIN},
    {"shape_flock.kalman.r_scale.over", P_ENUM, OFF(flock.kalman_r_over), 0, 0, 0},
    {"shape_flock.kalman.r_scale.points", P_FUZZY, OFF(flock.kalman_r_scale), 0, 1e9, POSITIVE_WEIGHTS},
    {"shape_flock.kalman.r_scale.velocity", P_BOOL, OFF(flock.kalman_r_scale_velocity), 0, 0, 0},
    {"shape_flock.fuzzy.strategy", P_ENUM, OFF(flock.fuzzy_strategy), 0, 0, 0},
    {"shape_flock.fuzzy.steering", P_FUZZY, OFF(flock.fuzzy[FM_FUZZY_STEERING]), 0, 1e9, 0},
    {"shape_flock.fuzzy.homing", P_FUZZY, OFF(flock.fuzzy[FM_FUZZY_HOMING]), 0, 1e9, 0},
    {"shape_flock.fuzzy.damping", P_FUZZY, OFF(flock.fuzzy[FM_FUZZY_DAMPING]), 0, 1e9, 0},
    {"shape_flock.fuzzy.external", P_FUZZY, OFF(flock.fuzzy[FM_FUZZY_EXTERNAL]), 0, 1e9, 0},
    {"shape_flock.fuzzy.tracking.steering", P_FUZZY, OFF(flock.fuzzy_tracking[FM_FUZZY_STEERING]), 0, 1e9, 0},
    {"shape_flock.fuzzy.tracking.homing", P_FUZZY, OFF(flock.fuzzy_tracking[FM_FUZZY_HOMING]), 0, 1e9, 0},
    {"shape_flock.fuzzy.tracking.damping", P_FUZZY, OFF(flock.fuzzy_tracking[FM_FUZZY_DAMPING]), 0, 1e9, 0},
    {"shape_flock.fuzzy.tracking.external", P_FUZZY, OFF(flock.fuzzy_tracking[FM_FUZZY_EXTERNAL]), 0, 1e9, 0},
    {"shape_flock.damping", P_DOUBLE, OFF(flock.damping), 0, 1e6, 0},
    {"shape_flock.external_gain", P_DOUBLE, OFF(flock.external_gain), 0, 1e6, 0},
    {"shape_flock.path_time", P_DOUBLE, OFF(flock.path_time), 0, 1e9, 0},
    {"shape_flock.ease.in", P_DOUBLE, OFF(flock.ease_in), 0, 1e9, 0},
    {"shape_flock.ease.out", P_DOUBLE, OFF(flock.ease_out), 0, 1e9, 0},
    {"shape_flock.ease.spread", P_DOUBLE, OFF(flock.ease_spread), 0, 1e9, 0},
    {"shape_flock.reform", P_DOUBLE, OFF(flock.reform), 0, 1, 0},
    {"shape_flock.uncross", P_BOOL, OFF(flock.uncross), 0, 0, 0},
    {"shape_flock.arrival.radius", P_DOUBLE, OFF(flock.arrival_radius), 0, 1e9, 0},
    {"shape_flock.arrival.time", P_DOUBLE, OFF(flock.arrival_time), 0, 1e6, OPEN_MIN},
    {"shape_flock.arrival.turn_rate", P_DOUBLE, OFF(flock.turn_rate_deg), 0, 1e9, OPEN_MIN},
    {"shape_flock.arrival.bind_distance", P_DOUBLE, OFF(flock.bind_distance), 0, 1e9, 0},
    {"shape_flock.arrival.mode", P_ENUM, OFF(flock.arrival_mode), 0, 0, 0},
    {"shape_flock.arrival.float_amplitude", P_DOUBLE, OFF(flock.float_amplitude), 0, 1e9, 0},
    {"shape_flock.arrival.float_period", P_DOUBLE, OFF(flock.float_period), 0, 1e9, OPEN_MIN},
    {"shape_flock.deform.type", P_ENUM, OFF(flock.deform), 0, 0, 0},
    {"shape_flock.deform.amplitude", P_DOUBLE, OFF(flock.deform_amplitude), -1e9, 1e9, 0},
    {"shape_flock.deform.period", P_DOUBLE, OFF(flock.deform_period), 0, 1e9, OPEN_MIN},
    {"shape_flock.deform.wavelength", P_DOUBLE, OFF(flock.deform_wavelength), 0, 1e9, OPEN_MIN},
    {"shape_flock.deform.direction", P_VEC3, OFF(flock.deform_direction), -1e9, 1e9, 0},
    {"shape_flock.deform.sequence", P_PATTERN, OFF(flock.deform_sequence), 0, 0, 0},
    {"shape_flock.deform.frames", P_INT32, OFF(flock.deform_frames), 0, 1e6, 0},
    {"shape_flock.deform.frame_rate", P_DOUBLE, OFF(flock.deform_frame_rate), 0, 1e6, OPEN_MIN},
};
#define PARAM_COUNT (sizeof PARAMS / sizeof PARAMS[0])

static const param *find_param(const char *key)
{
    for (size_t i = 0; i < PARAM_COUNT; i++)
        if (!strcmp(PARAMS[i].key, key)) return &PARAMS[i];
    return NULL;
}

int fm_scene_is_key(const char *key)
{
    return find_param(key) || !strncmp(key, "obstacles.meshes[", 17) || !strncmp(key, "style.fields[", 13);
}

/* The keys of one element of obstacles.meshes (source and target share the ranges above). */
#define MOFF(field) offsetof(fm_mesh_ref, field)
static const param MESH_PARAMS[] = {
    {"mesh", P_MESH, MOFF(path), 0, 0, 0},
    {"translate", P_VEC3, MOFF(translate), -1e9, 1e9, 0},
    {"scale", P_DOUBLE, MOFF(scale), 0, 1e9, 1},
    {"rotate_deg", P_VEC3, MOFF(rotate_deg), -3600, 3600, 0},
};

/* The keys of one element of style.fields; FIELD_KEYS says which apply to each kind. */
#define FOFF(field) offsetof(fm_field_def, field)
static const param FIELD_PARAMS[] = {
    {"type", P_FIELD_KIND, FOFF(kind), 0, 0, 0},
    {"gain", P_DOUBLE, FOFF(gain), 0, 1e6, 0},
    {"scale", P_DOUBLE, FOFF(scale), 0, 1e9, OPEN_MIN},
    {"direction", P_VEC3, FOFF(direction), -1e9, 1e9, 0},
    {"speed", P_DOUBLE, FOFF(speed), 0, 1e9, 0},
    {"turbulence", P_DOUBLE, FOFF(turbulence), 0, 1e6, 0},
    {"period", P_DOUBLE, FOFF(period), 0, 1e9, 0},
    {"center", P_VEC3, FOFF(center), -1e9, 1e9, 0},
    {"axis", P_VEC3, FOFF(axis), -1e9, 1e9, 0},
    {"strength", P_DOUBLE, FOFF(strength), -1e6, 1e6, 0},
};
static const char *const FIELD_NAMES[] = {"curl_noise", "wind", "gravity", "vortex"};
static const char *const FIELD_KEYS[] = {" type gain scale ", " type direction speed turbulence scale period ",
                                         " type direction speed ", " type center axis strength "};

fm_field_def fm_default_field_def(fm_field_kind kind)
{
    fm_field_def f = {.kind = kind, .gain = 1, .scale = 1, .speed = 1, .period = 1, .strength = 1};
    f.direction[kind == FM_FIELD_GRAVITY ? 2 : 0] = kind == FM_FIELD_GRAVITY ? -1 : 1;
    f.axis[1] = 1;
    return f;
}

/* Where an error points: the scene text and a JSON path. */
typedef struct where {
    const char *file;
    const char *text;       /* NULL when validating a definition built in code */
    fm_error *err;
    fm_json_step steps[8];
    char names[8][64];
    int depth;
    int at_key;             /* point at the key rather than the value */
    char label[160];        /* the key named in messages inside list elements ("style.fields[1].gain") */
    const fm_scene_def *overridden; /* the overrides an error may be about (fm_override_blame), or NULL */
    int in_group, group;    /* reading group `group`'s merged document: keys are sought in its item first */
} where;

#define KEY(w, p) ((w)->label[0] ? (w)->label : (p)->key)

/* Points w at a dotted key; a list element is written "obstacles.meshes[1]" (then ".mesh" etc.). */
static void where_set_key(where *w, const char *dotted)
{
    w->depth = 0;
    w->at_key = 0;
    const char *s = dotted;
    while (*s && w->depth < 8) {
        size_t len = strcspn(s, ".["), name = w->depth;
        snprintf(w->names[name], sizeof w->names[0], "%.*s", (int)len, s);
        w->steps[w->depth++] = (fm_json_step){w->names[name], 0};
        s += len;
        while (*s == '[' && w->depth < 8) { /* one or more indices */
            w->names[w->depth][0] = 0;
            w->steps[w->depth++] = (fm_json_step){NULL, (int)strtol(s + 1, NULL, 10)};
            s += strcspn(s, "]") + (s[strcspn(s, "]")] == ']');
        }
        s += *s == '.';
    }
}

/* w's path as messages write keys: "obstacles.meshes[1].scale". */
static void where_path(const where *w, char *out, size_t size)
{
    size_t len = 0;
    out[0] = 0;
    for (int d = 0; d < w->depth && len < size; d++, len = strlen(out)) {
        if (w->steps[d].key) snprintf(out + len, size - len, "%s%s", d ? "." : "", w->steps[d].key);
        else snprintf(out + len, size - len, "[%d]", w->steps[d].index);
    }
}

/* The override an error at w about `key` is about, or NULL. */
static const fm_scene_override_note *blame(const where *w, const char *key)
{
    if (!w->overridden) return NULL;
    char path[256], in_group[300];
    where_path(w, path, sizeof path);
    if (w->in_group) { /* a group's key, as an override names it: groups[1].speed0 */
        snprintf(in_group, sizeof in_group, "groups[%d].%s", w->group, path);
        const fm_scene_override_note *note = fm_override_blame(w->overridden, in_group);
        if (note) return note;
    }
    const fm_scene_override_note *note = fm_override_blame(w->overridden, path);
    return note ? note : fm_override_blame(w->overridden, key);
}

/* In a group's merged document, w's key as it stands in the group's item (groups[i].KEY), if it
 * does: 0 and its line and column, else -1. */
static int locate_in_group(const where *w, int *line, int *col)
{
    fm_json_step steps[10] = {{"groups", 0}, {NULL, w->group}};
    for (int d = 0; d < w->depth && d < 8; d++) steps[d + 2] = w->steps[d];
    return fm_json_locate(w->text, steps, w->depth + 2, w->at_key, line, col);
}

/* The error message: "FILE:LINE:COL: key: what" (FILE: key: what without a text), or
 * "--set KEY=VALUE: key: what" when an override set the value. */
static fm_status fail_at(const where *w, const char *key, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static fm_status fail_at(const where *w, const char *key, const char *fmt, ...)
{
    char what[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    const fm_scene_override_note *note = blame(w, key);
    if (note) return fm_fail(w->err, FM_ERR_INPUT, "%s: %s: %s", note->label, key, what);
    int line = 0, col = 0;
    char group_key[192] = "";
    if (w->text && w->in_group && locate_in_group(w, &line, &col) == 0)
        snprintf(group_key, sizeof group_key, "groups[%d].", w->group);
    else if (w->text) fm_json_locate(w->text, w->steps, w->depth, w->at_key, &line, &col);
    const char *file = w->file && w->file[0] ? w->file : "scene";
    if (line > 0) return fm_fail(w->err, FM_ERR_INPUT, "%s:%d:%d: %s%s: %s", file, line, col, group_key, key, what);
    return fm_fail(w->err, FM_ERR_INPUT, "%s: %s: %s", file, key, what);
}

static fm_status check_range(const where *w, const param *p, double x)
{
    if (!isfinite(x)) return fail_at(w, KEY(w, p), "must be a finite number");
    int open_min = p->open & OPEN_MIN, open_max = p->open & OPEN_MAX;
    int low = open_min ? !(x > p->min) : !(x >= p->min);
    if (!low && (open_max ? x < p->max : x <= p->max)) return FM_OK;
    char value[FM_DOUBLE_CHARS], bound[FM_DOUBLE_CHARS]; /* every digit that decides */
    const char *op = low ? (open_min ? ">" : ">=") : (open_max ? "<" : "<=");
    return fail_at(w, KEY(w, p), "%s is out of range: must be %s %s", fm_shortest(value, x), op,
                   fm_shortest(bound, low ? p->min : p->max));
}

static fm_status read_number(const where *w, const param *p, const json_t *v, double *out)
{
    if (!json_is_number(v)) return fail_at(w, KEY(w, p), "expected a number, got %s", fm_json_type_name(v));
    *out = json_number_value(v);
    return check_range(w, p, *out);
}

static fm_status read_integer(const where *w, const param *p, const json_t *v, int64_t *out)
{
    if (!json_is_integer(v)) return fail_at(w, KEY(w, p), "expected an integer, got %s", fm_json_type_name(v));
    *out = json_integer_value(v);
    if (p->type == P_UINT64) { /* the seed */
        if (*out < 0) return fail_at(w, KEY(w, p), "must be >= 0");
        if ((uint64_t)*out > FM_SEED_MAX)
            return fail_at(w, KEY(w, p), "%lld is out of range: must be <= %llu (2^53 - 1: a larger integer does not "
                           "survive JSON readers that hold numbers as doubles, such as jq and JavaScript)",
                           (long long)*out, (unsigned long long)FM_SEED_MAX);
        return FM_OK;
    }
    return check_range(w, p, (double)*out);
}

/* [x, y, z] with each component in range; w points at the array and is extended per element. */
static fm_status read_vec3(where *w, const param *p, const json_t *v, double *out)
{
    if (!json_is_array(v) || json_array_size(v) != 3)
        return fail_at(w, KEY(w, p), "expected an array of 3 numbers, got %s%s", fm_json_type_name(v),
                       json_is_array(v) ? " of another length" : "");
    for (int k = 0; k < 3; k++) {
        w->steps[w->depth++] = (fm_json_step){NULL, k};
        fm_status st = read_number(w, p, json_array_get(v, (size_t)k), &out[k]);
        w->depth--;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

/* A list of points in the scene: path.points, target.path.points (the shape flock's travelling
 * target) or target_motion.path (the tetra morph's moving target). */
typedef struct points_ref {
    double (*at)[3];
    int32_t *count;
    int max;
} points_ref;
static points_ref points_of(const param *p, fm_scene_def *def)
{
    if (!strcmp(p->key, "target_motion.path"))
        return (points_ref){def->target_motion.path, &def->target_motion.path_count, FM_MAX_MOTION_POINTS};
    if (!strcmp(p->key, "target.path.points"))
        return (points_ref){def->flock.travel_points, &def->flock.travel_point_count, FM_MAX_PATH_POINTS};
    return (points_ref){def->path_points, &def->path_point_count, FM_MAX_PATH_POINTS};
}

static fm_status read_points(where *w, const param *p, const json_t *v, fm_scene_def *def)
{
    const points_ref pts = points_of(p, def);
    if (!json_is_array(v)) return fail_at(w, KEY(w, p), "expected an array of [x, y, z] points, got %s", fm_json_type_name(v));
    if (json_array_size(v) > (size_t)pts.max)
        return fail_at(w, KEY(w, p), "%zu points is more than the %d supported", json_array_size(v), pts.max);
    *pts.count = (int32_t)json_array_size(v);
    for (int32_t i = 0; i < *pts.count; i++) {
        w->steps[w->depth++] = (fm_json_step){NULL, i};
        fm_status st = read_vec3(w, p, json_array_get(v, (size_t)i), pts.at[i]);
        w->depth--;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

/* A mesh path, resolved against the scene file's directory when relative. */
static fm_status read_mesh_path(const where *w, const param *p, const json_t *v, char *out)
{
    if (!json_is_string(v)) return fail_at(w, KEY(w, p), "expected a file name, got %s", fm_json_type_name(v));
    const char *name = json_string_value(v);
    if (!name[0]) return fail_at(w, KEY(w, p), "the mesh file name is empty");
    const char *slash = strrchr(w->file, '/');
    int dir_len = (name[0] != '/' && slash) ? (int)(slash - w->file + 1) : 0;
    if ((size_t)dir_len + strlen(name) + 1 > FM_PATH_MAX) return fail_at(w, KEY(w, p), "the path is too long");
    snprintf(out, FM_PATH_MAX, "%.*s%s", dir_len, w->file, name);
    return FM_OK;
}

/* Why `name` cannot be the cache's name in the output directory, or NULL if it can. The run
 * writes its other files there too (FM_OUTPUT_*), and every file as NAME.partial first: a cache
 * named like one of them would overwrite it or be overwritten. */
static const char *cache_name_problem(const char *name)
{
    static const char *const taken[] = {FM_OUTPUT_STATS, FM_OUTPUT_CHECKPOINT, FM_OUTPUT_LOCK, FM_OUTPUT_MANIFEST,
                                         FM_OUTPUT_OBSTACLES};
    size_t len = strlen(name), suffix = strlen(".partial");
    if (!name[0] || strchr(name, '/') || len >= 256 || !strcmp(name, ".") || !strcmp(name, ".."))
        return "is not a plain file name (no '/', at most 255 bytes)";
    for (size_t i = 0; i < sizeof taken / sizeof *taken; i++)
        if (!strcmp(name, taken[i])) return "is the name of another file the run writes in the output directory";
    if (len >= suffix && !strcmp(name + len - suffix, ".partial"))
        return "ends in .partial, the name the run gives a file while writing it";
    return NULL;
}

static fm_status read_name(const where *w, const param *p, const json_t *v, char *out)
{
    if (!json_is_string(v)) return fail_at(w, KEY(w, p), "expected a file name, got %s", fm_json_type_name(v));
    const char *name = json_string_value(v), *problem = cache_name_problem(name);
    if (problem) return fail_at(w, KEY(w, p), "'%s' %s", name, problem);
    strcpy(out, name);
    return FM_OK;
}

/* One of `count` names; *out = its index. */
static fm_status read_enum(const where *w, const param *p, const json_t *v, const char *const *names, int count, int *out)
{
    const char *s = json_is_string(v) ? json_string_value(v) : "";
    for (int i = 0; i < count; i++)
        if (!strcmp(s, names[i])) return *out = i, FM_OK;
    char list[256] = "";
    for (int i = 0; i < count; i++)
        snprintf(list + strlen(list), sizeof list - strlen(list), "%s\"%s\"", i ? (i + 1 == count ? " or " : ", ") : "", names[i]);
    return fail_at(w, KEY(w, p), "expected %s", list);
}

static fm_status read_bool(const where *w, const param *p, const json_t *v, int32_t *out)
{
    if (!json_is_boolean(v)) return fail_at(w, KEY(w, p), "expected true or false, got %s", fm_json_type_name(v));
    *out = json_is_true(v);
    return FM_OK;
}

/* [nx, ny, nz] integers in range. */
static fm_status read_int3(where *w, const param *p, const json_t *v, int32_t *out)
{
    if (!json_is_array(v) || json_array_size(v) != 3)
        return fail_at(w, KEY(w, p), "expected an array of 3 integers, got %s", fm_json_type_name(v));
    for (int k = 0; k < 3; k++) {
        int64_t x = 0;
        w->steps[w->depth++] = (fm_json_step){NULL, k};
        fm_status st = read_integer(w, p, json_array_get(v, (size_t)k), &x);
        w->depth--;
        if (st != FM_OK) return st;
        out[k] = (int32_t)x;
    }
    return FM_OK;
}

static fm_status read_param(where *w, const param *p, const json_t *v, void *base, fm_scene_def *def);

/* [lo, hi] with both in range and lo <= hi; a single number sets both. */
static fm_status read_range(where *w, const param *p, const json_t *v, double *out)
{
    if (json_is_number(v)) {
        fm_status st = read_number(w, p, v, &out[0]);
        out[1] = out[0];
        return st;
    }
    if (!json_is_array(v) || json_array_size(v) != 2)
        return fail_at(w, KEY(w, p), "expected a number or a range [lo, hi], got %s", fm_json_type_name(v));
    for (int k = 0; k < 2; k++) {
        w->steps[w->depth++] = (fm_json_step){NULL, k};
        fm_status st = read_number(w, p, json_array_get(v, (size_t)k), &out[k]);
        w->depth--;
        if (st != FM_OK) return st;
    }
    if (out[0] > out[1]) return fail_at(w, KEY(w, p), "the range [%g, %g] runs backwards", out[0], out[1]);
    return FM_OK;
}

/* One [d, w] point of a fuzzy curve: d in the param's range, w >= 0, d above the previous point's. */
static fm_status read_fuzzy_point(where *w, const param *p, const json_t *v, fm_fuzzy_def *c, int i)
{
    param weight = *p; /* named like the curve; weights are 0 .. 10^6 */
    weight.min = 0, weight.max = 1e6, weight.open = p->open & POSITIVE_WEIGHTS ? OPEN_MIN : 0;
    if (!json_is_array(v) || json_array_size(v) != 2)
        return fail_at(w, KEY(w, p), "expected a point [distance, weight], got %s", fm_json_type_name(v));
    w->steps[w->depth++] = (fm_json_step){NULL, 0};
    fm_status st = read_number(w, p, json_array_get(v, 0), &c->d[i]);
    w->steps[w->depth - 1] = (fm_json_step){NULL, 1};
    if (st == FM_OK) st = read_number(w, &weight, json_array_get(v, 1), &c->w[i]);
    w->depth--;
    if (st == FM_OK && i > 0 && !((float)c->d[i] > (float)c->d[i - 1]))
        st = fail_at(w, KEY(w, p), "point %d: the distances must increase (%g after %g)", i, c->d[i], c->d[i - 1]);
    return st;
}

/* A fuzzy weight curve (SCF Figure 6): [[d, w], ...], 1 to FM_FUZZY_MAX_POINTS points. */
static fm_status read_fuzzy(where *w, const param *p, const json_t *v, fm_fuzzy_def *c)
{
    if (!json_is_array(v) || json_array_size(v) < 1 || json_array_size(v) > FM_FUZZY_MAX_POINTS)
        return fail_at(w, KEY(w, p), "expected 1 to %d points [distance, weight]", FM_FUZZY_MAX_POINTS);
    c->count = (int32_t)json_array_size(v);
    for (int32_t i = 0; i < c->count; i++) {
        w->steps[w->depth++] = (fm_json_step){NULL, i};
        fm_status st = read_fuzzy_point(w, p, json_array_get(v, (size_t)i), c, i);
        w->depth--;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

static int name_count(const char *const *names)
{
    int n = 0;
    while (names[n]) n++;
    return n;
}

/* Reads member p->key of a list element, naming it "<label>.<key>" in messages. */
static fm_status read_member(where *w, const char *label, const param *p, const json_t *v, void *base,
                             fm_scene_def *def)
{
    w->steps[w->depth++] = (fm_json_step){p->key, 0};
    snprintf(w->label, sizeof w->label, "%s.%s", label, p->key);
    fm_status st = read_param(w, p, v, base, def);
    w->label[0] = 0;
    w->depth--;
    return st;
}

/* Reads the keys of one list element (an object) into base through its table; unknown keys, and
 * keys not in `allowed` (" key key ... ", NULL = all), are errors. */
static fm_status read_element(where *w, const json_t *obj, const param *table, int count, void *base,
                              const char *label, const char *allowed, fm_scene_def *def)
{
    if (!json_is_object(obj)) return fail_at(w, label, "expected an object, got %s", fm_json_type_name(obj));
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)obj, key, value) {
        char spaced[80];
        snprintf(spaced, sizeof spaced, " %s ", key);
        int known = 0;
        for (int i = 0; i < count; i++) known |= !strcmp(table[i].key, key);
        if (known && (!allowed || strstr(allowed, spaced))) continue;
        w->steps[w->depth++] = (fm_json_step){key, 0};
        w->at_key = 1;
        snprintf(w->label, sizeof w->label, "%s.%s", label, key);
        fm_status st = fail_at(w, w->label, known ? "does not apply here (this element takes:%s)" : "unknown key%s",
                               known ? allowed : " (docs/scene.md lists the keys)");
        w->label[0] = 0;
        return st;
    }
    for (int i = 0; i < count; i++) {
        const json_t *v = json_object_get(obj, table[i].key);
        fm_status st = v ? read_member(w, label, &table[i], v, base, def) : FM_OK;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

typedef fm_status (*element_reader)(where *w, const json_t *e, int32_t i, const char *label, fm_scene_def *def);

/* A list of objects (style.fields, obstacles.meshes): each element read by read_one, with
 * messages naming "<key>[i]". */
static fm_status read_list(where *w, const param *p, const json_t *v, int max, int32_t *count,
                           element_reader read_one, fm_scene_def *def)
{
    if (!json_is_array(v)) return fail_at(w, p->key, "expected an array of objects, got %s", fm_json_type_name(v));
    if (json_array_size(v) > (size_t)max) return fail_at(w, p->key, "at most %d entries", max);
    *count = (int32_t)json_array_size(v);
    for (int32_t i = 0; i < *count; i++) {
        char label[64];
        snprintf(label, sizeof label, "%s[%d]", p->key, i);
        w->steps[w->depth++] = (fm_json_step){NULL, i};
        fm_status st = read_one(w, json_array_get(v, (size_t)i), i, label, def);
        w->depth--;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

/* One style field: {"type": "curl_noise", ...}, starting from its kind's defaults. */
static fm_status read_field(where *w, const json_t *e, int32_t i, const char *label, fm_scene_def *def)
{
    const json_t *type = json_is_object(e) ? json_object_get(e, "type") : NULL;
    if (json_is_object(e) && !type) return fail_at(w, label, "every field needs a \"type\"");
    fm_field_def probe = {.kind = FM_FIELD_CURL_NOISE};
    fm_status st = type ? read_member(w, label, &FIELD_PARAMS[0], type, &probe, def) : FM_OK;
    if (st != FM_OK) return st;
    def->fields[i] = fm_default_field_def(probe.kind);
    return read_element(w, e, FIELD_PARAMS, (int)(sizeof FIELD_PARAMS / sizeof FIELD_PARAMS[0]), &def->fields[i],
                        label, FIELD_KEYS[probe.kind], def);
}

/* One obstacle: {"mesh": "king.obj", "translate": [...], ...}. */
static fm_status read_obstacle(where *w, const json_t *e, int32_t i, const char *label, fm_scene_def *def)
{
    fm_mesh_ref *ref = &def->obstacles[i];
    memset(ref, 0, sizeof *ref);
    ref->scale = 1;
    fm_status st = read_element(w, e, MESH_PARAMS, (int)(sizeof MESH_PARAMS / sizeof MESH_PARAMS[0]), ref, label, NULL, def);
    if (st == FM_OK && !ref->path[0]) st = fail_at(w, label, "every obstacle needs a \"mesh\"");
    return st;
}

static const char *const CURVE_NAMES[] = {"polyline", "catmull_rom"};
static const char *const SWITCH_NAMES[] = {"sphere", "distance"};

/* Reads one value into the field at base + p->offset (base: the scene, or a list element). */
static fm_status read_param(where *w, const param *p, const json_t *v, void *base, fm_scene_def *def)
{
    char *field = (char *)base + p->offset;
    int64_t i = 0;
    int e = 0;
    fm_status st;
    switch (p->type) {
    case P_DOUBLE: return read_number(w, p, v, (double *)field);
    case P_INT32: st = read_integer(w, p, v, &i); *(int32_t *)field = (int32_t)i; return st;
    case P_INT64: return read_integer(w, p, v, (int64_t *)field);
    case P_UINT64: st = read_integer(w, p, v, &i); *(uint64_t *)field = (uint64_t)i; return st;
    case P_VEC3: return read_vec3(w, p, v, (double *)field);
    case P_MESH: case P_PATTERN: return read_mesh_path(w, p, v, field);
    case P_ENUM: st = read_enum(w, p, v, enum_names(p), name_count(enum_names(p)), &e); *(int *)field = e; return st;
    case P_RANGE: return read_range(w, p, v, (double *)field);
    case P_FUZZY: return read_fuzzy(w, p, v, (fm_fuzzy_def *)field);
    case P_NAME: return read_name(w, p, v, field);
    case P_CURVE: st = read_enum(w, p, v, CURVE_NAMES, 2, &e); *(fm_curve *)field = (fm_curve)e; return st;
    case P_SWITCH: st = read_enum(w, p, v, SWITCH_NAMES, 2, &e); *(fm_phase_switch *)field = (fm_phase_switch)e; return st;
    case P_FIELD_KIND: st = read_enum(w, p, v, FIELD_NAMES, 4, &e); *(fm_field_kind *)field = (fm_field_kind)e; return st;
    case P_BOOL: return read_bool(w, p, v, (int32_t *)field);
    case P_INT3: return read_int3(w, p, v, (int32_t *)field);
    case P_POINTS: return read_points(w, p, v, def);
    case P_FIELDS: return read_list(w, p, v, FM_MAX_FIELDS, &def->field_count, read_field, def);
    case P_OBSTACLES: return read_list(w, p, v, FM_MAX_OBSTACLES, &def->obstacle_count, read_obstacle, def);
    }
    return FM_OK;
}

/* The value at a dotted key, or NULL. A group that is not an object is an error. */
static fm_status lookup(where *w, const json_t *root, const char *dotted, const json_t **out)
{
    *out = NULL;
    where_set_key(w, dotted);
    const json_t *v = root;
    for (int d = 0; d < w->depth; d++) {
        if (!json_is_object(v)) {
            int depth = w->depth;
            w->depth = d;
            fm_status st = fail_at(w, w->names[d - 1], "expected an object, got %s", fm_json_type_name(v));
            w->depth = depth;
            return st;
        }
        v = json_object_get(v, w->names[d]);
        if (!v) return FM_OK;
    }
    *out = v;
    return FM_OK;
}

/* Is `key` (inside group `prefix`, "" for the top) a parameter or a group of parameters? */
static int known_key(const char *prefix, const char *key)
{
    if (strchr(key, '.')) return 0; /* "time.frame_rate" must be written as a nested object */
    char full[160];
    snprintf(full, sizeof full, "%s%s%s", prefix, prefix[0] ? "." : "", key);
    size_t len = strlen(full);
    for (size_t i = 0; i < PARAM_COUNT; i++)
        if (!strncmp(PARAMS[i].key, full, len) && (PARAMS[i].key[len] == 0 || PARAMS[i].key[len] == '.')) return 1;
    return 0;
}

static fm_status check_unknown_keys(where *w, const json_t *obj, const char *prefix)
{
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)obj, key, value) {
        char full[160];
        snprintf(full, sizeof full, "%s%s%s", prefix, prefix[0] ? "." : "", key);
        if (!prefix[0] && !strcmp(key, "groups")) continue; /* scene_groups.c reads it */
        if (!known_key(prefix, key)) {
            where_set_key(w, prefix);
            if (!prefix[0]) w->depth = 0;
            w->steps[w->depth++] = (fm_json_step){key, 0};
            w->at_key = 1;
            return fail_at(w, full, "unknown key (docs/scene.md lists the keys)");
        }
        if (json_is_object(value)) {
            fm_status st = check_unknown_keys(w, value, full);
            if (st != FM_OK) return st;
        }
    }
    return FM_OK;
}

/* A key given in the scene (w points at it) must belong to its mode and, for the sampling
 * groups, to its sampling method ("mode" and "shape_flock.sampling" are read before them). */
static fm_status check_applies(where *w, const param *p, const fm_scene_def *def)
{
    const int method = sampling_of(p);
    w->at_key = 1;
    if (!applies(p, def->mode)) return fail_at(w, p->key, "does not apply to mode \"%s\"", MODE_NAMES[def->mode]);
    if (method >= 0 && method != (int)def->flock.sampling)
        return fail_at(w, p->key, "applies only with shape_flock.sampling \"%s\" (this scene's is \"%s\")",
                       SAMPLING_NAMES[method], SAMPLING_NAMES[def->flock.sampling]);
    w->at_key = 0;
    return FM_OK;
}

static fm_status read_scene(where *w, const json_t *root, fm_scene_def *def)
{
    if (!json_is_object(root)) {
        w->depth = 0;
        return fail_at(w, "scene", "the scene must be a JSON object");
    }
    fm_status st = check_unknown_keys(w, root, "");
    for (size_t i = 0; i < PARAM_COUNT && st == FM_OK; i++) { /* "mode" comes first */
        const json_t *v;
        st = lookup(w, root, PARAMS[i].key, &v);
        if (st == FM_OK && v) st = check_applies(w, &PARAMS[i], def);
        if (st == FM_OK && v) st = read_param(w, &PARAMS[i], v, def, def);
        else if (st == FM_OK && PARAMS[i].type == P_MESH && !(def->group_count > 0 && def->group_index < 0)) {
            where_set_key(w, PARAMS[i].key);
            w->depth = 0;
            st = fail_at(w, PARAMS[i].key, "required key is missing");
        }
    }
    return st;
}

enum { MAX_STEPS_PER_FRAME = 1000000 };
#define FIELD_GRID_MAX_CELLS 268435456.0 /* 2^28, as fm_fields_create allows */

static int is_zero3(const double v[3]) { return v[0] == 0 && v[1] == 0 && v[2] == 0; }

/* A wind or gravity needs a direction and a vortex an axis: a zero vector has none. */
static fm_status check_field_vectors(where *w, const fm_scene_def *def)
{
    for (int32_t i = 0; i < def->field_count; i++) {
        const fm_field_def *f = &def->fields[i];
        int needs_direction = f->kind == FM_FIELD_WIND || f->kind == FM_FIELD_GRAVITY;
        if (!(needs_direction ? is_zero3(f->direction) : f->kind == FM_FIELD_VORTEX && is_zero3(f->axis))) continue;
        char key[64];
        snprintf(key, sizeof key, "style.fields[%d].%s", i, needs_direction ? "direction" : "axis");
        where_set_key(w, key);
        return fail_at(w, key, "must not be [0, 0, 0]: it gives the field's %s", needs_direction ? "direction" : "axis");
    }
    return FM_OK;
}

/* Checks that span several parameters. */
static fm_status check_target_motion(where *w, const fm_scene_def *def);

static fm_status check_consistency(where *w, const fm_scene_def *def)
{
    if (!(fabs(def->up[0]) + fabs(def->up[1]) + fabs(def->up[2]) > 0)) {
        where_set_key(w, "up");
        return fail_at(w, "up", "the up direction must not be zero");
    }
    if (def->compression_level == 0) { /* zstd reads 0 as its default, 3: say which one */
        where_set_key(w, "output.compression_level");
        return fail_at(w, "output.compression_level", "0 is not a level: use 1 ... 19, or -7 ... -1 for zstd's fast levels");
    }
    if (def->time_step > 0) {
        double steps = (1.0 / def->frame_rate) / def->time_step;
        where_set_key(w, "time.time_step");
        if (steps < 0.999999 || fabs(steps - floor(steps + 0.5)) > 1e-6 * steps)
            return fail_at(w, "time.time_step", "%g s does not divide the frame interval 1/%g s "
                           "into whole steps", def->time_step, def->frame_rate);
        if (steps > MAX_STEPS_PER_FRAME)
            return fail_at(w, "time.time_step", "%g s makes %.3g steps per frame, more than the %d supported",
                           def->time_step, steps, MAX_STEPS_PER_FRAME);
    }
    const int32_t *g = def->field_grid;
    if ((g[0] > 0 || g[1] > 0 || g[2] > 0) && !(g[0] > 0 && g[1] > 0 && g[2] > 0)) {
        where_set_key(w, "style.grid");
        return fail_at(w, "style.grid", "[%d, %d, %d]: give all three sizes, or [0, 0, 0] to evaluate the fields "
                       "directly", g[0], g[1], g[2]);
    }
    if ((double)g[0] * g[1] * g[2] > FIELD_GRID_MAX_CELLS) {
        where_set_key(w, "style.grid");
        return fail_at(w, "style.grid", "[%d, %d, %d] is %.3g cells, more than the 2^28 supported (16 bytes each)",
                       g[0], g[1], g[2], (double)g[0] * g[1] * g[2]);
    }
    fm_status st = def->mode == FM_MODE_TETRA_MORPH ? check_target_motion(w, def) : FM_OK;
    return st == FM_OK ? check_field_vectors(w, def) : st;
}

static fm_status check_range_pair(const where *w, const param *p, const double *lo_hi)
{
    fm_status st = check_range(w, p, lo_hi[0]);
    if (st == FM_OK) st = check_range(w, p, lo_hi[1]);
    if (st == FM_OK && lo_hi[0] > lo_hi[1]) st = fail_at(w, KEY(w, p), "the range [%g, %g] runs backwards", lo_hi[0], lo_hi[1]);
    return st;
}

/* The stratified sampler's work (sample_stratified.c) per surface: about oversample x n occupied
 * voxels, each weighing its triangles' pieces of edge h / max(2, 2 lambda), about 8 max(1, lambda)^2
 * pieces a voxel. Measured at about 1.2e-7 CPU s a piece (a 320-triangle sphere, n 300, oversample 16,
 * lambda 4 to 32; more past lambda 32, where pieces are split one by one). lambda 100 with oversample
 * 16 and 300 agents would weigh 3.8e8 pieces a surface, minutes of CPU; the limit refuses that at
 * once. The larger of the two limits holds so that lambda <= 4 passes at any n (the memory check
 * bounds n, and the time then grows only as n). */
#define STRATIFIED_MAX_PIECES 268435456.0 /* 2^28: about 30 CPU s a surface */
#define STRATIFIED_FREE_LAMBDA 4.0

static double stratified_pieces(double voxels, double lambda)
{
    const double l = lambda > 1 ? lambda : 1;
    return voxels * 8 * l * l;
}

static fm_status check_stratified_work(where *w, const fm_scene_def *def)
{
    const fm_flock_def *f = &def->flock;
    const double voxels = ceil(f->stratified_oversample * (double)def->n), pieces = stratified_pieces(voxels, f->stratified_lambda);
    const double limit = fmax(STRATIFIED_MAX_PIECES, stratified_pieces(voxels, STRATIFIED_FREE_LAMBDA));
    if (pieces <= limit) return FM_OK;
    const double most = sqrt(limit / (8 * voxels));
    char lambda[FM_DOUBLE_CHARS], oversample[FM_DOUBLE_CHARS];
    where_set_key(w, "shape_flock.stratified.lambda");
    return fail_at(w, "shape_flock.stratified.lambda", "%s with shape_flock.stratified.oversample %s and n %lld asks the "
                   "stratified sampler to weigh about %.3g triangle pieces per surface (%.0f voxels, oversample x n, of "
                   "8 lambda^2 = %.3g pieces each), more than the limit of %.3g (about %.0f CPU s a surface); use a "
                   "lambda of at most %.3g, or a smaller oversample or n", fm_shortest(lambda, f->stratified_lambda),
                   fm_shortest(oversample, f->stratified_oversample), (long long)def->n, pieces, voxels, pieces / voxels,
                   limit, limit * 1.2e-7, most);
}

/* The shape flock's checks that span several keys. */
static fm_status check_flock(where *w, const fm_scene_def *def)
{
    const fm_flock_def *f = &def->flock;
    if (def->n < 1) {
        where_set_key(w, "mode");
        return fail_at(w, "n", "the shape flock needs its number of agents (n >= 1)");
    }
    if (f->sampling == FM_FLOCK_SAMPLE_STRATIFIED) {
        fm_status st = check_stratified_work(w, def);
        if (st != FM_OK) return st;
    }
    if (f->travel_point_count == 1) {
        where_set_key(w, "target.path.points");
        return fail_at(w, "target.path.points", "a route needs at least 2 points: where the target is (the point it "
                       "turns about) and where it goes");
    }
    const double *dir = f->deform_direction;
    if (f->deform == FM_DEFORM_WAVE && dir[0] == 0 && dir[1] == 0 && dir[2] == 0) {
        where_set_key(w, "shape_flock.deform.type");
        return fail_at(w, "shape_flock.deform.direction", "a wave needs a non-zero direction");
    }
    if (f->deform != FM_DEFORM_SEQUENCE) return FM_OK;
    where_set_key(w, "shape_flock.deform.type");
    if (!f->deform_sequence[0] || !fm_one_integer_conversion(f->deform_sequence))
        return fail_at(w, "shape_flock.deform.sequence", "'%s' is not a file name pattern with one integer "
                       "(%%d, %%i or %%u, a width of at most 2 digits), like \"wave_%%03d.obj\"", f->deform_sequence);
    if (f->deform_frames < 1) return fail_at(w, "shape_flock.deform.frames", "a sequence needs at least one mesh");
    return FM_OK;
}

/* The tetra morph's moving target (issue 38): a sequence needs a pattern and meshes, and frames
 * without a sequence say nothing. A shot's groups chain their formed shapes (morph_shot.c), which a
 * target in motion has not got. */
static fm_status check_target_motion(where *w, const fm_scene_def *def)
{
    const struct fm_target_motion_def *tm = &def->target_motion;
    if (!tm->sequence[0] && tm->frames != 0) {
        where_set_key(w, "target_motion.frames");
        return fail_at(w, "target_motion.frames", "meshes of no sequence: give target_motion.sequence");
    }
    if (!tm->sequence[0] && tm->path_count == 0) return FM_OK;
    if (def->group_index >= 0 || def->group_count > 0) {
        where_set_key(w, "target_motion");
        return fail_at(w, "target_motion", "a shot's groups cannot move their target yet (a single morph can)");
    }
    if (def->phase_switch == FM_SWITCH_DISTANCE) {
        where_set_key(w, "phase2.switch");
        return fail_at(w, "phase2.switch", "\"distance\" reads the target's distance at rest: with target_motion "
                       "the switch is the travelling sphere (\"sphere\")");
    }
    if (!tm->sequence[0]) return FM_OK;
    where_set_key(w, "target_motion.sequence");
    if (!fm_one_integer_conversion(tm->sequence))
        return fail_at(w, "target_motion.sequence", "'%s' is not a file name pattern with one integer (%%d, "
                       "%%i or %%u, a width of at most 2 digits), like \"walk_%%03d.obj\"", tm->sequence);
    if (tm->frames < 1) return fail_at(w, "target_motion.frames", "a sequence needs at least one mesh");
    return FM_OK;
}

/* Range checks of every numeric entry of a table over the struct at base. */
static fm_status check_table(where *w, const param *table, size_t count, const void *base, const char *prefix)
{
    for (size_t i = 0; i < count; i++) {
        const param *p = &table[i];
        const char *field = (const char *)base + p->offset;
        if (prefix) snprintf(w->label, sizeof w->label, "%s.%s", prefix, p->key);
        fm_status st = FM_OK;
        if (p->type == P_DOUBLE) st = check_range(w, p, *(const double *)field);
        else if (p->type == P_INT32) st = check_range(w, p, *(const int32_t *)field);
        else if (p->type == P_INT64) st = check_range(w, p, (double)*(const int64_t *)field);
        else if (p->type == P_VEC3 || p->type == P_INT3)
            for (int k = 0; k < 3 && st == FM_OK; k++)
                st = check_range(w, p, p->type == P_VEC3 ? ((const double *)field)[k] : ((const int32_t *)field)[k]);
        else if (p->type == P_RANGE) st = check_range_pair(w, p, (const double *)field);
        else if (p->type == P_ENUM && (*(const int *)field < 0 || *(const int *)field >= name_count(enum_names(p))))
            st = fail_at(w, KEY(w, p), "unknown value %d", *(const int *)field);
        else if (p->type == P_FUZZY) {
            const fm_fuzzy_def *c = (const fm_fuzzy_def *)field;
            st = fm_fuzzy_def_check(c, KEY(w, p), w->err);
            for (int32_t j = 0; j < c->count && st == FM_OK && (p->open & POSITIVE_WEIGHTS); j++)
                if (!(c->w[j] > 0)) st = fail_at(w, KEY(w, p), "point %d: the value must be > 0, got %g", j, c->w[j]);
        }
        w->label[0] = 0;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

/* The list parameters of a definition built in code. */
static fm_status check_lists(where *w, const fm_scene_def *def)
{
    if (def->field_count < 0 || def->field_count > FM_MAX_FIELDS)
        return fail_at(w, "style.fields", "between 0 and %d fields", FM_MAX_FIELDS);
    if (def->obstacle_count < 0 || def->obstacle_count > FM_MAX_OBSTACLES)
        return fail_at(w, "obstacles.meshes", "between 0 and %d obstacles", FM_MAX_OBSTACLES);
    char label[64];
    for (int32_t i = 0; i < def->field_count; i++) {
        snprintf(label, sizeof label, "style.fields[%d]", i);
        if ((unsigned)def->fields[i].kind > FM_FIELD_VORTEX) return fail_at(w, label, "unknown field type");
        fm_status st = check_table(w, FIELD_PARAMS, sizeof FIELD_PARAMS / sizeof FIELD_PARAMS[0], &def->fields[i], label);
        if (st != FM_OK) return st;
    }
    for (int32_t i = 0; i < def->obstacle_count; i++) {
        snprintf(label, sizeof label, "obstacles.meshes[%d]", i);
        if (!def->obstacles[i].path[0]) return fail_at(w, label, "no mesh given");
        fm_status st = check_table(w, MESH_PARAMS, sizeof MESH_PARAMS / sizeof MESH_PARAMS[0], &def->obstacles[i], label);
        if (st != FM_OK) return st;
    }
    if ((unsigned)def->phase_switch > FM_SWITCH_DISTANCE) return fail_at(w, "phase2.switch", "unknown switch");
    return FM_OK;
}

/* A P_POINTS list of a definition built in code (check_table skips lists). */
static fm_status check_points(const where *w, const fm_scene_def *def, const char *key)
{
    const param *p = find_param(key);
    const points_ref pts = points_of(p, (fm_scene_def *)def); /* read only */
    if (*pts.count < 0 || *pts.count > pts.max) return fail_at(w, key, "between 0 and %d points", pts.max);
    fm_status st = FM_OK;
    for (int32_t i = 0; i < *pts.count; i++)
        for (int k = 0; k < 3 && st == FM_OK; k++) st = check_range(w, p, pts.at[i][k]);
    return st;
}

fm_status fm_scene_validate(const fm_scene_def *def, fm_error *err)
{
    where w = {def->scene_path, NULL, err, {{0}}, {{0}}, 0, 0, "", def, 0, 0};
    if (!def->source.path[0] || !def->target.path[0])
        return fail_at(&w, def->source.path[0] ? "target.mesh" : "source.mesh", "no mesh given");
    fm_status st = check_table(&w, PARAMS, PARAM_COUNT, def, NULL);
    if (st == FM_OK) st = check_lists(&w, def);
    if (st != FM_OK) return st;
    if ((st = check_points(&w, def, "path.points")) != FM_OK || (st = check_points(&w, def, "target.path.points")) != FM_OK ||
        (st = check_points(&w, def, "target_motion.path")) != FM_OK)
        return st;
    if (def->path_curve != FM_CURVE_POLYLINE && def->path_curve != FM_CURVE_CATMULL_ROM)
        return fail_at(&w, "path.curve", "unknown curve %d", (int)def->path_curve);
    const char *problem = memchr(def->cache_name, 0, sizeof def->cache_name) ? cache_name_problem(def->cache_name)
                                                                              : "is not a plain file name";
    if (problem) return fail_at(&w, "output.cache", "'%.255s' %s", def->cache_name, problem);
    if (def->mode == FM_MODE_SHAPE_FLOCK && (st = check_flock(&w, def)) != FM_OK) return st;
    return check_consistency(&w, def);
}

/* Scenes are a few KiB (256 path points and every key fit in well under 1 MiB). */
#define FM_SCENE_MAX_BYTES (64 << 20)

/* The scene's text, without a byte-order mark (fm_read_text_file, which wedge files share). */
static char *read_text(const char *path, size_t *out_len, fm_status *st, fm_error *err)
{
    return fm_read_text_file(path, "scene file", FM_SCENE_MAX_BYTES, out_len, st, err);
}

void fm_scene_key_location(const fm_scene_def *def, const char *key, char *out, size_t size)
{
    const char *file = def->scene_path;
    const fm_scene_override_note *note = fm_override_blame(def, key);
    if (note || !file[0]) {
        snprintf(out, size, "%s%s%s", note ? note->label : "", note ? ": " : "", key);
        return;
    }
    fm_status st;
    size_t len;
    char *text = read_text(file, &len, &st, NULL);
    json_t *root = text ? json_loads(text, JSON_REJECT_DUPLICATES, NULL) : NULL; /* locate needs valid JSON */
    int line = 0, col = 0;
    char group_key[32] = ""; /* a group's key where its item sets it: "groups[1]." */
    if (root) {
        where w = {file, text, NULL, {{0}}, {{0}}, 0, 0, "", NULL, def->group_index >= 0, def->group_index};
        where_set_key(&w, key);
        if (w.in_group && locate_in_group(&w, &line, &col) == 0)
            snprintf(group_key, sizeof group_key, "groups[%d].", def->group_index);
        else fm_json_locate(text, w.steps, w.depth, 0, &line, &col);
        json_decref(root);
    }
    free(text);
    if (line > 0) snprintf(out, size, "%s:%d:%d: %s%s", file, line, col, group_key, key);
    else snprintf(out, size, "%s: %s", file, key);
}

/* A curve of the strategy that does not run would be ignored: a static target runs the static
 * curves (shape_flock.fuzzy.*), a moving one the tracking curves (shape_flock.fuzzy.tracking.*),
 * unless shape_flock.fuzzy.strategy says which. Scene files written before the two strategies, with
 * shape_flock.fuzzy.* on a deforming target, are refused here naming the key, instead of running
 * with curves they did not choose. */
static const char *strategy_reason(const fm_flock_def *f)
{
    if (f->fuzzy_strategy != FM_FUZZY_AUTO) return "strategy is chosen by shape_flock.fuzzy.strategy";
    if (!fm_flock_target_moves(f)) return "target is static";
    return f->deform != FM_DEFORM_NONE ? "target deforms" : "target travels (target.path.points)";
}

static fm_status check_fuzzy_strategy(where *w, const json_t *root, const fm_scene_def *def)
{
    static const char *const names[FM_FUZZY_FORCES] = {"steering", "homing", "damping", "external"};
    const int tracking = fm_flock_tracking_strategy(&def->flock);
    for (int f = 0; f < FM_FUZZY_FORCES; f++) {
        char key[64], other[64];
        snprintf(key, sizeof key, tracking ? "shape_flock.fuzzy.%s" : "shape_flock.fuzzy.tracking.%s", names[f]);
        snprintf(other, sizeof other, tracking ? "shape_flock.fuzzy.tracking.%s" : "shape_flock.fuzzy.%s", names[f]);
        const json_t *v;
        fm_status st = lookup(w, root, key, &v);
        if (st != FM_OK) return st;
        w->at_key = 1;
        if (v)
            return fail_at(w, key, "the %s, so the %s strategy's curve %s applies (docs/scene.md)",
                           strategy_reason(&def->flock), tracking ? "tracking" : "static", other);
        w->at_key = 0;
    }
    return FM_OK;
}

/* R's scale curve with "none" would be ignored; the default curve's x is a distance, never a speed. */
static fm_status check_r_scale(where *w, const json_t *root, const fm_scene_def *def)
{
    const json_t *v;
    fm_status st = lookup(w, root, "shape_flock.kalman.r_scale.points", &v);
    if (st != FM_OK) return st;
    if (v && def->flock.kalman_r_over == FM_KALMAN_R_FIXED) {
        w->at_key = 1;
        return fail_at(w, "shape_flock.kalman.r_scale.points", "set shape_flock.kalman.r_scale.over to \"distance\" or "
                       "\"leader_speed\": the curve's x is one of them");
    }
    if (!v && def->flock.kalman_r_over == FM_KALMAN_R_OVER_LEADER_SPEED) {
        st = lookup(w, root, "shape_flock.kalman.r_scale.over", &v);
        if (st == FM_OK) st = fail_at(w, "shape_flock.kalman.r_scale.over", "\"leader_speed\" needs "
                                      "shape_flock.kalman.r_scale.points: the default points are distances");
    }
    return st;
}

/* A rule's radius is given in spacings (.radius) or as the paper's J (.radius_j), not both: the one
 * given is the one used (by_j). */
static fm_status read_radius_units(where *w, const json_t *root, fm_scene_def *def)
{
    static const char *const names[3] = {"separation", "cohesion", "alignment"};
    fm_boid_rule_def *rules[3] = {&def->flock.separation, &def->flock.cohesion, &def->flock.alignment};
    for (int r = 0; r < 3 && def->mode == FM_MODE_SHAPE_FLOCK; r++) {
        char key[64], key_j[64];
        snprintf(key, sizeof key, "shape_flock.%s.radius", names[r]);
        snprintf(key_j, sizeof key_j, "shape_flock.%s.radius_j", names[r]);
        const json_t *v, *v_j;
        fm_status st = lookup(w, root, key, &v);
        if (st == FM_OK) st = lookup(w, root, key_j, &v_j);
        if (st != FM_OK) return st;
        rules[r]->by_j = v_j != NULL;
        if (v && v_j) {
            w->at_key = 1;
            return fail_at(w, key_j, "give %s (in spacings) or %s (SCF's J), not both (docs/scene.md)", key, key_j);
        }
    }
    return FM_OK;
}

/* The route's timing and turning without a route would be ignored. */
static fm_status check_travel(where *w, const json_t *root, const fm_scene_def *def)
{
    static const char *const keys[] = {"target.path.start", "target.path.speed", "target.path.ease", "target.path.orient"};
    for (size_t i = 0; i < sizeof keys / sizeof keys[0] && def->flock.travel_point_count == 0; i++) {
        const json_t *v;
        fm_status st = lookup(w, root, keys[i], &v);
        if (st != FM_OK) return st;
        w->at_key = 1;
        if (v) return fail_at(w, keys[i], "the target has no route: set target.path.points (docs/scene.md)");
        w->at_key = 0;
    }
    return FM_OK;
}

/* Reads the document (changed by the overrides, if any) into def. */
/* What only the whole document of a mode can be checked for. */
static fm_status check_mode(where *w, const json_t *root, const fm_scene_def *def)
{
    fm_status st = FM_OK;
    if (st == FM_OK && def->mode == FM_MODE_SHAPE_FLOCK) st = check_r_scale(w, root, def);
    if (st == FM_OK && def->mode == FM_MODE_SHAPE_FLOCK) st = check_flock(w, def);
    if (st == FM_OK && def->mode == FM_MODE_SHAPE_FLOCK) st = check_fuzzy_strategy(w, root, def);
    if (st == FM_OK && def->mode == FM_MODE_SHAPE_FLOCK) st = check_travel(w, root, def);
    return st;
}

/* The scene's groups (scene_groups.c), read before the rest: a shot's top level needs no meshes. */
static fm_status read_groups(where *w, const json_t *root, fm_group_def *groups, fm_scene_def *def)
{
    int count = 0;
    fm_status st = json_is_object(root) ? fm_groups_read(root, w->file && w->file[0] ? w->file : "scene", w->text,
                                                         groups, &count, w->err)
                                        : FM_OK;
    def->group_count = count;
    const json_t *mode = json_object_get(root, "mode");
    const int flock = json_is_string(mode) && !strcmp(json_string_value(mode), "shape_flock");
    for (int g = 0; st == FM_OK && flock && g < count; g++) {
        if (groups[g].avoid_count > 0) {
            where_set_key(w, "groups");
            w->steps[w->depth++] = (fm_json_step){NULL, g};
            w->steps[w->depth++] = (fm_json_step){"avoid", 0};
            w->at_key = 1;
            char key[48];
            snprintf(key, sizeof key, "groups[%d].avoid", g);
            return fail_at(w, key, "the shape flock's groups take no avoid in this version (the tetra morph's do)");
        }
    }
    return st;
}

/* An override of a top-level key that every group of the shot sets itself changes nothing: an
 * error naming it, rather than a run that silently ignores it. */
static fm_status check_overrides_reach_groups(where *w, const json_t *root, const fm_scene_override *set, int count,
                                              const fm_scene_def *def)
{
    const json_t *list = json_object_get(root, "groups");
    for (int i = 0; i < count && def->group_count > 0; i++) {
        const char after = set[i].key[6];
        if (!strncmp(set[i].key, "groups", 6) && (after == 0 || after == '.' || after == '[')) continue; /* a group's own */
        int shadowed = 0;
        for (int g = 0; g < def->group_count; g++) shadowed += fm_override_shadowed(json_array_get(list, (size_t)g), set[i].key);
        if (shadowed == def->group_count)
            return fm_fail(w->err, FM_ERR_INPUT, "%s: every group of the shot sets %s itself, so the scene's top-level "
                           "value reaches none of them: set it in a group (groups.0.%s)", def->overrides[i].label,
                           set[i].key, set[i].key);
    }
    return FM_OK;
}

static fm_status read_document(where *w, json_t *root, const fm_scene_override *set, int count, fm_scene_def *def)
{
    fm_group_def groups[FM_MAX_GROUPS];
    fm_status st = json_is_object(root) ? fm_overrides_apply(root, set, count, def, w->err) : FM_OK;
    if (st == FM_OK) st = read_groups(w, root, groups, def);
    if (st == FM_OK) st = check_overrides_reach_groups(w, root, set, count, def);
    if (st == FM_OK) st = read_scene(w, root, def);
    if (st == FM_OK) st = read_radius_units(w, root, def);
    if (st == FM_OK) st = check_consistency(w, def);
    if (st == FM_OK && def->group_count == 0) st = check_mode(w, root, def); /* a shot's groups are checked whole */
    return st;
}

static fm_status read_group_document(where *w, json_t *root, const fm_scene_override *set, int count, int g,
                                     fm_scene_def *def);

static fm_status parse_scene(const char *text, size_t len, const char *name, const fm_scene_override *set, int count,
                             int group, fm_scene_def *def, fm_error *err)
{
    *def = fm_default_scene_def();
    snprintf(def->scene_path, sizeof def->scene_path, "%s", name ? name : "");
    const char *file = def->scene_path[0] ? def->scene_path : "scene";
    /* json_locate walks a NUL-terminated text; jansson rejects embedded NULs itself. */
    char *copy = malloc(len + 1);
    if (!copy) return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for the scene text", file);
    memcpy(copy, text, len);
    copy[len] = 0;
    json_error_t jerr;
    fm_status st;
    json_t *root = json_loadb(copy, len, JSON_REJECT_DUPLICATES, &jerr);
    if (!root) {
        st = fm_fail(err, FM_ERR_INPUT, "%s:%d:%d: %s", file, jerr.line, jerr.column, jerr.text);
    } else {
        where w = {def->scene_path, copy, err, {{0}}, {{0}}, 0, 0, "", def, 0, 0};
        st = group < 0 ? read_document(&w, root, set, count, def) : read_group_document(&w, root, set, count, group, def);
        json_decref(root);
    }
    free(copy);
    return st;
}

fm_status fm_scene_parse(const char *text, size_t len, const char *name, fm_scene_def *def, fm_error *err)
{
    return parse_scene(text, len, name, NULL, 0, -1, def, err);
}

/* The file's scene, or its group `group` (>= 0). */
static fm_status load_scene(const char *path, const fm_scene_override *overrides, int count, int group,
                            fm_scene_def *def, fm_error *err)
{
    *def = fm_default_scene_def();
    snprintf(def->scene_path, sizeof def->scene_path, "%s", path);
    size_t len = 0;
    fm_status st = FM_OK;
    char *text = read_text(path, &len, &st, err);
    if (!text) return st;
    st = parse_scene(text, len, path, overrides, count, group, def, err);
    free(text);
    return st;
}

fm_status fm_scene_load_overridden(const char *path, const fm_scene_override *overrides, int count,
                                   fm_scene_def *def, fm_error *err)
{
    return load_scene(path, overrides, count, -1, def, err);
}

/* Group g's merged document read as a scene (fm_scene_load_group). */
static fm_status read_group_document(where *w, json_t *root, const fm_scene_override *set, int count, int g,
                                     fm_scene_def *def)
{
    fm_group_def groups[FM_MAX_GROUPS];
    fm_status st = json_is_object(root) ? fm_overrides_apply(root, set, count, def, w->err) : FM_OK;
    if (st == FM_OK) st = read_groups(w, root, groups, def);
    if (st == FM_OK && (g < 0 || g >= def->group_count))
        return fm_fail(w->err, FM_ERR_USAGE, "%s: no group %d (the scene has %d)", w->file, g, def->group_count);
    if (st != FM_OK) return st;
    json_t *doc = fm_groups_merge(root, groups, g);
    if (!doc) return fm_fail(w->err, FM_ERR_MEMORY, "%s: out of memory for group %d", w->file, g);
    def->group_index = g, def->group = groups[g];
    w->in_group = 1, w->group = g;
    st = read_scene(w, doc, def);
    if (st == FM_OK) st = read_radius_units(w, doc, def);
    if (st == FM_OK) st = check_consistency(w, def);
    if (st == FM_OK) st = check_mode(w, doc, def);
    json_decref(doc);
    return st;
}

fm_status fm_scene_load_group(const char *path, const fm_scene_override *overrides, int count, int g,
                              fm_scene_def *def, fm_error *err)
{
    if (g < 0) return fm_fail(err, FM_ERR_USAGE, "%s: no group %d", path, g);
    return load_scene(path, overrides, count, g, def, err);
}

fm_status fm_scene_parse_group(const char *text, size_t len, const char *name, const fm_scene_override *overrides,
                               int count, int g, fm_scene_def *def, fm_error *err)
{
    if (g < 0) return fm_fail(err, FM_ERR_USAGE, "%s: no group %d", name, g);
    return parse_scene(text, len, name, overrides, count, g, def, err);
}

fm_status fm_scene_load(const char *path, fm_scene_def *def, fm_error *err)
{
    return fm_scene_load_overridden(path, NULL, 0, def, err);
}

/* ---------------------------------------------------------------- canonical bytes (checkpoints) */

static void feed_table(const param *table, size_t count, const void *base, const fm_scene_def *def, fm_bytes_fn add,
                       void *user);

static void feed_list(const param *table, size_t count, const void *items, size_t item_bytes, int32_t n,
                      const fm_scene_def *def, fm_bytes_fn add, void *user)
{
    add(&n, sizeof n, user);
    for (int32_t i = 0; i < n; i++) feed_table(table, count, (const char *)items + (size_t)i * item_bytes, def, add, user);
}

/* One value in a fixed width: enums as int32, strings without their unused tail. */
static void feed_value(const param *p, const char *field, const fm_scene_def *def, fm_bytes_fn add, void *user)
{
    int32_t e;
    switch (p->type) {
    case P_DOUBLE: case P_INT64: case P_UINT64: add(field, 8, user); break;
    case P_INT32: case P_BOOL: add(field, 4, user); break;
    case P_VEC3: add(field, 24, user); break;
    case P_INT3: add(field, 12, user); break;
    case P_MESH: break; /* the file's contents are in the model hash */
    case P_NAME: case P_PATTERN: add(field, strlen(field) + 1, user); break;
    case P_ENUM: e = (int32_t)*(const int *)field, add(&e, sizeof e, user); break;
    case P_RANGE: add(field, 2 * sizeof(double), user); break;
    case P_FUZZY: {
        const fm_fuzzy_def *f = (const fm_fuzzy_def *)field;
        add(&f->count, sizeof f->count, user);
        add(f->d, sizeof f->d[0] * (size_t)f->count, user);
        add(f->w, sizeof f->w[0] * (size_t)f->count, user);
        break;
    }
    case P_CURVE: e = (int32_t)*(const fm_curve *)field, add(&e, sizeof e, user); break;
    case P_SWITCH: e = (int32_t)*(const fm_phase_switch *)field, add(&e, sizeof e, user); break;
    case P_FIELD_KIND: e = (int32_t)*(const fm_field_kind *)field, add(&e, sizeof e, user); break;
    case P_POINTS: {
        const points_ref pts = points_of(p, (fm_scene_def *)def); /* read only */
        add(pts.count, sizeof *pts.count, user);
        add(pts.at, sizeof pts.at[0] * (size_t)*pts.count, user);
        break;
    }
    case P_FIELDS:
        feed_list(FIELD_PARAMS, sizeof FIELD_PARAMS / sizeof FIELD_PARAMS[0], def->fields, sizeof def->fields[0],
                  def->field_count, def, add, user);
        break;
    case P_OBSTACLES:
        feed_list(MESH_PARAMS, sizeof MESH_PARAMS / sizeof MESH_PARAMS[0], def->obstacles, sizeof def->obstacles[0],
                  def->obstacle_count, def, add, user);
        break;
    }
}

static void feed_table(const param *table, size_t count, const void *base, const fm_scene_def *def, fm_bytes_fn add,
                       void *user)
{
    for (size_t i = 0; i < count; i++) {
        add(table[i].key, strlen(table[i].key) + 1, user);
        feed_value(&table[i], (const char *)base + table[i].offset, def, add, user);
    }
}

void fm_scene_def_feed(const fm_scene_def *def, fm_bytes_fn add, void *user)
{
    feed_table(PARAMS, PARAM_COUNT, def, def, add, user);
}

fm_status fm_fuzzy_def_check(const fm_fuzzy_def *def, const char *key, fm_error *err)
{
    if (def->count < 1 || def->count > FM_FUZZY_MAX_POINTS)
        return fm_fail(err, FM_ERR_INPUT, "%s: a weight curve needs 1 to %d points, got %d", key, FM_FUZZY_MAX_POINTS,
                       def->count);
    for (int32_t i = 0; i < def->count; i++) {
        if (!isfinite(def->d[i]) || !isfinite(def->w[i]) || def->d[i] < 0 || def->w[i] < 0)
            return fm_fail(err, FM_ERR_INPUT, "%s[%d]: distance and weight must be finite and >= 0", key, i);
        if (i > 0 && !((float)def->d[i] > (float)def->d[i - 1]))
            return fm_fail(err, FM_ERR_INPUT, "%s[%d]: the distances must increase (%g after %g)", key, i, def->d[i],
                           def->d[i - 1]);
    }
    return FM_OK;
}

/* Prefixes err's message with where the scene sets `key` ("scene.json:3:14: source.mesh: ..."). */
fm_status fm_scene_name_key(const fm_scene_def *def, fm_status st, const char *key, fm_error *err)
{
    if (st != FM_OK && err) {
        char msg[sizeof err->message], where[FM_PATH_MAX + 64];
        snprintf(msg, sizeof msg, "%s", err->message);
        fm_scene_key_location(def, key, where, sizeof where);
        fm_fail(err, st, "%s: %s", where, msg);
    }
    return st;
}
