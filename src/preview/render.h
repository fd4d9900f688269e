/* Internal pieces shared by the preview renderer's files (render.c, render_colour.c,
 * render_png.c, render_points.c). */
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

/* ---------------------------------------------------------------- colours (render_colour.c) */

#define FM_RAMP_STOPS 5 /* the gradient over agent index */
#define FM_MAP_LUT 1024 /* entries of the colormap's table in linear light */

/* The renderer's colour tables, in linear light. */
typedef struct fm_colour_tables {
    float ramp[FM_RAMP_STOPS][3];
    float map[FM_MAP_LUT][3]; /* fm_render_colormap at j / (FM_MAP_LUT - 1) */
    float unknown[3];         /* NaN values, phases outside the palette */
} fm_colour_tables;

double fm_srgb_to_linear(double c);
void fm_colour_tables_init(fm_colour_tables *t);
/* FM_OK, or FM_ERR_USAGE when c cannot colour n agents; c NULL colours by index. */
fm_status fm_check_colours(const fm_render_colours *c, size_t n, fm_error *err);
/* out: n x 3 linear colours, agent i's at 3i (c checked). */
void fm_agent_colours(const fm_colour_tables *t, const fm_render_colours *c, size_t n, float *out);

#endif
