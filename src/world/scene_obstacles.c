/* The scene's meshes as the modes load them, and its obstacles (obstacles.h): loading, the checks
 * that keep agents out of an obstacle at the start and the end, and the distance grid's size. */
#include "fm_math.h"
#include "obstacles.h"
#include "scene_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Loads, checks and places one mesh. */
fm_status fm_scene_mesh_load(const fm_scene_def *def, const fm_mesh_ref *ref, const char *key, fm_mesh *mesh,
                           fm_error *err)
{
    fm_status st = fm_mesh_load(ref->path, mesh, err);
    if (st == FM_OK) st = fm_mesh_check_closed(mesh, ref->path, err);
    if (st == FM_OK) fm_mesh_place(mesh, ref);
    if (st == FM_OK) st = fm_mesh_check_extent(mesh, ref->path, err);
    return fm_scene_name_key(def, st, key, err);
}

/* Refuses an obstacle that shares volume with the source or target. */
static fm_status refuse_overlap(const fm_scene_def *def, const fm_mesh *obstacle, const char *key, const fm_mesh *shape,
                                const char *shape_name, fm_error *err)
{
    char how[512], where[FM_PATH_MAX + 64];
    int overlap = fm_meshes_overlap(obstacle, key, shape, shape_name, how, sizeof how, err);
    if (overlap <= 0) return overlap < 0 ? (err ? err->status : FM_ERR_INTERNAL) : FM_OK;
    fm_scene_key_location(def, key, where, sizeof where);
    return fm_fail(err, FM_ERR_INPUT, "%s: the obstacle overlaps %s: %s; %s would start or end inside it. Move "
                   "it clear (translate) or make it smaller (scale)", where, shape_name, how,
                   def->mode == FM_MODE_SHAPE_FLOCK ? "agents" : "tets");
}

/* An obstacle may overlap neither the source nor the target: agents (tets or points) would start
 * or finish inside it (FM §5.3 assumes free space). */
static fm_status refuse_overlaps(const fm_scene_def *def, const fm_mesh *obstacle, const char *key,
                                 const fm_mesh *source, const fm_mesh *target, fm_error *err)
{
    fm_status st = refuse_overlap(def, obstacle, key, source, "the source", err);
    return st == FM_OK ? refuse_overlap(def, obstacle, key, target, "the target", err) : st;
}

fm_status fm_obstacle_mesh_load(const fm_scene_def *def, int i, const fm_mesh *source, const fm_mesh *target,
                                fm_mesh *mesh, fm_error *err)
{
    char key[48];
    snprintf(key, sizeof key, "obstacles.meshes[%d]", i);
    fm_status st = fm_scene_mesh_load(def, &def->obstacles[i], key, mesh, err);
    if (st == FM_OK && source && target) st = refuse_overlaps(def, mesh, key, source, target, err);
    return st;
}

/* The distance grid of placed obstacle meshes, with a band wide enough for `reach` (FM eq 7's k_a
 * plus the largest agent radius); the voxel is obstacles.voxel or 1/160 of the extent. */
fm_obstacles *fm_obstacles_grid(const fm_scene_def *def, const fm_mesh *meshes, double reach, fm_error *err)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, extent = 0;
    for (int i = 0; i < def->obstacle_count; i++) fm_grow_bounds(lo, hi, meshes[i].v, meshes[i].nv);
    for (int k = 0; k < 3; k++) extent = fmax(extent, hi[k] - lo[k] + 2 * reach);
    double voxel = def->obstacle_voxel > 0 ? def->obstacle_voxel : extent / 160;
    fm_obstacles *o = fm_obstacles_build(meshes, def->obstacle_count, voxel, reach + 2 * voxel, err);
    if (!o) fm_scene_name_key(def, err ? err->status : FM_ERR_INPUT, "obstacles.voxel", err);
    return o;
}

/* Whether the keep's grid was made from these placed meshes, reach and voxel. */
static int kept_grid_fits(const fm_kept_grid *k, const fm_scene_def *def, const fm_mesh *meshes, double reach)
{
    if (!k->has || k->meshes != def->obstacle_count || k->reach != reach || k->voxel != def->obstacle_voxel) return 0;
    for (int i = 0; i < k->meshes; i++)
        if (!fm_mesh_same(&k->mesh[i], &meshes[i])) return 0;
    return 1;
}

void fm_kept_grid_clear(fm_kept_grid *keep)
{
    if (!keep) return;
    fm_obstacles_destroy(keep->grid);
    for (int i = 0; i < keep->meshes; i++) fm_mesh_free(&keep->mesh[i]);
    memset(keep, 0, sizeof *keep);
}

/* The keep holds grid, with what it was made from. */
static fm_status keep_grid(fm_kept_grid *k, fm_obstacles *grid, const fm_scene_def *def, const fm_mesh *meshes,
                           double reach, fm_error *err)
{
    fm_kept_grid_clear(k);
    for (; k->meshes < def->obstacle_count; k->meshes++) {
        fm_status st = fm_mesh_copy(&meshes[k->meshes], &k->mesh[k->meshes], err);
        if (st != FM_OK) return fm_kept_grid_clear(k), st;
    }
    k->reach = reach, k->voxel = def->obstacle_voxel, k->grid = fm_obstacles_share(grid), k->has = 1;
    return FM_OK;
}

fm_obstacles *fm_obstacles_grid_keeping(const fm_scene_def *def, const fm_mesh *meshes, double reach, fm_kept_grid *keep,
                                        int *reused, fm_error *err)
{
    const int fits = keep && kept_grid_fits(keep, def, meshes, reach);
    if (reused) *reused = fits;
    if (fits) return fm_obstacles_share(keep->grid);
    fm_obstacles *o = fm_obstacles_grid(def, meshes, reach, err);
    if (o && keep && keep_grid(keep, o, def, meshes, reach, err) != FM_OK) fm_obstacles_destroy(o), o = NULL;
    return o;
}

fm_obstacles *fm_obstacles_from_scene_keeping(const fm_scene_def *def, double reach, const fm_mesh *source,
                                              const fm_mesh *target, fm_kept_grid *keep, int *reused, fm_error *err)
{
    if (reused) *reused = 0;
    fm_mesh *meshes = calloc((size_t)def->obstacle_count, sizeof *meshes);
    if (!meshes) return fm_fail(err, FM_ERR_MEMORY, "out of memory for obstacles"), NULL;
    fm_status st = FM_OK;
    for (int i = 0; i < def->obstacle_count && st == FM_OK; i++) {
        st = fm_obstacle_mesh_load(def, i, source, target, &meshes[i], err);
    }
    fm_obstacles *out = st == FM_OK ? fm_obstacles_grid_keeping(def, meshes, reach, keep, reused, err) : NULL;
    for (int i = 0; i < def->obstacle_count; i++) fm_mesh_free(&meshes[i]);
    free(meshes);
    return out;
}

fm_obstacles *fm_obstacles_from_scene(const fm_scene_def *def, double reach, const fm_mesh *source, const fm_mesh *target,
                                      fm_error *err)
{
    return fm_obstacles_from_scene_keeping(def, reach, source, target, NULL, NULL, err);
}
