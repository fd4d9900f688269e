/* Internal pieces shared by the preview renderer's files (render.c, render_png.c,
 * render_points.c). */
#ifndef FM_RENDER_H
#define FM_RENDER_H

#include "fm_internal.h"

#include <math.h>

#define FM_RENDER_MAX_DIM 16384
/* Coordinates beyond this are treated like NaN: Embree's float BVH cannot hold them usefully. */
#define FM_RENDER_MAX_COORD 1e18f

/* 1 if the first `count` floats of p are finite and within FM_RENDER_MAX_COORD. */
static inline int fm_render_coords_ok(const float *p, int count)
{
    for (int i = 0; i < count; i++)
        if (!(fabsf(p[i]) <= FM_RENDER_MAX_COORD)) return 0;
    return 1;
}

#endif
