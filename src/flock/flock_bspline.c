/* Interpolating uniform cubic B-spline with an arc-length table (SCF eqs 10-12; see flock_bspline.h). */
#include "flock_bspline.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define P(b, j) ((b)->ctrl + 3 * ((j) + 1)) /* control point P_j, j = -1 .. count */

/* Solves P_{i-1} + 4 P_i + P_{i+1} = 6 Q_i for i = 1 .. n-1 with P_0 = Q_0 and P_n = Q_n (Thomas
 * algorithm), then sets the natural-end phantoms P_{-1} and P_{n+1}. */
static fm_status solve_control_points(fm_bspline *b, const double *q, fm_error *err)
{
    const int32_t n = b->count - 1;
    double *c = malloc(sizeof(double) * (size_t)(n + 1)); /* modified super-diagonal */
    if (!c) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the path");
    memcpy(P(b, 0), q, 3 * sizeof(double));
    memcpy(P(b, n), q + 3 * n, 3 * sizeof(double));
    for (int k = 0; k < 3; k++) {
        double prev_c = 0;
        for (int32_t i = 1; i < n; i++) { /* forward sweep; rhs kept in P_i */
            double rhs = 6 * q[3 * i + k] - (i == 1 ? q[k] : 0) - (i == n - 1 ? q[3 * n + k] : 0);
            double m = 4 - prev_c;
            c[i] = 1 / m;
            P(b, i)[k] = (rhs - (i > 1 ? P(b, i - 1)[k] : 0)) / m;
            prev_c = c[i];
        }
        for (int32_t i = n - 2; i >= 1; i--) P(b, i)[k] -= c[i] * P(b, i + 1)[k];
    }
    free(c);
    for (int k = 0; k < 3; k++) {
        P(b, -1)[k] = 2 * P(b, 0)[k] - P(b, 1)[k];
        P(b, n + 1)[k] = 2 * P(b, n)[k] - P(b, n - 1)[k];
    }
    return FM_OK;
}

void fm_bspline_eval(const fm_bspline *b, double u, double p[3], double d[3])
{
    const int32_t segments = b->count - 1;
    u = u < 0 ? 0 : u > segments ? segments : u;
    int32_t i = (int32_t)u;
    if (i >= segments) i = segments - 1;
    double t = u - i, t2 = t * t, t3 = t2 * t, s = 1 - t;
    const double w[4] = {s * s * s / 6, (3 * t3 - 6 * t2 + 4) / 6, (-3 * t3 + 3 * t2 + 3 * t + 1) / 6, t3 / 6};
    const double dw[4] = {-s * s / 2, (3 * t2 - 4 * t) / 2, (-3 * t2 + 2 * t + 1) / 2, t2 / 2};
    for (int k = 0; k < 3; k++) {
        double x = 0, dx = 0;
        for (int j = 0; j < 4; j++) x += w[j] * P(b, i - 1 + j)[k], dx += dw[j] * P(b, i - 1 + j)[k];
        p[k] = x;
        if (d) d[k] = dx;
    }
}

static double speed_at(const fm_bspline *b, double u)
{
    double p[3], d[3];
    fm_bspline_eval(b, u, p, d);
    return sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

/* Length of the curve between parameters u0 and u1 (5-point Gauss-Legendre). */
static double length_between(const fm_bspline *b, double u0, double u1)
{
    static const double x[5] = {0, -0.5384693101056831, 0.5384693101056831, -0.9061798459386640, 0.9061798459386640};
    static const double w[5] = {0.5688888888888889, 0.4786286704993665, 0.4786286704993665, 0.2369268850561891,
                                0.2369268850561891};
    double mid = 0.5 * (u0 + u1), half = 0.5 * (u1 - u0), sum = 0;
    for (int j = 0; j < 5; j++) sum += w[j] * speed_at(b, mid + half * x[j]);
    return sum * half;
}

fm_status fm_bspline_build(const double *points, int32_t count, fm_bspline *out, fm_error *err)
{
    memset(out, 0, sizeof *out);
    if (count < 2) return fm_fail(err, FM_ERR_INPUT, "a path needs at least 2 points, got %d", count);
    int distinct = 0;
    for (int32_t i = 1; i < count; i++)
        for (int k = 0; k < 3; k++) distinct |= points[3 * i + k] != points[k];
    if (!distinct) return fm_fail(err, FM_ERR_INPUT, "the path has zero length: its start, end and control points coincide");
    out->count = count;
    out->table = (count - 1) * FM_BSPLINE_TABLE_PER_SEGMENT + 1;
    out->ctrl = malloc(sizeof(double) * 3 * (size_t)(count + 2));
    out->table_s = malloc(sizeof(double) * (size_t)out->table);
    if (!out->ctrl || !out->table_s) {
        fm_bspline_free(out);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the path");
    }
    fm_status st = solve_control_points(out, points, err);
    if (st != FM_OK) return fm_bspline_free(out), st;
    out->table_s[0] = 0;
    for (int32_t j = 1; j < out->table; j++) {
        double u0 = (double)(j - 1) / FM_BSPLINE_TABLE_PER_SEGMENT, u1 = (double)j / FM_BSPLINE_TABLE_PER_SEGMENT;
        out->table_s[j] = out->table_s[j - 1] + length_between(out, u0, u1);
    }
    out->length = out->table_s[out->table - 1];
    if (!(out->length > 0) || !isfinite(out->length)) {
        fm_bspline_free(out);
        return fm_fail(err, FM_ERR_INPUT, "the path has zero length: its start, end and control points coincide");
    }
    out->arc = malloc(sizeof(double) * 6 * (FM_BSPLINE_ARC_SAMPLES + 1));
    if (!out->arc) {
        fm_bspline_free(out);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the path");
    }
    for (int32_t j = 0; j <= FM_BSPLINE_ARC_SAMPLES; j++)
        fm_bspline_eval_arc(out, (double)j / FM_BSPLINE_ARC_SAMPLES, out->arc + 6 * j, out->arc + 6 * j + 3);
    return FM_OK;
}

void fm_bspline_free(fm_bspline *b)
{
    free(b->ctrl), free(b->table_s), free(b->arc);
    b->ctrl = b->table_s = b->arc = NULL;
    b->count = b->table = 0;
}

double fm_bspline_param_at(const fm_bspline *b, double s)
{
    double target = (s < 0 ? 0 : s > 1 ? 1 : s) * b->length;
    int32_t lo = 0, hi = b->table - 1; /* table_s[lo] <= target <= table_s[hi] */
    while (hi - lo > 1) {
        int32_t mid = (lo + hi) / 2;
        if (b->table_s[mid] <= target) lo = mid;
        else hi = mid;
    }
    const double u_lo = (double)lo / FM_BSPLINE_TABLE_PER_SEGMENT, u_hi = (double)hi / FM_BSPLINE_TABLE_PER_SEGMENT;
    double span = b->table_s[hi] - b->table_s[lo];
    double u = span > 0 ? u_lo + (u_hi - u_lo) * (target - b->table_s[lo]) / span : u_lo;
    for (int it = 0; it < 4; it++) { /* Newton on length(u_lo..u) = target - table_s[lo], kept in the interval */
        double speed = speed_at(b, u);
        if (!(speed > 0)) break;
        u -= (b->table_s[lo] + length_between(b, u_lo, u) - target) / speed;
        u = u < u_lo ? u_lo : u > u_hi ? u_hi : u;
    }
    return u;
}

void fm_bspline_eval_arc(const fm_bspline *b, double s, double p[3], double d[3])
{
    double u = fm_bspline_param_at(b, s), du[3];
    fm_bspline_eval(b, u, p, du);
    if (!d) return;
    double speed = sqrt(du[0] * du[0] + du[1] * du[1] + du[2] * du[2]);
    for (int k = 0; k < 3; k++) d[k] = speed > 0 ? du[k] / speed * b->length : 0; /* dR/ds = length * unit tangent */
}

void fm_bspline_eval_table(const fm_bspline *b, double s, double p[3])
{
    const double x = (s < 0 ? 0 : s > 1 ? 1 : s) * FM_BSPLINE_ARC_SAMPLES;
    int32_t j = (int32_t)x;
    if (j >= FM_BSPLINE_ARC_SAMPLES) j = FM_BSPLINE_ARC_SAMPLES - 1;
    const double t = x - j, t2 = t * t, t3 = t2 * t, h = 1.0 / FM_BSPLINE_ARC_SAMPLES; /* s per step */
    const double h00 = 2 * t3 - 3 * t2 + 1, h10 = t3 - 2 * t2 + t, h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
    const double *a = b->arc + 6 * j, *c = a + 6;
    for (int k = 0; k < 3; k++) p[k] = h00 * a[k] + h10 * h * a[3 + k] + h01 * c[k] + h11 * h * c[3 + k];
}

void fm_path_map(const double r[3], const double o1[3], const double o2[3], const double c1[3],
                 const double c2[3], double s, double out[3])
{
    fm_path_map_blend(r, o1, o2, c1, c2, s, s, out);
}

void fm_path_map_blend(const double r[3], const double o1[3], const double o2[3], const double c1[3],
                       const double c2[3], double s, double f, double out[3])
{
    double oo = 0, cc = 0;
    for (int k = 0; k < 3; k++) oo += (o2[k] - o1[k]) * (o2[k] - o1[k]), cc += (c2[k] - c1[k]) * (c2[k] - c1[k]);
    const double alpha = oo > 0 ? sqrt(cc / oo) : 1.0;
    for (int k = 0; k < 3; k++) {
        const double o = (1 - s) * o1[k] + s * o2[k];
        const double c = o + (1 - f) * (c1[k] - o1[k]) + f * (c2[k] - o2[k]);
        out[k] = alpha * r[k] - alpha * o + c;
    }
}
