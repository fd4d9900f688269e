/* Small dense 3x3 linear algebra, polar decomposition, rotations as quaternions and axis-angle,
 * and the exact minimal enclosing sphere of a point set. Double precision throughout; no global
 * state; only fm_min_sphere allocates (one index array, freed before it returns). */
#ifndef FM_MATH_H
#define FM_MATH_H

#include <stddef.h>
#include <stdint.h>

typedef struct fm_mat3 { double m[3][3]; } fm_mat3;   /* row-major: m[row][col] */

/* The identity matrix. */
fm_mat3 fm_mat3_identity(void);
/* The product a*b. */
fm_mat3 fm_mat3_mul(fm_mat3 a, fm_mat3 b);
/* The transpose of a. */
fm_mat3 fm_mat3_transpose(fm_mat3 a);
/* Every entry of a times s. */
fm_mat3 fm_mat3_scale(fm_mat3 a, double s);
/* The entrywise sum a+b. */
fm_mat3 fm_mat3_add(fm_mat3 a, fm_mat3 b);
/* The determinant of a. */
double  fm_mat3_det(fm_mat3 a);
/* *out = a^-1 (from the adjugate). Returns 0, or -1 if an entry of a is not finite, det a is
 * exactly 0 or the inverse overflows; *out is untouched then. No conditioning test is made:
 * callers that care should look at the condition number themselves. */
int     fm_mat3_inverse(fm_mat3 a, fm_mat3 *out);          /* 0 ok, -1 singular or not finite */
/* out = a*v; out may alias v. */
void    fm_mat3_apply(fm_mat3 a, const double v[3], double out[3]);  /* out = a*v */

/* Polar decomposition A = R S (Shoemake & Duff; Higham's scaled Newton iteration
   R <- (g R + R^-T / g)/2 until converged, then S = R^T A symmetrised).
   R is a proper rotation (det +1), S symmetric positive definite. Requires det A > 0 and finite
   entries; returns 0 on success, -1 otherwise (R, S untouched). Must stay accurate for
   near-degenerate A (condition numbers up to ~1e8): test it.
   Either of r and s may be NULL when that factor is not wanted. */
int fm_polar_decompose(fm_mat3 a, fm_mat3 *r, fm_mat3 *s);

/* Unit quaternion q = (w, x, y, z) with w >= 0 from a rotation matrix (Shepperd's method, robust
   for all angles incl. 180 degrees). The result is normalised, so r only needs to be orthonormal
   to rounding. At exactly 180 degrees (w = 0) q and -q are both valid; either may be returned. */
void fm_quat_from_rotation(fm_mat3 r, double q[4]);

/* Axis (unit) and angle theta in [0, pi] of a unit quaternion; when theta is ~0 the axis is (1,0,0).
   q need not be normalised and may have w < 0 (q and -q give the same rotation). */
void fm_quat_to_axis_angle(const double q[4], double axis[3], double *theta);

/* Rotation matrix R(n, theta) (Rodrigues) for a unit axis: a right-handed rotation by theta
   about n, acting on column vectors (R*v). */
fm_mat3 fm_rotation_axis_angle(const double axis[3], double theta);

/* Exact minimal enclosing sphere of n points (xyz packed, 3 doubles per point), Welzl's algorithm
   written iteratively (move-to-front nested loops for 1, 2, 3 boundary points; no recursion on n:
   n can be 10^6). Points are visited in a pseudo-random order from `seed` (use a splitmix64
   shuffle on a malloc'd index array; free it). Handles duplicates, collinear and coplanar subsets
   (degenerate 3- and 4-point circumspheres must not produce NaN/huge spheres: fall back to the
   smallest sphere of a subset that contains the others). n == 0 gives centre 0, radius 0.
   Returns 0, or -1 if the index array cannot be allocated.
   Points must be finite. The returned radius is the largest distance from the returned centre
   to any point, so every point is inside to rounding. */
int fm_min_sphere(const double *xyz, size_t n, uint64_t seed, double center[3], double *radius);

/* Radius-edge ratio of a tetrahedron (4 vertices, 12 doubles): circumradius over shortest edge,
   the measure TetGen's -q bounds. sqrt(6)/4 ~ 0.612 for a regular tet, the smallest possible;
   +inf for a flat or collapsed one. */
double fm_tet_radius_edge(const double *tet);

/* Grows the box [lo, hi] to hold `count` points (3 doubles each). */
void fm_grow_bounds(double lo[3], double hi[3], const double *pts, int64_t count);

#endif
