// OpenVDB points adapter for the VDB exporter: plain arrays in, a PointDataGrid named "points"
// with the attributes P (position), v (velocity, vec3s) and id (int32) out, and, when the frame
// has them, orient (quats: x, y, z, w), pscale and age (float) and phase (int32): the names and
// types Houdini gives them; and readers for the tests. Behind extern "C": every exception is caught here and
// turned into an fm_status with a message.
#include <openvdb/openvdb.h>
#include <openvdb/points/PointConversion.h>
#include <openvdb/points/PointCount.h>
#include <openvdb/points/PointDataGrid.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <mutex>
#include <new>
#include <streambuf>
#include <vector>

extern "C" {
#include "export.h"
}

namespace {

using openvdb::Vec3f;
namespace vp = openvdb::points;

// Index coordinates are int32: keep every point well inside them.
const double max_index = 1073741824.0; // 2^30

void init_openvdb()
{
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

// An unbuffered std::streambuf over the FILE of an fm_output_file, with the seeking OpenVDB
// needs to write grid offsets; write errors stay on the FILE for fm_output_commit to report.
class file_streambuf : public std::streambuf {
public:
    explicit file_streambuf(FILE *f) : f_(f) {}

protected:
    std::streamsize xsputn(const char *s, std::streamsize n) override
    {
        return (std::streamsize)std::fwrite(s, 1, (size_t)n, f_);
    }
    int_type overflow(int_type c) override
    {
        if (traits_type::eq_int_type(c, traits_type::eof())) return traits_type::not_eof(c);
        return std::fputc(c, f_) == EOF ? traits_type::eof() : c;
    }
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override
    {
        int whence = dir == std::ios_base::beg ? SEEK_SET : dir == std::ios_base::cur ? SEEK_CUR : SEEK_END;
        if (fseeko(f_, (off_t)off, whence) != 0) return pos_type(off_type(-1));
        return pos_type((off_type)ftello(f_));
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode mode) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, mode);
    }
    int sync() override { return std::fflush(f_) == 0 ? 0 : -1; }

private:
    FILE *f_;
};

// io::File::write opens its own stream and never checks it after writing; Archive's stream
// writer (protected) lets us write to ours and check every byte.
class stream_archive : public openvdb::io::Archive {
public:
    void write_to(std::ostream &os, const openvdb::GridCPtrVec &grids) const
    {
        Archive::write(os, grids, /*seekable=*/true);
    }
};

// Ids were checked to fit int32 by fm_export_frame_write.
fm_status check_points(const float *pos, size_t n, double voxel, const char *path, fm_error *err)
{
    for (size_t i = 0; i < 3 * n; i++)
        if (!std::isfinite(pos[i]))
            return fm_fail(err, FM_ERR_INPUT, "cannot export to '%s': agent %zu has a non-finite position",
                           path, i / 3);
    if (voxel < 0 || !std::isfinite(voxel))
        return fm_fail(err, FM_ERR_USAGE, "cannot export to '%s': voxel size %g is not positive", path, voxel);
    return FM_OK;
}

double reach_of(const std::vector<Vec3f> &p)
{
    double reach = 0;
    for (const Vec3f &v : p)
        for (int k = 0; k < 3; k++) reach = std::fmax(reach, std::fabs((double)v[k]));
    return reach;
}

// The given voxel size, or one from the point density (OpenVDB's computeVoxelSize), made large
// enough that every point's index coordinate fits.
fm_status choose_voxel(const std::vector<Vec3f> &p, const fm_export_options *o, const char *path,
                       double *voxel, fm_error *err)
{
    double reach = reach_of(p);
    if (o->voxel_size > 0) {
        if (reach / o->voxel_size > max_index)
            return fm_fail(err, FM_ERR_INPUT, "cannot export to '%s': points reach %g from the origin, "
                           "too far for voxel size %g (at most 2^30 voxels); use a voxel size of at "
                           "least %g", path, reach, o->voxel_size, reach / max_index);
        *voxel = o->voxel_size;
        return FM_OK;
    }
    if (o->points_per_voxel < 1)
        return fm_fail(err, FM_ERR_USAGE, "cannot export to '%s': points per voxel must be at least 1", path);
    vp::PointAttributeVector<Vec3f> wrapper(p);
    *voxel = std::fmax((double)vp::computeVoxelSize(wrapper, (uint32_t)o->points_per_voxel),
                       reach / max_index);
    return FM_OK;
}

template <typename T>
void add_attribute(vp::PointDataGrid &grid, const openvdb::tools::PointIndexGrid &index, const char *name,
                   const std::vector<T> &values)
{
    vp::appendAttribute<T>(grid.tree(), name);
    vp::populateAttribute(grid.tree(), index.tree(), name, vp::PointAttributeVector<T>(values));
}

// The frame's optional attributes, each only when the frame has it.
void add_optional(vp::PointDataGrid &grid, const openvdb::tools::PointIndexGrid &index, const fm_export_frame *f)
{
    size_t n = f->n;
    if (f->orientations) {
        std::vector<openvdb::math::Quats> q(n);
        for (size_t i = 0; i < n; i++) { // the cache's w, x, y, z; Quats(x, y, z, w)
            const float *o = f->orientations + 4 * i;
            q[i] = openvdb::math::Quats(o[1], o[2], o[3], o[0]);
        }
        add_attribute(grid, index, "orient", q);
    }
    if (f->pscales) add_attribute(grid, index, "pscale", std::vector<float>(f->pscales, f->pscales + n));
    if (f->ages) add_attribute(grid, index, "age", std::vector<float>(f->ages, f->ages + n));
    if (f->phases) add_attribute(grid, index, "phase", std::vector<int32_t>(f->phases, f->phases + n));
    if (f->groups) add_attribute(grid, index, "group", std::vector<int32_t>(f->groups, f->groups + n));
}

openvdb::GridBase::Ptr build_grid(const std::vector<Vec3f> &p, const std::vector<Vec3f> &v,
                                  const std::vector<int32_t> &id, const fm_export_frame *f, double voxel)
{
    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(voxel);
    vp::PointAttributeVector<Vec3f> positions(p);
    auto index = openvdb::tools::createPointIndexGrid<openvdb::tools::PointIndexGrid>(positions, *xform);
    // NullCodec: positions as full floats (relative to their voxel), not 8 or 16 bit fixed point.
    auto grid = vp::createPointDataGrid<vp::NullCodec, vp::PointDataGrid>(*index, positions, *xform);
    add_attribute(*grid, *index, "v", v);
    add_attribute(*grid, *index, "id", id);
    add_optional(*grid, *index, f);
    grid->setName("points");
    return grid;
}

fm_status write_points(const fm_export_frame *f, const float *pos, const fm_export_options *opts,
                       const char *path, fm_error *err)
{
    init_openvdb();
    const float *vel = f->velocities;
    const uint32_t *ids = f->ids;
    size_t n = f->n;
    std::vector<Vec3f> p(n), v(n, Vec3f(0.0f));
    std::vector<int32_t> id(n);
    for (size_t i = 0; i < n; i++) {
        p[i] = Vec3f(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]);
        if (vel) v[i] = Vec3f(vel[3 * i], vel[3 * i + 1], vel[3 * i + 2]);
        id[i] = ids ? (int32_t)ids[i] : (int32_t)i;
    }
    double voxel = 0;
    fm_status st = choose_voxel(p, opts, path, &voxel, err);
    if (st != FM_OK) return st;
    openvdb::GridCPtrVec grids{build_grid(p, v, id, f, voxel)};

    fm_output_file out;
    if ((st = fm_output_open(&out, path, err)) != FM_OK) return st;
    try {
        file_streambuf buf(out.f);
        std::ostream os(&buf);
        stream_archive().write_to(os, grids);
        if (!os && !std::ferror(out.f)) { // e.g. a failed seek: the FILE itself has no error
            fm_output_discard(&out);
            return fm_fail(err, FM_ERR_IO, "cannot write '%s'", path);
        }
    } catch (...) {
        fm_output_discard(&out);
        throw;
    }
    return fm_output_commit(&out, NULL, err);
}

template <typename T>
T *malloc_array(size_t n)
{
    T *p = (T *)std::malloc(sizeof(T) * (n ? n : 1));
    if (!p) throw std::bad_alloc();
    return p;
}

// Every point of every leaf, in leaf order.
fm_status read_points(const char *path, size_t *n, float **pos, float **vel, int32_t **ids,
                      double *voxel_size, fm_error *err)
{
    init_openvdb();
    openvdb::io::File file(path);
    file.open(/*delayLoad=*/false);
    auto grid = openvdb::GridBase::grid<vp::PointDataGrid>(file.readGrid("points"));
    file.close();
    if (!grid) return fm_fail(err, FM_ERR_INPUT, "'%s': the grid 'points' is not a PointDataGrid", path);
    const auto &tree = grid->tree();
    size_t count = (size_t)vp::pointCount(tree);
    auto leaf0 = tree.cbeginLeaf();
    if (count && (!leaf0 || leaf0->attributeSet().find("v") == vp::AttributeSet::INVALID_POS ||
                  leaf0->attributeSet().find("id") == vp::AttributeSet::INVALID_POS))
        return fm_fail(err, FM_ERR_INPUT, "'%s': the points lack the attribute v or id", path);
    *pos = malloc_array<float>(3 * count);
    *vel = malloc_array<float>(3 * count);
    *ids = malloc_array<int32_t>(count);
    size_t i = 0;
    for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf) {
        vp::AttributeHandle<Vec3f> ph(leaf->constAttributeArray("P"));
        vp::AttributeHandle<Vec3f> vh(leaf->constAttributeArray("v"));
        vp::AttributeHandle<int32_t> ih(leaf->constAttributeArray("id"));
        for (auto idx = leaf->beginIndexOn(); idx; ++idx, ++i) {
            openvdb::Vec3d world = grid->transform().indexToWorld(ph.get(*idx) + idx.getCoord().asVec3d());
            Vec3f vel_i = vh.get(*idx);
            for (int k = 0; k < 3; k++) (*pos)[3 * i + k] = (float)world[k], (*vel)[3 * i + k] = vel_i[k];
            (*ids)[i] = ih.get(*idx);
        }
    }
    *n = i;
    if (voxel_size) *voxel_size = grid->voxelSize()[0];
    return FM_OK;
}

template <typename T> double component(const T &v, int) { return (double)v; }
double component(const Vec3f &v, int c) { return v[c]; }
double component(const openvdb::math::Quats &q, int c) { return q[c]; } // x, y, z, w

// One attribute of every point, in leaf order (that of read_points), as floats.
template <typename T, int C>
void read_values(const vp::PointDataTree &tree, const char *name, float *out)
{
    size_t i = 0;
    for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf) {
        vp::AttributeHandle<T> h(leaf->constAttributeArray(name));
        for (auto idx = leaf->beginIndexOn(); idx; ++idx, ++i) {
            T v = h.get(*idx);
            for (int c = 0; c < C; c++) out[C * i + c] = (float)component(v, c);
        }
    }
}


fm_status read_attr(const char *path, const char *name, size_t *n, int *components, float **values,
                    fm_error *err)
{
    init_openvdb();
    openvdb::io::File file(path);
    file.open(false);
    auto grid = openvdb::GridBase::grid<vp::PointDataGrid>(file.readGrid("points"));
    file.close();
    if (!grid) return fm_fail(err, FM_ERR_INPUT, "'%s': the grid 'points' is not a PointDataGrid", path);
    const auto &tree = grid->tree();
    auto leaf = tree.cbeginLeaf();
    size_t pos = leaf ? leaf->attributeSet().find(name) : vp::AttributeSet::INVALID_POS;
    if (pos == vp::AttributeSet::INVALID_POS) return fm_fail(err, FM_ERR_INPUT, "'%s': no attribute %s", path, name);
    const std::string type = leaf->attributeArray(pos).type().first;
    *n = (size_t)vp::pointCount(tree);
    *components = type == "vec3s" ? 3 : type == "quats" ? 4 : 1;
    *values = malloc_array<float>((size_t)*components * *n);
    if (type == "float") read_values<float, 1>(tree, name, *values);
    else if (type == "int32") read_values<int32_t, 1>(tree, name, *values);
    else if (type == "vec3s") read_values<Vec3f, 3>(tree, name, *values);
    else if (type == "quats") read_values<openvdb::math::Quats, 4>(tree, name, *values);
    else return std::free(*values), *values = nullptr, fm_fail(err, FM_ERR_INPUT, "'%s': %s has type %s", path, name, type.c_str());
    return FM_OK;
}

// "NAME:TYPE" of every attribute, in the descriptor's order, space-separated.
fm_status list_attrs(const char *path, char *out, size_t size, fm_error *err)
{
    init_openvdb();
    openvdb::io::File file(path);
    file.open(false);
    auto grid = openvdb::GridBase::grid<vp::PointDataGrid>(file.readGrid("points"));
    file.close();
    auto leaf = grid ? grid->tree().cbeginLeaf() : vp::PointDataTree::LeafCIter();
    if (!leaf) return fm_fail(err, FM_ERR_INPUT, "'%s': no points", path);
    const vp::AttributeSet::Descriptor &d = leaf->attributeSet().descriptor();
    std::string list;
    for (size_t i = 0; i < d.size(); i++)
        for (const auto &named : d.map())
            if (named.second == i) list += (list.empty() ? "" : " ") + named.first + ":" + d.type(i).first;
    std::snprintf(out, size, "%s", list.c_str());
    return FM_OK;
}

} // namespace

extern "C" fm_status fm_vdb_points_list_attrs(const char *path, char *out, size_t size, fm_error *err)
{
    out[0] = 0;
    try {
        return list_attrs(path, out, size, err);
    } catch (const std::bad_alloc &) {
        return fm_fail(err, FM_ERR_MEMORY, "out of memory reading '%s'", path);
    } catch (const std::exception &e) {
        return fm_fail(err, FM_ERR_INPUT, "cannot read '%s': %s", path, e.what());
    }
}

extern "C" fm_status fm_vdb_points_read_attr(const char *path, const char *name, size_t *n, int *components,
                                             float **values, fm_error *err)
{
    *n = 0, *components = 0, *values = nullptr;
    try {
        return read_attr(path, name, n, components, values, err);
    } catch (const std::bad_alloc &) {
        std::free(*values), *values = nullptr;
        return fm_fail(err, FM_ERR_MEMORY, "out of memory reading '%s'", path);
    } catch (const std::exception &e) {
        std::free(*values), *values = nullptr;
        return fm_fail(err, FM_ERR_INPUT, "cannot read '%s': %s", path, e.what());
    }
}

extern "C" fm_status fm_vdb_points_write(const fm_export_frame *frame, const float *positions,
                                         const fm_export_options *opts, const char *path, fm_error *err)
{
    size_t n = frame->n;
    if (n > 0 && !positions) return fm_fail(err, FM_ERR_USAGE, "export to '%s': no positions", path);
    fm_status st = check_points(positions, n, opts->voxel_size, path, err);
    if (st != FM_OK) return st;
    try {
        return write_points(frame, positions, opts, path, err);
    } catch (const std::bad_alloc &) {
        return fm_fail(err, FM_ERR_MEMORY, "out of memory writing %zu points to '%s'", n, path);
    } catch (const std::exception &e) {
        return fm_fail(err, FM_ERR_INTERNAL, "OpenVDB failed writing '%s': %s", path, e.what());
    } catch (...) {
        return fm_fail(err, FM_ERR_INTERNAL, "OpenVDB failed writing '%s'", path);
    }
}

extern "C" fm_status fm_vdb_points_read(const char *path, size_t *n, float **positions,
                                        float **velocities, int32_t **ids, double *voxel_size,
                                        fm_error *err)
{
    *n = 0;
    *positions = *velocities = nullptr;
    *ids = nullptr;
    fm_status st;
    try {
        st = read_points(path, n, positions, velocities, ids, voxel_size, err);
    } catch (const std::bad_alloc &) {
        st = fm_fail(err, FM_ERR_MEMORY, "out of memory reading '%s'", path);
    } catch (const openvdb::IoError &e) {
        st = fm_fail(err, FM_ERR_INPUT, "cannot read '%s': %s", path, e.what());
    } catch (const std::exception &e) {
        st = fm_fail(err, FM_ERR_INPUT, "cannot read '%s': %s", path, e.what());
    } catch (...) {
        st = fm_fail(err, FM_ERR_INTERNAL, "OpenVDB failed reading '%s'", path);
    }
    if (st != FM_OK) {
        std::free(*positions), std::free(*velocities), std::free(*ids);
        *positions = *velocities = nullptr;
        *ids = nullptr;
        *n = 0;
    }
    return st;
}
