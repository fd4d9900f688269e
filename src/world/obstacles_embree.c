/* Obstacles (FM §5.3): validation, the OpenVDB grid (obstacles_vdb.cpp) made exact near the
 * surfaces by the Embree closest-point queries of closest_embree.c.
 *
 * fm_obstacles_closest is fm_closest_signed with the grid's value as the search radius hint. */
#include "closest.h"
#include "obstacles.h"

#include <math.h>
#include <string.h>

struct fm_obstacles {
    fm_closest *mesh;   /* the union of the obstacles, with pseudo-normals for the sign */
    float *sdf;
    fm_sdf_view view;
    int owners;         /* fm_obstacles_share: a model and the studio's keep (morph_model.c) */
};

double fm_obstacles_closest(const fm_obstacles *o, const double p[3], double closest[3], double normal[3])
{
    /* The grid bounds the distance: its nodes are exact (see refine_grid) and d is 1-Lipschitz, so
       the trilinear value is within sqrt(3) voxels of the true one. */
    double hint = INFINITY;
    if (o && o->view.d && fabs(p[0]) <= 1e30 && fabs(p[1]) <= 1e30 && fabs(p[2]) <= 1e30) {
        float g = fm_sdf_sample(&o->view, (float)p[0], (float)p[1], (float)p[2], NULL);
        if (fabsf(g) < o->view.far) hint = fabs((double)g) + 2.0 * (double)o->view.voxel;
    }
    return fm_closest_signed(o ? o->mesh : NULL, p, hint, closest, normal);
}

double fm_obstacles_distance_within(const fm_obstacles *o, const double p[3], double radius)
{
    return fm_closest_within(o ? o->mesh : NULL, p, radius);
}

fm_obstacles *fm_obstacles_share(fm_obstacles *o)
{
    if (o) o->owners++;
    return o;
}

void fm_obstacles_destroy(fm_obstacles *o)
{
    if (!o || --o->owners > 0) return;
    fm_closest_destroy(o->mesh);
    fm_free(o->sdf);
    fm_free(o);
}

fm_sdf_view fm_obstacles_sdf(const fm_obstacles *o)
{
    if (!o) return (fm_sdf_view){0};
    return o->view;
}

/* OpenVDB's values within the band are good to a fraction of a voxel, but its errors (its closest
   triangle is propagated from neighbouring voxels, not searched) tilt the gradient of d_t by up to
   ~8-15 degrees inside a finely tessellated sphere. Replace every node inside the band by the exact
   signed distance, so d_t(i) is the paper's "shortest distance from the centre of cell i"; OpenVDB's
   value (off by well under half a voxel) is the search radius hint, and a miss only costs a second
   search. Nodes OpenVDB put at +-far stay there. This roughly doubles the build time (0.7 us per
   band voxel per thread here). */
static void refine_grid(fm_obstacles *o)
{
    float *d = o->sdf;
    const fm_sdf_view *s = &o->view;
    const double h = (double)s->voxel, far = (double)s->far;
    const int64_t n0 = s->n[0], n1 = s->n[1], rows = (int64_t)s->n[1] * s->n[2];
#pragma omp parallel for num_threads(fm_threads(0)) schedule(dynamic, 4)
    for (int64_t r = 0; r < rows; r++) {
        int64_t j = r % n1, k = r / n1;
        float *row = d + n0 * r;
        for (int64_t i = 0; i < n0; i++) {
            if (!(fabsf(row[i]) < s->far)) continue;
            double p[3] = {(double)s->origin[0] + h * (double)i, (double)s->origin[1] + h * (double)j,
                           (double)s->origin[2] + h * (double)k};
            double v = fm_closest_signed(o->mesh, p, fabs((double)row[i]) + 0.5 * h, NULL, NULL);
            row[i] = (float)(v >= far ? far : v <= -far ? -far : v);
        }
    }
}

fm_obstacles *fm_obstacles_build(const fm_mesh *meshes, int count, double voxel, double band, fm_error *err)
{
    static const fm_sdf_names obstacles = {"obstacle", "the obstacles"};
    return fm_obstacles_build_named(meshes, count, voxel, band, &obstacles, err);
}

fm_obstacles *fm_obstacles_build_named(const fm_mesh *meshes, int count, double voxel, double band,
                                       const fm_sdf_names *name, fm_error *err)
{
    if (!(voxel > 0) || !isfinite(voxel)) {
        fm_fail(err, FM_ERR_INPUT, "%s voxel size must be positive and finite (got %g)", name->grid, voxel);
        return NULL;
    }
    if (!(band > 0) || !isfinite(band)) {
        fm_fail(err, FM_ERR_INPUT, "%s distance band must be positive and finite (got %g)", name->grid, band);
        return NULL;
    }
    fm_obstacles *o = fm_alloc(sizeof *o);
    if (!o) {
        fm_fail(err, FM_ERR_MEMORY, "out of memory for the obstacles");
        return NULL;
    }
    o->owners = 1;
    o->mesh = fm_closest_build(meshes, count, "obstacle", 1, err);
    fm_status st = o->mesh ? FM_OK : (err ? err->status : FM_ERR_INPUT);
    if (st == FM_OK) {
        fm_closest_soup s = fm_closest_get_soup(o->mesh);
        float *d = NULL;
        int32_t n[3];
        float origin[3];
        st = fm_obstacles_vdb_grid(s.v, s.nv, s.tri, s.nt, voxel, band, FM_OBSTACLE_MAX_VOXELS, name, &d, n, origin, err);
        if (st == FM_OK) {
            o->sdf = d;
            o->view = (fm_sdf_view){d, {n[0], n[1], n[2]}, {origin[0], origin[1], origin[2]}, (float)voxel, (float)band};
        }
    }
    if (st == FM_OK) refine_grid(o);
    if (st != FM_OK) {
        fm_obstacles_destroy(o);
        return NULL;
    }
    return o;
}
