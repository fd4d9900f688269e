/* Exact closest points on triangle meshes: an Embree 3 BVH queried with rtcPointQuery.
 *
 * Shared by the obstacles (FM §5.3: the exact signed distance d_t near a surface) and the SCF
 * surface sampling (§3, eq 5: each mosaic point projected back onto the mesh). Distances are
 * computed in double from the caller's double vertices; Embree's BVH (float) only culls, with its
 * query radius padded beyond the float rounding of the point and the vertices, so a result is the
 * exact minimum over all triangles, ties broken by the lowest triangle index (it does not depend on
 * the traversal). Every query is thread-safe: callable from OpenMP threads concurrently. */
#ifndef FM_CLOSEST_H
#define FM_CLOSEST_H

#include "geom.h"

#include <stdint.h>

typedef struct fm_closest fm_closest;

/* Checks one mesh: not empty, not beyond int32 indices, finite vertices, indices in range and no
   triangle repeating a vertex. Messages name the mesh as "<what> <index>" (e.g. "obstacle 1"). */
fm_status fm_closest_check_mesh(const fm_mesh *mesh, const char *what, int index, fm_error *err);

/* Builds the BVH over the union of count meshes (each checked with fm_closest_check_mesh, named
   by `what` and its index). With want_sign, every mesh must also be closed (every edge shared by
   two triangles running opposite ways: fm_mesh_pair_edges), and its angle-weighted pseudo-normals
   are built for fm_closest_signed; without it any valid triangle soup will do. Triangles are
   numbered in mesh order: mesh m's triangle t is fm_closest_first_triangle(c, m) + t. NULL on
   failure, with err set. */
fm_closest *fm_closest_build(const fm_mesh *meshes, int count, const char *what, int want_sign, fm_error *err);
void fm_closest_destroy(fm_closest *c); /* NULL is fine */

/* The nearest point of any mesh to p: returns the distance (NaN for a non-finite p or one beyond
   1e30), writes the point to closest and its triangle to tri (either may be NULL; closest NaN and
   tri -1 when the distance is NaN). hint: a guess at an upper bound of the distance (INFINITY if
   none); the search starts with that radius and is repeated without one if nothing within it turns
   up, so the result does not depend on it. */
double fm_closest_point(const fm_closest *c, const double p[3], double hint, double closest[3], int64_t *tri);

/* The signed distance to the union of the meshes (negative inside; needs want_sign). The sign
   comes from the angle-weighted pseudo-normal of the closest feature (face, edge or vertex;
   Baerentzen & Aanaes, "Signed distance computation using the angle weighted pseudonormal", IEEE
   TVCG 2005): for a closed mesh (p - c) . N < 0 exactly when p is inside. Inside overlapping meshes
   the deepest containing one wins. closest and normal (may be NULL) as fm_obstacles_closest
   documents; hint as for fm_closest_point. */
double fm_closest_signed(const fm_closest *c, const double p[3], double hint, double closest[3], double normal[3]);

/* The distance from p to the nearest triangle when it is nearer than radius, else +inf: one
   Embree query within that sphere, which finds nothing quickly when no triangle is that near (NaN
   for a point the queries cannot take). Unsigned: for a point outside every mesh it is the union's
   distance. */
double fm_closest_within(const fm_closest *c, const double p[3], double radius);

/* The unit face normal of triangle t (outward with want_sign; 0 for a zero-area triangle). */
const double *fm_closest_face_normal(const fm_closest *c, int64_t t);
int64_t fm_closest_first_triangle(const fm_closest *c, int mesh);

/* All meshes as one triangle soup (indices into v), valid until fm_closest_destroy. */
typedef struct fm_closest_soup {
    const double *v;
    int64_t nv;
    const int32_t *tri;
    int64_t nt;
} fm_closest_soup;
fm_closest_soup fm_closest_get_soup(const fm_closest *c);

#endif
