/* Subdivision to n tets (FM eqs 1-2): counts, exact volume, orientation, the three schemes; and
 * longest-edge bisection (fm_bisect_to, issue 38): the same properties, and better shapes than
 * the centroid split. */
#include "geom.h"
#include "test_macros.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double uniform(void) { return test_uniform(&rng_state); }

/* n random positively oriented tets with volumes spread over two orders of magnitude. */
static fm_tets random_tets(int64_t n)
{
    fm_tets t = {malloc(sizeof(double) * 12 * (size_t)n), n};
    for (int64_t i = 0; i < n; i++) {
        double *v = t.v + 12 * i, scale = 0.1 + 10 * uniform();
        for (int k = 0; k < 12; k++) v[k] = (k < 3 ? 20 * uniform() : v[k % 3] + scale * (uniform() - 0.5));
        if (fm_tet_signed_volume(v) < 0) {
            double tmp[3];
            memcpy(tmp, v + 6, sizeof tmp), memcpy(v + 6, v + 9, sizeof tmp), memcpy(v + 9, tmp, sizeof tmp);
        }
    }
    return t;
}

static double total_volume(const fm_tets *t, double *min_volume)
{
    double sum = 0;
    *min_volume = 1e300;
    for (int64_t i = 0; i < t->n; i++) {
        double v = fm_tet_signed_volume(t->v + 12 * i);
        sum += v;
        if (v < *min_volume) *min_volume = v;
    }
    return sum;
}

static void check_subdivision(int64_t n1, int64_t n)
{
    fm_tets t = random_tets(n1);
    double vmin, before = total_volume(&t, &vmin);
    fm_error err = {0};
    ENSURE_MSG(fm_subdivide_to(&t, n, &err) == FM_OK, "n1 %lld n %lld: %s", (long long)n1, (long long)n, err.message);
    ENSURE_MSG(t.n == n, "n1 %lld: got %lld tets, wanted %lld", (long long)n1, (long long)t.n, (long long)n);
    double after = total_volume(&t, &vmin);
    ENSURE_MSG(fabs(after - before) <= 1e-12 * before, "n1 %lld n %lld: volume %.17g -> %.17g", (long long)n1,
               (long long)n, before, after);
    ENSURE_MSG(vmin > 0, "n1 %lld n %lld: a child is inverted or flat (%g)", (long long)n1, (long long)n, vmin);
    fm_tets_free(&t);
}

static void test_counts_and_volume_across_ranges(void)
{
    const int64_t n1s[] = {1, 2, 3, 7, 50, 1831};
    for (size_t i = 0; i < sizeof n1s / sizeof n1s[0]; i++) {
        int64_t n1 = n1s[i];
        const int64_t ns[] = {n1, n1 + 1, n1 + 2, n1 + 3, n1 + 4, 2 * n1 + 1, 4 * n1 - 1, 4 * n1, 4 * n1 + 1,
                              4 * n1 + 2, 16 * n1 - 1, 16 * n1 + 5, 64 * n1 + 3};
        for (size_t j = 0; j < sizeof ns / sizeof ns[0]; j++) check_subdivision(n1, ns[j]);
    }
}

static void test_smaller_n_is_an_error(void)
{
    fm_tets t = random_tets(10);
    fm_error err = {0};
    ENSURE(fm_subdivide_to(&t, 9, &err) == FM_ERR_INPUT);
    ENSURE(strstr(err.message, "smaller") != NULL);
    ENSURE(t.n == 10);
    fm_tets_free(&t);
}

/* Each scheme's children have equal volumes: 1/4, 1/3, 1/2 of the parent. */
static void test_scheme_volume_fractions(void)
{
    for (int trial = 0; trial < 200; trial++) {
        fm_tets t = random_tets(1);
        double parent = fm_tet_signed_volume(t.v), out[48];
        fm_split_1to4(t.v, out);
        /* small tets far from the origin: round-off is relative to the coordinates, not the volume */
        for (int c = 0; c < 4; c++) ENSURE_NEAR(fm_tet_signed_volume(out + 12 * c), parent / 4, 1e-9 * parent);
        fm_split_1to3(t.v, out);
        for (int c = 0; c < 3; c++) ENSURE_NEAR(fm_tet_signed_volume(out + 12 * c), parent / 3, 1e-9 * parent);
        fm_split_1to2(t.v, out);
        for (int c = 0; c < 2; c++) ENSURE_NEAR(fm_tet_signed_volume(out + 12 * c), parent / 2, 1e-9 * parent);
        fm_tets_free(&t);
    }
}

/* 1-to-2 splits the longest edge at its midpoint; 1-to-3 puts the point on the largest face. */
static void test_scheme_geometry(void)
{
    /* longest edge v0-v1 (length 4); largest face v0 v1 v3 (area 3, opposite v2) */
    double tet[12] = {0, 0, 0, 4, 0, 0, 2, 1, 0, 2, 0, 1.5}, out[36];
    ENSURE(fm_tet_signed_volume(tet) > 0);
    fm_split_1to2(tet, out);
    ENSURE(out[0] == 2.0 && out[1] == 0.0 && out[2] == 0.0);           /* child 0: v0 -> midpoint */
    ENSURE(out[12 + 3] == 2.0 && out[12 + 4] == 0.0 && out[12 + 5] == 0.0); /* child 1: v1 -> midpoint */
    fm_split_1to3(tet, out); /* new point: the face centroid (2, 0, 0.5); v2 kept in every child */
    for (int c = 0; c < 3; c++) ENSURE(out[12 * c + 6] == 2.0 && out[12 * c + 7] == 1.0 && out[12 * c + 8] == 0.0);
    ENSURE_NEAR(out[0], 2.0, 1e-15);
    ENSURE_NEAR(out[2], 0.5, 1e-15);
}

/* Eq 2 subdivides the largest tets first: one tet 100x larger than the others takes the split. */
static void test_largest_tets_split_first(void)
{
    fm_tets t = random_tets(5);
    for (int k = 3; k < 12; k++) t.v[12 * 2 + k] = t.v[12 * 2 + k % 3] + 50 * (t.v[12 * 2 + k] - t.v[12 * 2 + k % 3]);
    double big = fm_tet_signed_volume(t.v + 24);
    fm_error err = {0};
    ENSURE(fm_subdivide_to(&t, 8, &err) == FM_OK); /* d = 1: exactly the biggest is split 1-to-4 */
    int quarter = 0;
    for (int64_t i = 0; i < t.n; i++) quarter += fabs(fm_tet_signed_volume(t.v + 12 * i) - big / 4) < 1e-9 * big;
    ENSURE(quarter == 4);
    fm_tets_free(&t);
}


static void check_bisection(int64_t n1, int64_t n)
{
    fm_tets t = random_tets(n1);
    double vmin, before = total_volume(&t, &vmin);
    fm_error err = {0};
    ENSURE_MSG(fm_bisect_to(&t, n, &err) == FM_OK, "n1 %lld n %lld: %s", (long long)n1, (long long)n, err.message);
    ENSURE_MSG(t.n == n, "n1 %lld: got %lld tets, wanted %lld", (long long)n1, (long long)t.n, (long long)n);
    double after = total_volume(&t, &vmin);
    ENSURE_MSG(fabs(after - before) <= 1e-12 * before, "n1 %lld n %lld: volume %.17g -> %.17g", (long long)n1,
               (long long)n, before, after);
    ENSURE_MSG(vmin > 0, "n1 %lld n %lld: a child is inverted or flat (%g)", (long long)n1, (long long)n, vmin);
    fm_tets_free(&t);
}

static void test_bisection_counts_and_volume(void)
{
    const int64_t n1s[] = {1, 2, 3, 7, 50, 1831};
    for (size_t i = 0; i < sizeof n1s / sizeof n1s[0]; i++) {
        int64_t n1 = n1s[i];
        const int64_t ns[] = {n1, n1 + 1, n1 + 2, 2 * n1 - 1 + (n1 == 1), 2 * n1, 2 * n1 + 1, 4 * n1 + 1, 16 * n1 + 5};
        for (size_t j = 0; j < sizeof ns / sizeof ns[0]; j++) check_bisection(n1, ns[j]);
    }
    fm_tets t = random_tets(10);
    fm_error err = {0};
    ENSURE(fm_bisect_to(&t, 9, &err) == FM_ERR_INPUT && strstr(err.message, "smaller") != NULL && t.n == 10);
    fm_tets_free(&t);
}

/* Well-shaped tets (a regular tet, randomly scaled, turned and perturbed by 10 %: ratios 0.6 to
 * about 1), brought to 3x, 8x and 20x their count: the centroid split makes caps (a regular tet's
 * children have ratio 1.5, and levels compound it), bisection keeps them within its few shape
 * classes. Measured (x3, x8, x20): median 1.00, 1.13, 1.02 against 1.53, 3.83, 4.05; above 2.0: 0,
 * 3.5 %, 1.9 % against 0, 67 %, 99.9 %; max 1.20, 2.61, 2.62 against 1.72, 6.48, 26.1. */
static fm_tets good_tets(int64_t n)
{
    static const double regular[12] = {1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1};
    fm_tets t = {malloc(sizeof(double) * 12 * (size_t)n), n};
    for (int64_t i = 0; i < n; i++) {
        double *v = t.v + 12 * i, scale = 0.2 + uniform(), a = 6.283185307179586 * uniform(), c = cos(a), s = sin(a);
        double at[3] = {20 * uniform(), 20 * uniform(), 20 * uniform()};
        for (int k = 0; k < 4; k++) {
            double p[3];
            for (int d = 0; d < 3; d++) p[d] = regular[3 * k + d] + 0.2 * (uniform() - 0.5);
            v[3 * k + 0] = at[0] + scale * (c * p[0] - s * p[1]);
            v[3 * k + 1] = at[1] + scale * (s * p[0] + c * p[1]);
            v[3 * k + 2] = at[2] + scale * p[2];
        }
        if (fm_tet_signed_volume(v) < 0) {
            double tmp[3];
            memcpy(tmp, v + 6, sizeof tmp), memcpy(v + 6, v + 9, sizeof tmp), memcpy(v + 9, tmp, sizeof tmp);
        }
    }
    return t;
}

/* The largest tet is halved first, and its halves again while they are the largest: a regular tet
 * 10x as large as four others (1000x the volume) takes all of n - 5 = 7 splits (8 pieces of 1/8),
 * the others none. */
static void test_bisection_splits_the_largest(void)
{
    static const double regular[12] = {1, 1, 1, 1, -1, -1, -1, -1, 1, -1, 1, -1}; /* positively oriented */
    fm_tets t = {malloc(sizeof(double) * 60), 5};
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 12; k++) t.v[12 * i + k] = (i == 2 ? 10.0 : 1.0) * regular[k] + 30.0 * i;
    double big = fm_tet_signed_volume(t.v + 24), small = fm_tet_signed_volume(t.v);
    ENSURE(small > 0 && big > 999 * small);
    fm_error err = {0};
    ENSURE(fm_bisect_to(&t, 12, &err) == FM_OK);
    int eighths = 0, kept = 0;
    for (int64_t i = 0; i < t.n; i++) {
        double v = fm_tet_signed_volume(t.v + 12 * i);
        eighths += fabs(v - big / 8) < 1e-9 * big;
        kept += fabs(v - small) < 1e-9 * small;
    }
    ENSURE_MSG(eighths == 8 && kept == 4, "%d eighths, %d kept", eighths, kept);
    fm_tets_free(&t);
}

static void test_bisection_keeps_shapes(void)
{
    const int64_t factors[] = {3, 8, 20};
    for (size_t f = 0; f < sizeof factors / sizeof factors[0]; f++) {
        const int64_t n1 = 500, n = factors[f] * n1;
        fm_tets a = good_tets(n1), b = {malloc(sizeof(double) * 12 * (size_t)n1), n1};
        memcpy(b.v, a.v, sizeof(double) * 12 * (size_t)n1);
        fm_tet_quality start = fm_tets_quality(&a, 2.0);
        fm_error err = {0};
        ENSURE(fm_subdivide_to(&a, n, &err) == FM_OK && fm_bisect_to(&b, n, &err) == FM_OK);
        fm_tet_quality centroid = fm_tets_quality(&a, 2.0), bisect = fm_tets_quality(&b, 2.0);
        printf("  x%lld: start median %.3f max %.3f; centroid split median %.3f, %.1f %% above 2, max %.2f; "
               "bisection median %.3f, %.1f %% above 2, max %.2f\n", (long long)factors[f], start.median_ratio,
               start.max_ratio, centroid.median_ratio, 100.0 * (double)centroid.above / (double)n, centroid.max_ratio,
               bisect.median_ratio, 100.0 * (double)bisect.above / (double)n, bisect.max_ratio);
        ENSURE(start.max_ratio < 1.2);
        ENSURE(bisect.median_ratio < 0.75 * centroid.median_ratio);
        ENSURE(bisect.above * 10 <= centroid.above);
        ENSURE(bisect.max_ratio < centroid.max_ratio);
        ENSURE(bisect.above_4 == 0);
        fm_tets_free(&a), fm_tets_free(&b);
    }
}

/* The quality pass: median and counts over a known set (a regular tet, ratio sqrt(6)/4, and one
 * stretched along z). */
static void test_quality_figures(void)
{
    double v[36] = {1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1, 1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1,
                    1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1};
    for (int k = 0; k < 4; k++) v[12 + 3 * k + 2] *= 20.0;  /* a needle: ratio well above 4 */
    fm_tets t = {v, 3};
    fm_tet_quality q = fm_tets_quality(&t, 2.0);
    ENSURE(q.count == 3 && q.above == 1 && q.above_4 == 1);
    ENSURE_NEAR(q.median_ratio, sqrt(6.0) / 4.0, 1e-12);
    ENSURE(q.max_ratio > 4.0);
    fm_tets none = {NULL, 0};
    q = fm_tets_quality(&none, 2.0);
    ENSURE(q.count == 0 && q.max_ratio == 0 && isnan(q.median_ratio));
}

int main(void)
{
    RUN_TEST(test_counts_and_volume_across_ranges);
    RUN_TEST(test_smaller_n_is_an_error);
    RUN_TEST(test_scheme_volume_fractions);
    RUN_TEST(test_scheme_geometry);
    RUN_TEST(test_largest_tets_split_first);
    RUN_TEST(test_bisection_counts_and_volume);
    RUN_TEST(test_bisection_splits_the_largest);
    RUN_TEST(test_bisection_keeps_shapes);
    RUN_TEST(test_quality_figures);
    return test_result();
}
