// OpenVDB adapter for the obstacle potential d_t (FM §5.3): the only OpenVDB code in the engine,
// behind extern "C"; every exception is caught here and turned into an fm_status with a message.
// One small file on purpose: OpenVDB's mesh-to-volume headers take ~15 s to compile.
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <openvdb/tools/MeshToVolume.h>

#include <cmath>
#include <cstdint>
#include <exception>
#include <mutex>
#include <new>
#include <vector>

extern "C" {
#include "obstacles.h"
}

namespace {

// Narrow band half-width in voxels: one voxel beyond `band`, so every value with |d| < band is
// computed, not background.
double band_voxels(double voxel, double band) { return std::ceil(band / voxel) + 1.0; }

// Upper bound on the dense grid's voxel count at voxel size h: the vertices' bounding box in index
// space, widened by the band and the one-voxel border (the band's active voxels lie inside it).
double estimate_voxels(const double lo[3], const double hi[3], double h, double band, double dims[3])
{
    double w = band_voxels(h, band) + 1.0, total = 1.0;
    for (int k = 0; k < 3; k++) {
        dims[k] = std::ceil(hi[k] / h) - std::floor(lo[k] / h) + 2.0 * w + 1.0;
        total *= dims[k];
    }
    return total;
}

struct dense_guard {
    float *p = nullptr;
    ~dense_guard() { fm_free(p); }
};

fm_status build(const double *v, int64_t nv, const int32_t *tri, int64_t nt, double voxel,
                double band, int64_t max_voxels, const fm_sdf_names *name, float **out, int32_t n[3],
                float origin[3], fm_error *err)
{
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });

    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int64_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++) lo[k] = std::fmin(lo[k], v[3 * i + k]), hi[k] = std::fmax(hi[k], v[3 * i + k]);
    // Index-space coordinates are floats (and so is the sampler's arithmetic): keep them well
    // within float's 24 bits so a voxel still has 1/32 or finer resolution.
    double reach = 0;
    for (int k = 0; k < 3; k++) reach = std::fmax(reach, std::fmax(std::fabs(lo[k]), std::fabs(hi[k])) + band);
    if (reach / voxel > 262144.0)
        return fm_fail(err, FM_ERR_INPUT, "%s reach %g from the origin, %.3g voxels of size %g: too "
                       "far for the grid's float coordinates (at most 262144 voxels); use a voxel size of "
                       "at least %g or move the scene nearer the origin", name->surfaces, reach, reach / voxel, voxel,
                       reach / 262144.0);
    double dims[3];
    double count = estimate_voxels(lo, hi, voxel, band, dims);
    if (!(count <= (double)max_voxels)) {
        // The smallest voxel size (to two significant digits, rounded up) that fits.
        double h = voxel * std::cbrt(count / (double)max_voxels), unused[3];
        while (std::isfinite(h) && estimate_voxels(lo, hi, h, band, unused) > (double)max_voxels) h *= 1.02;
        if (!std::isfinite(h) || h <= 0)
            return fm_fail(err, FM_ERR_INPUT, "%s distance grid too large at voxel size %g "
                           "(%s span %g x %g x %g); use a larger voxel size", name->grid, voxel, name->surfaces,
                           hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
        double mag = std::pow(10.0, std::floor(std::log10(h)) - 1.0);
        h = std::ceil(h / mag) * mag;
        return fm_fail(err, FM_ERR_INPUT,
                       "%s distance grid too large: voxel size %g over the %g x %g x %g bounding box "
                       "of %s with a band of %g needs about %.0f x %.0f x %.0f "
                       "= %.3g voxels, more than the limit of %lld; use a voxel size of at least %g",
                       name->grid, voxel, hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], name->surfaces, band, dims[0], dims[1],
                       dims[2], count, (long long)max_voxels, h);
    }

    // meshToVolume takes index-space points: world / voxel (the linear transform's centres).
    std::vector<openvdb::Vec3s> points((size_t)nv);
    for (int64_t i = 0; i < nv; i++)
        points[(size_t)i] = openvdb::Vec3s((float)(v[3 * i] / voxel), (float)(v[3 * i + 1] / voxel),
                                           (float)(v[3 * i + 2] / voxel));
    std::vector<openvdb::Vec3I> tris((size_t)nt);
    for (int64_t t = 0; t < nt; t++)
        tris[(size_t)t] = openvdb::Vec3I((openvdb::Index32)tri[3 * t], (openvdb::Index32)tri[3 * t + 1],
                                         (openvdb::Index32)tri[3 * t + 2]);

    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(voxel);
    float width = (float)band_voxels(voxel, band);
    openvdb::tools::QuadAndTriangleDataAdapter<openvdb::Vec3s, openvdb::Vec3I> mesh(points, tris);
    // No renormalisation: it smooths the values near the surface, but obstacles_embree.c replaces
    // every value inside the band by the exact distance anyway, and it costs about half the time.
    const int flags = openvdb::tools::DISABLE_RENORMALIZATION;
    openvdb::FloatGrid::Ptr grid =
        openvdb::tools::meshToVolume<openvdb::FloatGrid>(mesh, *xform, width, width, flags);
    points = {};
    tris = {};

    openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
    if (grid->activeVoxelCount() == 0 || box.empty())
        return fm_fail(err, FM_ERR_INPUT, "%s give an empty distance field at voxel size %g "
                       "(are they flat, or much thinner than a voxel?)", name->surfaces, voxel);
    box.expand(1); // the border of far values
    openvdb::Coord dim = box.dim();
    int64_t total = (int64_t)dim[0] * dim[1] * dim[2];
    if (total > max_voxels) // cannot happen if the estimate is an upper bound; kept as a guard
        return fm_fail(err, FM_ERR_INPUT, "%s distance grid too large: %d x %d x %d voxels at "
                       "voxel size %g; use a larger voxel size", name->grid, dim[0], dim[1], dim[2], voxel);

    dense_guard dense;
    dense.p = (float *)fm_alloc(sizeof(float) * (size_t)total);
    if (!dense.p)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the %d x %d x %d %s distance grid",
                       dim[0], dim[1], dim[2], name->grid);
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> view(box, dense.p);
    openvdb::tools::copyToDense(*grid, view);
    grid.reset();

    const float far = (float)band;
    for (int64_t i = 0; i < total; i++) {
        float d = dense.p[i];
        dense.p[i] = d >= far ? far : d <= -far ? -far : d;
    }
    for (int k = 0; k < 3; k++) {
        n[k] = dim[k];
        origin[k] = (float)(voxel * box.min()[k]);
    }
    *out = dense.p;
    dense.p = nullptr;
    return FM_OK;
}

} // namespace

extern "C" fm_status fm_obstacles_vdb_grid(const double *v, int64_t nv, const int32_t *tri, int64_t nt,
                                           double voxel, double band, int64_t max_voxels,
                                           const fm_sdf_names *name, float **d, int32_t n[3],
                                           float origin[3], fm_error *err)
{
    *d = nullptr;
    if (!(voxel > 0) || !std::isfinite(voxel) || !(band > 0) || !std::isfinite(band))
        return fm_fail(err, FM_ERR_INPUT, "%s distance grid: voxel size (%g) and band (%g) must be positive",
                       name->grid, voxel, band);
    if (nv <= 0 || nt <= 0)
        return fm_fail(err, FM_ERR_INPUT, "%s distance grid: no triangles", name->grid);
    try {
        return build(v, nv, tri, nt, voxel, band, max_voxels, name, d, n, origin, err);
    } catch (const std::bad_alloc &) {
        return fm_fail(err, FM_ERR_MEMORY, "out of memory building the %s distance grid "
                       "at voxel size %g; try a larger voxel size", name->grid, voxel);
    } catch (const std::exception &e) {
        return fm_fail(err, FM_ERR_INTERNAL, "OpenVDB failed building the %s distance grid: %s", name->grid, e.what());
    } catch (...) {
        return fm_fail(err, FM_ERR_INTERNAL, "OpenVDB failed building the %s distance grid", name->grid);
    }
}
