// TetGen adapter (FM §4): the only C++ in the tetrahedralization path, behind extern "C".
// TetGen 1.5 reports failures by throwing an int (with TETLIBRARY defined) and crashes on
// self-intersecting input, so a detect-only pass ("d") runs first; every exception is caught
// here and turned into an fm_status with a message.
#define TETLIBRARY
#include <tetgen.h>

#include <cstdio>
#include <cstring>
#include <new>

extern "C" {
#include "prep.h"
}

namespace {

void fill_input(const fm_mesh *mesh, tetgenio &in)
{
    in.firstnumber = 0;
    in.numberofpoints = (int)mesh->nv;
    in.pointlist = new REAL[3 * mesh->nv];
    std::memcpy(in.pointlist, mesh->v, sizeof(REAL) * 3 * mesh->nv);
    in.numberoffacets = (int)mesh->nt;
    in.facetlist = new tetgenio::facet[mesh->nt];
    for (int64_t t = 0; t < mesh->nt; t++) {
        tetgenio::facet &f = in.facetlist[t];
        f.numberofpolygons = 1;
        f.polygonlist = new tetgenio::polygon[1];
        f.numberofholes = 0;
        f.holelist = nullptr;
        f.polygonlist[0].numberofvertices = 3;
        f.polygonlist[0].vertexlist = new int[3];
        for (int k = 0; k < 3; k++) f.polygonlist[0].vertexlist[k] = mesh->tri[3 * t + k];
    }
}

const char *tetgen_reason(int code)
{
    switch (code) {
    case 1: return "TetGen ran out of memory";
    case 2: return "TetGen hit an internal error";
    case 3: return "the surface intersects itself";
    case 4: return "the surface has a very small feature (faces or edges nearly touching)";
    case 5: return "two surface facets are very close to each other";
    case 10: return "TetGen rejected the input";
    default: return "TetGen failed";
    }
}

// Runs TetGen's self-intersection detection; non-zero count means the surface intersects itself.
int count_intersecting_faces(tetgenio &in)
{
    tetgenio check;
    tetrahedralize((char *)"dzQ", &in, &check);
    return check.numberoftrifaces;
}

fm_status copy_tets(const tetgenio &out, const char *name, fm_tets *tets, fm_error *err)
{
    if (out.numberoftetrahedra <= 0 || out.numberofcorners < 4)
        return fm_fail(err, FM_ERR_INPUT, "%s: TetGen produced no tetrahedra (is the surface "
                       "closed and non-degenerate?)", name);
    tets->n = out.numberoftetrahedra;
    tets->v = (double *)std::malloc(sizeof(double) * 12 * (size_t)tets->n);
    if (!tets->v) return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for tets", name);
    for (int64_t t = 0; t < tets->n; t++) {
        double *dst = tets->v + 12 * t;
        for (int k = 0; k < 4; k++) {
            int p = out.tetrahedronlist[t * out.numberofcorners + k];
            std::memcpy(dst + 3 * k, out.pointlist + 3 * p, 3 * sizeof(double));
        }
        if (fm_tet_signed_volume(dst) < 0) { // engine convention: positive orientation
            double tmp[3];
            std::memcpy(tmp, dst + 6, sizeof tmp);
            std::memcpy(dst + 6, dst + 9, sizeof tmp);
            std::memcpy(dst + 9, tmp, sizeof tmp);
        }
    }
    return FM_OK;
}

} // namespace

extern "C" fm_status fm_tetrahedralize(const fm_mesh *mesh, double quality, double max_volume,
                                       const char *name, fm_tets *out, fm_error *err)
{
    out->v = nullptr;
    out->n = 0;
    try {
        tetgenio in;
        fill_input(mesh, in);
        int bad = count_intersecting_faces(in);
        if (bad > 0)
            return fm_fail(err, FM_ERR_INPUT, "%s: the surface intersects itself (%d triangles "
                           "involved); TetGen cannot mesh it", name, bad);
        char switches[96];
        if (max_volume > 0)
            std::snprintf(switches, sizeof switches, "pq%.6ga%.9gzQ", quality, max_volume);
        else
            std::snprintf(switches, sizeof switches, "pq%.6gzQ", quality);
        tetgenio result;
        tetrahedralize(switches, &in, &result);
        return copy_tets(result, name, out, err);
    } catch (int code) {
        return fm_fail(err, code == 1 ? FM_ERR_MEMORY : FM_ERR_INPUT,
                       "%s: tetrahedralization failed: %s (TetGen code %d)", name,
                       tetgen_reason(code), code);
    } catch (std::bad_alloc &) {
        return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory in TetGen", name);
    } catch (...) {
        return fm_fail(err, FM_ERR_INTERNAL, "%s: TetGen failed with an unknown exception", name);
    }
}

extern "C" void fm_tets_free(fm_tets *tets)
{
    std::free(tets->v);
    tets->v = nullptr;
    tets->n = 0;
}
