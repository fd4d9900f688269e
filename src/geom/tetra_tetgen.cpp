// TetGen adapter (FM §4): the only C++ in the tetrahedralization path, behind extern "C".
// TetGen 1.5 reports failures by throwing an int (with TETLIBRARY defined) and crashes on
// self-intersecting input, so a detect-only pass ("d") runs first; every exception is caught
// here and turned into an fm_status with a message. Regions TetGen fills that lie outside the
// solid (cavities) are dropped by a winding-number test.
#define TETLIBRARY
#include <tetgen.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <new>
#include <string>
#include <vector>

extern "C" {
#include "geom.h"
}

namespace {

// One facet per triangle of the meshes (their vertices concatenated); facet markers number the
// triangles from 1 across all meshes, so TetGen's reports name them.
void fill_input(const fm_mesh *const *meshes, int count, tetgenio &in)
{
    int64_t nv = 0, nt = 0;
    for (int i = 0; i < count; i++) nv += meshes[i]->nv, nt += meshes[i]->nt;
    in.firstnumber = 0;
    in.numberofpoints = (int)nv;
    in.pointlist = new REAL[3 * nv];
    in.numberoffacets = (int)nt;
    in.facetlist = new tetgenio::facet[nt];
    in.facetmarkerlist = new int[nt];
    for (int i = 0, vbase = 0, t0 = 0; i < count; vbase += (int)meshes[i]->nv, t0 += (int)meshes[i]->nt, i++) {
        const fm_mesh *mesh = meshes[i];
        std::memcpy(in.pointlist + 3 * vbase, mesh->v, sizeof(REAL) * 3 * mesh->nv);
        for (int64_t t = 0; t < mesh->nt; t++) {
            tetgenio::facet &f = in.facetlist[t0 + t];
            f.numberofpolygons = 1;
            f.polygonlist = new tetgenio::polygon[1];
            f.numberofholes = 0;
            f.holelist = nullptr;
            f.polygonlist[0].numberofvertices = 3;
            f.polygonlist[0].vertexlist = new int[3];
            for (int k = 0; k < 3; k++) f.polygonlist[0].vertexlist[k] = vbase + mesh->tri[3 * t + k];
            in.facetmarkerlist[t0 + t] = (int)(t0 + t + 1);
        }
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

// TetGen fills every region its facets enclose, cavities included. With the "A" switch each
// region gets its own attribute; keep the regions whose first tet lies inside the solid.
std::vector<char> solid_regions(const tetgenio &out, const fm_mesh *mesh, double orientation)
{
    std::vector<char> keep(out.numberoftetrahedra, 1);
    if (out.numberoftetrahedronattributes < 1) return keep;
    std::map<double, char> inside; // region attribute -> inside the solid?
    for (int t = 0; t < out.numberoftetrahedra; t++) {
        double region = out.tetrahedronattributelist[t * out.numberoftetrahedronattributes];
        auto it = inside.find(region);
        if (it == inside.end()) {
            double c[3] = {0, 0, 0};
            for (int k = 0; k < 4; k++)
                for (int i = 0; i < 3; i++) c[i] += 0.25 * out.pointlist[3 * out.tetrahedronlist[t * out.numberofcorners + k] + i];
            it = inside.emplace(region, orientation * fm_mesh_winding_number(mesh, c) > 0.5).first;
        }
        keep[t] = it->second;
    }
    return keep;
}

// TetGen's self-intersection detection ("d"): the markers (triangle numbers from 1, sorted) of
// the triangles it finds crossing another; empty if the surface is clean.
std::vector<int> intersecting_triangles(tetgenio &in)
{
    tetgenio check;
    tetrahedralize((char *)"dzQ", &in, &check);
    std::vector<int> found;
    for (int i = 0; i < check.numberoftrifaces; i++)
        found.push_back(check.trifacemarkerlist ? check.trifacemarkerlist[i] : 0);
    std::sort(found.begin(), found.end());
    return found;
}

// "triangles 3, 4, 7 and 5 more" for a message.
std::string triangle_list(const std::vector<int> &tris)
{
    std::string s = tris.size() == 1 ? "triangle " : "triangles ";
    size_t shown = std::min<size_t>(tris.size(), 8);
    for (size_t i = 0; i < shown; i++) s += (i ? ", " : "") + std::to_string(tris[i]);
    if (tris.size() > shown) s += " and " + std::to_string(tris.size() - shown) + " more";
    return s;
}

fm_status copy_tets(const tetgenio &out, const std::vector<char> &keep, const char *name, fm_tets *tets,
                    fm_error *err)
{
    int64_t count = 0;
    for (char k : keep) count += k;
    if (out.numberofcorners < 4 || count == 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: TetGen produced no tetrahedra (is the surface "
                       "closed and non-degenerate?)", name);
    tets->n = count;
    tets->v = (double *)std::malloc(sizeof(double) * 12 * (size_t)tets->n);
    if (!tets->v) return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for tets", name);
    for (int64_t t = 0, j = 0; t < out.numberoftetrahedra; t++) {
        if (!keep[t]) continue;
        double *dst = tets->v + 12 * j++;
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
        fill_input(&mesh, 1, in);
        std::vector<int> bad = intersecting_triangles(in);
        if (!bad.empty()) {
            const double *c = mesh->v + 3 * (int64_t)mesh->tri[3 * (int64_t)(bad[0] > 0 ? bad[0] - 1 : 0)];
            return fm_fail(err, FM_ERR_INPUT, "%s: the surface intersects itself: TetGen finds %s crossing other "
                           "triangles (triangle %d has a corner at (%g, %g, %g) in the world); TetGen cannot mesh it",
                           name, triangle_list(bad).c_str(), bad[0], c[0], c[1], c[2]);
        }
        // Facets with different markers are never merged, so TetGen would keep every triangle as a
        // constraint and make many more tets: the meshing pass runs without them.
        delete[] in.facetmarkerlist;
        in.facetmarkerlist = nullptr;
        char switches[96];
        if (max_volume > 0)
            std::snprintf(switches, sizeof switches, "pq%.6ga%.9gAzQ", quality, max_volume);
        else
            std::snprintf(switches, sizeof switches, "pq%.6gAzQ", quality);
        tetgenio result;
        tetrahedralize(switches, &in, &result);
        double orientation = fm_mesh_signed_volume(mesh) < 0 ? -1.0 : 1.0; // inside-out meshes are fine
        return copy_tets(result, solid_regions(result, mesh, orientation), name, out, err);
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

// Van Oosterom & Strackee solid angles: ~1 inside an outward-facing surface, ~0 outside and
// inside cavities, ~-1 inside an inward-facing one.
extern "C" double fm_mesh_winding_number(const fm_mesh *mesh, const double p[3])
{
    double total = 0;
    for (int64_t t = 0; t < mesh->nt; t++) {
        double a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = mesh->v[3 * mesh->tri[3 * t] + k] - p[k];
            b[k] = mesh->v[3 * mesh->tri[3 * t + 1] + k] - p[k];
            c[k] = mesh->v[3 * mesh->tri[3 * t + 2] + k] - p[k];
        }
        double la = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        double lb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        double lc = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
        double dot = la * lb * lc + (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) * lc +
                     (b[0] * c[0] + b[1] * c[1] + b[2] * c[2]) * la + (c[0] * a[0] + c[1] * a[1] + c[2] * a[2]) * lb;
        total += 2 * std::atan2(det, dot);
    }
    return total / (4 * 3.14159265358979323846);
}

namespace {

bool boxes_apart(const fm_mesh *a, const fm_mesh *b)
{
    for (int k = 0; k < 3; k++) {
        double alo = INFINITY, ahi = -INFINITY, blo = INFINITY, bhi = -INFINITY;
        for (int64_t i = 0; i < a->nv; i++) alo = std::fmin(alo, a->v[3 * i + k]), ahi = std::fmax(ahi, a->v[3 * i + k]);
        for (int64_t i = 0; i < b->nv; i++) blo = std::fmin(blo, b->v[3 * i + k]), bhi = std::fmax(bhi, b->v[3 * i + k]);
        if (ahi < blo || bhi < alo) return true;
    }
    return false;
}

// A closed, consistently oriented surface: only such a mesh has an inside.
bool encloses(const fm_mesh *m)
{
    fm_error ignored = {};
    return fm_mesh_pair_edges(m, "", nullptr, nullptr, &ignored) == FM_OK;
}

} // namespace

extern "C" int fm_meshes_overlap(const fm_mesh *a, const char *name_a, const fm_mesh *b, const char *name_b,
                                 char *how, size_t how_size, fm_error *err)
{
    if (boxes_apart(a, b)) return 0;
    try {
        tetgenio in;
        const fm_mesh *both[2] = {a, b};
        fill_input(both, 2, in);
        std::vector<int> crossing = intersecting_triangles(in);
        int in_a = 0, in_b = 0; // the first crossing triangle of each (markers above a->nt are b's)
        for (int m : crossing) {
            if (m <= a->nt && !in_a) in_a = m;
            if (m > a->nt && !in_b) in_b = m - (int)a->nt;
        }
        if (in_a && in_b) {
            std::snprintf(how, how_size, "their surfaces intersect (triangle %d of %s and triangle %d of %s; TetGen finds "
                          "%zu intersecting triangles)", in_a, name_a, in_b, name_b, crossing.size());
            return 1;
        }
        if (encloses(b) && std::fabs(fm_mesh_winding_number(b, a->v)) > 0.5) {
            std::snprintf(how, how_size, "%s lies inside %s", name_a, name_b);
            return 1;
        }
        if (encloses(a) && std::fabs(fm_mesh_winding_number(a, b->v)) > 0.5) {
            std::snprintf(how, how_size, "%s lies inside %s", name_b, name_a);
            return 1;
        }
        return 0;
    } catch (int code) {
        // TetGen refuses surfaces that touch (shared or nearly coincident points and facets).
        std::snprintf(how, how_size, "their surfaces touch (%s, TetGen code %d)", tetgen_reason(code), code);
        return code == 1 ? (fm_fail(err, FM_ERR_MEMORY, "out of memory in TetGen"), -1) : 1;
    } catch (std::bad_alloc &) {
        fm_fail(err, FM_ERR_MEMORY, "out of memory in TetGen");
        return -1;
    } catch (...) {
        fm_fail(err, FM_ERR_INTERNAL, "TetGen failed with an unknown exception");
        return -1;
    }
}
