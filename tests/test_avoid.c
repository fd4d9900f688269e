/* Obstacle avoidance (FM eqs 7-8) on a hand-made signed distance grid of the plane x = 5
 * (d = x - 5, obstacle on the +x side... inside where d < 0, i.e. x < 5). */
#include "kernel_avoid.h"
#include "test_macros.h"

enum { NX = 40, NY = 4, NZ = 4 };
static float grid[NX * NY * NZ];

/* d = 5 - x: the obstacle fills x > 5; agents fly toward +x. Voxel 0.25 from the origin. */
static fm_obstacle_view plane_view(float k_a)
{
    for (int k = 0; k < NZ; k++)
        for (int j = 0; j < NY; j++)
            for (int i = 0; i < NX; i++) grid[i + NX * (j + NY * k)] = 5.0f - 0.25f * (float)i;
    fm_sdf_view sdf = {grid, {NX, NY, NZ}, {0, 0, 0}, 0.25f, 100.0f};
    return (fm_obstacle_view){sdf, k_a, 2.0f, NULL, NULL, 0.0f};
}

static const float zero_radius[4] = {0, 0, 0, 0};
static const int32_t identity_ids[4] = {0, 1, 2, 3};

static void test_outside_influence_keeps_v_grn(void)
{
    fm_obstacle_view o = plane_view(1.0f);
    fm_radius_view r = {zero_radius, identity_ids, 1.0f, 0.0f, 1.0};
    float x[1] = {2.0f}, y[1] = {0.4f}, z[1] = {0.4f}, vx[1] = {1.5f}, vy[1] = {0.5f}, vz[1] = {0};
    uint8_t phase[1] = {1};
    const float *p[3] = {x, y, z};
    float *v[3] = {vx, vy, vz};
    float c = fm_kernel_avoid(&o, &r, p, v, phase, 1, 0, 1, 0.0, 0.1f);
    ENSURE(vx[0] == 1.5f && vy[0] == 0.5f && vz[0] == 0); /* d = 3 > k_a: V_oa = V_grn */
    ENSURE_NEAR(c, 3.0, 1e-5);
}

static void test_on_the_surface_v_oa_is_tangent(void)
{
    fm_obstacle_view o = plane_view(1.0f);
    fm_radius_view r = {zero_radius, identity_ids, 1.0f, 0.0f, 1.0};
    float x[2] = {5.0f, 5.0f}, y[2] = {0.4f, 0.4f}, z[2] = {0.4f, 0.4f};
    float vx[2] = {1.5f, 2.0f}, vy[2] = {0.5f, 0}, vz[2] = {0, 0}; /* agent 1 hits head-on */
    uint8_t phase[2] = {1, 1};
    const float *p[3] = {x, y, z};
    float *v[3] = {vx, vy, vz};
    fm_kernel_avoid(&o, &r, p, v, phase, 1, 0, 2, 0.0, 0.1f);
    for (int a = 0; a < 2; a++) {
        ENSURE_NEAR(vx[a], 0.0, 1e-6);                                   /* no normal component */
        ENSURE_NEAR(sqrt(vy[a] * vy[a] + vz[a] * vz[a]), 2.0, 1e-5);     /* D * speed0 */
    }
    ENSURE(vy[0] > 0); /* D follows the tangential part of V_grn */
}

/* Halfway into the influence range: V_oa = 1/2 V_grn + 1/2 D speed0 (eq 7). */
static void test_eq7_blend(void)
{
    fm_obstacle_view o = plane_view(1.0f);
    fm_radius_view r = {zero_radius, identity_ids, 1.0f, 0.0f, 1.0};
    float x[1] = {4.5f}, y[1] = {0.4f}, z[1] = {0.4f}, vx[1] = {10.0f}, vy[1] = {0}, vz[1] = {1.0f};
    uint8_t phase[1] = {1};
    const float *p[3] = {x, y, z};
    float *v[3] = {vx, vy, vz};
    fm_kernel_avoid(&o, &r, p, v, phase, 1, 0, 1, 0.0, 0.1f); /* look-ahead: x + 1 is inside */
    ENSURE_NEAR(vx[0], 5.0, 1e-4);
    /* D is the tangential part (0, 0, 1) nudged sideways by the bias, normalised */
    ENSURE_NEAR(sqrt(vy[0] * vy[0] + (vz[0] - 0.5) * (vz[0] - 0.5)), 1.0, 1e-4);
}

static void test_no_look_ahead_collision_keeps_v_grn(void)
{
    fm_obstacle_view o = plane_view(1.0f);
    fm_radius_view r = {zero_radius, identity_ids, 1.0f, 0.0f, 1.0};
    float x[1] = {4.5f}, y[1] = {0.4f}, z[1] = {0.4f}, vx[1] = {-1.0f}, vy[1] = {0}, vz[1] = {0};
    uint8_t phase[1] = {1};
    const float *p[3] = {x, y, z};
    float *v[3] = {vx, vy, vz};
    fm_kernel_avoid(&o, &r, p, v, phase, 1, 0, 1, 0.0, 0.1f); /* moving away: eq 8's second case */
    ENSURE(vx[0] == -1.0f && vy[0] == 0 && vz[0] == 0);
}

/* Contact: a push straight into the obstacle is turned so the step ends at d = R_X. */
static void test_contact_stops_at_the_surface(void)
{
    fm_obstacle_view o = plane_view(1.0f);
    const float radius[1] = {0.2f};
    fm_radius_view r = {radius, identity_ids, 1.0f, 0.0f, 1.0};
    float x[1] = {4.6f}, y[1] = {0.4f}, z[1] = {0.4f}, vx[1] = {3.0f}, vy[1] = {1.0f}, vz[1] = {0};
    uint8_t phase[1] = {1};
    const float *p[3] = {x, y, z};
    float *v[3] = {vx, vy, vz};
    fm_kernel_contact(&o, &r, p, v, phase, 1, 0, 1, 0.0, 0.1f);
    float end = 5.0f - (x[0] + vx[0] * 0.1f);
    ENSURE_MSG(end >= 0.2f && end < 0.21f, "ends at clearance %g", end - 0.2f);
    ENSURE(vy[0] == 1.0f); /* the tangential part is kept */
}

int main(void)
{
    RUN_TEST(test_outside_influence_keeps_v_grn);
    RUN_TEST(test_on_the_surface_v_oa_is_tangent);
    RUN_TEST(test_eq7_blend);
    RUN_TEST(test_no_look_ahead_collision_keeps_v_grn);
    RUN_TEST(test_contact_stops_at_the_surface);
    return test_result();
}
