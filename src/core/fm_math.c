/* 3x3 matrices, polar decomposition, rotations, and the minimal enclosing sphere.
 * See fm_math.h for the contracts. */
#include "fm_math.h"
#include "fm_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ================================================================ vectors */

static double fm_dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void fm_cross3(const double a[3], const double b[3], double out[3])
{
    double t[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                   a[0] * b[1] - a[1] * b[0]};
    memcpy(out, t, sizeof t);
}

static void fm_sub3(const double a[3], const double b[3], double out[3])
{
    for (int i = 0; i < 3; ++i) out[i] = a[i] - b[i];
}

static double fm_dist2(const double a[3], const double b[3])
{
    double d[3];
    fm_sub3(a, b, d);
    return fm_dot3(d, d);
}

/* |v| without overflow or underflow in the squares (tiny quaternion parts matter near 0). */
static double fm_norm3(const double v[3])
{
    double big = fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2])));
    if (big == 0.0 || !isfinite(big)) return big;
    double u[3] = {v[0] / big, v[1] / big, v[2] / big};
    return big * sqrt(fm_dot3(u, u));
}

/* ================================================================ 3x3 matrices */

fm_mat3 fm_mat3_identity(void)
{
    fm_mat3 r = {{{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}}};
    return r;
}

fm_mat3 fm_mat3_mul(fm_mat3 a, fm_mat3 b)
{
    fm_mat3 r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
    return r;
}

fm_mat3 fm_mat3_transpose(fm_mat3 a)
{
    fm_mat3 r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[j][i];
    return r;
}

fm_mat3 fm_mat3_scale(fm_mat3 a, double s)
{
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a.m[i][j] *= s;
    return a;
}

fm_mat3 fm_mat3_add(fm_mat3 a, fm_mat3 b)
{
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a.m[i][j] += b.m[i][j];
    return a;
}

/* a*d - b*c to about one ulp of the result, however much the products cancel (Kahan's
 * algorithm: the fused multiply-add recovers the rounding error of b*c exactly). */
static double fm_det2(double a, double b, double c, double d)
{
    double w = b * c;
    double e = fma(-b, c, w); /* w - b*c, exactly */
    double f = fma(a, d, -w);
    return f + e;
}

/* a x b with every component accurate to about one ulp (see fm_det2). */
static void fm_cross3_accurate(const double a[3], const double b[3], double out[3])
{
    double t[3] = {fm_det2(a[1], a[2], b[1], b[2]), fm_det2(a[2], a[0], b[2], b[0]),
                   fm_det2(a[0], a[1], b[0], b[1])};
    memcpy(out, t, sizeof t);
}

/* Row i of the cofactor matrix is the cross product of the other two rows (cyclically), so
 * a * cof(a)^T = det(a) I and a^-T = cof(a) / det(a). The minors are computed to full relative
 * accuracy: with plain products, the minors of a nearly rank-1 matrix lose up to
 * eps * |a|^2 / minor, which made the polar decomposition of matrices with two small singular
 * values (condition 1e8) miss A by ~1e-12 instead of ~1e-16. */
static fm_mat3 fm_mat3_cofactor(fm_mat3 a)
{
    fm_mat3 c;
    fm_cross3_accurate(a.m[1], a.m[2], c.m[0]);
    fm_cross3_accurate(a.m[2], a.m[0], c.m[1]);
    fm_cross3_accurate(a.m[0], a.m[1], c.m[2]);
    return c;
}

double fm_mat3_det(fm_mat3 a)
{
    double c[3];
    fm_cross3(a.m[1], a.m[2], c);
    return fm_dot3(a.m[0], c);
}

static int fm_mat3_is_finite(fm_mat3 a)
{
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (!isfinite(a.m[i][j])) return 0;
    return 1;
}

/* a^-T; -1 if det is 0 or the result is not finite. Dividing (rather than multiplying by
 * 1/det) keeps a subnormal det from overflowing the reciprocal. */
static int fm_mat3_inverse_transpose(fm_mat3 a, fm_mat3 *out)
{
    fm_mat3 c = fm_mat3_cofactor(a);
    double det = fm_dot3(a.m[0], c.m[0]);
    if (det == 0.0 || !isfinite(det)) return -1;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) c.m[i][j] /= det;
    if (!fm_mat3_is_finite(c)) return -1;
    *out = c;
    return 0;
}

int fm_mat3_inverse(fm_mat3 a, fm_mat3 *out)
{
    fm_mat3 it;
    if (!fm_mat3_is_finite(a) || fm_mat3_inverse_transpose(a, &it) != 0) return -1;
    *out = fm_mat3_transpose(it);
    return 0;
}

void fm_mat3_apply(fm_mat3 a, const double v[3], double out[3])
{
    double t[3] = {fm_dot3(a.m[0], v), fm_dot3(a.m[1], v), fm_dot3(a.m[2], v)};
    memcpy(out, t, sizeof t);
}

static double fm_mat3_frobenius(fm_mat3 a)
{
    return sqrt(fm_dot3(a.m[0], a.m[0]) + fm_dot3(a.m[1], a.m[1]) + fm_dot3(a.m[2], a.m[2]));
}

static double fm_mat3_max_abs(fm_mat3 a)
{
    double big = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) big = fmax(big, fabs(a.m[i][j]));
    return big;
}

/* ================================================================ polar decomposition */

/* Newton converges in ~10 steps for condition numbers up to 1e16; more means trouble. */
#define FM_POLAR_MAX_ITER 100
/* Scaling only pays while X is far from orthogonal; near convergence the scale factor is 1 up
 * to rounding and would just perturb the quadratic convergence (Higham, Functions of Matrices
 * 8.6), so it is switched off once a step changes X by less than this (relative). */
#define FM_POLAR_UNSCALE 1e-2
/* Convergence is quadratic: a step that moved X by d (relative) leaves an error of about d^2,
 * so d <= 1e-9 means the new X is orthogonal to well below rounding. */
#define FM_POLAR_DONE 1e-9

/* One Newton step X <- (g X + X^-T / g) / 2 with Higham's Frobenius-norm scale
 * g = sqrt(|X^-1| / |X|) (or g = 1); *change = |X_new - X| / |X_new|. */
static int fm_polar_step(fm_mat3 *x, int scaled, double *change)
{
    fm_mat3 xit;
    if (fm_mat3_inverse_transpose(*x, &xit) != 0) return -1;
    double g = scaled ? sqrt(fm_mat3_frobenius(xit) / fm_mat3_frobenius(*x)) : 1.0;
    fm_mat3 next = fm_mat3_add(fm_mat3_scale(*x, 0.5 * g), fm_mat3_scale(xit, 0.5 / g));
    fm_mat3 diff = fm_mat3_add(next, fm_mat3_scale(*x, -1.0));
    *change = fm_mat3_frobenius(diff) / fm_mat3_frobenius(next);
    *x = next;
    return fm_mat3_is_finite(next) && isfinite(*change) ? 0 : -1;
}

/* a scaled by 2^-e entrywise: exact, and safe even when 2^-e itself would overflow. */
static fm_mat3 fm_mat3_ldexp(fm_mat3 a, int e)
{
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a.m[i][j] = ldexp(a.m[i][j], e);
    return a;
}

/* The Newton iterate converged to the rotation of a; *rot gets it. -1 if it did not converge. */
static int fm_polar_rotation(fm_mat3 a, fm_mat3 *rot)
{
    /* R does not change when A is scaled by a positive factor; bringing the largest entry to
     * [0.5, 1) by a power of two is exact and keeps det A and A^-1 clear of over/underflow. */
    int e;
    frexp(fm_mat3_max_abs(a), &e);
    fm_mat3 x = fm_mat3_ldexp(a, -e);
    if (!(fm_mat3_det(x) > 0.0)) return -1;
    int scaled = 1;
    for (int it = 0; it < FM_POLAR_MAX_ITER; ++it) {
        double change;
        if (fm_polar_step(&x, scaled, &change) != 0) return -1;
        if (change <= FM_POLAR_DONE) {
            *rot = x;
            return 0;
        }
        if (change < FM_POLAR_UNSCALE) scaled = 0;
    }
    return -1;
}

int fm_polar_decompose(fm_mat3 a, fm_mat3 *r, fm_mat3 *s)
{
    fm_mat3 rot;
    if (!fm_mat3_is_finite(a) || fm_polar_rotation(a, &rot) != 0) return -1;
    if (s) {
        /* R^T A is symmetric only up to rounding; averaging with its transpose makes it exact
         * and moves it by no more than that rounding. */
        fm_mat3 p = fm_mat3_mul(fm_mat3_transpose(rot), a);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) s->m[i][j] = 0.5 * (p.m[i][j] + p.m[j][i]);
    }
    if (r) *r = rot;
    return 0;
}

/* ================================================================ rotations */

void fm_quat_from_rotation(fm_mat3 r, double q[4])
{
    double(*m)[3] = r.m; /* r is our copy */
    double t = m[0][0] + m[1][1] + m[2][2];
    /* Shepperd: 4w^2 = 1 + t and 4x^2 = 1 + m00 - m11 - m22 (etc.). Take the square root of
     * the largest of the four, which is >= 1/4, and get the others from off-diagonal sums and
     * differences divided by it, so nothing comes from cancellation near 0 or 180 degrees. */
    if (t >= m[0][0] && t >= m[1][1] && t >= m[2][2]) {
        double f = 2.0 * sqrt(1.0 + t); /* 4w */
        q[0] = 0.25 * f;
        q[1] = (m[2][1] - m[1][2]) / f;
        q[2] = (m[0][2] - m[2][0]) / f;
        q[3] = (m[1][0] - m[0][1]) / f;
    } else if (m[0][0] >= m[1][1] && m[0][0] >= m[2][2]) {
        double f = 2.0 * sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]); /* 4x */
        q[0] = (m[2][1] - m[1][2]) / f;
        q[1] = 0.25 * f;
        q[2] = (m[0][1] + m[1][0]) / f;
        q[3] = (m[0][2] + m[2][0]) / f;
    } else if (m[1][1] >= m[2][2]) {
        double f = 2.0 * sqrt(1.0 - m[0][0] + m[1][1] - m[2][2]); /* 4y */
        q[0] = (m[0][2] - m[2][0]) / f;
        q[1] = (m[0][1] + m[1][0]) / f;
        q[2] = 0.25 * f;
        q[3] = (m[1][2] + m[2][1]) / f;
    } else {
        double f = 2.0 * sqrt(1.0 - m[0][0] - m[1][1] + m[2][2]); /* 4z */
        q[0] = (m[1][0] - m[0][1]) / f;
        q[1] = (m[0][2] + m[2][0]) / f;
        q[2] = (m[1][2] + m[2][1]) / f;
        q[3] = 0.25 * f;
    }
    /* Normalise away r's own rounding; q and -q are the same rotation, pick w >= 0. */
    double norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double k = q[0] < 0.0 ? -1.0 / norm : 1.0 / norm;
    for (int i = 0; i < 4; ++i) q[i] *= k;
}

void fm_quat_to_axis_angle(const double q[4], double axis[3], double *theta)
{
    /* q and -q are the same rotation: using |w| keeps theta in [0, pi]. */
    double sign = q[0] < 0.0 ? -1.0 : 1.0;
    double v[3] = {sign * q[1], sign * q[2], sign * q[3]};
    double s = fm_norm3(v); /* sin(theta/2), up to q's norm */
    /* atan2 of half-angle sine and cosine is accurate at every angle, unlike acos(w) near 0
     * or asin(s) near pi, and does not need q normalised. */
    *theta = 2.0 * atan2(s, fabs(q[0]));
    if (s >= DBL_MIN) {
        for (int i = 0; i < 3; ++i) axis[i] = v[i] / s;
    } else {
        /* No usable direction (theta < 1e-307): any axis gives the identity. */
        axis[0] = 1.0;
        axis[1] = 0.0;
        axis[2] = 0.0;
    }
}

fm_mat3 fm_rotation_axis_angle(const double axis[3], double theta)
{
    double c = cos(theta), s = sin(theta);
    double h = sin(0.5 * theta);
    double k = 2.0 * h * h; /* 1 - cos(theta), without cancellation for small theta */
    double x = axis[0], y = axis[1], z = axis[2];
    fm_mat3 r = {{{c + k * x * x, k * x * y - s * z, k * x * z + s * y},
                  {k * x * y + s * z, c + k * y * y, k * y * z - s * x},
                  {k * x * z - s * y, k * y * z + s * x, c + k * z * z}}};
    return r;
}

/* ================================================================ minimal enclosing sphere */

/* Relative and absolute (times the bounding box's half-diagonal) slack of the inside test.
 * Points on the surface of the current sphere (cube corners, points sampled on a sphere) must
 * not count as outside because of rounding: each false "outside" rebuilds the sphere from a
 * (near-)degenerate support set. The price: a point up to this far outside may be accepted,
 * so the radius (the largest true distance, from the last pass) can exceed the minimal one by
 * about 1e-13 relative. The bounds were picked so that no input in the tests or in a search of
 * ~10^6 near-degenerate sets ever reached the fallback below. */
#define FM_SPHERE_TOL 1e-13
#define FM_SPHERE_TOL_ABS 1e-15

/* A sphere in working coordinates; lim2 is the squared radius of the inside test. */
typedef struct fm_ball {
    double c[3];
    double r;
    double lim2;
} fm_ball;

typedef struct fm_msph {
    const double *xyz;
    size_t *idx;       /* visiting order; rearranged by move-to-front */
    double ref[3];     /* bounding-box centre: working coordinates are relative to it, so
                          rounding scales with the set's extent, not its offset from 0 */
    double bound;      /* no valid sphere built during the search is larger than this */
    double tol_abs;
} fm_msph;

static void fm_msph_point(const fm_msph *ms, size_t pos, double q[3])
{
    fm_sub3(ms->xyz + 3 * ms->idx[pos], ms->ref, q);
}

static int fm_ball_misses(const fm_ball *b, const double q[3])
{
    return fm_dist2(b->c, q) > b->lim2;
}

/* Grows b's radius to the largest distance from its centre to the m points, so they are all
 * inside however the centre was rounded; also sets the inside-test limit. */
static void fm_ball_grow(const fm_msph *ms, fm_ball *b, double (*p)[3], int m)
{
    double r2 = b->r * b->r;
    for (int i = 0; i < m; ++i) r2 = fmax(r2, fm_dist2(b->c, p[i]));
    b->r = sqrt(r2);
    double lim = b->r * (1.0 + FM_SPHERE_TOL) + ms->tol_abs;
    b->lim2 = lim * lim;
}

/* Radius = largest distance from the (already set) centre to the m points. */
static void fm_ball_fit(const fm_msph *ms, fm_ball *b, double (*p)[3], int m)
{
    b->r = 0.0;
    fm_ball_grow(ms, b, p, m);
}

/* A circumsphere is accepted only if its centre is finite and its radius within the bound:
 * exact Welzl never builds a sphere larger than the final one, so a larger one can only come
 * from dividing by a rounding-sized determinant. */
static int fm_ball_accept(const fm_msph *ms, fm_ball *b, double (*p)[3], int m)
{
    if (!isfinite(b->c[0]) || !isfinite(b->c[1]) || !isfinite(b->c[2])) return -1;
    fm_ball_fit(ms, b, p, m);
    return b->r <= ms->bound ? 0 : -1;
}

/* Smallest sphere through p[i] and p[j]: the one with that diameter. */
static void fm_ball_pair(const fm_msph *ms, fm_ball *b, double (*p)[3], int i, int j)
{
    double two[2][3];
    for (int k = 0; k < 3; ++k) {
        two[0][k] = p[i][k];
        two[1][k] = p[j][k];
        b->c[k] = 0.5 * (p[i][k] + p[j][k]);
    }
    fm_ball_fit(ms, b, two, 2);
}

/* Smallest sphere through the triangle p[0..2]: centred on its circumcentre, in its plane.
 * With u = p1 - p0, v = p2 - p0, n = u x v: c = p0 + (|u|^2 v - |v|^2 u) x n / (2 |n|^2). */
static int fm_ball_circle(const fm_msph *ms, fm_ball *b, double (*p)[3])
{
    double u[3], v[3], n[3], w[3], t[3];
    fm_sub3(p[1], p[0], u);
    fm_sub3(p[2], p[0], v);
    fm_cross3(u, v, n);
    double uu = fm_dot3(u, u), vv = fm_dot3(v, v), nn2 = 2.0 * fm_dot3(n, n);
    for (int k = 0; k < 3; ++k) w[k] = uu * v[k] - vv * u[k];
    fm_cross3(w, n, t);
    for (int k = 0; k < 3; ++k) b->c[k] = p[0][k] + t[k] / nn2;
    return fm_ball_accept(ms, b, p, 3);
}

/* Circumcentre of the tetrahedron p0..p3, written as p0 + x: with u, v, w the edges from p0, x
 * solves 2 u.x = |u|^2 (etc.), i.e. x = (|u|^2 v x w + |v|^2 w x u + |w|^2 u x v) / (2 u.(v x w)).
 * Not finite for a flat tetrahedron. */
static void fm_circumcenter4(const double p0[3], const double p1[3], const double p2[3], const double p3[3],
                             double c[3])
{
    double u[3], v[3], w[3], vw[3], wu[3], uv[3];
    fm_sub3(p1, p0, u);
    fm_sub3(p2, p0, v);
    fm_sub3(p3, p0, w);
    fm_cross3(v, w, vw);
    fm_cross3(w, u, wu);
    fm_cross3(u, v, uv);
    double uu = fm_dot3(u, u), vv = fm_dot3(v, v), ww = fm_dot3(w, w);
    double det2 = 2.0 * fm_dot3(u, vw);
    for (int k = 0; k < 3; ++k) c[k] = p0[k] + (uu * vw[k] + vv * wu[k] + ww * uv[k]) / det2;
}

/* Sphere through the tetrahedron p[0..3]. */
static int fm_ball_tetra(const fm_msph *ms, fm_ball *b, double (*p)[3])
{
    fm_circumcenter4(p[0], p[1], p[2], p[3], b->c);
    return fm_ball_accept(ms, b, p, 4);
}

/* Grows cand to contain the m support points and the points at positions [0, end), and makes
 * it the best fallback if it is then still smaller. */
static void fm_ball_consider(const fm_msph *ms, fm_ball *best, fm_ball *cand, double (*p)[3],
                             int m, size_t end)
{
    fm_ball_grow(ms, cand, p, m);
    for (size_t i = 0; i < end && cand->r < best->r; ++i) {
        double q[1][3];
        fm_msph_point(ms, i, q[0]);
        if (fm_ball_misses(cand, q[0])) fm_ball_grow(ms, cand, q, 1);
    }
    if (cand->r < best->r) *best = *cand;
}

/* Fallback when the support set p[0..m-1] (m = 3 or 4, p[m-1] the point found outside b) has
 * no usable circumsphere: collinear or coplanar points, or a rounding-sized determinant. Exact
 * Welzl never gets here (such a point would lie on b, not outside it); rounding that puts a
 * point on b's surface just outside could. The result is the smallest of the spheres of a pair
 * or (m = 4) a triangle of p, and b itself, each grown just enough to contain all of p and the
 * points [0, end) the new sphere must enclose. A subset's sphere that already contains the
 * others needs no growing and wins if smallest; b (grown to the new point) always qualifies,
 * so no enclosed point is ever lost. The O(end) scans cost no more than the loop that found
 * the point, and this path is rare (no test input reaches it with the slack above). */
static void fm_ball_fallback(const fm_msph *ms, fm_ball *b, double (*p)[3], int m, size_t end)
{
    fm_ball best = *b, cand;
    fm_ball_grow(ms, &best, p, m); /* b already contains [0, end) */
    for (int i = 0; i < m; ++i)
        for (int j = i + 1; j < m; ++j) {
            fm_ball_pair(ms, &cand, p, i, j);
            fm_ball_consider(ms, &best, &cand, p, m, end);
        }
    for (int skip = 0; m == 4 && skip < 4; ++skip) {
        double tri[3][3];
        for (int i = 0, k = 0; i < 4; ++i)
            if (i != skip) memcpy(tri[k++], p[i], sizeof tri[0]);
        if (fm_ball_circle(ms, &cand, tri) == 0) fm_ball_consider(ms, &best, &cand, p, m, end);
    }
    *b = best;
}

/* b becomes the smallest sphere through p[0..2] (through p[0..3] for the 4-point version), or
 * the fallback if that does not exist; it must contain the points [0, end). */
static void fm_ball_through3(const fm_msph *ms, fm_ball *b, double (*p)[3], size_t end)
{
    fm_ball circ;
    if (fm_ball_circle(ms, &circ, p) == 0) *b = circ;
    else fm_ball_fallback(ms, b, p, 3, end);
}

static void fm_ball_through4(const fm_msph *ms, fm_ball *b, double (*p)[3], size_t end)
{
    fm_ball sph;
    if (fm_ball_tetra(ms, &sph, p) == 0) *b = sph;
    else fm_ball_fallback(ms, b, p, 4, end);
}

/* A point that forced a new sphere is likely to do so again in a later pass: move it to the
 * front. Positions 0..pos keep the same set of points, so the loops' invariants hold. */
static void fm_move_to_front(size_t *idx, size_t pos)
{
    size_t v = idx[pos];
    memmove(idx + 1, idx, pos * sizeof *idx);
    idx[0] = v;
}

/* Each loop makes b the smallest sphere containing the points at positions [0, end) with the
 * given boundary points on its surface; a point outside joins the boundary for the next loop,
 * which rebuilds the sphere over the positions before it (Welzl without recursion on n). */
static void fm_msph_loop3(const fm_msph *ms, fm_ball *b, double (*bnd)[3], size_t end)
{
    for (size_t l = 0; l < end; ++l) {
        double p[4][3];
        fm_msph_point(ms, l, p[3]);
        if (!fm_ball_misses(b, p[3])) continue;
        memcpy(p, bnd, 3 * sizeof p[0]);
        fm_ball_through4(ms, b, p, l);
        fm_move_to_front(ms->idx, l);
    }
}

static void fm_msph_loop2(const fm_msph *ms, fm_ball *b, double (*bnd)[3], size_t end)
{
    for (size_t k = 0; k < end; ++k) {
        double p[3][3];
        fm_msph_point(ms, k, p[2]);
        if (!fm_ball_misses(b, p[2])) continue;
        memcpy(p, bnd, 2 * sizeof p[0]);
        fm_ball_through3(ms, b, p, k);
        fm_msph_loop3(ms, b, p, k);
        fm_move_to_front(ms->idx, k);
    }
}

static void fm_msph_loop1(const fm_msph *ms, fm_ball *b, double (*bnd)[3], size_t end)
{
    for (size_t j = 0; j < end; ++j) {
        double p[2][3];
        fm_msph_point(ms, j, p[1]);
        if (!fm_ball_misses(b, p[1])) continue;
        memcpy(p[0], bnd[0], sizeof p[0]);
        fm_ball_pair(ms, b, p, 0, 1);
        fm_msph_loop2(ms, b, p, j);
        fm_move_to_front(ms->idx, j);
    }
}

static void fm_msph_loop0(const fm_msph *ms, fm_ball *b, size_t n)
{
    double p[1][3];
    fm_msph_point(ms, 0, p[0]);
    memcpy(b->c, p[0], sizeof b->c);
    fm_ball_fit(ms, b, p, 1);
    for (size_t i = 1; i < n; ++i) {
        fm_msph_point(ms, i, p[0]);
        if (!fm_ball_misses(b, p[0])) continue;
        memcpy(b->c, p[0], sizeof b->c);
        fm_ball_fit(ms, b, p, 1);
        fm_msph_loop1(ms, b, p, i);
        fm_move_to_front(ms->idx, i);
    }
}

/* Bounding-box centre and half-diagonal h. The minimal sphere has radius <= h, and so has
 * every sphere exact Welzl builds on the way (each is the answer of a sub-problem). */
static void fm_msph_bounds(fm_msph *ms, size_t n)
{
    double lo[3], hi[3], half[3];
    memcpy(lo, ms->xyz, sizeof lo);
    memcpy(hi, ms->xyz, sizeof hi);
    for (size_t i = 1; i < n; ++i)
        for (int k = 0; k < 3; ++k) {
            lo[k] = fmin(lo[k], ms->xyz[3 * i + k]);
            hi[k] = fmax(hi[k], ms->xyz[3 * i + k]);
        }
    for (int k = 0; k < 3; ++k) {
        ms->ref[k] = 0.5 * lo[k] + 0.5 * hi[k];
        half[k] = 0.5 * hi[k] - 0.5 * lo[k];
    }
    double h = fm_norm3(half);
    ms->tol_abs = FM_SPHERE_TOL_ABS * h;
    ms->bound = h * (1.0 + 1e-9) + ms->tol_abs;
}

/* Fisher-Yates; the modulo bias (< n / 2^64) does not matter for a visiting order. */
static void fm_shuffle(size_t *idx, size_t n, uint64_t seed)
{
    for (size_t i = 0; i < n; ++i) idx[i] = i;
    for (size_t i = n; i > 1; --i) {
        size_t j = (size_t)(fm_splitmix64(&seed) % i);
        size_t t = idx[i - 1];
        idx[i - 1] = idx[j];
        idx[j] = t;
    }
}

int fm_min_sphere(const double *xyz, size_t n, uint64_t seed, double center[3], double *radius)
{
    if (n == 0) {
        center[0] = center[1] = center[2] = 0.0;
        *radius = 0.0;
        return 0;
    }
    if (n > SIZE_MAX / sizeof(size_t)) return -1;
    fm_msph ms = {.xyz = xyz, .idx = malloc(n * sizeof(size_t))};
    if (!ms.idx) return -1;
    fm_shuffle(ms.idx, n, seed);
    fm_msph_bounds(&ms, n);
    fm_ball b;
    fm_msph_loop0(&ms, &b, n);
    free(ms.idx);

    /* Report the largest distance from the centre actually returned, in the caller's
     * coordinates: points accepted within the inside test's slack are then inside too. */
    double c[3], r2 = 0.0;
    for (int k = 0; k < 3; ++k) c[k] = ms.ref[k] + b.c[k];
    for (size_t i = 0; i < n; ++i) r2 = fmax(r2, fm_dist2(xyz + 3 * i, c));
    memcpy(center, c, sizeof c);
    *radius = sqrt(r2);
    return 0;
}

void fm_grow_bounds(double lo[3], double hi[3], const double *pts, int64_t count)
{
    for (int64_t i = 0; i < count; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], pts[3 * i + k]), hi[k] = fmax(hi[k], pts[3 * i + k]);
}

/* ================================================================ tetrahedron quality */

/* The circumradius is measured from the centre to all four vertices and the largest taken, so a
 * rounded centre can only overstate the ratio, never hide a bad tet. The tet is recentred on its
 * first vertex first: rounding then scales with the tet's size, not its distance from 0. */
double fm_tet_radius_edge(const double *tet)
{
    double p[4][3], c[3];
    for (int k = 0; k < 4; ++k) fm_sub3(tet + 3 * k, tet, p[k]);
    fm_circumcenter4(p[0], p[1], p[2], p[3], c);
    if (!isfinite(c[0]) || !isfinite(c[1]) || !isfinite(c[2])) return INFINITY; /* flat: as bad as it gets */
    double r2 = 0.0, e2 = INFINITY;
    for (int a = 0; a < 4; ++a) {
        r2 = fmax(r2, fm_dist2(c, p[a]));
        for (int b = a + 1; b < 4; ++b) e2 = fmin(e2, fm_dist2(p[a], p[b]));
    }
    if (!isfinite(r2) || e2 == 0.0) return INFINITY;
    return sqrt(r2 / e2);
}
