/* FM eqs 7-8: obstacle avoidance by sliding along the obstacle's level sets.
 *   V_oa = (c / k_a) V_grn + (1 - c / k_a) D speed0      where c < k_a,  V_grn beyond,
 * D the unit projection of V_grn on the plane normal to grad d_t (any unit vector on that plane,
 * chosen deterministically, if the projection vanishes; we always add a small sideways nudge so
 * nearly head-on agents do not stall in concave corners).
 * Our reading: c = d_t - R_X, the clearance of the tet's bounding sphere, rather than the
 * centroid's d_t, so a tet in contact (c = 0) moves only tangentially and its body never enters
 * the obstacle; a tet that is already in (c < 0, e.g. pushed by MDE) is also moved back out along
 * grad d_t at up to speed0. */
#include "kernel_avoid.h"
#include "fm_internal.h" /* fm_splitmix64 */

#include <math.h>

/* Weight of the sideways nudge in D relative to |V_grn|: decides head-on cases (where the paper
 * allows any direction) and barely turns glancing ones. */
#define SIDE_BIAS 0.3f
/* Contact keeps tets this many voxels clear of the surface, above float round-off. */
#define CONTACT_MARGIN 0.02f

/* d_t refined where the grid is too coarse: the exact callback within exact_band of the surface;
 * g becomes the unit gradient. dg and g come from the grid at (x, y, z). */
static float refine_distance(const fm_obstacle_view *o, float x, float y, float z, float dg, float g[3])
{
    float d = dg;
    if (o->exact && fabsf(d) < o->exact_band) {
        double p[3] = {x, y, z}, n[3] = {0, 0, 0};
        d = (float)o->exact(o->exact_ctx, p, n);
        g[0] = (float)n[0], g[1] = (float)n[1], g[2] = (float)n[2];
    }
    float len = sqrtf(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if (len > 0) g[0] /= len, g[1] /= len, g[2] /= len;
    return d;
}

float fm_obstacle_distance(const fm_obstacle_view *o, float x, float y, float z, float g[3])
{
    return refine_distance(o, x, y, z, fm_sdf_sample(&o->sdf, x, y, z, g), g);
}

/* Can a tet of radius rx whose centroid is dg from the surface (the grid's value) come within rx of
 * it by moving `reach`? Not if dg - rx > 2 reach + 2 voxels: the trilinear field changes by at most
 * sqrt(3) per unit of distance, and the exact refinement differs from the grid by well under a
 * voxel. The look-ahead of eq 8 and the contact step are both skipped for such agents, which are
 * most of the flock. */
static int beyond_reach(const fm_obstacle_view *o, float dg, float rx, float reach)
{
    return dg - rx > 2 * reach + 2 * o->sdf.voxel;
}

/* A unit vector normal to the unit vector up: the axis least aligned with up, less its part along
 * up (for up = +Z, the x axis). */
static void horizontal(const float up[3], float out[3])
{
    int e = 0;
    for (int k = 1; k < 3; k++)
        if (fabsf(up[k]) < fabsf(up[e])) e = k;
    for (int k = 0; k < 3; k++) out[k] = (k == e) - up[e] * up[k];
    float len = sqrtf(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
    for (int k = 0; k < 3; k++) out[k] /= len;
}

/* A unit vector perpendicular to the unit vector g, the same for the same g: horizontal (g x up)
 * where possible, so flocks pass upright obstacles at the side rather than into the floor or a
 * concave corner, whichever axis the scene calls up; `flip` reverses it, so odd and even agents
 * go opposite ways round a head-on obstacle instead of piling up. */
static void any_perpendicular(const float g[3], const float up[3], int flip, float out[3])
{
    out[0] = g[1] * up[2] - g[2] * up[1], out[1] = g[2] * up[0] - g[0] * up[2], out[2] = g[0] * up[1] - g[1] * up[0];
    float len = sqrtf(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
    if (len < 1e-3f) horizontal(up, out), len = 1; /* g is vertical: any horizontal direction */
    float sign = flip ? -1.0f : 1.0f;
    for (int k = 0; k < 3; k++) out[k] *= sign / len;
}

/* Eq 7 at clearance c with unit gradient g: writes V_oa over vg in place. */
static void slide_velocity(const fm_obstacle_view *o, float c, float dt, const float g[3], int flip, float vg[3])
{
    if (c >= o->k_a) return;
    float w = c > 0 ? c / o->k_a : 0.0f, along = vg[0] * g[0] + vg[1] * g[1] + vg[2] * g[2];
    float speed = sqrtf(vg[0] * vg[0] + vg[1] * vg[1] + vg[2] * vg[2]), side[3];
    /* D: the projection of V_grn, nudged sideways so a nearly head-on agent does not stall */
    any_perpendicular(g, o->up, flip, side);
    float t[3];
    for (int k = 0; k < 3; k++) t[k] = vg[k] - along * g[k] + SIDE_BIAS * speed * side[k];
    float len = sqrtf(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    if (len > 1e-6f * (o->speed0 + 1e-30f)) t[0] /= len, t[1] /= len, t[2] /= len;
    else t[0] = side[0], t[1] = side[1], t[2] = side[2];
    float out = c < 0 ? fminf(-c / dt, o->speed0) : 0.0f; /* back out of the obstacle */
    for (int k = 0; k < 3; k++) vg[k] = w * vg[k] + (1 - w) * t[k] * o->speed0 + out * g[k];
}

static float radius_now(const fm_radius_view *r, int64_t a, double time)
{
    const int32_t i = r->id[a];
    double tau = time - (double)i / r->launch_rate;
    double s = r->shrink_time > 0 ? tau / r->shrink_time : 1.0;
    s = s < 0 ? 0 : s > 1 ? 1 : s;
    return r->rest[a] * (float)(1.0 - (1.0 - r->shrink) * s);
}

static float speed_of(const float v[3]) { return sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

/* Eq 8 for one agent whose grid distance dg and unit gradient g at its centroid are known; with
 * `skip_far`, the look-ahead is not sampled where it cannot reach the obstacle. Returns d_t - R_X. */
/* Which way round a head-on obstacle: half the agents one way, half the other, drawn again every
 * FLIP_STEPS steps, so an agent held in a concave corner tries the other side now and then. A hash
 * of (agent id, time), never of the store slot: the same wherever, and on whichever rank, the agent
 * is stored. */
enum { FLIP_STEPS = 16 };
static int side_flip(int32_t id, double time, float dt)
{
    uint64_t epoch = (uint64_t)llround(time / dt) / FLIP_STEPS, state = (uint64_t)(uint32_t)id << 32 ^ epoch;
    return (int)(fm_splitmix64(&state) >> 63);
}

static float avoid_agent(const fm_obstacle_view *o, const float *const p[3], float *const v[3], int64_t a, int32_t id,
                         double time, float rx, float dg, float g[3], float dt, int skip_far)
{
    float x = p[0][a], y = p[1][a], z = p[2][a], vg[3] = {v[0][a], v[1][a], v[2][a]};
    float d = refine_distance(o, x, y, z, dg, g);
    if (skip_far && beyond_reach(o, dg, rx, speed_of(vg) * dt)) return d - rx; /* eq 8's look-ahead cannot collide */
    float g_ahead[3];
    float d_ahead = fm_obstacle_distance(o, x + vg[0] * dt, y + vg[1] * dt, z + vg[2] * dt, g_ahead);
    if (!(d_ahead < rx)) return d - rx; /* eq 8, second case: V_syn */
    slide_velocity(o, d - rx, dt, g, side_flip(id, time, dt), vg); /* eq 8, first case: V_oa (eq 7) */
    v[0][a] = vg[0], v[1][a] = vg[1], v[2][a] = vg[2];
    return d - rx;
}

float fm_kernel_avoid(const fm_obstacle_view *o, const fm_radius_view *r, const float *const p[3],
                      float *const v[3], const uint8_t *phase, uint8_t phase_sel, int64_t begin,
                      int64_t end, double time, float dt, fm_obstacle_scratch sc)
{
    float clearance = INFINITY, g[3];
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        float rx = radius_now(r, a, time), dg = fm_sdf_sample(&o->sdf, p[0][a], p[1][a], p[2][a], g);
        sc.d_grid[a] = dg, sc.radius[a] = rx; /* for fm_kernel_contact */
        clearance = fminf(clearance, avoid_agent(o, p, v, a, r->id[a], time, rx, dg, g, dt, 1));
    }
    return clearance;
}

float fm_kernel_avoid_ref(const fm_obstacle_view *o, const fm_radius_view *r, const float *const p[3],
                          float *const v[3], const uint8_t *phase, uint8_t phase_sel, int64_t begin,
                          int64_t end, double time, float dt)
{
    float clearance = INFINITY, g[3];
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        float dg = fm_sdf_sample(&o->sdf, p[0][a], p[1][a], p[2][a], g);
        clearance = fminf(clearance, avoid_agent(o, p, v, a, r->id[a], time, radius_now(r, a, time), dg, g, dt, 0));
    }
    return clearance;
}

void fm_kernel_contact(const fm_obstacle_view *o, fm_obstacle_scratch sc, const float *const p[3],
                       float *const v[3], const uint8_t *phase, uint8_t phase_sel, int64_t begin,
                       int64_t end, float dt)
{
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != phase_sel) continue;
        float x = p[0][a], y = p[1][a], z = p[2][a], vv[3] = {v[0][a], v[1][a], v[2][a]}, g[3];
        float rx = sc.radius[a];
        if (beyond_reach(o, sc.d_grid[a], rx, speed_of(vv) * dt)) continue; /* far: cheap exit */
        /* Project the end point out along grad d_t; a few passes, since sliding into a concave
         * corner or past a thin feature meets another face. */
        float target = rx + CONTACT_MARGIN * o->sdf.voxel; /* a hair outside, against round-off */
        int inside = 1;
        for (int pass = 0; pass < 3 && inside; pass++) {
            float d_ahead = fm_obstacle_distance(o, x + vv[0] * dt, y + vv[1] * dt, z + vv[2] * dt, g);
            inside = d_ahead < target;
            float out = inside ? (target - d_ahead) / dt : 0.0f; /* however deep */
            for (int k = 0; k < 3; k++) vv[k] += out * g[k];
        }
        if (inside) { /* still not clear: slide along the surface where the agent stands ... */
            float gc[3], vt[3] = {v[0][a], v[1][a], v[2][a]};
            fm_obstacle_distance(o, x, y, z, gc);
            float into = vt[0] * gc[0] + vt[1] * gc[1] + vt[2] * gc[2];
            for (int k = 0; k < 3; k++) vv[k] = vt[k] - (into < 0 ? into : 0) * gc[k];
        }
        /* ... shortening the step if need be (the agent is clear where it stands), down to none */
        for (int halve = 0; halve < 8 && inside; halve++) {
            inside = fm_obstacle_distance(o, x + vv[0] * dt, y + vv[1] * dt, z + vv[2] * dt, g) < target;
            if (inside) vv[0] *= 0.5f, vv[1] *= 0.5f, vv[2] *= 0.5f;
        }
        if (inside) vv[0] = vv[1] = vv[2] = 0;
        v[0][a] = vv[0], v[1][a] = vv[1], v[2][a] = vv[2];
    }
}
