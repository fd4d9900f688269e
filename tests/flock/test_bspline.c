/* The shape flock's global path (SCF eqs 10-12): the B-spline passes through its points, is C1 at
 * the joints, its arc-length parameterisation has constant speed, and eq 12 maps it onto every
 * agent's endpoints. */
#include "flock_bspline.h"
#include "test_macros.h"

#include <math.h>
#include <string.h>

static const double POINTS[5][3] = {{-10, 0, 0}, {-4, -6, 3}, {0, -1, 9}, {5, 4, 2}, {10, 0, 0}};

static double dist(const double *a, const double *b)
{
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

static void test_curve_passes_through_every_point(void)
{
    fm_bspline b;
    ENSURE(fm_bspline_build(&POINTS[0][0], 5, &b, NULL) == FM_OK);
    for (int i = 0; i < 5; i++) {
        double p[3];
        fm_bspline_eval(&b, i, p, NULL);
        ENSURE_MSG(dist(p, POINTS[i]) < 1e-12, "point %d off by %g", i, dist(p, POINTS[i]));
    }
    double s0[3], s1[3];
    fm_bspline_eval_arc(&b, 0, s0, NULL);
    fm_bspline_eval_arc(&b, 1, s1, NULL);
    ENSURE(dist(s0, POINTS[0]) < 1e-12 && dist(s1, POINTS[4]) < 1e-12);
    fm_bspline_free(&b);
}

/* The first derivative is continuous across each joint (a cubic B-spline is C2). */
static void test_tangent_is_continuous_at_the_joints(void)
{
    fm_bspline b;
    ENSURE(fm_bspline_build(&POINTS[0][0], 5, &b, NULL) == FM_OK);
    for (int i = 1; i < 4; i++) {
        double p[3], left[3], right[3];
        fm_bspline_eval(&b, i - 1e-9, p, left);
        fm_bspline_eval(&b, i + 1e-9, p, right);
        ENSURE_MSG(dist(left, right) < 1e-6, "joint %d: tangent jumps by %g", i, dist(left, right));
    }
    fm_bspline_free(&b);
}

static void test_two_points_give_the_straight_segment(void)
{
    const double pts[2][3] = {{1, 2, 3}, {4, -2, 3}};
    fm_bspline b;
    ENSURE(fm_bspline_build(&pts[0][0], 2, &b, NULL) == FM_OK);
    ENSURE_NEAR(b.length, 5.0, 1e-12);
    for (int j = 0; j <= 10; j++) {
        double s = j / 10.0, p[3], want[3];
        fm_bspline_eval_arc(&b, s, p, NULL);
        for (int k = 0; k < 3; k++) want[k] = pts[0][k] + s * (pts[1][k] - pts[0][k]);
        ENSURE_MSG(dist(p, want) < 1e-9, "s = %g off by %g", s, dist(p, want));
    }
    fm_bspline_free(&b);
}

/* Equal steps of s cover equal lengths of curve: the chord of each of 2000 steps, divided by
 * length * ds, is within 1 % of 1 (the chord of a step this short is its arc to ~1e-6), and
 * |dR/ds| is the length. A raw B-spline parameter would not be: the check is also made to fail on u. */
static void test_arc_length_speed_is_constant(void)
{
    fm_bspline b;
    ENSURE(fm_bspline_build(&POINTS[0][0], 5, &b, NULL) == FM_OK);
    const int steps = 2000;
    double worst = 0, worst_raw = 0, prev[3], prev_raw[3];
    fm_bspline_eval_arc(&b, 0, prev, NULL);
    fm_bspline_eval(&b, 0, prev_raw, NULL);
    for (int j = 1; j <= steps; j++) {
        double s = (double)j / steps, p[3], d[3], raw[3];
        fm_bspline_eval_arc(&b, s, p, d);
        fm_bspline_eval(&b, s * 4, raw, NULL);
        double speed = dist(p, prev) * steps / b.length, speed_raw = dist(raw, prev_raw) * steps / b.length;
        worst = fmax(worst, fabs(speed - 1));
        worst_raw = fmax(worst_raw, fabs(speed_raw - 1));
        ENSURE_NEAR(sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), b.length, 1e-9 * b.length);
        for (int k = 0; k < 3; k++) prev[k] = p[k], prev_raw[k] = raw[k];
    }
    ENSURE_MSG(worst < 0.01, "arc-length speed varies by %.3g %%", 100 * worst);
    ENSURE_MSG(worst < 1e-4, "arc-length speed varies by %.3g %% (expected < 0.01 %%)", 100 * worst);
    ENSURE_MSG(worst_raw > 0.05, "the raw parameter is already uniform (%.3g %%): the check proves nothing", 100 * worst_raw);
    fm_bspline_free(&b);
}

/* Eq 12: R~(0) = C1, R~(1) = C2 for any pair, and the agent whose endpoints are O1 and O2 flies R
 * itself. */
static void test_eq12_maps_the_path_onto_each_pair(void)
{
    fm_bspline b;
    ENSURE(fm_bspline_build(&POINTS[0][0], 5, &b, NULL) == FM_OK);
    const double *o1 = POINTS[0], *o2 = POINTS[4];
    uint64_t rng = 12;
    for (int trial = 0; trial < 100; trial++) {
        double c1[3], c2[3], r[3], out[3];
        for (int k = 0; k < 3; k++) c1[k] = 20 * test_uniform(&rng) - 10, c2[k] = 20 * test_uniform(&rng) - 10;
        fm_bspline_eval_arc(&b, 0, r, NULL);
        fm_path_map(r, o1, o2, c1, c2, 0, out);
        ENSURE(dist(out, c1) < 1e-12);
        fm_bspline_eval_arc(&b, 1, r, NULL);
        fm_path_map(r, o1, o2, c1, c2, 1, out);
        ENSURE(dist(out, c2) < 1e-12);
    }
    for (int j = 0; j <= 8; j++) {
        double r[3], out[3];
        fm_bspline_eval_arc(&b, j / 8.0, r, NULL);
        fm_path_map(r, o1, o2, o1, o2, j / 8.0, out);
        ENSURE(dist(out, r) < 1e-12);
    }
    fm_bspline_free(&b);
}

static void test_degenerate_paths_are_refused(void)
{
    const double same[3][3] = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
    fm_bspline b;
    fm_error err = {0};
    ENSURE(fm_bspline_build(&same[0][0], 3, &b, &err) == FM_ERR_INPUT);
    ENSURE(strstr(err.message, "zero length") != NULL);
    ENSURE(b.ctrl == NULL && b.table_s == NULL);
    ENSURE(fm_bspline_build(&same[0][0], 1, &b, &err) == FM_ERR_INPUT);
}

int main(void)
{
    RUN_TEST(test_curve_passes_through_every_point);
    RUN_TEST(test_tangent_is_continuous_at_the_joints);
    RUN_TEST(test_two_points_give_the_straight_segment);
    RUN_TEST(test_arc_length_speed_is_constant);
    RUN_TEST(test_eq12_maps_the_path_onto_each_pair);
    RUN_TEST(test_degenerate_paths_are_refused);
    return test_result();
}
