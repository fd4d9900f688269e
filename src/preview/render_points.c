/* The preview renderer's automatic sphere radius for point agents: from their nearest-neighbour
 * spacing, found on the engine's hash grid (grid.h). */
#define _POSIX_C_SOURCE 200809L
#include "grid.h"
#include "render.h"

#include <stdlib.h>
#include <string.h>

/* Squared distance from point a to its nearest other point among the 27 grid cells around it
 * (+inf if there is none; coincident points are not neighbours). */
static double nearest_in_cells(const fm_grid *g, const float *const p[3], int32_t a)
{
    int32_t c[3];
    const float x[3] = {p[0][a], p[1][a], p[2][a]};
    for (int k = 0; k < 3; k++) c[k] = fm_grid_coord(fm_grid_scaled(g, x[k]));
    double best = INFINITY;
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                uint32_t s = fm_grid_slot(g, c[0] + dx, c[1] + dy, c[2] + dz);
                for (int32_t e = g->start[s]; e < g->start[s + 1]; e++) {
                    const fm_grid_quad *q = g->quad + (e >> 2);
                    double ex = q->x[e & 3] - x[0], ey = q->y[e & 3] - x[1], ez = q->z[e & 3] - x[2];
                    double d2 = ex * ex + ey * ey + ez * ez;
                    if (d2 > 0.0 && d2 < best) best = d2;
                }
            }
    return best;
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

#define FM_RADIUS_SAMPLES 4096

/* Nearest-neighbour distances d[] of up to FM_RADIUS_SAMPLES evenly strided points, searched in
 * the 27 cells around each. A distance up to the cell edge is exact (anything nearer lies in those
 * cells); a larger one (or +inf: nothing found) is only an upper bound. Returns how many are exact. */
static int sample_spacings(const fm_grid *g, const float *const p[3], int32_t n, double cell,
                           double *d, int *count)
{
    int32_t stride = n > FM_RADIUS_SAMPLES ? n / FM_RADIUS_SAMPLES : 1;
    int exact = 0;
    *count = 0;
    for (int32_t a = 0; a < n && *count < FM_RADIUS_SAMPLES; a += stride) {
        double dist = sqrt(nearest_in_cells(g, p, a));
        d[(*count)++] = dist;
        exact += dist <= cell;
    }
    return exact;
}

/* Median nearest-neighbour distance over a sample of the points; 0 if there is none. The grid's
 * cell starts at the spacing the points would have filling their box and doubles until most
 * samples' distances are exact, which points on a surface or a curve need. */
static double median_spacing(const float *const p[3], int32_t n, const double lo[3],
                             const double hi[3])
{
    double diag = 0.0, volume = 1.0;
    for (int k = 0; k < 3; k++) diag += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    diag = sqrt(diag);
    for (int k = 0; k < 3; k++) volume *= fmax(hi[k] - lo[k], 1e-3 * diag);
    double cell = cbrt(volume / n);
    fm_grid g;
    uint8_t *member = malloc((size_t)n);
    double *d = malloc(sizeof(double) * FM_RADIUS_SAMPLES);
    if (!member || !d || !(cell > 0.0) || fm_grid_init(&g, n, NULL) != FM_OK) {
        free(member), free(d);
        return 0.0;
    }
    memset(member, 1, (size_t)n);
    int count = 0;
    for (int round = 0; round < 64; round++, cell *= 2.0) {
        fm_grid_build(&g, p, member, n, (float)cell, 1);
        /* 60 % exact: the median is then one of the exact ones (the others are larger). */
        if (5 * sample_spacings(&g, p, n, cell, d, &count) >= 3 * count || cell > 2.0 * diag) break;
    }
    qsort(d, (size_t)count, sizeof *d, compare_double);
    double median = count && isfinite(d[count / 2]) ? d[count / 2] : 0.0;
    fm_grid_free(&g);
    free(member), free(d);
    return median;
}

double fm_render_point_radius(const float *positions, size_t n)
{
    if (n > (size_t)FM_GRID_MAX_CAPACITY) n = (size_t)FM_GRID_MAX_CAPACITY; /* a prefix will do */
    float *soa = malloc(sizeof(float) * 3 * (n ? n : 1));
    if (!soa || !positions) return free(soa), 1.0;
    float *const p[3] = {soa, soa + n, soa + 2 * n};
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    int32_t m = 0;
    for (size_t i = 0; i < n; i++) {
        const float *q = positions + 3 * i;
        if (!fm_render_coords_ok(q, 3)) continue;
        for (int k = 0; k < 3; k++) {
            p[k][m] = q[k];
            lo[k] = fmin(lo[k], q[k]), hi[k] = fmax(hi[k], q[k]);
        }
        m++;
    }
    double spacing = m > 1 ? median_spacing((const float *const *)p, m, lo, hi) : 0.0;
    double diag = 0.0;
    for (int k = 0; k < 3 && m > 0; k++) diag += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    free(soa);
    /* Without neighbours to measure: 1 % of the points' extent, or 1 for a single point. */
    if (!(spacing > 0.0)) return diag > 0.0 ? 0.01 * sqrt(diag) : 1.0;
    return 0.45 * spacing;
}

