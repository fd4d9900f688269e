/* The scene wing's interface to the engine above it, besides the public fm_scene_* calls: the
 * defaults that other wings share, the canonical bytes of a definition (checkpoints hash them),
 * where a key sits in the scene file (for errors found after loading), and the checks of values
 * that a mode later compiles (the fuzzy curves). */
#ifndef FM_SCENE_INTERNAL_H
#define FM_SCENE_INTERNAL_H

#include "fm_internal.h"

/* The samplers' defaults (fm_default_scene_def; sample.h): a field of fm_sample_opts left 0 takes its default (except iterations: 0 keeps the mosaic's random
 * start), so a zeroed struct is a valid request for random sampling with seed 0. */
#define FM_SAMPLE_MOSAIC_ITERATIONS 30 /* the paper gives no count: see docs/sampling.md */
#define FM_SAMPLE_MOSAIC_K 2.0         /* eq 1: "k is 2.0 in our current implementation" */
#define FM_SAMPLE_MOSAIC_W 0.9         /* eq 3: "we choose w as 0.9" */
#define FM_SAMPLE_MOSAIC_STEP 0.25     /* eq 5's delta t, in units of sqrt(M/N) (the paper gives none) */
#define FM_SAMPLE_LAMBDA 1.0           /* the paper gives none; per voxel edge, see below */
#define FM_SAMPLE_OVERSAMPLE 2.0       /* stratified candidates per sample (the paper gives none) */

/* Feeds `add` every value a scene file can set, each after its key, in the parameter
 * table's order: a canonical byte stream of the definition (no padding, no bytes past a string's
 * end), which checkpoints hash. Mesh file names are left out (where a file lies does not change
 * the run; the model hash covers the meshes), and so is scene_path. */
typedef void (*fm_bytes_fn)(const void *bytes, size_t n, void *user);
void fm_scene_def_feed(const fm_scene_def *def, fm_bytes_fn add, void *user);

/* "FILE:LINE:COL: key" for a key of the loaded scene (a dotted path, list elements as
 * "obstacles.meshes[1]"), found by reading the scene file again; "FILE: key" when it cannot be
 * located, "key" for a definition built in code. For errors found after loading (model build). */
void fm_scene_key_location(const fm_scene_def *def, const char *key, char *out, size_t size);
/* Whether key names a scene parameter ("source.mesh", "obstacles.meshes[2].scale"). */
int fm_scene_is_key(const char *key);

/* On failure (st != FM_OK) prefixes err's message with where the scene sets `key`
 * ("scene.json:3:14: source.mesh: ..."); returns st. */
fm_status fm_scene_name_key(const fm_scene_def *def, fm_status st, const char *key, fm_error *err);

/* The shape flock's target moves: it deforms or travels along a route (target.path.points). A moving
 * target runs the tracking strategy's curves and is evaluated every step. */
static inline int fm_flock_target_moves(const fm_flock_def *f)
{
    return f->deform != FM_DEFORM_NONE || f->travel_point_count > 0;
}

/* SCF Figure 6: the tracking strategy runs for a moving target, or where the scene asks for it. */
static inline int fm_flock_tracking_strategy(const fm_flock_def *f)
{
    return f->fuzzy_strategy == FM_FUZZY_AUTO ? fm_flock_target_moves(f) : f->fuzzy_strategy == FM_FUZZY_TRACKING;
}

/* Checks a fuzzy weight curve (1 .. FM_FUZZY_MAX_POINTS points, finite, d strictly increasing in
 * float, w >= 0); errors name `key` ("shape_flock.fuzzy.homing"). */
fm_status fm_fuzzy_def_check(const fm_fuzzy_def *def, const char *key, fm_error *err);

#endif
