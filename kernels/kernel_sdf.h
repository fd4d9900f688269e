/* The obstacle potential d_t (FM §5.3) as a dense signed-distance grid, and its sampler.
 * Pure C: no allocation, no I/O, no globals; safe to call from any number of threads. */
#ifndef FM_KERNEL_SDF_H
#define FM_KERNEL_SDF_H

#include <stdint.h>

/* A dense signed-distance grid: d[i + n0*(j + n1*k)] is the signed distance (negative inside) at
   the voxel centre origin + voxel*(i, j, k). Outside the grid, or where |d| >= far, the value is
   far; inside an obstacle deeper than far the stored value is -far (the sign is kept, so an agent
   deep inside an obstacle never reads "free space"). The grid built by fm_obstacles_build has a
   one-voxel border of far on every side, so the sampled field is continuous where it leaves the
   grid. */
typedef struct fm_sdf_view { const float *d; int32_t n[3]; float origin[3]; float voxel; float far; } fm_sdf_view;

/* Trilinear d at (x, y, z) and its gradient: the exact gradient of the trilinear interpolant
   (world units, so |grad| ~ 1 within the band near the surface; it points away from the surface,
   i.e. towards increasing d, both outside and inside). On the shared face of two cells the
   gradient is taken from the cell with the larger index. Where the field is clamped to +-far the
   gradient is 0. Returns far with gradient 0 outside the grid (and for a NaN position or an empty
   view). grad may be NULL. */
float fm_sdf_sample(const fm_sdf_view *s, float x, float y, float z, float grad[3]);

#endif
