/* The tet morph (FM §6).
 *
 * A maps the source tet (relative to its centroid) onto the target tet; its polar decomposition
 * A = RS (Shoemake) gives a rotation R = R(n, theta) and a stretch S, and the interpolated shape is
 *     A(t) = (1 - t) I + t R(n, t theta) S,      A(0) = I, A(1) = A.
 * Which source vertex goes to which target vertex is free. Among the 12 orientation-preserving
 * correspondences (the even permutations: both tets are positively oriented, so det A > 0) we take
 * the one with the smallest rotation angle theta. det A(t) > 0 for all t is guaranteed when
 * theta < pi/2: a negative real eigenvalue -(1-t)/t of R_t S would need v.R_t v < 0 for a real v
 * with R_t S v = lambda v, and v.R_t v >= |v|^2 cos(t theta) > 0. For larger angles the candidate is
 * checked on a fine grid of t; if no correspondence passes, the agent uses the safe form
 *     A(t) = R(n, t theta) ((1 - t) I + t S),
 * whose determinant is positive for every t because (1 - t) I + t S is positive definite. */
#include "sim.h"
#include "fm_math.h"

#include <math.h>
#include <string.h>

const uint8_t fm_even_permutations[12][4] = {
    {0, 1, 2, 3}, {1, 0, 3, 2}, {2, 3, 0, 1}, {3, 2, 1, 0}, /* identity, double transpositions */
    {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 2, 0, 3}, {2, 0, 1, 3}, /* 3-cycles */
    {1, 3, 2, 0}, {3, 0, 2, 1}, {2, 1, 3, 0}, {3, 1, 0, 2},
};

enum { DET_CHECK_SAMPLES = 256 };
static const double HALF_PI = 1.57079632679489661923;

double fm_shrink_scale(const fm_scene_def *def, double tau)
{
    if (tau <= 0) return 1.0;
    double s = def->shrink_time > 0 ? tau / def->shrink_time : 1.0;
    if (s > 1) s = 1;
    return 1.0 - (1.0 - def->shrink) * s;
}

/* Columns = edges from vertex order[0] to the other three. */
static fm_mat3 edge_matrix(const float *rel, const uint8_t *order)
{
    fm_mat3 e;
    for (int c = 0; c < 3; c++)
        for (int r = 0; r < 3; r++)
            e.m[r][c] = (double)rel[3 * order[c + 1] + r] - (double)rel[3 * order[0] + r];
    return e;
}

static void pack_morph(const double axis[3], double theta, fm_mat3 s, float *morph)
{
    for (int k = 0; k < 3; k++) morph[k] = (float)axis[k];
    morph[3] = (float)theta;
    morph[4] = (float)s.m[0][0], morph[5] = (float)s.m[1][1], morph[6] = (float)s.m[2][2];
    morph[7] = (float)(0.5 * (s.m[0][1] + s.m[1][0]));
    morph[8] = (float)(0.5 * (s.m[0][2] + s.m[2][0]));
    morph[9] = (float)(0.5 * (s.m[1][2] + s.m[2][1]));
}

void fm_morph_matrix(const float *morph, int safe, double t, double out[9])
{
    const double axis[3] = {morph[0], morph[1], morph[2]};
    fm_mat3 r = fm_rotation_axis_angle(axis, t * morph[3]);
    fm_mat3 s = {{{morph[4], morph[7], morph[8]}, {morph[7], morph[5], morph[9]}, {morph[8], morph[9], morph[6]}}};
    fm_mat3 a;
    if (safe) { /* R(t theta) ((1-t) I + t S) */
        a = fm_mat3_mul(r, fm_mat3_add(fm_mat3_scale(fm_mat3_identity(), 1 - t), fm_mat3_scale(s, t)));
    } else {    /* (1-t) I + t R(t theta) S */
        a = fm_mat3_add(fm_mat3_scale(fm_mat3_identity(), 1 - t), fm_mat3_scale(fm_mat3_mul(r, s), t));
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) out[3 * i + j] = a.m[i][j];
}

static int det_stays_positive(const float *morph)
{
    for (int k = 1; k <= DET_CHECK_SAMPLES; k++) {
        double a[9];
        fm_morph_matrix(morph, 0, (double)k / DET_CHECK_SAMPLES, a);
        fm_mat3 m;
        memcpy(m.m, a, sizeof a);
        if (!(fm_mat3_det(m) > 0)) return 0;
    }
    return 1;
}

int fm_morph_setup(const float *src, const float *dst, float *morph, uint8_t *perm)
{
    static const uint8_t identity[4] = {0, 1, 2, 3};
    fm_mat3 es = edge_matrix(src, identity), es_inv;
    double theta[12];
    float cand[12][FM_MORPH_FLOATS];
    int ok[12] = {0};
    if (fm_mat3_inverse(es, &es_inv) != 0) es_inv = fm_mat3_identity(); /* degenerate source */
    for (int p = 0; p < 12; p++) {
        fm_mat3 a = fm_mat3_mul(edge_matrix(dst, fm_even_permutations[p]), es_inv), r, s;
        theta[p] = 1e300;
        if (fm_polar_decompose(a, &r, &s) != 0) continue;
        double q[4], axis[3];
        fm_quat_from_rotation(r, q);
        fm_quat_to_axis_angle(q, axis, &theta[p]);
        pack_morph(axis, theta[p], s, cand[p]);
        ok[p] = 1;
    }
    for (int tries = 0; tries < 12; tries++) { /* smallest rotation first */
        int best = -1;
        for (int p = 0; p < 12; p++)
            if (ok[p] && (best < 0 || theta[p] < theta[best])) best = p;
        if (best < 0) break;
        if (theta[best] < HALF_PI || det_stays_positive(cand[best])) {
            memcpy(morph, cand[best], sizeof cand[best]);
            *perm = (uint8_t)best;
            return 0;
        }
        ok[best] = 0;
    }
    int best = 0; /* no candidate passed: the safe form with the smallest rotation */
    for (int p = 1; p < 12; p++)
        if (theta[p] < theta[best]) best = p;
    if (theta[best] >= 1e300) { /* degenerate tets: no A at all; keep the shape, scale only */
        static const float still[FM_MORPH_FLOATS] = {1, 0, 0, 0, 1, 1, 1, 0, 0, 0};
        memcpy(cand[best], still, sizeof still);
    }
    memcpy(morph, cand[best], sizeof cand[best]);
    *perm = (uint8_t)best;
    return 1;
}
