/* The path's key points and the launch/arrival orders D1 and D2 (FM eqs 3-4) on hand-made cases. */
#include "morph.h"
#include "test_macros.h"

#include <stdlib.h>
#include <string.h>

/* A tiny tet centred at (x, y, z). */
static void tet_at(double *v, double x, double y, double z)
{
    const double corners[12] = {0, 0, 0, 0.1, 0, 0, 0, 0.1, 0, 0, 0, 0.1};
    for (int i = 0; i < 12; i++) v[i] = corners[i] + (i % 3 == 0 ? x : i % 3 == 1 ? y : z) - 0.025;
}

static void test_key_points_from_cs_to_ct(void)
{
    fm_scene_def def = fm_default_scene_def();
    def.path_point_count = 1;
    def.path_points[0][0] = 5, def.path_points[0][1] = 5, def.path_points[0][2] = 0;
    def.path_key_points = 9;
    const double cs[3] = {0, 0, 0}, ct[3] = {10, 0, 0};
    fm_path path;
    fm_error err = {0};
    ENSURE(fm_path_build(&def, cs, ct, &path, &err) == FM_OK);
    ENSURE(path.count == 11);
    for (int k = 0; k < 3; k++) {
        ENSURE(path.q[k] == cs[k]);                          /* Q_0 = C_S exactly */
        ENSURE(path.q[3 * (path.count - 1) + k] == ct[k]);   /* Q_{m+1} = C_T exactly */
    }
    double first = -1; /* evenly spaced by arc length along the polyline */
    for (int i = 0; i + 1 < path.count; i++) {
        double d = sqrt(pow(path.q[3 * i + 3] - path.q[3 * i], 2) + pow(path.q[3 * i + 4] - path.q[3 * i + 1], 2));
        if (first < 0) first = d;
        ENSURE_NEAR(d, first, 1e-12);
    }
    ENSURE_NEAR(path.q[3 * 5], 5.0, 1e-12); /* the middle key point is the control point */
    ENSURE_NEAR(path.q[3 * 5 + 1], 5.0, 1e-12);
    fm_path_free(&path);
}

static void test_zero_length_path_is_an_error(void)
{
    fm_scene_def def = fm_default_scene_def();
    const double c[3] = {1, 2, 3};
    fm_path path = {0};
    fm_error err = {0};
    ENSURE(fm_path_build(&def, c, c, &path, &err) == FM_ERR_INPUT);
    ENSURE(strstr(err.message, "zero length") != NULL);
}

/* Straight path along +x from (0,0,0) to (10,0,0): D1 launches the front (largest x) first, D2
 * hands out the far side of the target (largest x) first; ties keep index order. */
static void test_d1_d2_hand_made(void)
{
    fm_scene_def def = fm_default_scene_def();
    def.path_key_points = 8;
    const double cs[3] = {0, 0, 0}, ct[3] = {10, 0, 0};
    fm_path path;
    fm_error err = {0};
    ENSURE(fm_path_build(&def, cs, ct, &path, &err) == FM_OK);
    const double xs[5] = {-0.5, 0.6, 0.1, 0.6, -0.2}; /* indices 1 and 3 tie */
    double v[60];
    for (int i = 0; i < 5; i++) tet_at(v + 12 * i, xs[i], 0.3 * i, 0);
    fm_tets tets = {v, 5};
    int64_t order[5];
    ENSURE(fm_order_d1(&tets, &path, order, &err) == FM_OK);
    const int64_t want1[5] = {1, 3, 2, 4, 0};
    for (int i = 0; i < 5; i++) ENSURE_MSG(order[i] == want1[i], "D1 position %d: %lld, want %lld", i, (long long)order[i], (long long)want1[i]);
    for (int i = 0; i < 5; i++) tet_at(v + 12 * i, 10 + xs[i], 0, 0.2 * i);
    ENSURE(fm_order_d2(&tets, &path, order, &err) == FM_OK);
    for (int i = 0; i < 5; i++) ENSURE_MSG(order[i] == want1[i], "D2 position %d: %lld, want %lld", i, (long long)order[i], (long long)want1[i]);
    fm_path_free(&path);
}

/* D1 uses the first path segment and D2 the last: on an L-shaped path they differ. */
static void test_orders_follow_their_own_segments(void)
{
    fm_scene_def def = fm_default_scene_def();
    def.path_point_count = 1;
    def.path_points[0][0] = 0, def.path_points[0][1] = 0, def.path_points[0][2] = 10; /* up, then across */
    def.path_key_points = 1;                                                          /* Q = C_S, corner, C_T */
    const double cs[3] = {0, 0, 0}, ct[3] = {10, 0, 10};
    fm_path path;
    fm_error err = {0};
    ENSURE(fm_path_build(&def, cs, ct, &path, &err) == FM_OK);
    double v[24];
    tet_at(v, 1, 0, 0), tet_at(v + 12, 0, 0, 1); /* tet 1 is higher: in front along +z */
    fm_tets tets = {v, 2};
    int64_t order[2];
    ENSURE(fm_order_d1(&tets, &path, order, &err) == FM_OK);
    ENSURE(order[0] == 1 && order[1] == 0);
    tet_at(v, 11, 0, 10), tet_at(v + 12, 10, 0, 11); /* tet 0 is farther along +x, the last segment */
    ENSURE(fm_order_d2(&tets, &path, order, &err) == FM_OK);
    ENSURE(order[0] == 0 && order[1] == 1);
    fm_path_free(&path);
}

int main(void)
{
    RUN_TEST(test_key_points_from_cs_to_ct);
    RUN_TEST(test_zero_length_path_is_an_error);
    RUN_TEST(test_d1_d2_hand_made);
    RUN_TEST(test_orders_follow_their_own_segments);
    return test_result();
}
