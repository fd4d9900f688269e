/* Subdivision to n tets (FM eqs 1-2): counts, exact volume, orientation, the three schemes. */
#include "geom.h"
#include "test_macros.h"

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

int main(void)
{
    RUN_TEST(test_counts_and_volume_across_ranges);
    RUN_TEST(test_smaller_n_is_an_error);
    RUN_TEST(test_scheme_volume_fractions);
    RUN_TEST(test_scheme_geometry);
    RUN_TEST(test_largest_tets_split_first);
    return test_result();
}
