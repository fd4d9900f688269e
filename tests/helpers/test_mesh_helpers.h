/* Mesh measures shared by the tests that check points against a surface (test_sample.c,
 * test_flock_scale.c): their tolerance is a fraction of the mesh's bounding-box diagonal. */
#ifndef FM_TEST_MESH_HELPERS_H
#define FM_TEST_MESH_HELPERS_H

#include "geom.h"

#include <math.h>

static inline double bbox_diagonal(const fm_mesh *m)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, d2 = 0;
    for (int64_t i = 0; i < m->nv; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], m->v[3 * i + k]), hi[k] = fmax(hi[k], m->v[3 * i + k]);
    for (int k = 0; k < 3; k++) d2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    return sqrt(d2);
}

#endif
