/* The global detour's per-agent part (kernel_detour.h; issue 38). */
#include "kernel_detour.h"
#include "kernel_path.h"

#include <math.h>
#include <stddef.h>

void fm_kernel_detour_velocity(const fm_detour_view *dv, const float *const p[3], const uint8_t *phase,
                               fm_detour_store st, int64_t begin, int64_t end, float *const v[3])
{
    for (int64_t a = begin; a < end; a++) {
        if (!st.on[a] || phase[a] != FM_KERNEL_FLYING) continue;
        const float x = p[0][a], y = p[1][a], z = p[2][a];
        float grad[3], out[3], dir[3];
        fm_sdf_sample(&dv->u, x, y, z, grad);
        const float d = fm_sdf_sample(&dv->d, x, y, z, out), w = d < dv->near ? 1 - fmaxf(d, 0) / dv->near : 0;
        const float lu = sqrtf(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2]);
        const float lo = sqrtf(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
        for (int k = 0; k < 3; k++) dir[k] = (lu > 1e-6f ? -grad[k] / lu : 0) + (lo > 1e-6f ? w * out[k] / lo : 0);
        const float len = sqrtf(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        if (!(len > 1e-6f)) continue; /* outside the grid, or a ridge: eq 3 as it is */
        const float s = dv->speed / len;
        v[0][a] = s * dir[0], v[1][a] = s * dir[1], v[2][a] = s * dir[2];
    }
}

/* Does eq 3 at (x, y, z) lead the way the navigation function does (within 45 degrees)? Then a tet
 * back on the path may follow it again; where the path runs into an obstacle it does not. */
static int path_agrees(const fm_detour_view *dv, const fm_path_view *path, float x, float y, float z)
{
    float grad[3], f[3];
    fm_sdf_sample(&dv->u, x, y, z, grad);
    const int32_t i = path_nearest_key(path, x, y, z), last = path->count - 1;
    if (i == last) f[0] = path->q[0][last] - x, f[1] = path->q[1][last] - y, f[2] = path->q[2][last] - z;
    else f[0] = path->f[0][i], f[1] = path->f[1][i], f[2] = path->f[2][i];
    const float dot = -(grad[0] * f[0] + grad[1] * f[1] + grad[2] * f[2]);
    const float g2 = grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2], f2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
    return dot > 0 && dot * dot > 0.5f * g2 * f2;
}

int64_t fm_kernel_detour_track(const fm_detour_view *dv, const fm_path_view *path, fm_obstacle_scratch sc,
                               const float *const p[3], const uint8_t *phase, fm_detour_store st, int64_t begin,
                               int64_t end, double time)
{
    const float t = (float)time;
    int64_t on = 0;
    for (int64_t a = begin; a < end; a++) {
        if (phase[a] != FM_KERNEL_FLYING) continue;
        const int near = sc.d_grid[a] - sc.radius[a] < dv->near;
        if (!st.on[a] && !near) { /* clear of the obstacles: nothing to watch */
            st.best[a] = INFINITY;
            continue;
        }
        const float x = p[0][a], y = p[1][a], z = p[2][a], u = fm_sdf_sample(&dv->u, x, y, z, NULL);
        if (st.on[a] && fm_sdf_sample(&dv->g, x, y, z, NULL) < dv->join && path_agrees(dv, path, x, y, z)) {
            /* back on the path, where it leads on */
            st.on[a] = 0, st.best[a] = INFINITY;
            continue;
        }
        if (!(st.best[a] < INFINITY) || u < st.best[a] - dv->progress) { /* (re)start the clock */
            st.best[a] = u, st.since[a] = t;
        } else if (!st.on[a] && t - st.since[a] > dv->wait) { /* stalled: detour */
            st.on[a] = 1, st.best[a] = u, st.since[a] = t;
        } else if (st.on[a] && t - st.since[a] > 2 * dv->wait) { /* the detour stalls too: the path again */
            st.on[a] = 0, st.best[a] = INFINITY;
        }
        on += st.on[a];
    }
    return on;
}
