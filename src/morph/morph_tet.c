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
 * whose determinant is positive for every t because (1 - t) I + t S is positive definite.
 *
 * Only n and theta are stored per agent. A is rebuilt from the two tets' vertices in double each
 * time it is needed and S = R(n, theta)^T A, so A(1) = A to double precision however
 * ill-conditioned S is (a float copy of S would not be: its error scales with |S|). */
#include "morph.h"
#include "kernel_synth.h"
#include "fm_math.h"

#include <math.h>
#include <string.h>

const uint8_t fm_even_permutations[12][4] = {
    {0, 1, 2, 3}, {1, 0, 3, 2}, {2, 3, 0, 1}, {3, 2, 1, 0}, /* identity, double transpositions */
    {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 2, 0, 3}, {2, 0, 1, 3}, /* 3-cycles */
    {1, 3, 2, 0}, {3, 0, 2, 1}, {2, 1, 3, 0}, {3, 1, 0, 2},
};

uint8_t fm_compose_even_permutations(uint8_t outer, uint8_t inner)
{
    uint8_t p[4];
    for (int i = 0; i < 4; i++) p[i] = fm_even_permutations[inner][fm_even_permutations[outer][i]];
    for (uint8_t k = 0; k < 12; k++)
        if (!memcmp(p, fm_even_permutations[k], 4)) return k;
    return 0; /* unreachable: even permutations compose to an even one */
}

enum { DET_CHECK_SAMPLES = 256 };
static const double HALF_PI = 1.57079632679489661923;

double fm_shrink_scale(const fm_scene_def *def, double tau) { return fm_shrink_at(tau, def->shrink, def->shrink_time); }

/* Columns = edges from vertex order[0] to the other three. */
static fm_mat3 edge_matrix(const float *rel, const uint8_t *order)
{
    fm_mat3 e;
    for (int c = 0; c < 3; c++)
        for (int r = 0; r < 3; r++)
            e.m[r][c] = (double)rel[3 * order[c + 1] + r] - (double)rel[3 * order[0] + r];
    return e;
}

/* A with A (src_i - src_0) = dst_order(i) - dst_order(0); identity if the source is degenerate. */
static fm_mat3 affine_map(const float *src, const float *dst, const uint8_t *order)
{
    static const uint8_t identity[4] = {0, 1, 2, 3};
    fm_mat3 es_inv;
    if (fm_mat3_inverse(edge_matrix(src, identity), &es_inv) != 0) return fm_mat3_identity();
    return fm_mat3_mul(edge_matrix(dst, order), es_inv);
}

void fm_morph_affine(const float *src, const float *dst, double a[9])
{
    static const uint8_t identity[4] = {0, 1, 2, 3};
    fm_mat3 m = affine_map(src, dst, identity);
    memcpy(a, m.m, sizeof m.m);
}

void fm_morph_matrix(const float *morph, int safe, const double a_full[9], double t, double out[9])
{
    double axis[3] = {morph[0], morph[1], morph[2]};
    double len = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    for (int k = 0; k < 3; k++) axis[k] = len > 0 ? axis[k] / len : (k == 0); /* float n is not unit */
    fm_mat3 a, r = fm_rotation_axis_angle(axis, morph[3]), rt = fm_rotation_axis_angle(axis, t * morph[3]);
    memcpy(a.m, a_full, sizeof a.m);
    fm_mat3 s = fm_mat3_mul(fm_mat3_transpose(r), a), i_t = fm_mat3_scale(fm_mat3_identity(), 1 - t), m;
    if (safe) /* R(t theta) ((1-t) I + t S) */
        m = fm_mat3_mul(rt, fm_mat3_add(i_t, fm_mat3_scale(s, t)));
    else      /* (1-t) I + t R(t theta) S */
        m = fm_mat3_add(i_t, fm_mat3_scale(fm_mat3_mul(rt, s), t));
    memcpy(out, m.m, sizeof m.m);
}

static int det_stays_positive(const float *morph, const double a[9])
{
    for (int k = 1; k <= DET_CHECK_SAMPLES; k++) {
        double out[9];
        fm_morph_matrix(morph, 0, a, (double)k / DET_CHECK_SAMPLES, out);
        fm_mat3 m;
        memcpy(m.m, out, sizeof out);
        if (!(fm_mat3_det(m) > 0)) return 0;
    }
    return 1;
}

int fm_morph_setup(const float *src, const float *dst, float *morph, uint8_t *perm)
{
    double theta[12];
    float cand[12][FM_MORPH_FLOATS];
    fm_mat3 a[12];
    int ok[12] = {0};
    for (int p = 0; p < 12; p++) {
        fm_mat3 r, s;
        a[p] = affine_map(src, dst, fm_even_permutations[p]);
        theta[p] = 1e300;
        if (fm_polar_decompose(a[p], &r, &s) != 0) continue;
        double q[4], axis[3];
        fm_quat_from_rotation(r, q);
        fm_quat_to_axis_angle(q, axis, &theta[p]);
        for (int k = 0; k < 3; k++) cand[p][k] = (float)axis[k];
        cand[p][3] = (float)theta[p];
        ok[p] = 1;
    }
    for (int tries = 0; tries < 12; tries++) { /* smallest rotation first */
        int best = -1;
        for (int p = 0; p < 12; p++)
            if (ok[p] && (best < 0 || theta[p] < theta[best])) best = p;
        if (best < 0) break;
        double flat[9];
        memcpy(flat, a[best].m, sizeof flat);
        if (theta[best] < HALF_PI || det_stays_positive(cand[best], flat)) {
            memcpy(morph, cand[best], sizeof cand[best]);
            *perm = (uint8_t)best;
            return 0;
        }
        ok[best] = 0;
    }
    int best = 0; /* no candidate passed: the safe form with the smallest rotation */
    for (int p = 1; p < 12; p++)
        if (theta[p] < theta[best]) best = p;
    if (theta[best] >= 1e300) { /* degenerate tets: no rotation; A(t) only blends the shapes */
        static const float still[FM_MORPH_FLOATS] = {1, 0, 0, 0};
        memcpy(cand[best], still, sizeof still);
    }
    memcpy(morph, cand[best], sizeof cand[best]);
    *perm = (uint8_t)best;
    return 1;
}
