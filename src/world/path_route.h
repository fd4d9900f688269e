/* path_route.c: a path rerouted round the obstacles, and the navigation function round them
 * (issue 38). The tetra morph routes its key-point path (morph_path.c) and builds the navigation
 * function for its detours; the shape flock routes its B-spline R (flock_model.c). */
#ifndef FM_PATH_ROUTE_H
#define FM_PATH_ROUTE_H

#include "fm_internal.h"
#include "obstacles.h"

#include "flockmorph/scene.h"

#include <stdint.h>

/* What the route and the navigation function read: the obstacles, the inflation radius (the tetra
 * morph: the largest tet radius; the shape flock: k_a and a margin) and the clearance preferred
 * beyond it (k_a), the box of the source and target; routed and unroutable count the stretches of
 * the path that were rerouted and the ones with no way round (left as the user's). */
typedef struct fm_path_route {
    const fm_obstacles *obstacles;
    double r_infl, r_soft;
    double lo[3], hi[3];
    double obstacle_lo[3], obstacle_hi[3];
    int meshes;                       /* each obstacle mesh's box: a stretch is routed round the whole */
    double mesh_lo[FM_MAX_OBSTACLES][3], mesh_hi[FM_MAX_OBSTACLES][3];
    int routed, unroutable;
} fm_path_route;
/* The path with every stretch that passes closer than r_infl to an obstacle replaced by a shortest
 * way round (A* on a coarse grid, pulled taut, corner-cut); the other points are kept as they are.
 * pts (n points, malloc'd) is replaced only when a stretch was rerouted. */
fm_status fm_path_route_dense(fm_path_route *r, double **pts, int64_t *n, fm_error *err);
/* The navigation function over the key points q (3 doubles each): u, the shortest cost to C_T
 * (weighted up near obstacles, halved along the clear stretches of the key-point polyline); g, the
 * cost onto those stretches; n nodes from origin, h apart (fm_alloc'd; fm_free). */
typedef struct fm_nav {
    float *u, *g;
    int32_t n[3];
    float origin[3];
    float h;
} fm_nav;
fm_status fm_nav_build(const fm_path_route *r, const double *q, int32_t keys, fm_nav *nav, fm_error *err);

/* What a path routed round obstacles is made from (the tetra morph's fm_path_build_routed; the
 * shape flock's R, flock_model.c): the centroids (the flock's O1 and O2), the route's inputs (its
 * obstacles pointer and counts cleared; the grid is the keep's when this is compared) and the
 * scene's path keys; built zeroed (fm_route_key_of), so that it compares byte for byte. */
typedef struct fm_route_key {
    double cs[3], ct[3];
    fm_path_route route;
    int32_t curve, key_points, point_count, pad;
    double points[FM_MAX_PATH_POINTS][3];
} fm_route_key;

void fm_route_key_of(const fm_scene_def *def, const double cs[3], const double ct[3], const fm_path_route *r,
                     fm_route_key *key);

#endif
