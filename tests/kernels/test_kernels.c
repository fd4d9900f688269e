/* The step kernels on hand-made inputs: eq 3's nearest-key-point direction, the phase switch at
 * the bounding sphere, and eq 9's closed-form straight flight. */
#include "kernels.h"
#include "test_macros.h"

#include <math.h>

/* Key points on an L: (0,0,0) -> (10,0,0) -> (10,10,0); f_i points to the next key point. */
static const float QX[3] = {0, 10, 10}, QY[3] = {0, 0, 10}, QZ[3] = {0, 0, 0};
static const float FX[3] = {1, 0, 0}, FY[3] = {0, 1, 0}, FZ[3] = {0, 0, 0};

static void test_global_velocity_follows_nearest_key_point(void)
{
    const fm_path_view path = {{QX, QY, QZ}, {FX, FY, FZ}, 3, 0, 0};
    float x[5] = {1, 9, 11, 12, 3}, y[5] = {1, 1, 2, 13, 0}, z[5] = {0, 0, 0, 0, 5};
    float vx[5] = {7, 7, 7, 7, 7}, vy[5] = {7, 7, 7, 7, 7}, vz[5] = {7, 7, 7, 7, 7};
    uint8_t phase[5] = {1, 1, 1, 1, 0}; /* the last agent is waiting: untouched */
    const float *p[3] = {x, y, z};
    float *v[3] = {vx, vy, vz};
    fm_kernel_global_velocity(&path, p, phase, 0, 5, 2.0f, v);
    ENSURE(vx[0] == 2 && vy[0] == 0 && vz[0] == 0); /* nearest Q_0: along f_0 = +x */
    ENSURE(vx[1] == 0 && vy[1] == 2);               /* nearest Q_1: along f_1 = +y */
    ENSURE(vx[2] == 0 && vy[2] == 2);
    /* nearest the last key point (10, 10, 0): straight for it, at full speed */
    ENSURE_NEAR(vx[3], -2 * 2 / sqrt(2 * 2 + 3 * 3), 1e-6);
    ENSURE_NEAR(vy[3], -2 * 3 / sqrt(2 * 2 + 3 * 3), 1e-6);
    ENSURE(vx[4] == 7 && vy[4] == 7 && vz[4] == 7);
}

static void test_integrate_flags_sphere_entry(void)
{
    float x[3] = {0, 0, 5}, y[3] = {0, 0, 0}, z[3] = {0, 0, 0};
    float vx[3] = {10, 10, 10}, vy[3] = {0}, vz[3] = {0};
    uint8_t phase[3] = {1, 2, 1}, entered[3] = {9, 9, 9};
    float *p[3] = {x, y, z};
    const float *v[3] = {vx, vy, vz};
    fm_sphere_view sphere = {{3, 0, 0}, 1.5f};
    int64_t n = fm_kernel_integrate_flying(p, v, phase, 0, 3, 0.25f, sphere, NULL, 0, entered);
    ENSURE(x[0] == 2.5f && entered[0] == 1);  /* moved to 2.5: inside */
    ENSURE(x[1] == 0 && entered[1] == 0);     /* phase 2: not integrated here */
    ENSURE(x[2] == 7.5f && entered[2] == 0);  /* moved to 7.5: outside */
    ENSURE(n == 1);
}

static void test_homing_closed_form_and_arrival(void)
{
    float x[2] = {0, 0}, y[2] = {0, 0}, z[2] = {0, 0}, vx[2], vy[2], vz[2];
    float p2x[2] = {0, 4}, p2y[2] = {0, 0}, p2z[2] = {0, 0}, t2[2] = {1, 1}, tf[2] = {2, 0.5f};
    float cx[2] = {8, 5}, cy[2] = {0, 0}, cz[2] = {6, 0};
    int64_t target[2] = {0, 1};
    uint8_t phase[2] = {2, 2};
    float *p[3] = {x, y, z}, *v[3] = {vx, vy, vz};
    const float *tc[3] = {cx, cy, cz}, *p2[3] = {p2x, p2y, p2z};
    int64_t arrived = fm_kernel_homing(p, v, phase, target, tc, p2, t2, tf, 0, 2, 2.0, 0.0);
    ENSURE(arrived == 1);
    ENSURE_NEAR(x[0], 4, 1e-6); /* halfway at t = t2 + tf/2 */
    ENSURE_NEAR(z[0], 3, 1e-6);
    ENSURE_NEAR(vx[0], 4, 1e-6); /* (P' - P)/tf: speed |(8, 0, 6)|/2 = 5 */
    ENSURE(phase[0] == 2);
    ENSURE(x[1] == 5 && phase[1] == 3); /* past tf: exactly at the target, arrived */
}

/* The switch blend (issue 38): the agent leaves the switch point with its phase-1 velocity, turns
 * without a jump in velocity, flies straight from T_b on and lands exactly on its target at t2 + tf,
 * as the hard switch does. A 120-degree turn, stepped at 1/48 s. */
static void test_homing_blend_lands_on_target(void)
{
    const double dt = 1.0 / 48, blend = 0.25, t2v = 1.0;
    const float v1[3] = {-5.0f, 8.660254f, 0.0f}; /* speed 10, 120 degrees from V_2 = (10, 0, 0) */
    float x[2] = {2, 2}, y[2] = {0, 0}, z[2] = {0, 0}, vx[2], vy[2], vz[2];
    float p2x[2] = {2, 2}, p2y[2] = {0, 0}, p2z[2] = {0, 0}, t2[2] = {1, 1}, tf[2] = {1, 1};
    float cx[2] = {12, 12}, cy[2] = {0, 0}, cz[2] = {0, 0};
    int64_t target[2] = {0, 1};
    uint8_t phase[2] = {2, 2};
    float *p[3] = {x, y, z}, *v[3] = {vx, vy, vz};
    const float *tc[3] = {cx, cy, cz}, *p2[3] = {p2x, p2y, p2z};
    for (int k = 0; k < 3; k++) v[k][0] = v[k][1] = v1[k];
    /* V_e = (P' - P - T_b V_1 / 2) / (t_f - T_b / 2) */
    const double ve[2] = {(10 + 0.125 * 5) / 0.875, -0.125 * 8.660254 / 0.875};
    double last[3] = {2, 0, 0}, last_v[3] = {v1[0], v1[1], v1[2]};
    int arrived_at = -1, hard_at = -1;
    for (int i = 1; i <= 48 && arrived_at < 0; i++) {
        const double t = t2v + i * dt;
        /* agent 0 blends; agent 1 is the hard switch (blend 0) */
        int64_t n0 = fm_kernel_homing(p, v, phase, target, tc, p2, t2, tf, 0, 1, t, blend);
        if (fm_kernel_homing(p, v, phase, target, tc, p2, t2, tf, 1, 2, t, 0.0)) hard_at = i;
        double vel[3] = {(x[0] - last[0]) / dt, (y[0] - last[1]) / dt, (z[0] - last[2]) / dt};
        /* the velocity changes by at most |V_e - V_1| max h' dt / T_b = 19.8 * 1.5 / 12 = 2.5 a step,
         * and by little in the first: no kink (the hard switch jumps by |V_2 - V_1| = 17.3 at once) */
        double dv = sqrt((vel[0] - last_v[0]) * (vel[0] - last_v[0]) + (vel[1] - last_v[1]) * (vel[1] - last_v[1]));
        ENSURE(dv < (i == 1 ? 0.5 : 2.6));
        ENSURE(n0 || (vx[0] == v1[0] && vy[0] == v1[1])); /* v keeps V_1 until arrival */
        if (i * dt < blend - 1e-9) {
            ENSURE(y[0] > 0); /* still carried off the line by V_1 */
        } else if (!n0 && (i - 1) * dt > blend + 1e-9) {
            ENSURE_NEAR(vel[0], ve[0], 1e-3); /* straight at V_e */
            ENSURE_NEAR(vel[1], ve[1], 1e-3);
        }
        for (int k = 0; k < 3; k++) last_v[k] = vel[k];
        last[0] = x[0], last[1] = y[0], last[2] = z[0];
        if (n0) arrived_at = i;
    }
    ENSURE(arrived_at == 48 && hard_at == 48); /* t2 + tf, as eq 9 */
    ENSURE(x[0] == 12 && y[0] == 0 && z[0] == 0 && phase[0] == 3 && phase[1] == 3);
}

/* The blend with t_f shorter than the blend time: it takes the whole flight and still lands. */
static void test_homing_blend_shorter_than_flight(void)
{
    float x[1] = {0}, y[1] = {0}, z[1] = {0}, vx[1] = {0}, vy[1] = {10}, vz[1] = {0};
    float p2x[1] = {0}, p2y[1] = {0}, p2z[1] = {0}, t2[1] = {0}, tf[1] = {0.125f};
    float cx[1] = {1}, cy[1] = {0}, cz[1] = {0};
    int64_t target[1] = {0};
    uint8_t phase[1] = {2};
    float *p[3] = {x, y, z}, *v[3] = {vx, vy, vz};
    const float *tc[3] = {cx, cy, cz}, *p2[3] = {p2x, p2y, p2z};
    ENSURE(fm_kernel_homing(p, v, phase, target, tc, p2, t2, tf, 0, 1, 0.0625, 0.25) == 0);
    ENSURE(y[0] > 0 && x[0] > 0 && x[0] < 1);
    ENSURE(fm_kernel_homing(p, v, phase, target, tc, p2, t2, tf, 0, 1, 0.125, 0.25) == 1);
    ENSURE(x[0] == 1 && y[0] == 0 && phase[0] == 3);
}

/* Steered phase 2 with the blend: the velocity turns linearly from V_1 to the aim over the blend. */
static void test_steered_homing_blend(void)
{
    float x[1] = {0}, y[1] = {0}, z[1] = {0}, vx[1] = {0}, vy[1] = {-10}, vz[1] = {0};
    float cx[1] = {100}, cy[1] = {0}, cz[1] = {0};
    const float t2[1] = {1.0f};
    int64_t target[1] = {0};
    uint8_t phase[1] = {2};
    float *p[3] = {x, y, z}, *v[3] = {vx, vy, vz};
    const float *tc[3] = {cx, cy, cz};
    fm_kernel_homing_aim((const float *const *)p, v, phase, target, tc, t2, 0, 1, 10.0f, 1.0, 0.25f, 1.0);
    ENSURE_NEAR(vx[0], 2.5, 1e-5); /* a quarter of the way from (0, -10) to (10, 0) */
    ENSURE_NEAR(vy[0], -7.5, 1e-5);
    fm_kernel_homing_aim((const float *const *)p, v, phase, target, tc, t2, 0, 1, 10.0f, 1.75, 0.25f, 1.0);
    ENSURE(vx[0] == 10 && vy[0] == 0); /* the last step of the blend: the aim */
}

/* FM §5.1 path width: inside the width nothing changes; outside, a pull toward the path
 * proportional to the excess distance. */
static void test_path_width_attraction(void)
{
    const fm_path_view path = {{QX, QY, QZ}, {FX, FY, FZ}, 3, 1.0f, 2.0f}; /* width 2, attraction 2/s */
    float x[2] = {3, 3}, y[2] = {0.5f, -4}, z[2] = {0, 0}, vx[2], vy[2], vz[2];
    uint8_t phase[2] = {1, 1};
    const float *p[3] = {x, y, z};
    float *v[3] = {vx, vy, vz};
    fm_kernel_global_velocity(&path, p, phase, 0, 2, 1.0f, v);
    ENSURE(vx[0] == 1 && vy[0] == 0);          /* within the width: eq 3 only */
    ENSURE(vx[1] == 1);
    ENSURE_NEAR(vy[1], 2.0 * (4 - 1), 1e-5);   /* 3 units outside: pulled toward y = 0 at 6/s */
}

/* A one-voxel-per-unit SDF of the plane x = 5 (d = x - 5): the distance switch fires below the
 * threshold instead of at the sphere. */
static void test_distance_switch(void)
{
    float d[8 * 2 * 2];
    for (int k = 0; k < 2; k++)
        for (int j = 0; j < 2; j++)
            for (int i = 0; i < 8; i++) d[i + 8 * (j + 2 * k)] = (float)i - 5;
    fm_sdf_view sdf = {d, {8, 2, 2}, {0, 0, 0}, 1.0f, 100.0f};
    float x[2] = {3.6f, 4.5f}, y[2] = {0.5f, 0.5f}, z[2] = {0.5f, 0.5f}, vx[2] = {0, 0}, vy[2] = {0}, vz[2] = {0};
    uint8_t phase[2] = {1, 1}, entered[2];
    float *p[3] = {x, y, z};
    const float *v[3] = {vx, vy, vz};
    fm_sphere_view far_sphere = {{100, 100, 100}, 1};
    int64_t n = fm_kernel_integrate_flying(p, v, phase, 0, 2, 0.1f, far_sphere, &sdf, -1.0f, entered);
    ENSURE(n == 1 && entered[0] == 1 && entered[1] == 0); /* d = -1.4 < -1 enters; d = -0.5 does not */
}

/* Steered phase 2: aimed at the target at speed0; arrives when within one step. */
static void test_steered_homing(void)
{
    float x[1] = {0}, y[1] = {0}, z[1] = {0}, vx[1], vy[1], vz[1];
    float cx[1] = {3}, cy[1] = {4}, cz[1] = {0};
    int64_t target[1] = {0};
    uint8_t phase[1] = {2};
    float *p[3] = {x, y, z}, *v[3] = {vx, vy, vz};
    const float *tc[3] = {cx, cy, cz};
    const float t2[1] = {0};
    fm_kernel_homing_aim((const float *const *)p, v, phase, target, tc, t2, 0, 1, 10.0f, 0.0, 0.25f, 0.0);
    ENSURE_NEAR(vx[0], 6, 1e-5);
    ENSURE_NEAR(vy[0], 8, 1e-5);
    ENSURE(fm_kernel_homing_steered(p, (const float *const *)v, phase, target, tc, 0, 1, 0.25f) == 0);
    ENSURE_NEAR(x[0], 1.5, 1e-5); /* moved 2.5 of the 5 units */
    ENSURE(fm_kernel_homing_steered(p, (const float *const *)v, phase, target, tc, 0, 1, 0.25f) == 1);
    ENSURE(x[0] == 3 && y[0] == 4 && phase[0] == 3);
}

int main(void)
{
    RUN_TEST(test_global_velocity_follows_nearest_key_point);
    RUN_TEST(test_integrate_flags_sphere_entry);
    RUN_TEST(test_homing_closed_form_and_arrival);
    RUN_TEST(test_homing_blend_lands_on_target);
    RUN_TEST(test_homing_blend_shorter_than_flight);
    RUN_TEST(test_steered_homing_blend);
    RUN_TEST(test_path_width_attraction);
    RUN_TEST(test_distance_switch);
    RUN_TEST(test_steered_homing);
    return test_result();
}
