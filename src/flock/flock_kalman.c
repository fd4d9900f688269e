/* Per-agent Kalman homing (SCF eq 9); see flock_kalman.h. */
#include "flock_kalman.h"
#include "kernel_kalman.h"

#include <math.h>

void fm_kalman_init(fm_kalman *kf, double dt, double q, double r_pos, double r_vel)
{
    *kf = (fm_kalman){.dt = dt, .q = q, .r_pos = r_pos, .r_vel = r_vel};
}

void fm_kalman_advance(fm_kalman *kf)
{
    fm_kalman_covariance_step(kf, 1.0, kf->p, kf->k);
}

void fm_kalman_covariance_step(const fm_kalman *kf, double r_scale, double p[3], double k[4])
{
    const double dt = kf->dt, a = p[0], b = p[1], c = p[2];
    /* P- = A P A^T + Q */
    const double pa = a + 2 * b * dt + c * dt * dt + kf->q * dt * dt * dt / 3;
    const double pb = b + c * dt + kf->q * dt * dt / 2;
    const double pc = c + kf->q * dt;
    /* K = P- S^-1, S = P- + R; the scale loosens the position only unless told otherwise, so the
     * agent keeps its leader's velocity however loosely it holds its place (docs/shape-flock.md,
     * "R over the flight") */
    const double sa = pa + kf->r_pos * r_scale, sc = pc + kf->r_vel * (kf->scale_velocity ? r_scale : 1.0);
    const double det = sa * sc - pb * pb;
    const double ia = sc / det, ib = -pb / det, ic = sa / det;
    k[0] = pa * ia + pb * ib, k[1] = pa * ib + pb * ic;
    k[2] = pb * ia + pc * ib, k[3] = pb * ib + pc * ic;
    /* P+ = (I - K) P-, symmetrised against rounding */
    const double na = (1 - k[0]) * pa - k[1] * pb;
    const double nb = 0.5 * (((1 - k[0]) * pb - k[1] * pc) + (-k[2] * pa + (1 - k[3]) * pb));
    const double nc = -k[2] * pb + (1 - k[3]) * pc;
    p[0] = na, p[1] = nb, p[2] = nc;
}

void fm_kalman_homing(const fm_kalman *kf, const fm_kalman_agents *own, int64_t begin, int64_t end, const uint8_t *phase,
                      uint8_t phase_sel, const float *const p[3], const float *const v[3],
                      const float *const z_p[3], const float *const z_v[3], const float *weight,
                      const float *max_accel, const float *const u[3], float *const h[3])
{
    const double dt = kf->dt, gain = 2.0 / (dt * dt);
    double k_pp = kf->k[0], k_pv = kf->k[1];
    /* whole groups of agents in SIMD lanes (the same bits), the rest here */
    const fm_kalman_lanes lanes = {dt, gain, kf->q * dt * dt * dt / 3, kf->q * dt * dt / 2, kf->q * dt, kf->r_pos,
                                   kf->r_vel, kf->scale_velocity, k_pp, k_pv, own ? own->p : NULL,
                                   own ? own->r_scale : NULL};
    for (int64_t a = fm_kernel_kalman_homing(&lanes, begin, end, phase, phase_sel, p, v, z_p, z_v, weight, max_accel, u, h);
         a < end; a++) {
        if (phase[a] != phase_sel) continue;
        if (own) {
            double k[4];
            fm_kalman_covariance_step(kf, own->r_scale[a], own->p + 3 * a, k);
            k_pp = k[0], k_pv = k[1];
        }
        double f[3], f2 = 0;
        for (int k = 0; k < 3; k++) {
            const double e_p = (double)z_p[k][a] - ((double)p[k][a] + (double)v[k][a] * dt); /* z - x- */
            const double e_v = (double)z_v[k][a] - ((double)v[k][a] + (double)u[k][a] * dt);
            /* Pos+ - (Pos + Vel dt) = k_pp e_p + k_pv e_v, so eq 9 gives F_h / m = 2 (...) / dt^2 */
            f[k] = weight[a] * gain * (k_pp * e_p + k_pv * e_v);
            f2 += f[k] * f[k];
        }
        /* |w F_h| <= MaxForce, truncated as Reynolds truncates the steering force: the weight softens
         * the pull toward a near leader, and an agent far from its leader still gets the whole of it */
        const double scale = max_accel && f2 > (double)max_accel[a] * max_accel[a] ? max_accel[a] / sqrt(f2) : 1.0;
        for (int k = 0; k < 3; k++) h[k][a] = (float)(scale * f[k]);
    }
}
