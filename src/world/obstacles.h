/* Obstacles (FM §5.3): the potential d_t as a dense signed-distance grid built with OpenVDB, and
 * exact closest-point queries with an Embree BVH.
 *
 * Several obstacles form one solid, their union: the signed distance is the minimum over the
 * obstacles of each one's signed distance (negative inside). Outside every obstacle that is the
 * exact distance to the nearest obstacle triangle; inside overlapping obstacles the grid (OpenVDB
 * removes the buried surfaces) and fm_obstacles_closest (the deepest containing obstacle) may
 * differ in magnitude, never in sign. */
#ifndef FM_OBSTACLES_H
#define FM_OBSTACLES_H

#include "kernel_sdf.h"
#include "geom.h"

#include <stddef.h>
#include <stdint.h>

/* The dense grid refused beyond this many voxels (2^27: 512 MiB of floats). */
#define FM_OBSTACLE_MAX_VOXELS ((int64_t)1 << 27)

typedef struct fm_obstacles fm_obstacles;

/* meshes: count closed meshes in world space (every edge shared by exactly two triangles running
   opposite ways; either orientation). Builds
   (a) a signed distance grid (inside negative) with OpenVDB (meshToVolume, a narrow band of
       ceil(band / voxel) + 1 voxels on each side), as one dense float array over the band's
       bounding box plus a one-voxel border, voxel size `voxel` (> 0), far = band, values clamped
       to [-far, far]; every node OpenVDB puts inside the band is then replaced by the exact signed
       distance from (b), so the nodes are exact to float precision and only interpolation errs;
       refuses with FM_ERR_INPUT if the dense grid would exceed FM_OBSTACLE_MAX_VOXELS, naming the
       voxel size and suggesting a larger one;
   (b) an Embree BVH over all triangles for exact closest-point queries.
   NULL on failure, with err set. */
fm_obstacles *fm_obstacles_build(const fm_mesh *meshes, int count, double voxel, double band, fm_error *err);
/* What the grid's messages call it and its surfaces: {"obstacle", "the obstacles"} for
   fm_obstacles_build, {"target", "the target"} for the distance phase switch's grid of the target
   (a scene without obstacles must not read of obstacles). */
typedef struct fm_sdf_names {
    const char *grid, *surfaces;
} fm_sdf_names;
fm_obstacles *fm_obstacles_build_named(const fm_mesh *meshes, int count, double voxel, double band,
                                       const fm_sdf_names *name, fm_error *err);
/* Another owner of o (not thread-safe: one thread shares and destroys): each owner calls
   fm_obstacles_destroy, and the last one frees it. The studio's keep shares a model's grid with the
   next model built from the same meshes (morph_model.c). */
fm_obstacles *fm_obstacles_share(fm_obstacles *o);
void fm_obstacles_destroy(fm_obstacles *o); /* NULL is fine; frees o once its last owner destroys it */
/* The grid; valid until fm_obstacles_destroy. */
fm_sdf_view fm_obstacles_sdf(const fm_obstacles *o);

/* Exact signed distance from p to the obstacles (negative inside), with rtcPointQuery and the
   closest point computed in double. The sign comes from the angle-weighted pseudo-normal of the
   closest feature (face, edge or vertex; Baerentzen & Aanaes 2005), which is exact for closed
   meshes. closest (may be NULL) receives the closest surface point; normal (may be NULL) the unit
   direction of increasing signed distance: sign * (p - closest) / |p - closest|, or the
   pseudo-normal of the closest feature when p is on the surface. A non-finite p (or one beyond
   1e30) gives NaN. The grid's value at p, when inside the band, seeds the search radius; the result
   does not depend on it. Thread-safe: callable from OpenMP threads concurrently. */
double fm_obstacles_closest(const fm_obstacles *o, const double p[3], double closest[3], double normal[3]);

/* The exact distance from p, a point outside every obstacle, to the obstacles when it is less than
   radius, else +inf (fm_closest_within): the cheap query for "is p nearer than the nearest found
   so far". */
double fm_obstacles_distance_within(const fm_obstacles *o, const double p[3], double radius);

/* scene_obstacles.c: the scene's meshes and obstacles as both modes load them. */

/* Loads, checks closed and places one mesh of the scene; errors name where the scene sets `key`. */
fm_status fm_scene_mesh_load(const fm_scene_def *def, const fm_mesh_ref *ref, const char *key, fm_mesh *mesh,
                             fm_error *err);
/* Obstacle i (obstacles.meshes[i]) loaded, checked and placed; given the placed source and target
   meshes (both or neither), one that overlaps either is refused: agents would start or finish
   inside it. */
fm_status fm_obstacle_mesh_load(const fm_scene_def *def, int i, const fm_mesh *source, const fm_mesh *target,
                                fm_mesh *mesh, fm_error *err);
/* The distance grid of the scene's placed obstacle meshes with a band wide enough for `reach`
   (FM eq 7's k_a plus the largest agent radius), so the look-ahead of eq 8 always reads real
   distances; the voxel is obstacles.voxel or 1/160 of the extent plus the reach. */
fm_obstacles *fm_obstacles_grid(const fm_scene_def *def, const fm_mesh *meshes, double reach, fm_error *err);
/* Both: every obstacle of the scene, then its grid. NULL on failure. */
fm_obstacles *fm_obstacles_from_scene(const fm_scene_def *def, double reach, const fm_mesh *source, const fm_mesh *target,
                                      fm_error *err);

/* A distance grid kept for the next build of an edited scene (flockmorph studio: docs/studio.md, "An
   edit and the model"), with the placed meshes, reach and obstacles.voxel it was made from. Zeroed at
   first; fm_kept_grid_clear frees it. */
typedef struct fm_kept_grid {
    int has, meshes;
    fm_mesh mesh[FM_MAX_OBSTACLES]; /* placed */
    double reach, voxel;
    fm_obstacles *grid;             /* shared with the models built from it (fm_obstacles_share) */
} fm_kept_grid;
/* fm_obstacles_grid; or, where keep (NULL: none) holds a grid made from the same placed meshes (byte
   for byte), reach and voxel, that grid, shared, with *reused set (reused may be NULL). A grid made
   here takes the keep's place. The grid is a function of those inputs alone: the same bytes either way. */
fm_obstacles *fm_obstacles_grid_keeping(const fm_scene_def *def, const fm_mesh *meshes, double reach, fm_kept_grid *keep,
                                        int *reused, fm_error *err);
/* fm_obstacles_from_scene, its grid kept the same way. */
fm_obstacles *fm_obstacles_from_scene_keeping(const fm_scene_def *def, double reach, const fm_mesh *source,
                                              const fm_mesh *target, fm_kept_grid *keep, int *reused, fm_error *err);
void fm_kept_grid_clear(fm_kept_grid *keep);

/* Internal: obstacles_vdb.cpp, OpenVDB behind extern "C" (never throws). Builds the clamped dense
   grid of the closed triangle soup (v: 3 doubles per vertex; tri: 3 indices per triangle) and
   stores it in *d (allocated with fm_alloc; the caller frees it with fm_free), n and origin.
   Refuses with FM_ERR_INPUT if it would exceed max_voxels. */
#ifdef __cplusplus
extern "C" {
#endif
fm_status fm_obstacles_vdb_grid(const double *v, int64_t nv, const int32_t *tri, int64_t nt,
                                double voxel, double band, int64_t max_voxels, const fm_sdf_names *name,
                                float **d, int32_t n[3], float origin[3], fm_error *err);
#ifdef __cplusplus
}
#endif

#endif
