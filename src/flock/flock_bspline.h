/* The shape flock's global path (SCF "Global Path Control", eqs 10-12): a cubic B-spline R from the
 * source's centre O1 through the user's control points to the target's centre O2, re-parameterised
 * by arc length, and its per-agent copy R~ from C1 to C2 (eq 12).
 *
 * The curve interpolates every point it is given (O1, the user's points, O2): the control polygon
 * is solved for, so the flock passes where the user put a point, as the tetra morph's path does.
 * (The paper's curve "interpolates its end points"; ours does that and the inner points too.) It is
 * a uniform cubic B-spline with natural ends (zero second derivative at O1 and O2): data point Q_i
 * sits at knot i, and the control points P_{-1} .. P_{n+1} solve
 *     (P_{i-1} + 4 P_i + P_{i+1}) / 6 = Q_i,   P_{-1} = 2 P_0 - P_1,   P_{n+1} = 2 P_n - P_{n-1},
 * a tridiagonal system (diagonally dominant, solved by the Thomas algorithm). Two points give the
 * straight segment.
 *
 * Arc length: a table of the length at FM_BSPLINE_TABLE_PER_SEGMENT parameters per segment (each
 * interval integrated by 5-point Gauss-Legendre), inverted by bisection in the table and Newton
 * steps on the segment, so |dR/ds| is the curve's length to ~1e-9 relative. Double throughout.
 *
 * Each agent has its own path fraction (its leader eases in and out and starts a little after the
 * front of the flock, flock_step.c), so R is also kept at FM_BSPLINE_ARC_SAMPLES + 1 equal steps of
 * arc length, with dR/ds, and evaluated per agent by cubic Hermite interpolation
 * (fm_bspline_eval_table): C1 along the curve, within ~(L/4096)^4 |R''''| of it, a few dozen
 * instructions instead of the inversion's hundreds. */
#ifndef FM_BSPLINE_H
#define FM_BSPLINE_H

#include "fm_internal.h"

#include <stdint.h>

enum { FM_BSPLINE_TABLE_PER_SEGMENT = 64, FM_BSPLINE_ARC_SAMPLES = 4096 };

typedef struct fm_bspline {
    int32_t count;   /* data points Q_0 .. Q_{count-1}, count >= 2; the curve parameter u is in [0, count-1] */
    double *ctrl;    /* control points P_{-1} .. P_{count}: 3 * (count + 2) doubles */
    int32_t table;   /* entries of the arc-length table */
    double *table_s; /* arc length from Q_0 at u = j / FM_BSPLINE_TABLE_PER_SEGMENT */
    double length;
    double *arc;     /* R and dR/ds at s = j / FM_BSPLINE_ARC_SAMPLES: 6 doubles each */
} fm_bspline;

/* points: count >= 2 points (3 doubles each), finite. Fails with FM_ERR_INPUT if the curve has
 * zero length (all points equal), FM_ERR_MEMORY if out of memory. */
fm_status fm_bspline_build(const double *points, int32_t count, fm_bspline *out, fm_error *err);
void fm_bspline_free(fm_bspline *b);

/* R(u) and dR/du at curve parameter u in [0, count-1] (clamped). d may be NULL. */
void fm_bspline_eval(const fm_bspline *b, double u, double p[3], double d[3]);

/* The curve parameter u at arc-length fraction s in [0, 1] (clamped): length(0..u) = s * length. */
double fm_bspline_param_at(const fm_bspline *b, double s);

/* R and dR/ds at arc-length fraction s in [0, 1]; |dR/ds| = length. d may be NULL. */
void fm_bspline_eval_arc(const fm_bspline *b, double s, double p[3], double d[3]);

/* R at arc-length fraction s in [0, 1] (clamped), interpolated from the table (see the top). */
void fm_bspline_eval_table(const fm_bspline *b, double s, double p[3]);

/* Eq 12 at path fraction s: the agent's path from C1 to C2,
 *     R~(s) = alpha R(s) - alpha O(s) + C(s),  O(s) = (1-s) O1 + s O2 (eq 10),  C(s) = (1-s) C1 + s C2 (eq 11),
 * alpha = |C1 C2| / |O1 O2| (1 when O1 = O2: the paper leaves it undefined there), given r = R(s).
 * So R~(0) = C1 and R~(1) = C2. */
void fm_path_map(const double r[3], const double o1[3], const double o2[3], const double c1[3],
                 const double c2[3], double s, double out[3]);

/* Eq 12 with the formation's blend f in place of eq 11's s: C(s) = O(s) + (1 - f)(C1 - O1) + f (C2 - O2),
 * so the agent rides the path at fraction s while its offset from the flock's centre turns from the
 * source's layout (f = 0) into the target's (f = 1); f = s is eq 11's C(s) (fm_path_map). R~ = C1 when
 * s = f = 0 and C2 when s = f = 1. */
void fm_path_map_blend(const double r[3], const double o1[3], const double o2[3], const double c1[3],
                       const double c2[3], double s, double f, double out[3]);

#endif
