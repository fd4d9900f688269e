/* The tet morph (FM §6): A(0) = I, A(1) maps the source tet onto its target, det A(t) > 0 for all
 * t, the smallest-rotation correspondence, and the launch shrink. */
#include "morph.h"
#include "fm_math.h"
#include "test_macros.h"

#include <float.h>
#include <string.h>

static uint64_t rng_state = 12345;
static double uniform(void) { return test_uniform(&rng_state); }

static double volume6(const float *t)
{
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; k++) a[k] = t[3 + k] - t[k], b[k] = t[6 + k] - t[k], c[k] = t[9 + k] - t[k];
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

/* A random positively oriented tet, centroid at the origin. kind 0: regular-ish, 1: sliver
 * (one vertex nearly in the plane of the others), 2: needle (one long axis). */
static void random_tet(float *t, int kind)
{
    for (;;) {
        double stretch[3] = {1, 1, 1};
        if (kind == 1) stretch[2] = 0.02;
        if (kind == 2) stretch[0] = 30;
        for (int i = 0; i < 12; i++) t[i] = (float)(stretch[i % 3] * (2 * uniform() - 1));
        if (kind) { /* rotate the anisotropy to a random direction */
            double axis[3] = {uniform() - 0.5, uniform() - 0.5, uniform() - 0.5}, len = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
            for (int k = 0; k < 3; k++) axis[k] /= len;
            fm_mat3 r = fm_rotation_axis_angle(axis, 6.28 * uniform());
            for (int i = 0; i < 4; i++) {
                double p[3] = {t[3 * i], t[3 * i + 1], t[3 * i + 2]}, q[3];
                fm_mat3_apply(r, p, q);
                for (int k = 0; k < 3; k++) t[3 * i + k] = (float)q[k];
            }
        }
        if (volume6(t) < 0) {
            float tmp[3];
            memcpy(tmp, t + 6, sizeof tmp), memcpy(t + 6, t + 9, sizeof tmp), memcpy(t + 9, tmp, sizeof tmp);
        }
        if (fabs(volume6(t)) < 1e-4) continue;
        float c[3] = {0, 0, 0};
        for (int i = 0; i < 12; i++) c[i % 3] += 0.25f * t[i];
        for (int i = 0; i < 12; i++) t[i] -= c[i % 3];
        return;
    }
}

static double mat_det(const double a[9])
{
    return a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6]);
}

/* dst's vertices in the order the correspondence gives them to src's vertices */
static void permuted(const float *dst, uint8_t perm, float *out)
{
    const uint8_t *p = fm_even_permutations[perm];
    for (int i = 0; i < 4; i++) memcpy(out + 3 * i, dst + 3 * p[i], 3 * sizeof(float));
}

/* Returns 1 if the pair needed the safe form. */
static int check_pair(const float *src, const float *dst)
{
    float morph[FM_MORPH_FLOATS], dp[12];
    uint8_t perm;
    int safe = fm_morph_setup(src, dst, morph, &perm);
    ENSURE(perm < 12);
    permuted(dst, perm, dp);
    double full[9], a[9];
    fm_morph_affine(src, dp, full);
    fm_morph_matrix(morph, safe, full, 0.0, a); /* A(0) = I */
    for (int i = 0; i < 9; i++) ENSURE_NEAR(a[i], i % 4 == 0 ? 1.0 : 0.0, 1e-15);
    fm_morph_matrix(morph, safe, full, 1.0, a); /* A(1) (p_i - p_0) = p'_perm(i) - p'_perm(0) */
    for (int i = 1; i < 4; i++)
        for (int k = 0; k < 3; k++) {
            double x = 0, terms = 0;
            for (int j = 0; j < 3; j++) {
                x += a[3 * k + j] * ((double)src[3 * i + j] - src[j]);
                terms += fabs(a[3 * k + j] * ((double)src[3 * i + j] - src[j]));
            }
            /* double round-off on the terms (large for the deliberately ill-conditioned slivers) */
            ENSURE_NEAR(x, (double)dp[3 * i + k] - dp[k], 1e-10 * terms + 1e-12);
        }
    for (int s = 0; s <= 1000; s++) { /* no inverted tet along the way */
        fm_morph_matrix(morph, safe, full, s / 1000.0, a);
        ENSURE_MSG(mat_det(a) > 0, "det A(%g) = %g", s / 1000.0, mat_det(a));
    }
    return safe;
}

static void test_random_pairs_interpolate_without_inversion(void)
{
    int fallbacks = 0;
    for (int trial = 0; trial < 3000; trial++) {
        float src[12], dst[12];
        random_tet(src, trial % 3);
        random_tet(dst, (trial / 3) % 3);
        fallbacks += check_pair(src, dst);
    }
    printf("  safe-form fallbacks: %d of 3000 pairs\n", fallbacks);
    ENSURE(fallbacks < 300); /* the paper's form is the rule, the safe form the exception */
}

/* Source and target the same shape, rotated: A is a pure rotation, found with angle <= the
 * rotation applied, and S = I. */
static void test_rotated_copy_gives_pure_rotation(void)
{
    for (int trial = 0; trial < 200; trial++) {
        float src[12], dst[12];
        random_tet(src, 0);
        double axis[3] = {uniform() - 0.5, uniform() - 0.5, uniform() - 0.5}, len = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
        for (int k = 0; k < 3; k++) axis[k] /= len;
        double angle = 3.1 * uniform();
        fm_mat3 r = fm_rotation_axis_angle(axis, angle);
        for (int i = 0; i < 4; i++) {
            double p[3] = {src[3 * i], src[3 * i + 1], src[3 * i + 2]}, q[3];
            fm_mat3_apply(r, p, q);
            for (int k = 0; k < 3; k++) dst[3 * i + k] = (float)q[k];
        }
        float morph[FM_MORPH_FLOATS];
        uint8_t perm;
        fm_morph_setup(src, dst, morph, &perm);
        ENSURE_MSG(morph[3] <= angle + 1e-4, "theta %g > applied rotation %g", morph[3], angle);
        if (perm != 0) continue; /* another correspondence rotated less; its S is not I */
        ENSURE_NEAR(morph[3], angle, 1e-4);
        float dp[12]; /* S = R^T A = I: A(t) is the rotation R(n, t theta) blended with I */
        permuted(dst, perm, dp);
        double full[9];
        fm_morph_affine(src, dp, full);
        fm_mat3 rot = fm_rotation_axis_angle((double[3]){morph[0], morph[1], morph[2]}, morph[3]), a;
        memcpy(a.m, full, sizeof full);
        fm_mat3 s = fm_mat3_mul(fm_mat3_transpose(rot), a);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) ENSURE_NEAR(s.m[i][j], i == j, 1e-4);
    }
}

static void test_safe_form_endpoints(void)
{
    float src[12], dst[12], morph[FM_MORPH_FLOATS];
    uint8_t perm;
    random_tet(src, 2), random_tet(dst, 1);
    fm_morph_setup(src, dst, morph, &perm);
    float dp[12];
    permuted(dst, perm, dp);
    double full[9], a0[9], a1[9], b1[9];
    fm_morph_affine(src, dp, full);
    fm_morph_matrix(morph, 1, full, 0.0, a0);
    fm_morph_matrix(morph, 1, full, 1.0, a1);
    fm_morph_matrix(morph, 0, full, 1.0, b1);
    for (int i = 0; i < 9; i++) ENSURE_NEAR(a0[i], i % 4 == 0 ? 1.0 : 0.0, 1e-15);
    for (int i = 0; i < 9; i++) ENSURE_NEAR(a1[i], b1[i], 1e-12); /* both forms end at A = RS */
}

static void test_shrink_scale(void)
{
    fm_scene_def def = fm_default_scene_def();
    def.shrink = 0.5, def.shrink_time = 2.0;
    ENSURE(fm_shrink_scale(&def, -1.0) == 1.0);
    ENSURE(fm_shrink_scale(&def, 0.0) == 1.0);
    ENSURE_NEAR(fm_shrink_scale(&def, 1.0), 0.75, 1e-15);
    ENSURE(fm_shrink_scale(&def, 2.0) == 0.5);
    ENSURE(fm_shrink_scale(&def, 100.0) == 0.5);
    def.shrink_time = 0;
    ENSURE(fm_shrink_scale(&def, 1e-9) == 0.5);
}

int main(void)
{
    RUN_TEST(test_random_pairs_interpolate_without_inversion);
    RUN_TEST(test_rotated_copy_gives_pure_rotation);
    RUN_TEST(test_safe_form_endpoints);
    RUN_TEST(test_shrink_scale);
    return test_result();
}
