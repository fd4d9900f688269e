/* FM §5.3: d_t(X) and its gradient g(d_t(X)) by trilinear interpolation of the dense grid. */
#include "kernel_sdf.h"

#include <math.h>
#include <stddef.h>

/* Splits coordinate u (in voxels from the first node) into a cell index in [0, n-2] and a
   fraction in [0, 1]; 0 if u is outside [0, n-1] or NaN. */
static int cell_of(float u, int32_t n, int32_t *i, float *f)
{
    if (!(u >= 0.0f && u <= (float)(n - 1))) return 0;
    int32_t c = (int32_t)u; /* u >= 0: truncation is floor */
    if (c > n - 2) c = n - 2;
    *i = c;
    *f = u - (float)c;
    return 1;
}

float fm_sdf_sample(const fm_sdf_view *s, float x, float y, float z, float grad[3])
{
    if (grad) grad[0] = grad[1] = grad[2] = 0.0f;
    if (!s->d || s->n[0] < 2 || s->n[1] < 2 || s->n[2] < 2 || !(s->voxel > 0.0f)) return s->far;
    float inv = 1.0f / s->voxel;
    int32_t i, j, k;
    float fx, fy, fz;
    if (!cell_of((x - s->origin[0]) * inv, s->n[0], &i, &fx) ||
        !cell_of((y - s->origin[1]) * inv, s->n[1], &j, &fy) ||
        !cell_of((z - s->origin[2]) * inv, s->n[2], &k, &fz))
        return s->far;

    size_t sy = (size_t)s->n[0], sz = (size_t)s->n[0] * (size_t)s->n[1];
    const float *c = s->d + (size_t)i + sy * (size_t)j + sz * (size_t)k;
    float c000 = c[0], c100 = c[1], c010 = c[sy], c110 = c[sy + 1];
    float c001 = c[sz], c101 = c[sz + 1], c011 = c[sz + sy], c111 = c[sz + sy + 1];

    /* along x, then y, then z */
    float c00 = c000 + fx * (c100 - c000), c10 = c010 + fx * (c110 - c010);
    float c01 = c001 + fx * (c101 - c001), c11 = c011 + fx * (c111 - c011);
    float c0 = c00 + fy * (c10 - c00), c1 = c01 + fy * (c11 - c01);
    float d = c0 + fz * (c1 - c0);

    if (grad) { /* the derivatives of the same interpolant, divided by the voxel size */
        float gx = (1.0f - fz) * ((1.0f - fy) * (c100 - c000) + fy * (c110 - c010)) +
                   fz * ((1.0f - fy) * (c101 - c001) + fy * (c111 - c011));
        float gy = (1.0f - fz) * (c10 - c00) + fz * (c11 - c01);
        float gz = c1 - c0;
        grad[0] = gx * inv;
        grad[1] = gy * inv;
        grad[2] = gz * inv;
    }
    return d;
}
