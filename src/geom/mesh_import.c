/* Mesh import through assimp's C API, exact vertex welding, and the closed-manifold check. */
#include "geom.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void fm_mesh_free(fm_mesh *mesh)
{
    free(mesh->v);
    free(mesh->tri);
    memset(mesh, 0, sizeof *mesh);
}

static int compare_xyz(const void *a, const void *b, const double *v)
{
    const double *p = v + 3 * *(const int64_t *)a, *q = v + 3 * *(const int64_t *)b;
    for (int k = 0; k < 3; k++) {
        if (p[k] < q[k]) return -1;
        if (p[k] > q[k]) return 1;
    }
    return 0;
}

static const double *g_sort_vertices; /* qsort has no context argument in C17 */
static int compare_vertex_index(const void *a, const void *b)
{
    int c = compare_xyz(a, b, g_sort_vertices);
    if (c) return c;
    int64_t i = *(const int64_t *)a, j = *(const int64_t *)b;
    return (i > j) - (i < j);
}

/* Merges vertices with exactly equal positions (STL and glTF repeat them per face). With file_vertex,
 * hands over remap: for each vertex as read, the welded vertex it became. */
static fm_status weld_vertices(fm_mesh *mesh, int32_t **file_vertex, fm_error *err)
{
    int64_t n = mesh->nv;
    int64_t *idx = malloc(sizeof *idx * (size_t)(n ? n : 1));
    int32_t *remap = malloc(sizeof *remap * (size_t)(n ? n : 1));
    double *welded = malloc(sizeof *welded * 3 * (size_t)(n ? n : 1));
    if (!idx || !remap || !welded) {
        free(idx), free(remap), free(welded);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory welding %lld vertices", (long long)n);
    }
    for (int64_t i = 0; i < n; i++) idx[i] = i;
    g_sort_vertices = mesh->v;
    qsort(idx, (size_t)n, sizeof *idx, compare_vertex_index);
    int64_t unique = 0;
    for (int64_t k = 0; k < n; k++) {
        if (k == 0 || compare_xyz(&idx[k - 1], &idx[k], mesh->v) != 0) {
            memcpy(welded + 3 * unique, mesh->v + 3 * idx[k], 3 * sizeof(double));
            unique++;
        }
        remap[idx[k]] = (int32_t)(unique - 1);
    }
    for (int64_t t = 0; t < 3 * mesh->nt; t++) mesh->tri[t] = remap[mesh->tri[t]];
    free(mesh->v);
    mesh->v = welded;
    mesh->nv = unique;
    free(idx);
    if (file_vertex) *file_vertex = remap;
    else free(remap);
    return FM_OK;
}

/* Copies every triangle of every assimp mesh (already in world space) into one mesh. */
static fm_status gather_triangles(const struct aiScene *scene, const char *path, fm_mesh *out,
                                  fm_error *err)
{
    int64_t nv = 0, nt = 0;
    for (unsigned m = 0; m < scene->mNumMeshes; m++) {
        const struct aiMesh *am = scene->mMeshes[m];
        nv += am->mNumVertices;
        for (unsigned f = 0; f < am->mNumFaces; f++) nt += am->mFaces[f].mNumIndices == 3;
    }
    if (nt == 0) return fm_fail(err, FM_ERR_INPUT, "%s: the mesh has no triangles (is it empty, or not a mesh?)", path);
    if (nv > INT32_MAX)
        return fm_fail(err, FM_ERR_INPUT, "%s: %lld vertices is more than supported (2^31)", path,
                       (long long)nv);
    out->v = malloc(sizeof(double) * 3 * (size_t)nv);
    out->tri = malloc(sizeof(int32_t) * 3 * (size_t)nt);
    if (!out->v || !out->tri) {
        fm_mesh_free(out);
        return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for %lld triangles", path,
                       (long long)nt);
    }
    int64_t vbase = 0, t = 0;
    for (unsigned m = 0; m < scene->mNumMeshes; m++) {
        const struct aiMesh *am = scene->mMeshes[m];
        for (unsigned i = 0; i < am->mNumVertices; i++) {
            out->v[3 * (vbase + i) + 0] = am->mVertices[i].x;
            out->v[3 * (vbase + i) + 1] = am->mVertices[i].y;
            out->v[3 * (vbase + i) + 2] = am->mVertices[i].z;
        }
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            const struct aiFace *face = &am->mFaces[f];
            if (face->mNumIndices != 3) continue; /* points and lines carry no volume */
            for (int k = 0; k < 3; k++) out->tri[3 * t + k] = (int32_t)(vbase + face->mIndices[k]);
            t++;
        }
        vbase += am->mNumVertices;
    }
    out->nv = nv;
    out->nt = nt;
    return FM_OK;
}

static fm_status check_finite(const fm_mesh *mesh, const char *path, fm_error *err)
{
    for (int64_t i = 0; i < 3 * mesh->nv; i++)
        if (!isfinite(mesh->v[i]))
            return fm_fail(err, FM_ERR_INPUT, "%s: vertex %lld has a non-finite coordinate", path,
                           (long long)(i / 3 + 1));
    return FM_OK;
}

/* A face without indices cannot come from a sound file; some readers (binary PLY: a face whose
 * list count is 0) still make one. assimp's ValidateDataStructure runs before its scene
 * preprocessor has set the primitive types, so it does not see it; the preprocessor then marks such
 * a face as a polygon and the triangulation's assertion aborts the process. So the faces are
 * checked here, between the import and the post-processing. */
static fm_status check_faces(const struct aiScene *scene, const char *name, fm_error *err)
{
    for (unsigned m = 0; m < scene->mNumMeshes; m++)
        for (unsigned f = 0; f < scene->mMeshes[m]->mNumFaces; f++)
            if (scene->mMeshes[m]->mFaces[f].mNumIndices == 0)
                return fm_fail(err, FM_ERR_INPUT, "%s: face %u (of mesh %u in the file) has no vertex indices: the "
                               "file is damaged", name, f + 1, m + 1);
    return FM_OK;
}

/* assimp failed to read (or triangulate) the mesh. Its C API catches its own exceptions and keeps
 * only their text: an allocation that failed inside it (std::bad_alloc, under ulimit -v) is out of
 * memory (exit 4), not a mesh it cannot read (issue 42). */
static fm_status import_failed(const char *name, const char *step, fm_error *err)
{
    const char *why = aiGetErrorString();
    if (strstr(why, "bad_alloc"))
        return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory reading the mesh (assimp: %s)", name, why);
    if (!strcmp(step, "read"))
        return fm_fail(err, FM_ERR_INPUT, "%s: cannot read the mesh (%s); supported: OBJ, PLY, STL, OFF, glTF", name, why);
    return fm_fail(err, FM_ERR_INPUT, "%s: cannot %s the mesh (%s)", name, step, why);
}

/* How take_scene hands the vertices over. */
typedef enum vertex_mode {
    WELDED,        /* coincident vertices merged (fm_mesh_load) */
    WELDED_MAPPED, /* the same, with the map from the vertices as read (fm_mesh_load_mapped) */
    AS_READ        /* as assimp reads them, unmerged (fm_mesh_load_as_read) */
} vertex_mode;

/* Triangles of an imported assimp scene (NULL: the import failed) into out, welded or not. */
static fm_status take_scene(const struct aiScene *scene, const char *name, vertex_mode mode, fm_mesh *out,
                            int32_t **file_vertex, int64_t *file_count, fm_error *err)
{
    if (!scene) return import_failed(name, "read", err);
    fm_status st = check_faces(scene, name, err);
    if (st != FM_OK) {
        aiReleaseImport(scene);
        return st;
    }
    /* releases the scene itself if a step fails */
    if (!(scene = aiApplyPostProcessing(scene, aiProcess_Triangulate | aiProcess_PreTransformVertices)))
        return import_failed(name, "triangulate", err);
    st = gather_triangles(scene, name, out, err);
    aiReleaseImport(scene);
    if (st == FM_OK) st = check_finite(out, name, err);
    if (st == FM_OK && file_count) *file_count = out->nv;
    if (st == FM_OK && mode != AS_READ) st = weld_vertices(out, mode == WELDED_MAPPED ? file_vertex : NULL, err);
    if (st != FM_OK) fm_mesh_free(out);
    return st;
}

/* The import runs only assimp's ValidateDataStructure, which rejects what a damaged file leaves
 * behind (a face without an index array, an index past the vertices); without it, assimp's later
 * steps abort the process. The triangulation follows in take_scene, after check_faces. */
static const unsigned IMPORT_FLAGS = aiProcess_ValidateDataStructure;

static fm_status load_file(const char *path, vertex_mode mode, fm_mesh *out, int32_t **file_vertex,
                           int64_t *file_count, fm_error *err)
{
    memset(out, 0, sizeof *out);
    fm_status st = fm_check_input_file(path, "mesh", err);
    if (st == FM_OK) st = fm_mesh_check_file_counts(path, err);
    if (st != FM_OK) return st;
    return take_scene(aiImportFile(path, IMPORT_FLAGS), path, mode, out, file_vertex, file_count, err);
}

fm_status fm_mesh_load(const char *path, fm_mesh *out, fm_error *err)
{
    return load_file(path, WELDED, out, NULL, NULL, err);
}

fm_status fm_mesh_load_mapped(const char *path, fm_mesh *out, int32_t **file_vertex, int64_t *file_count,
                              fm_error *err)
{
    *file_vertex = NULL;
    return load_file(path, WELDED_MAPPED, out, file_vertex, file_count, err);
}

fm_status fm_mesh_load_as_read(const char *path, fm_mesh *out, fm_error *err)
{
    return load_file(path, AS_READ, out, NULL, NULL, err);
}

fm_status fm_mesh_parse(const void *data, size_t len, const char *format, const char *name, fm_mesh *out,
                        fm_error *err)
{
    memset(out, 0, sizeof *out);
    if (len == 0 || len > UINT32_MAX) return fm_fail(err, FM_ERR_INPUT, "%s: the mesh data is empty or too large", name);
    fm_status st = fm_mesh_check_counts(data, len, format, name, err);
    if (st != FM_OK) return st;
    return take_scene(aiImportFileFromMemory(data, (unsigned)len, IMPORT_FLAGS, format), name, WELDED, out, NULL, NULL, err);
}

typedef struct directed_edge {
    int32_t lo, hi;   /* undirected key */
    int32_t forward;  /* 1 if the triangle walks lo -> hi */
    int64_t half;     /* 3 * triangle + corner: the edge from corner k to corner k + 1 */
} directed_edge;

static int compare_edges(const void *a, const void *b)
{
    const directed_edge *e = a, *f = b;
    if (e->lo != f->lo) return (e->lo > f->lo) - (e->lo < f->lo);
    if (e->hi != f->hi) return (e->hi > f->hi) - (e->hi < f->hi);
    return (e->half > f->half) - (e->half < f->half);
}

static fm_status edge_error(const fm_mesh *mesh, const char *name, const directed_edge *e,
                            const char *what, fm_error *err)
{
    const double *a = mesh->v + 3 * (int64_t)e->lo, *b = mesh->v + 3 * (int64_t)e->hi;
    return fm_fail(err, FM_ERR_INPUT,
                   "%s: the mesh is not a closed manifold: the edge (%g, %g, %g)-(%g, %g, %g) "
                   "of triangle %lld %s", name, a[0], a[1], a[2], b[0], b[1], b[2],
                   (long long)(e->half / 3 + 1), what);
}

/* A triangle whose area is below this fraction of its longest edge squared has (up to rounding)
 * collinear corners: it has no normal, and TetGen fails on it. */
#define ZERO_AREA_RATIO 1e-12

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Twice the triangle's area, and its longest edge squared. */
static double twice_area(const fm_mesh *mesh, const int32_t *f, double *longest2)
{
    const double *p[3] = {mesh->v + 3 * (int64_t)f[0], mesh->v + 3 * (int64_t)f[1], mesh->v + 3 * (int64_t)f[2]};
    double e[3][3], c[3];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) e[i][k] = p[(i + 1) % 3][k] - p[i][k];
    c[0] = e[0][1] * e[1][2] - e[0][2] * e[1][1];
    c[1] = e[0][2] * e[1][0] - e[0][0] * e[1][2];
    c[2] = e[0][0] * e[1][1] - e[0][1] * e[1][0];
    *longest2 = fmax(dot3(e[0], e[0]), fmax(dot3(e[1], e[1]), dot3(e[2], e[2])));
    return sqrt(dot3(c, c));
}

static fm_status check_degenerate(const fm_mesh *mesh, const char *name, fm_error *err)
{
    for (int64_t t = 0; t < mesh->nt; t++) {
        const int32_t *f = mesh->tri + 3 * t;
        if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2])
            return fm_fail(err, FM_ERR_INPUT, "%s: triangle %lld is degenerate (two corners at the "
                           "same position)", name, (long long)t + 1);
        double longest2, area2 = twice_area(mesh, f, &longest2);
        if (!(area2 > ZERO_AREA_RATIO * longest2)) {
            const double *a = mesh->v + 3 * (int64_t)f[0];
            return fm_fail(err, FM_ERR_INPUT, "%s: triangle %lld (corner (%g, %g, %g)) is degenerate: zero area, "
                           "its corners lie on one line", name, (long long)t + 1, a[0], a[1], a[2]);
        }
    }
    return FM_OK;
}

/* A closed surface can still enclose nothing: a flat sheet of two back-to-back triangles, or parts
 * whose volumes cancel. TetGen asserts (aborts) on a flat input, so this is checked first. */
static fm_status check_volume(const fm_mesh *mesh, const char *name, fm_error *err)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int64_t i = 0; i < mesh->nv; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], mesh->v[3 * i + k]), hi[k] = fmax(hi[k], mesh->v[3 * i + k]);
    double d[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}, diagonal = sqrt(dot3(d, d));
    double volume = fm_mesh_signed_volume(mesh);
    if (fabs(volume) > 1e-9 * diagonal * diagonal * diagonal) return FM_OK;
    return fm_fail(err, FM_ERR_INPUT, "%s: the mesh encloses no volume (%g in a %g x %g x %g box): it is flat, "
                   "or its parts cancel out", name, volume, d[0], d[1], d[2]);
}

fm_status fm_mesh_pair_edges(const fm_mesh *mesh, const char *name, fm_edge_pair_fn pair, void *user,
                             fm_error *err)
{
    size_t ne = 3 * (size_t)mesh->nt;
    directed_edge *edges = malloc(sizeof *edges * (ne ? ne : 1));
    if (!edges) return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory checking edges", name);
    for (int64_t t = 0; t < mesh->nt; t++) {
        for (int k = 0; k < 3; k++) {
            int32_t a = mesh->tri[3 * t + k], b = mesh->tri[3 * t + (k + 1) % 3];
            edges[3 * t + k] = (directed_edge){FM_MIN(a, b), FM_MAX(a, b), a < b, 3 * t + k};
        }
    }
    qsort(edges, ne, sizeof *edges, compare_edges);
    fm_status st = FM_OK;
    for (size_t i = 0; i < ne && st == FM_OK;) {
        size_t j = i;
        while (j < ne && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) j++;
        if (j - i == 1)
            st = edge_error(mesh, name, &edges[i], "has no neighbour: the surface has a hole there", err);
        else if (j - i > 2)
            st = edge_error(mesh, name, &edges[i], "is shared by more than two triangles", err);
        else if (edges[i].forward == edges[i + 1].forward)
            st = edge_error(mesh, name, &edges[i], "runs the same way in both of its triangles: "
                            "their orientations disagree", err);
        else if (pair)
            pair(edges[i].half, edges[i + 1].half, user);
        i = j;
    }
    free(edges);
    return st;
}

fm_status fm_mesh_check_closed(const fm_mesh *mesh, const char *path, fm_error *err)
{
    fm_status st = check_degenerate(mesh, path, err);
    if (st == FM_OK) st = fm_mesh_pair_edges(mesh, path, NULL, NULL, err);
    return st == FM_OK ? check_volume(mesh, path, err) : st;
}

void fm_mesh_place(fm_mesh *mesh, const fm_mesh_ref *ref)
{
    const double deg = 3.14159265358979323846 / 180.0;
    double c[3], s[3];
    for (int k = 0; k < 3; k++) c[k] = cos(ref->rotate_deg[k] * deg), s[k] = sin(ref->rotate_deg[k] * deg);
    for (int64_t i = 0; i < mesh->nv; i++) {
        double *p = mesh->v + 3 * i;
        double x = ref->scale * p[0], y = ref->scale * p[1], z = ref->scale * p[2], t;
        t = c[0] * y - s[0] * z, z = s[0] * y + c[0] * z, y = t; /* about X */
        t = c[1] * x + s[1] * z, z = -s[1] * x + c[1] * z, x = t; /* about Y */
        t = c[2] * x - s[2] * y, y = s[2] * x + c[2] * y, x = t; /* about Z */
        p[0] = x + ref->translate[0];
        p[1] = y + ref->translate[1];
        p[2] = z + ref->translate[2];
    }
}

/* The agents and the cache hold float32 positions (2^-23, about 1.2e-7, relative): a mesh that spans
 * less than 1e-6 of its largest coordinate is under 8 float32 steps across and cannot keep its
 * shape (and in double the placement itself may collapse it: scale 1e-30 at translate 10 rounds
 * every vertex to the same point, on which TetGen asserts). Below 1e-9 units, even away from the
 * origin, the volumes of a billion tets (extent^3 / n) fall under float32's smallest normal number,
 * and TetGen's predicates (products of up to five coordinate differences) approach double's. */
fm_status fm_mesh_check_extent(const fm_mesh *mesh, const char *path, fm_error *err)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, extent = 0, far = 0;
    for (int64_t i = 0; i < mesh->nv; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], mesh->v[3 * i + k]), hi[k] = fmax(hi[k], mesh->v[3 * i + k]);
    for (int k = 0; k < 3; k++) extent = fmax(extent, hi[k] - lo[k]), far = fmax(far, fmax(fabs(lo[k]), fabs(hi[k])));
    double least = fmax(FM_MESH_MIN_EXTENT, FM_MESH_MIN_RELATIVE_EXTENT * far);
    if (mesh->nv == 0 || extent >= least) return FM_OK;
    return fm_fail(err, FM_ERR_INPUT, "%s: placed in the world (scale, rotate_deg, translate) the mesh spans %g, "
                   "less than the %g it needs (%g units, and %g of its largest coordinate %g) to keep its shape in "
                   "the agents' float32 precision: raise scale or move it nearer the origin", path, extent, least,
                   FM_MESH_MIN_EXTENT, FM_MESH_MIN_RELATIVE_EXTENT, far);
}

double fm_mesh_signed_volume(const fm_mesh *mesh)
{
    double vol = 0;
    for (int64_t t = 0; t < mesh->nt; t++) {
        const double *a = mesh->v + 3 * mesh->tri[3 * t], *b = mesh->v + 3 * mesh->tri[3 * t + 1],
                     *c = mesh->v + 3 * mesh->tri[3 * t + 2];
        vol += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
               a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    return vol / 6.0;
}
