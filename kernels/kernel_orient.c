/* The agent's frame from its velocity (kernel_orient.h). */
#include "kernel_orient.h"
#include "fm_math.h"

#include <math.h>

/* The agent's frame: x along v, y = unit(world Z x x), z = x cross y, so the agent stays upright;
 * flying straight up or down (no such y), y is the previous y made perpendicular to x. Unchanged
 * when v is 0. */
void fm_flock_update_orientation(float *q, const float v[3])
{
    double len = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
    if (!(len > 1e-12)) return;
    const double x[3] = {v[0] / len, v[1] / len, v[2] / len};
    const double h = sqrt(x[0] * x[0] + x[1] * x[1]);
    if (h >= 1e-3) { /* the usual case, in closed form (no branch on the heading, no division by it) */
        /* The frame is a yaw psi about Z after a pitch theta about y: R = Rz(psi) Ry(theta), whose x
         * axis is (cos theta cos psi, cos theta sin psi, -sin theta) and y axis (-sin psi, cos psi, 0);
         * so cos theta = h, sin theta = -x_z, cos psi = x_x / h, sin psi = x_y / h. Its quaternion is
         * (cos psi/2, 0, 0, sin psi/2) (cos theta/2, 0, sin theta/2, 0) = (a c, -b d, a d, b c),
         * w = a c >= 0 as fm_quat_from_rotation picks it. The half angles from the cosines: in double,
         * 1 +- cos loses at most 1e-16 absolutely, far below the float the frame is stored in. */
        const double cos_psi = x[0] / h;
        const double a = sqrt(0.5 * (1 + cos_psi)), b = copysign(sqrt(0.5 * (1 - cos_psi)), x[1]);
        const double c = sqrt(0.5 * (1 + h)), d = copysign(sqrt(0.5 * (1 - h)), -x[2]);
        q[0] = (float)(a * c), q[1] = (float)(-b * d), q[2] = (float)(a * d), q[3] = (float)(b * c);
        return;
    }
    /* near vertical: the previous frame's y, minus its part along x */
    const double w = q[0], i = q[1], j = q[2], k = q[3];
    const double prev[3] = {2 * (i * j - w * k), 1 - 2 * (i * i + k * k), 2 * (j * k + w * i)};
    const double along = prev[0] * x[0] + prev[1] * x[1] + prev[2] * x[2];
    double y[3];
    for (int c = 0; c < 3; c++) y[c] = prev[c] - along * x[c];
    const double ylen = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
    if (!(ylen > 1e-9)) return;
    for (int c = 0; c < 3; c++) y[c] /= ylen;
    const double z[3] = {x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
    fm_mat3 r;
    for (int c = 0; c < 3; c++) r.m[c][0] = x[c], r.m[c][1] = y[c], r.m[c][2] = z[c];
    double out[4];
    fm_quat_from_rotation(r, out);
    for (int c = 0; c < 4; c++) q[c] = (float)out[c];
}

void fm_kernel_orient_along(float *q, const float *const v[3], const uint8_t *phase, uint8_t skip, int64_t begin,
                            int64_t end)
{
    fm_orient_along_fn *variant = FM_SIMD_PICK(fm_kernel_orient_along);
    if (variant) {
        variant(q, v, phase, skip, begin, end);
        return;
    }
    for (int64_t a = begin; a < end; a++)
        if (phase[a] != skip) {
            const float va[3] = {v[0][a], v[1][a], v[2][a]};
            fm_flock_update_orientation(q + 4 * a, va);
        }
}
