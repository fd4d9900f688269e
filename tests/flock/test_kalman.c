/* Kalman homing (SCF eq 9): an agent driven only by the homing force tracks a leader moving at
 * constant velocity; the tracking lag shrinks as R falls, vanishes in the steady state, and R -> 0
 * puts the agent on its leader. */
#include "flock_kalman.h"
#include "simd.h"
#include "test_macros.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { AGENTS = 3 };

typedef struct track_result {
    double mean_lag;   /* mean distance to the leader over the run */
    double final_lag;  /* distance at the end */
    double first_lag;  /* after the first step */
} track_result;

/* Agents start at rest where the leader starts; the leader flies at velocity u. Steps of dt with
 * the flock's integrator: p += v dt + a dt^2 / 2, v += a dt. */
static track_result track(double q, double r_pos, double r_vel, int steps)
{
    const double dt = 1.0 / 48, u[3] = {3, -1.5, 0.5}, start[3] = {1, 2, 3};
    fm_kalman kf;
    fm_kalman_init(&kf, dt, q, r_pos, r_vel);
    float px[AGENTS], py[AGENTS], pz[AGENTS], vx[AGENTS] = {0}, vy[AGENTS] = {0}, vz[AGENTS] = {0};
    float zx[AGENTS], zy[AGENTS], zz[AGENTS], wx[AGENTS], wy[AGENTS], wz[AGENTS];
    float ax[AGENTS], ay[AGENTS], az[AGENTS], weight[AGENTS] = {1, 1, 1};
    uint8_t phase[AGENTS] = {1, 1, 1};
    for (int a = 0; a < AGENTS; a++) px[a] = (float)start[0], py[a] = (float)start[1], pz[a] = (float)start[2];
    float *p[3] = {px, py, pz}, *v[3] = {vx, vy, vz}, *zp[3] = {zx, zy, zz}, *zv[3] = {wx, wy, wz}, *acc[3] = {ax, ay, az};
    track_result r = {0, 0, 0};
    for (int s = 0; s < steps; s++) {
        double t_end = (s + 1) * dt;
        for (int a = 0; a < AGENTS; a++)
            for (int k = 0; k < 3; k++) zp[k][a] = (float)(start[k] + u[k] * t_end), zv[k][a] = (float)u[k], acc[k][a] = 0;
        fm_kalman_advance(&kf);
        fm_kalman_homing(&kf, NULL, 0, AGENTS, phase, 1, (const float *const *)p, (const float *const *)v,
                         (const float *const *)zp, (const float *const *)zv, weight, NULL, (const float *const *)acc, acc);
        double lag = 0;
        for (int a = 0; a < AGENTS; a++) {
            double d2 = 0;
            for (int k = 0; k < 3; k++) {
                p[k][a] = (float)(p[k][a] + v[k][a] * dt + 0.5 * acc[k][a] * dt * dt);
                v[k][a] = (float)(v[k][a] + acc[k][a] * dt);
                d2 += (p[k][a] - zp[k][a]) * (double)(p[k][a] - zp[k][a]);
            }
            lag += sqrt(d2) / AGENTS;
        }
        r.mean_lag += lag / steps;
        r.final_lag = lag;
        if (s == 0) r.first_lag = lag;
    }
    return r;
}

static void test_lag_shrinks_as_r_falls(void)
{
    const double rs[4] = {10, 1, 0.1, 0.01};
    double previous = INFINITY;
    for (int i = 0; i < 4; i++) {
        track_result t = track(1.0, rs[i], rs[i], 96);
        ENSURE_MSG(t.mean_lag < previous, "R = %g: mean lag %g is not below %g", rs[i], t.mean_lag, previous);
        ENSURE_MSG(t.mean_lag > 0, "R = %g: no lag at all", rs[i]);
        printf("  R = %-5g mean lag over 2 s %.4f\n", rs[i], t.mean_lag);
        previous = t.mean_lag;
    }
    /* and a loose filter lags clearly: the leader covers 3.4 units/s */
    ENSURE(track(1.0, 10, 10, 96).mean_lag > 5 * track(1.0, 0.01, 0.01, 96).mean_lag);
}

/* Constant velocity is tracked without a steady-state error: the position and velocity measurements
 * together leave none. */
static void test_steady_state_has_no_lag(void)
{
    track_result t = track(1.0, 1.0, 1.0, 48 * 30);
    ENSURE_MSG(t.final_lag < 1e-3, "lag after 30 s: %g", t.final_lag);
}

/* R -> 0: the posterior is the leader's state, and eq 9 lands the agent on it in one step. */
static void test_tiny_r_puts_the_agent_on_its_leader(void)
{
    track_result t = track(1.0, 1e-9, 1e-9, 10);
    ENSURE_MSG(t.first_lag < 1e-4, "after one step: %g", t.first_lag);
    ENSURE_MSG(t.final_lag < 1e-4, "after ten steps: %g", t.final_lag);
}

/* The covariance stays symmetric positive definite and converges to the steady state (the
 * Riccati fixed point): the gain stops changing. */
static void test_covariance_converges(void)
{
    fm_kalman kf;
    fm_kalman_init(&kf, 1.0 / 48, 2.0, 0.5, 0.2);
    double k_prev = 0, change = 0;
    for (int s = 0; s < 5000; s++) {
        fm_kalman_advance(&kf);
        ENSURE(kf.p[0] > 0 && kf.p[2] > 0 && kf.p[0] * kf.p[2] - kf.p[1] * kf.p[1] > 0);
        change = fabs(kf.k[0] - k_prev);
        k_prev = kf.k[0];
    }
    ENSURE_MSG(change < 1e-12, "gain still changing by %g", change);
    ENSURE(kf.k[0] > 0 && kf.k[0] < 1 && kf.k[3] > 0 && kf.k[3] < 1);
    /* the first step of a fresh filter: P was 0, so the gain is small (Q over Q + R) */
    fm_kalman_init(&kf, 1.0 / 48, 2.0, 0.5, 0.2);
    fm_kalman_advance(&kf);
    ENSURE(kf.k[0] < 1e-4);
}

/* Only agents in the selected phase are touched, with their own weight. */
static void test_phase_and_weight(void)
{
    fm_kalman kf;
    fm_kalman_init(&kf, 0.1, 1, 1, 1);
    for (int s = 0; s < 100; s++) fm_kalman_advance(&kf);
    float zero[3] = {0, 0, 0}, one[3] = {1, 1, 1}, w[3] = {1, 0.5f, 1};
    float ax[3] = {0, 0, 7}, ay[3] = {0, 0, 7}, az[3] = {0, 0, 7};
    const float *p[3] = {zero, zero, zero}, *v[3] = {zero, zero, zero}, *zp[3] = {one, one, one}, *zv[3] = {zero, zero, zero};
    float *acc[3] = {ax, ay, az};
    uint8_t phase[3] = {1, 1, 2};
    fm_kalman_homing(&kf, NULL, 0, 3, phase, 1, p, v, zp, zv, w, NULL, (const float *const *)acc, acc);
    ENSURE(ax[0] > 0 && fabsf(ax[1] - 0.5f * ax[0]) <= 1e-6f * ax[0]);
    ENSURE(ax[2] == 7 && ay[2] == 7 && az[2] == 7);
    ENSURE_NEAR(ax[0], 2 * kf.k[0] / (0.1 * 0.1), 1e-3);
}

/* Per-agent filters (R over the run): with the scale 1 an agent's own filter is the shared one bit
 * for bit; a larger scale of R gives a smaller gain (a looser follower), and a zero-weight agent
 * still advances its covariance. */
static void test_own_filters(void)
{
    fm_kalman kf;
    fm_kalman_init(&kf, 1.0 / 48, 1, 0.2, 1);
    double own[9] = {0}, k[4];
    const float scale[3] = {1, 4, 1}, w[3] = {1, 1, 0};
    float zero[3] = {0, 0, 0}, one[3] = {1, 1, 1}, ax[3], ay[3], az[3];
    const float *p[3] = {zero, zero, zero}, *v[3] = {zero, zero, zero}, *zp[3] = {one, one, one}, *zv[3] = {zero, zero, zero};
    float *acc[3] = {ax, ay, az};
    uint8_t phase[3] = {1, 1, 1};
    const fm_kalman_agents agents = {own, scale};
    for (int s = 0; s < 200; s++) {
        fm_kalman_advance(&kf);
        memset(ax, 0, sizeof ax), memset(ay, 0, sizeof ay), memset(az, 0, sizeof az);
        fm_kalman_homing(&kf, &agents, 0, 3, phase, 1, p, v, zp, zv, w, NULL, (const float *const *)acc, acc);
        ENSURE(memcmp(own, kf.p, sizeof kf.p) == 0);     /* agent 0, scale 1 */
        ENSURE(memcmp(own + 6, kf.p, sizeof kf.p) == 0); /* agent 2: weight 0, same covariance */
    }
    ENSURE_NEAR(ax[0], 2 * kf.k[0] / (kf.dt * kf.dt), 1e-6 * ax[0]);
    ENSURE_MSG(ax[1] < 0.98 * ax[0], "R x 4 pulls %g against %g", ax[1], ax[0]);
    ENSURE(ax[2] == 0);
    double p4[3] = {0, 0, 0};
    for (int s = 0; s < 200; s++) fm_kalman_covariance_step(&kf, 4, p4, k);
    ENSURE(memcmp(p4, own + 3, sizeof p4) == 0);
}

/* R's scale loosens the hold on the position, not on the velocity (the shape flock's default R over
 * the distance: far from its destination an agent keeps its leader's velocity while the boids move
 * it about), unless scale_velocity asks for both. */
static void test_scale_loosens_the_position_only(void)
{
    fm_kalman kf;
    fm_kalman_init(&kf, 1.0 / 48, 1, 1, 1);
    double tight[3] = {0, 0, 0}, loose[3] = {0, 0, 0}, both[3] = {0, 0, 0}, kt[4], kl[4], kb[4];
    for (int s = 0; s < 2000; s++) {
        fm_kalman_covariance_step(&kf, 1, tight, kt);
        fm_kalman_covariance_step(&kf, 30, loose, kl);
        kf.scale_velocity = 1;
        fm_kalman_covariance_step(&kf, 30, both, kb);
        kf.scale_velocity = 0;
    }
    printf("  steady gains x 2/dt^2: scale 1 %.1f %.1f, 30 on the position %.1f %.1f, on both %.1f %.1f\n",
           kt[0] * 4608, kt[1] * 4608, kl[0] * 4608, kl[1] * 4608, kb[0] * 4608, kb[1] * 4608);
    ENSURE_MSG(kl[0] < 0.3 * kt[0], "position gain %g against %g", kl[0], kt[0]);
    ENSURE_MSG(fabs(kl[1] - kt[1]) < 0.2 * kt[1], "velocity gain %g against %g", kl[1], kt[1]);
    ENSURE_MSG(kb[1] < 0.8 * kt[1], "with scale_velocity the velocity gain %g against %g", kb[1], kt[1]);
}

/* The homing in SIMD lanes (kernel_kalman.h) gives the scalar code's bits at every level: shared
 * and own filters (R scaled on the position, and on both), agents not under forces untouched (their
 * covariance too), some bounded by MaxForce, h written over u, a range that is not whole groups. */
static void test_lanes_match_scalar(void)
{
    enum { N = 1003, FIRST = 2 };
    uint64_t seed = 11;
    float *st[5][3], *w = malloc(sizeof(float) * N), *m = malloc(sizeof(float) * N), *scale = malloc(sizeof(float) * N);
    float *h_want[3], *h_got[3];
    double *cov0 = malloc(sizeof(double) * 3 * N), *want = malloc(sizeof(double) * 3 * N), *got = malloc(sizeof(double) * 3 * N);
    uint8_t *phase = malloc(N);
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 3; k++) st[i][k] = malloc(sizeof(float) * N); /* p, v, z_p, z_v, u */
    for (int k = 0; k < 3; k++) h_want[k] = malloc(sizeof(float) * N), h_got[k] = malloc(sizeof(float) * N);
    for (int a = 0; a < N; a++) {
        for (int i = 0; i < 5; i++)
            for (int k = 0; k < 3; k++) st[i][k][a] = (float)(40 * test_uniform(&seed) - 20);
        w[a] = (float)test_uniform(&seed), m[a] = (float)(100 * test_uniform(&seed)), scale[a] = (float)(1 + 30 * test_uniform(&seed));
        for (int c = 0; c < 3; c++) cov0[3 * a + c] = c == 1 ? 0.01 * test_uniform(&seed) : 0.2 * test_uniform(&seed);
        phase[a] = a % 7 == 3 ? 2 : 1;
    }
    fm_kalman kf;
    fm_kalman_init(&kf, 1.0 / 48, 1.5, 0.3, 0.7);
    fm_kalman_advance(&kf);
    const fm_simd best = fm_simd_set_level(FM_SIMD_BEST);
    for (int variant = 0; variant < 4; variant++) { /* shared; own; own scaling both; shared unbounded */
        kf.scale_velocity = variant == 2;
        const fm_kalman_agents own = {NULL, scale};
        const float *bound = variant == 3 ? NULL : m;
        for (int level = FM_SIMD_SCALAR; level <= (int)best; level++) {
            fm_simd_set_level((fm_simd)level);
            double *cov = level == FM_SIMD_SCALAR ? want : got;
            float **h = level == FM_SIMD_SCALAR ? h_want : h_got;
            memcpy(cov, cov0, sizeof(double) * 3 * N);
            for (int k = 0; k < 3; k++) memcpy(h[k], st[4][k], sizeof(float) * N); /* h over u */
            const fm_kalman_agents mine = {cov, own.r_scale};
            fm_kalman_homing(&kf, variant == 1 || variant == 2 ? &mine : NULL, FIRST, N, phase, 1, (const float *const *)st[0],
                             (const float *const *)st[1], (const float *const *)st[2], (const float *const *)st[3], w, bound,
                             (const float *const *)h, h);
            if (level == FM_SIMD_SCALAR) continue;
            ENSURE_MSG(memcmp(cov, want, sizeof(double) * 3 * N) == 0, "variant %d, level %s: covariances differ", variant,
                       fm_simd_name((fm_simd)level));
            for (int k = 0; k < 3; k++)
                ENSURE_MSG(memcmp(h_got[k], h_want[k], sizeof(float) * N) == 0, "variant %d, level %s: homing differs", variant,
                           fm_simd_name((fm_simd)level));
        }
    }
    fm_simd_set_level(best);
    int bounded = 0, untouched = 1;
    for (int a = 0; a < N; a++)
        if (phase[a] != 1 || a < FIRST) untouched &= h_want[0][a] == st[4][0][a] && memcmp(want + 3 * a, cov0 + 3 * a, 24) == 0;
    fm_kalman_homing(&kf, NULL, FIRST, N, phase, 1, (const float *const *)st[0], (const float *const *)st[1],
                     (const float *const *)st[2], (const float *const *)st[3], w, m, (const float *const *)st[4], h_got);
    for (int a = FIRST; a < N; a++) bounded += phase[a] == 1 && sqrtf(h_got[0][a] * h_got[0][a] + h_got[1][a] * h_got[1][a] +
                                                                      h_got[2][a] * h_got[2][a]) > 0.999f * m[a];
    printf("  %d of %d agents at MaxForce\n", bounded, N);
    ENSURE(untouched);
    ENSURE_MSG(bounded > N / 10 && bounded < N - N / 5, "%d agents bounded: the test does not reach both sides", bounded);
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 3; k++) free(st[i][k]);
    for (int k = 0; k < 3; k++) free(h_want[k]), free(h_got[k]);
    free(w), free(m), free(scale), free(cov0), free(want), free(got), free(phase);
}

int main(void)
{
    RUN_TEST(test_lag_shrinks_as_r_falls);
    RUN_TEST(test_steady_state_has_no_lag);
    RUN_TEST(test_tiny_r_puts_the_agent_on_its_leader);
    RUN_TEST(test_covariance_converges);
    RUN_TEST(test_phase_and_weight);
    RUN_TEST(test_own_filters);
    RUN_TEST(test_scale_loosens_the_position_only);
    RUN_TEST(test_lanes_match_scalar);
    return test_result();
}
