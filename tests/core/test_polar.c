/* Tests of fm_math's 3x3 algebra, polar decomposition and quaternion / axis-angle round trips. */
#include "fm_math.h"
#include "test_macros.h"

#include <float.h>
#include <string.h>

#define PI 3.14159265358979323846

/* ---------------------------------------------------------------- helpers */

/* splitmix64: deterministic, so failures reproduce. */
static uint64_t rng_state = 0x1234567887654321u;

static double rng_uniform(double lo, double hi) { return lo + (hi - lo) * test_uniform(&rng_state); }

static double rng_gauss(void)
{
    double u = rng_uniform(DBL_MIN, 1.0), v = rng_uniform(0.0, 2.0 * PI);
    return sqrt(-2.0 * log(u)) * cos(v);
}

static void rng_unit_vector(double v[3])
{
    double n;
    do {
        for (int i = 0; i < 3; ++i) v[i] = rng_gauss();
        n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    } while (n < 1e-3);
    for (int i = 0; i < 3; ++i) v[i] /= n;
}

/* Rotation of a unit quaternion, written independently of the library. */
static fm_mat3 quat_matrix(const double q[4])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    fm_mat3 r = {{{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                  {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                  {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}}};
    return r;
}

static fm_mat3 axis_angle_matrix(const double n[3], double theta)
{
    double s = sin(0.5 * theta);
    double q[4] = {cos(0.5 * theta), s * n[0], s * n[1], s * n[2]};
    return quat_matrix(q);
}

static fm_mat3 random_rotation(void)
{
    double q[4], n = 0.0;
    for (int i = 0; i < 4; ++i) {
        q[i] = rng_gauss();
        n += q[i] * q[i];
    }
    for (int i = 0; i < 4; ++i) q[i] /= sqrt(n);
    return quat_matrix(q);
}

static fm_mat3 diag(double a, double b, double c)
{
    fm_mat3 d = {{{a, 0, 0}, {0, b, 0}, {0, 0, c}}};
    return d;
}

/* u diag(s) v^T */
static fm_mat3 svd_compose(fm_mat3 u, const double s[3], fm_mat3 v)
{
    return fm_mat3_mul(fm_mat3_mul(u, diag(s[0], s[1], s[2])), fm_mat3_transpose(v));
}

/* Frobenius norm, scaled so that entries near 1e200 do not overflow the squares. */
static double frob(fm_mat3 a)
{
    double big = 0.0, t = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) big = fmax(big, fabs(a.m[i][j]));
    if (big == 0.0) return 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) t += (a.m[i][j] / big) * (a.m[i][j] / big);
    return big * sqrt(t);
}

static double max_abs_diff(fm_mat3 a, fm_mat3 b)
{
    double t = 0.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) t = fmax(t, fabs(a.m[i][j] - b.m[i][j]));
    return t;
}

/* Cholesky succeeds (all pivots > 0) iff the symmetric matrix is positive definite. */
static int is_positive_definite(fm_mat3 s)
{
    double l[3][3] = {{0}};
    for (int j = 0; j < 3; ++j) {
        double d = s.m[j][j];
        for (int k = 0; k < j; ++k) d -= l[j][k] * l[j][k];
        if (!(d > 0.0)) return 0;
        l[j][j] = sqrt(d);
        for (int i = j + 1; i < 3; ++i) {
            double t = s.m[i][j];
            for (int k = 0; k < j; ++k) t -= l[i][k] * l[j][k];
            l[i][j] = t / l[j][j];
        }
    }
    return 1;
}

/* Largest errors seen per call of check_polar, printed so the margins are visible. */
typedef struct polar_stats {
    double orth, det, sym, resid;
} polar_stats;

static void stats_print(const char *what, const polar_stats *st)
{
    printf("  %-28s |R^TR-I| %.1e  |detR-1| %.1e  sym %.1e  |RS-A|/|A| %.1e\n", what, st->orth,
           st->det, st->sym, st->resid);
}

/* Decomposes a and checks every property of the result; resid_tol bounds |RS - A| / |A|. */
static int check_polar(fm_mat3 a, double resid_tol, polar_stats *st, fm_mat3 *r_out,
                       fm_mat3 *s_out)
{
    fm_mat3 r, s;
    int rc = fm_polar_decompose(a, &r, &s);
    ENSURE_MSG(rc == 0, "fm_polar_decompose failed, det A = %g", fm_mat3_det(a));
    if (rc != 0) return -1;
    double orth = max_abs_diff(fm_mat3_mul(fm_mat3_transpose(r), r), fm_mat3_identity());
    double det = fabs(fm_mat3_det(r) - 1.0);
    double sym = max_abs_diff(s, fm_mat3_transpose(s)) / frob(s);
    double resid = frob(fm_mat3_add(fm_mat3_mul(r, s), fm_mat3_scale(a, -1.0))) / frob(a);
    ENSURE_MSG(orth < 1e-10, "R not orthonormal: %g", orth);
    ENSURE_MSG(det < 1e-10, "det R - 1 = %g", det);
    ENSURE_MSG(sym <= 1e-12, "S not symmetric: %g", sym);
    /* The header promises R^T A symmetrised, i.e. averaged with its transpose: exact. */
    ENSURE_MSG(sym == 0.0, "S not symmetrised: %g", sym);
    ENSURE_MSG(is_positive_definite(s), "S not positive definite");
    ENSURE_MSG(resid < resid_tol, "|RS - A| / |A| = %g (tolerance %g)", resid, resid_tol);
    st->orth = fmax(st->orth, orth);
    st->det = fmax(st->det, det);
    st->sym = fmax(st->sym, sym);
    st->resid = fmax(st->resid, resid);
    if (r_out) *r_out = r;
    if (s_out) *s_out = s;
    return 0;
}

/* ---------------------------------------------------------------- 3x3 algebra */

static void test_mat3_basics(void)
{
    fm_mat3 a = {{{2, -1, 0}, {1, 3, 4}, {0, 5, -2}}};
    fm_mat3 b = {{{1, 2, 3}, {0, 1, -1}, {4, 0, 2}}};
    fm_mat3 ab = fm_mat3_mul(a, b);
    fm_mat3 ab_hand = {{{2, 3, 7}, {17, 5, 8}, {-8, 5, -9}}};
    ENSURE(max_abs_diff(ab, ab_hand) == 0.0);
    ENSURE(fm_mat3_transpose(a).m[0][1] == 1 && fm_mat3_transpose(a).m[2][1] == 4);
    ENSURE(fm_mat3_scale(a, -2).m[1][2] == -8);
    ENSURE(fm_mat3_add(a, b).m[2][0] == 4 && fm_mat3_add(a, b).m[1][1] == 4);
    ENSURE(max_abs_diff(fm_mat3_mul(a, fm_mat3_identity()), a) == 0.0);
    /* det by cofactor expansion along row 0: 2(-6-20) + 1(-2-0) + 0 = -54 */
    ENSURE_NEAR(fm_mat3_det(a), -54.0, 1e-12);

    fm_mat3 inv;
    ENSURE(fm_mat3_inverse(a, &inv) == 0);
    ENSURE(max_abs_diff(fm_mat3_mul(a, inv), fm_mat3_identity()) < 1e-15);
    ENSURE(max_abs_diff(fm_mat3_mul(inv, a), fm_mat3_identity()) < 1e-15);

    double v[3] = {1, -2, 3}, out[3];
    fm_mat3_apply(a, v, out);
    ENSURE(out[0] == 4 && out[1] == 7 && out[2] == -16);
    fm_mat3_apply(a, v, v); /* aliasing is allowed */
    ENSURE(v[0] == 4 && v[1] == 7 && v[2] == -16);
}

static void test_mat3_inverse_failures(void)
{
    fm_mat3 sentinel = diag(7, 7, 7), out = sentinel;
    fm_mat3 singular = {{{1, 2, 3}, {4, 5, 6}, {7, 8, 9}}};
    ENSURE(fm_mat3_inverse(singular, &out) == -1);
    ENSURE(fm_mat3_inverse(diag(0, 1, 1), &out) == -1);
    fm_mat3 bad = fm_mat3_identity();
    bad.m[1][2] = NAN;
    ENSURE(fm_mat3_inverse(bad, &out) == -1);
    bad.m[1][2] = INFINITY;
    ENSURE(fm_mat3_inverse(bad, &out) == -1);
    /* The inverse of diag(1e-200, ...) overflows. */
    ENSURE(fm_mat3_inverse(diag(1e-200, 1e-200, 1e-200), &out) == -1);
    ENSURE(memcmp(&out, &sentinel, sizeof out) == 0);
}

/* ---------------------------------------------------------------- polar decomposition */

static void test_polar_random(void)
{
    polar_stats st = {0};
    for (int t = 0; t < 1000; ++t) {
        fm_mat3 a;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) a.m[i][j] = rng_uniform(-1.0, 1.0);
        if (fm_mat3_det(a) < 0.0)
            for (int j = 0; j < 3; ++j) a.m[0][j] = -a.m[0][j];
        check_polar(a, 1e-12, &st, NULL, NULL);
    }
    stats_print("random", &st);
}

/* A = U diag(s) V^T has R = U V^T and S = V diag(s) V^T; compare with those too. */
static void check_polar_svd(const double s[3], double resid_tol, double factor_tol,
                            polar_stats *st)
{
    fm_mat3 u = random_rotation(), v = random_rotation(), r, sm;
    fm_mat3 a = svd_compose(u, s, v);
    if (check_polar(a, resid_tol, st, &r, &sm) != 0) return;
    double r_err = max_abs_diff(r, fm_mat3_mul(u, fm_mat3_transpose(v)));
    double s_err = max_abs_diff(sm, svd_compose(v, s, v)) / s[0];
    ENSURE_MSG(r_err < factor_tol, "R vs U V^T: %g (s = %g %g %g)", r_err, s[0], s[1], s[2]);
    ENSURE_MSG(s_err < factor_tol, "S vs V S V^T: %g (s = %g %g %g)", s_err, s[0], s[1], s[2]);
}

static void test_polar_near_singular(void)
{
    /* One singular value 1e-6..1e-8 of the largest (condition 1e6..1e8; nearly rank 2). R's
     * sensitivity to relative perturbations of A is ~2/(s2 + s3) (Higham), which stays O(1)
     * while only s3 is small, so R and S must come out as accurately as for a random matrix.
     * No tolerance needs relaxing: the residual |RS - A| / |A| measures backward error, and
     * the iteration stays backward stable because fm_math computes the minors of X (hence
     * X^-T) to full relative accuracy. (With plain products the nearly rank-1 matrices below
     * reached ~1e-12.) The measured errors are printed. */
    polar_stats st = {0};
    for (int t = 0; t < 300; ++t) {
        double s[3] = {1.0, rng_uniform(0.05, 1.0), pow(10.0, rng_uniform(-8.0, -6.0))};
        check_polar_svd(s, 1e-12, 1e-12, &st);
    }
    stats_print("one tiny singular value", &st);
}

static void test_polar_nearly_rank2(void)
{
    /* A rank-2 product plus a 1e-8 perturbation: the small singular value is not built in, so
     * this exercises a different, unstructured way of being nearly singular. */
    polar_stats st = {0};
    for (int t = 0; t < 300; ++t) {
        fm_mat3 a;
        double x[3][2], y[2][3];
        for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 2; ++k) {
                x[i][k] = rng_uniform(-1.0, 1.0);
                y[k][i] = rng_uniform(-1.0, 1.0);
            }
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                a.m[i][j] = x[i][0] * y[0][j] + x[i][1] * y[1][j] + 1e-8 * rng_uniform(-1, 1);
        double d = fm_mat3_det(a);
        if (d == 0.0) continue;
        if (d < 0.0)
            for (int j = 0; j < 3; ++j) a.m[2][j] = -a.m[2][j];
        check_polar(a, 1e-12, &st, NULL, NULL);
    }
    stats_print("rank 2 + 1e-8", &st);
}

static void test_polar_nearly_rank1(void)
{
    /* Two small singular values (condition 1e8). R is now genuinely ill-conditioned: A itself
     * is only U diag(s) V^T rounded, and that rounding (~eps |A|) moves the exact R by up to
     * ~eps * 2/(s2 + s3), i.e. up to ~1e-8 when s2 = s3 = 1e-8. So R and S are compared with
     * U V^T and V S V^T to 20 eps / (s2 + s3) only. Orthonormality, positive definiteness and
     * the backward error |RS - A| / |A| keep their full tolerances. */
    polar_stats st = {0};
    for (int t = 0; t < 300; ++t) {
        double s[3] = {1.0, pow(10.0, rng_uniform(-8.0, -3.0)), 1e-8};
        check_polar_svd(s, 1e-12, 20.0 * DBL_EPSILON / (s[1] + s[2]), &st);
    }
    stats_print("two small singular values", &st);
}

static void test_polar_rotations(void)
{
    /* Pure rotations, including by (nearly) 180 degrees, where R = A and S = I. */
    polar_stats st = {0};
    const double deltas[] = {0.0, 1e-15, 1e-12, 1e-8, 1e-4, 0.1};
    for (int t = 0; t < 200; ++t) {
        double n[3], theta = t < 120 ? PI - deltas[t % 6] : rng_uniform(0.0, PI);
        rng_unit_vector(n);
        fm_mat3 q = axis_angle_matrix(n, theta), r, s;
        if (check_polar(q, 1e-12, &st, &r, &s) != 0) continue;
        ENSURE(max_abs_diff(r, q) < 1e-14);
        ENSURE(max_abs_diff(s, fm_mat3_identity()) < 1e-14);
        /* A rotation by ~180 degrees times a stretch: R must still be that rotation. */
        double sv[3] = {rng_uniform(0.1, 10), rng_uniform(0.1, 10), rng_uniform(0.1, 10)};
        fm_mat3 v = random_rotation();
        fm_mat3 a = fm_mat3_mul(q, svd_compose(v, sv, v));
        if (check_polar(a, 1e-12, &st, &r, NULL) == 0) ENSURE(max_abs_diff(r, q) < 1e-13);
    }
    stats_print("rotations (~180 deg)", &st);
}

static void test_polar_symmetric(void)
{
    /* Symmetric positive definite A (also diagonal with mixed scales): R = I and S = A. */
    polar_stats st = {0};
    for (int t = 0; t < 200; ++t) {
        double sv[3] = {pow(10.0, rng_uniform(-4, 4)), pow(10.0, rng_uniform(-4, 4)),
                        pow(10.0, rng_uniform(-4, 4))};
        fm_mat3 v = random_rotation(), r, s;
        fm_mat3 a = t % 2 ? svd_compose(v, sv, v) : diag(sv[0], sv[1], sv[2]);
        /* a is symmetric only to rounding when built from v; symmetrise so R = I exactly. */
        fm_mat3 at = fm_mat3_transpose(a);
        a = fm_mat3_scale(fm_mat3_add(a, at), 0.5);
        if (check_polar(a, 1e-12, &st, &r, &s) != 0) continue;
        double scale = fmax(sv[0], fmax(sv[1], sv[2])) / fmin(sv[0], fmin(sv[1], sv[2]));
        /* Errors in R grow with A's condition number for mixed-scale symmetric A; allow
         * rounding times that (<= 1e8 here). */
        ENSURE_MSG(max_abs_diff(r, fm_mat3_identity()) < 1e-15 * scale, "R != I, cond %g", scale);
        ENSURE(max_abs_diff(s, a) <= 1e-14 * frob(a));
    }
    const fm_mat3 diags[] = {diag(1e4, 1, 1e-4), diag(1e8, 1, 1), diag(1, 1e-8, 1e-8),
                             diag(3, 3, 3), diag(1e-8, 1, 1e8 * 0.99)};
    for (size_t i = 0; i < sizeof diags / sizeof diags[0]; ++i) {
        fm_mat3 r, s;
        if (check_polar(diags[i], 1e-12, &st, &r, &s) != 0) continue;
        /* Newton keeps a diagonal iterate diagonal and positive: R = I, S = A to rounding. */
        ENSURE(max_abs_diff(r, fm_mat3_identity()) < 1e-15);
        ENSURE(max_abs_diff(s, diags[i]) <= 1e-15 * frob(diags[i]));
    }
    stats_print("symmetric / diagonal", &st);
}

static void test_polar_extreme_scale(void)
{
    /* R does not depend on a positive scale of A; entries near the ends of the double range
     * (whose determinant over- or underflows) must still work. */
    polar_stats st = {0};
    for (int t = 0; t < 50; ++t) {
        fm_mat3 a, r0, r1, r2;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) a.m[i][j] = rng_uniform(-1.0, 1.0);
        if (fm_mat3_det(a) < 0.0) a = fm_mat3_scale(a, -1.0);
        if (check_polar(a, 1e-12, &st, &r0, NULL) != 0) continue;
        if (check_polar(fm_mat3_scale(a, 1e-200), 1e-12, &st, &r1, NULL) == 0)
            ENSURE(max_abs_diff(r0, r1) < 1e-13);
        if (check_polar(fm_mat3_scale(a, 1e200), 1e-12, &st, &r2, NULL) == 0)
            ENSURE(max_abs_diff(r0, r2) < 1e-13);
    }
    stats_print("scaled by 1e-200 / 1e200", &st);
    fm_mat3 r, s;
    ENSURE(fm_polar_decompose(diag(2, 3, 4), &r, NULL) == 0);
    ENSURE(fm_polar_decompose(diag(2, 3, 4), NULL, &s) == 0 && s.m[2][2] == 4);
}

static void test_polar_rejects(void)
{
    fm_mat3 r = diag(5, 5, 5), s = diag(6, 6, 6);
    const fm_mat3 r0 = r, s0 = s;
    fm_mat3 singular = {{{1, 2, 3}, {4, 5, 6}, {7, 8, 9}}};
    ENSURE(fm_polar_decompose(diag(1, 1, -1), &r, &s) == -1);   /* reflection */
    ENSURE(fm_polar_decompose(diag(-1, -2, -3), &r, &s) == -1); /* det < 0 */
    ENSURE(fm_polar_decompose(singular, &r, &s) == -1);         /* det == 0 */
    ENSURE(fm_polar_decompose(diag(0, 0, 0), &r, &s) == -1);
    fm_mat3 a = random_rotation();
    fm_mat3 reflected = fm_mat3_mul(a, diag(1, -1, 1));
    ENSURE(fm_polar_decompose(reflected, &r, &s) == -1);
    a.m[2][1] = NAN;
    ENSURE(fm_polar_decompose(a, &r, &s) == -1);
    a.m[2][1] = INFINITY;
    ENSURE(fm_polar_decompose(a, &r, &s) == -1);
    a.m[2][1] = -INFINITY;
    ENSURE(fm_polar_decompose(a, &r, &s) == -1);
    ENSURE(memcmp(&r, &r0, sizeof r) == 0);
    ENSURE(memcmp(&s, &s0, sizeof s) == 0);
}

/* ---------------------------------------------------------------- quaternions */

static void test_quat_known(void)
{
    double q[4], axis[3], theta;
    fm_quat_from_rotation(fm_mat3_identity(), q);
    ENSURE(q[0] == 1 && q[1] == 0 && q[2] == 0 && q[3] == 0);
    fm_quat_to_axis_angle(q, axis, &theta);
    ENSURE(theta == 0 && axis[0] == 1 && axis[1] == 0 && axis[2] == 0);

    /* 90 degrees about z maps x to y. */
    double z[3] = {0, 0, 1}, x[3] = {1, 0, 0}, y[3];
    fm_mat3 rz = fm_rotation_axis_angle(z, PI / 2);
    fm_mat3_apply(rz, x, y);
    ENSURE_NEAR(y[0], 0, 1e-16);
    ENSURE_NEAR(y[1], 1, 1e-16);
    ENSURE_NEAR(y[2], 0, 1e-16);
    fm_quat_from_rotation(rz, q);
    ENSURE_NEAR(q[0], sqrt(0.5), 1e-15);
    ENSURE_NEAR(q[3], sqrt(0.5), 1e-15);

    /* 180 degrees about x: w = 0, the x-branch of Shepperd. */
    fm_quat_from_rotation(diag(1, -1, -1), q);
    ENSURE(q[0] == 0 && fabs(q[1]) == 1 && q[2] == 0 && q[3] == 0);
    fm_quat_to_axis_angle(q, axis, &theta);
    ENSURE_NEAR(theta, PI, 1e-15);

    /* w < 0 and unnormalised input: -q is the same rotation, |q| is ignored. */
    double qn[4] = {-2, 0, 0, -2};
    fm_quat_to_axis_angle(qn, axis, &theta);
    ENSURE_NEAR(theta, PI / 2, 1e-15);
    ENSURE_NEAR(axis[2], 1, 1e-15);
    double qid[4] = {-1, 0, 0, 0};
    fm_quat_to_axis_angle(qid, axis, &theta);
    ENSURE(theta == 0 && axis[0] == 1);
}

/* R -> q -> (axis, theta) -> R' must reproduce R; checks the pieces along the way. */
static void check_round_trip(const double n[3], double theta_in)
{
    fm_mat3 r = axis_angle_matrix(n, theta_in);
    /* Rodrigues against the independent quaternion formula. */
    double rod = max_abs_diff(fm_rotation_axis_angle(n, theta_in), r);
    ENSURE_MSG(rod < 4e-15, "Rodrigues at theta %.17g: %g", theta_in, rod);
    double q[4], axis[3], theta;
    fm_quat_from_rotation(r, q);
    ENSURE(q[0] >= 0.0);
    ENSURE_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, 1e-15);
    fm_quat_to_axis_angle(q, axis, &theta);
    ENSURE_MSG(theta >= 0.0 && theta <= PI, "theta %.17g", theta);
    ENSURE_NEAR(theta, theta_in, 1e-12);
    ENSURE_NEAR(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2], 1.0, 1e-15);
    double err = max_abs_diff(fm_rotation_axis_angle(axis, theta), r);
    ENSURE_MSG(err < 1e-12, "round trip error %g at theta %.17g", err, theta_in);
}

static void test_quat_round_trip(void)
{
    /* pi here is the double nearest pi, slightly below it; also exercise a step above. */
    const double special[] = {0.0, 1e-300, 1e-20, 1e-16, 1e-12, 1e-8, 1e-4,
                              PI, PI - 1e-15, PI - 1e-12, PI - 1e-8, PI - 1e-4, PI / 2};
    for (int t = 0; t < 2000; ++t) {
        double n[3];
        rng_unit_vector(n);
        int ns = (int)(sizeof special / sizeof special[0]);
        check_round_trip(n, t < 20 * ns ? special[t % ns] : rng_uniform(0.0, PI));
    }
    /* Coordinate axes exercise each branch of Shepperd's method exactly at 180 degrees. */
    const double axes[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int i = 0; i < 3; ++i) {
        check_round_trip(axes[i], PI);
        check_round_trip(axes[i], PI - 1e-9);
        check_round_trip(axes[i], 1e-9);
    }
}

static void test_quat_from_noisy_rotation(void)
{
    /* A rotation that went through arithmetic (orthonormal only to rounding) still gives a
     * unit quaternion that reproduces it. */
    for (int t = 0; t < 500; ++t) {
        fm_mat3 r = fm_mat3_mul(fm_mat3_mul(random_rotation(), random_rotation()),
                                random_rotation());
        double q[4], axis[3], theta;
        fm_quat_from_rotation(r, q);
        ENSURE_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, 1e-15);
        ENSURE(max_abs_diff(quat_matrix(q), r) < 1e-14);
        fm_quat_to_axis_angle(q, axis, &theta);
        ENSURE(theta >= 0.0 && theta <= PI);
        ENSURE(max_abs_diff(fm_rotation_axis_angle(axis, theta), r) < 1e-12);
    }
}

int main(void)
{
    RUN_TEST(test_mat3_basics);
    RUN_TEST(test_mat3_inverse_failures);
    RUN_TEST(test_polar_random);
    RUN_TEST(test_polar_near_singular);
    RUN_TEST(test_polar_nearly_rank2);
    RUN_TEST(test_polar_nearly_rank1);
    RUN_TEST(test_polar_rotations);
    RUN_TEST(test_polar_symmetric);
    RUN_TEST(test_polar_extreme_scale);
    RUN_TEST(test_polar_rejects);
    RUN_TEST(test_quat_known);
    RUN_TEST(test_quat_round_trip);
    RUN_TEST(test_quat_from_noisy_rotation);
    return test_result();
}
