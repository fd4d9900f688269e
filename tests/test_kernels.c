/* The step kernels on hand-made inputs: eq 3's nearest-key-point direction, the phase switch at
 * the bounding sphere, and eq 9's closed-form straight flight. */
#include "kernels.h"
#include "test_macros.h"

/* Key points on an L: (0,0,0) -> (10,0,0) -> (10,10,0); f_i points to the next key point. */
static const float QX[3] = {0, 10, 10}, QY[3] = {0, 0, 10}, QZ[3] = {0, 0, 0};
static const float FX[3] = {1, 0, 0}, FY[3] = {0, 1, 0}, FZ[3] = {0, 0, 0};

static void test_global_velocity_follows_nearest_key_point(void)
{
    const fm_path_view path = {{QX, QY, QZ}, {FX, FY, FZ}, 3};
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
    int64_t n = fm_kernel_integrate_flying(p, v, phase, 0, 3, 0.25f, sphere, entered);
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
    int64_t arrived = fm_kernel_homing(p, v, phase, target, tc, p2, t2, tf, 0, 2, 2.0);
    ENSURE(arrived == 1);
    ENSURE_NEAR(x[0], 4, 1e-6); /* halfway at t = t2 + tf/2 */
    ENSURE_NEAR(z[0], 3, 1e-6);
    ENSURE_NEAR(vx[0], 4, 1e-6); /* (P' - P)/tf: speed |(8, 0, 6)|/2 = 5 */
    ENSURE(phase[0] == 2);
    ENSURE(x[1] == 5 && phase[1] == 3); /* past tf: exactly at the target, arrived */
}

int main(void)
{
    RUN_TEST(test_global_velocity_follows_nearest_key_point);
    RUN_TEST(test_integrate_flags_sphere_entry);
    RUN_TEST(test_homing_closed_form_and_arrival);
    return test_result();
}
