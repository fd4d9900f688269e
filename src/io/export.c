/* Exporters: one frame of tets or points to PLY, OBJ, VTK or VDB (include/flockmorph/export.h).
 *
 * Each tet becomes 4 vertices and 4 triangles (0,2,1), (0,1,3), (0,3,2), (1,2,3), which face
 * outward when the tet has positive signed volume det[v1-v0, v2-v0, v3-v0] > 0. Points become
 * vertices only. Every file is written as PATH.partial and renamed to PATH only when every write
 * succeeded. */
#define _POSIX_C_SOURCE 200809L
#include "export.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

const int fm_tet_faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

/* ---------------------------------------------------------------- formats and names */

static const struct {
    fm_export_format format;
    const char *name, *extension;
} fm_formats[] = {{FM_EXPORT_PLY, "ply", "ply"},
                  {FM_EXPORT_OBJ, "obj", "obj"},
                  {FM_EXPORT_VTK, "vtk", "vtu"},
                  {FM_EXPORT_VDB, "vdb", "vdb"},
                  {FM_EXPORT_PC2, "pc2", "pc2"},
                  {FM_EXPORT_MDD, "mdd", "mdd"}};
#define FM_FORMAT_COUNT (sizeof fm_formats / sizeof fm_formats[0])

fm_export_format fm_export_format_named(const char *name)
{
    for (size_t i = 0; name && i < FM_FORMAT_COUNT; i++)
        if (!strcasecmp(name, fm_formats[i].name)) return fm_formats[i].format;
    return FM_EXPORT_UNKNOWN;
}

fm_export_format fm_export_format_of_path(const char *path)
{
    const char *slash = path ? strrchr(path, '/') : NULL;
    const char *base = slash ? slash + 1 : path;
    const char *dot = base ? strrchr(base, '.') : NULL;
    for (size_t i = 0; dot && i < FM_FORMAT_COUNT; i++)
        if (!strcasecmp(dot + 1, fm_formats[i].extension)) return fm_formats[i].format;
    return FM_EXPORT_UNKNOWN;
}

const char *fm_export_extension(fm_export_format format)
{
    for (size_t i = 0; i < FM_FORMAT_COUNT; i++)
        if (fm_formats[i].format == format) return fm_formats[i].extension;
    return "";
}

fm_export_options fm_default_export_options(void)
{
    return (fm_export_options){.voxel_size = 0.0, .points_per_voxel = 8, .vtk_zlib_level = FM_EXPORT_VTK_ZLIB_DEFAULT};
}

/* ---------------------------------------------------------------- little-endian output */

static int le_flush(fm_le_writer *w)
{
    if (!w->failed && w->used && fwrite(w->buf, 1, w->used, w->f) != w->used) w->failed = 1;
    w->used = 0;
    return w->failed ? -1 : 0;
}

int fm_le_write(FILE *f, fm_le_emit_fn emit, const void *data)
{
    fm_le_writer *w = malloc(sizeof *w); /* 64 KiB: not on the stack of a worker thread */
    if (!w) return errno = ENOMEM, -1;
    w->f = f, w->used = 0, w->failed = 0;
    emit(w, data);
    int rc = le_flush(w);
    free(w);
    return rc;
}

static unsigned char *le_reserve(fm_le_writer *w, size_t bytes)
{
    if (w->used + bytes > sizeof w->buf) le_flush(w);
    unsigned char *p = w->buf + w->used;
    w->used += bytes;
    return p;
}

void fm_le_u8(fm_le_writer *w, uint8_t v) { *le_reserve(w, 1) = v; }

void fm_le_u32(fm_le_writer *w, uint32_t v)
{
    unsigned char *p = le_reserve(w, 4);
    for (int k = 0; k < 4; k++) p[k] = (unsigned char)(v >> (8 * k));
}

void fm_le_store_u64(unsigned char *p, uint64_t v)
{
    for (int k = 0; k < 8; k++) p[k] = (unsigned char)(v >> (8 * k));
}

void fm_le_u64(fm_le_writer *w, uint64_t v) { fm_le_store_u64(le_reserve(w, 8), v); }

void fm_le_f32(fm_le_writer *w, float v)
{
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits);
    fm_le_u32(w, bits);
}

/* ---------------------------------------------------------------- PLY */

/* The header up to the vertices' coordinates; %zu is the vertex count. */
#define PLY_VERTICES(what)                                                                          \
    "ply\nformat binary_little_endian 1.0\ncomment flockmorph " FM_VERSION_STRING " " what "\n"    \
    "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"

static uint32_t agent_id(const fm_export_frame *frame, size_t i)
{
    return frame->ids ? frame->ids[i] : (uint32_t)i;
}

/* The vertex properties after x y z, in file order, with Houdini's attribute names: a vector's
 * components are NAMEx NAMEy NAMEz (NAMEw), since PLY has scalars only. */
enum { P_V, P_ORIENT, P_PSCALE, P_AGE, P_ID, P_PHASE, P_GROUP, P_COUNT };
static const struct {
    const char *name, *type;
    int components;
} ply_props[P_COUNT] = {{"v", "float", 3},     {"orient", "float", 4}, {"pscale", "float", 1},
                        {"age", "float", 1},   {"id", "int", 1},       {"phase", "uchar", 1},
                        {"group", "uchar", 1}};

/* Points carry every attribute given and always their id. */
static int has_prop(const fm_export_frame *f, int p)
{
    switch (p) {
    case P_V: return f->velocities != NULL;
    case P_ORIENT: return f->orientations != NULL;
    case P_PSCALE: return f->pscales != NULL;
    case P_AGE: return f->ages != NULL;
    case P_ID: return 1;
    case P_PHASE: return f->phases != NULL;
    default: return f->groups != NULL;
    }
}

static int ply_prop_header(FILE *file, const fm_export_frame *f)
{
    for (int p = 0; p < P_COUNT; p++) {
        for (int c = 0; has_prop(f, p) && c < ply_props[p].components; c++) {
            char suffix[2] = {ply_props[p].components > 1 ? "xyzw"[c] : 0, 0};
            if (fprintf(file, "property %s %s%s\n", ply_props[p].type, ply_props[p].name, suffix) < 0) return -1;
        }
    }
    return 0;
}

/* Agent i's properties (orient reordered from w, x, y, z to x, y, z, w). */
static void ply_emit_props(fm_le_writer *w, const fm_export_frame *f, size_t i)
{
    for (int c = 0; has_prop(f, P_V) && c < 3; c++) fm_le_f32(w, f->velocities[3 * i + c]);
    for (int c = 0; has_prop(f, P_ORIENT) && c < 4; c++) fm_le_f32(w, fm_orient_xyzw(f->orientations + 4 * i, c));
    if (has_prop(f, P_PSCALE)) fm_le_f32(w, f->pscales[i]);
    if (has_prop(f, P_AGE)) fm_le_f32(w, f->ages[i]);
    if (has_prop(f, P_ID)) fm_le_u32(w, agent_id(f, i));
    if (has_prop(f, P_PHASE)) fm_le_u8(w, f->phases[i]);
    if (has_prop(f, P_GROUP)) fm_le_u8(w, f->groups[i]);
}

/* Tets: the vertices carry their own velocity and a point id unique to each, 4 × the tet's id + the
 * vertex (Houdini wants `id` unique per point); the tet's own id, phase and group go on each of its
 * 4 faces, Houdini's primitive attributes. */
static int ply_tets_header(FILE *file, const fm_export_frame *f)
{
    if (fprintf(file, PLY_VERTICES("tets"), 4 * f->n) < 0) return -1;
    if (f->vertex_velocities && fputs("property float vx\nproperty float vy\nproperty float vz\n", file) < 0) return -1;
    if (f->ids && fputs("property int id\n", file) < 0) return -1;
    if (fprintf(file, "element face %zu\nproperty list uchar int vertex_indices\n", 4 * f->n) < 0) return -1;
    if (f->ids && fputs("property int agent_id\n", file) < 0) return -1;
    if (f->phases && fputs("property uchar phase\n", file) < 0) return -1;
    if (f->groups && fputs("property uchar group\n", file) < 0) return -1;
    return fputs("end_header\n", file) < 0 ? -1 : 0;
}

static void ply_tets_data(fm_le_writer *w, const void *data)
{
    const fm_export_frame *frame = data;
    for (size_t t = 0; t < frame->n; t++) {
        for (int j = 0; j < 4; j++) {
            for (int k = 0; k < 3; k++) fm_le_f32(w, frame->tet_vertices[12 * t + 3 * j + k]);
            for (int k = 0; frame->vertex_velocities && k < 3; k++) fm_le_f32(w, frame->vertex_velocities[12 * t + 3 * j + k]);
            if (frame->ids) fm_le_u32(w, fm_tet_point_id(frame->ids[t], j));
        }
    }
    for (size_t t = 0; t < frame->n; t++) {
        for (int j = 0; j < 4; j++) {
            fm_le_u8(w, 3);
            for (int k = 0; k < 3; k++) fm_le_u32(w, (uint32_t)(4 * t + (size_t)fm_tet_faces[j][k]));
            if (frame->ids) fm_le_u32(w, frame->ids[t]);
            if (frame->phases) fm_le_u8(w, frame->phases[t]);
            if (frame->groups) fm_le_u8(w, frame->groups[t]);
        }
    }
}

static int ply_tets_body(FILE *f, const void *data)
{
    const fm_export_frame *frame = data;
    return ply_tets_header(f, frame) ? -1 : fm_le_write(f, ply_tets_data, frame);
}

static void ply_points_data(fm_le_writer *w, const void *data)
{
    const fm_export_frame *frame = data;
    for (size_t i = 0; i < frame->n; i++) {
        for (int k = 0; k < 3; k++) fm_le_f32(w, frame->positions[3 * i + k]);
        ply_emit_props(w, frame, i);
    }
}

/* Points: vertices only, with the attributes given as vertex properties. */
static int ply_points_body(FILE *f, const void *data)
{
    const fm_export_frame *frame = data;
    if (fprintf(f, PLY_VERTICES("points"), frame->n) < 0 || ply_prop_header(f, frame) ||
        fputs("end_header\n", f) < 0)
        return -1;
    return fm_le_write(f, ply_points_data, frame);
}

/* Triangle meshes (a run's placed obstacles): one vertex and one face element for all of them, each
 * mesh's indices offset by the vertices of the meshes before it; a comment per mesh says which
 * vertices and faces are its. */
typedef struct ply_meshes {
    const fm_ply_mesh *m;
    int count;
    const char *comment; /* a header line of its own, or NULL */
} ply_meshes;

static void ply_meshes_data(fm_le_writer *w, const void *data)
{
    const ply_meshes *pm = data;
    for (int i = 0; i < pm->count; i++)
        for (int64_t j = 0; j < 3 * pm->m[i].nv; j++) fm_le_f32(w, (float)pm->m[i].v[j]);
    int64_t base = 0;
    for (int i = 0; i < pm->count; base += pm->m[i].nv, i++)
        for (int64_t t = 0; t < pm->m[i].nt; t++) {
            fm_le_u8(w, 3);
            for (int k = 0; k < 3; k++) fm_le_u32(w, (uint32_t)(base + pm->m[i].tri[3 * t + k]));
        }
}

/* A mesh's name on one line of a header: control characters (a newline in a file name) become '?'. */
static int put_header_text(FILE *f, const char *s)
{
    for (; *s; s++)
        if (fputc((unsigned char)*s < 0x20 ? '?' : *s, f) == EOF) return -1;
    return 0;
}

static int ply_meshes_body(FILE *f, const void *data)
{
    const ply_meshes *pm = data;
    int64_t nv = 0, nt = 0;
    for (int i = 0; i < pm->count; i++) nv += pm->m[i].nv, nt += pm->m[i].nt;
    if (fprintf(f, "ply\nformat binary_little_endian 1.0\ncomment flockmorph %s: %d meshes\n",
                FM_VERSION_STRING, pm->count) < 0)
        return -1;
    if (pm->comment && (fputs("comment ", f) < 0 || put_header_text(f, pm->comment) || fputc('\n', f) == EOF))
        return -1;
    int64_t v0 = 0, t0 = 0;
    for (int i = 0; i < pm->count; v0 += pm->m[i].nv, t0 += pm->m[i].nt, i++)
        if (fputs("comment ", f) < 0 || put_header_text(f, pm->m[i].name) ||
            fprintf(f, ": vertices %lld..%lld, faces %lld..%lld\n", (long long)v0, (long long)(v0 + pm->m[i].nv - 1),
                    (long long)t0, (long long)(t0 + pm->m[i].nt - 1)) < 0)
            return -1;
    if (fprintf(f, "element vertex %lld\nproperty float x\nproperty float y\nproperty float z\n"
                "element face %lld\nproperty list uchar int vertex_indices\nend_header\n", (long long)nv,
                (long long)nt) < 0)
        return -1;
    return fm_le_write(f, ply_meshes_data, pm);
}

fm_status fm_export_ply_meshes(const fm_ply_mesh *meshes, int count, const char *comment, const char *path,
                               fm_error *err)
{
    int64_t nv = 0;
    for (int i = 0; i < count; i++) nv += meshes[i].nv;
    if (nv > INT32_MAX) return fm_fail(err, FM_ERR_INPUT, "'%s': %lld vertices do not fit PLY's int indices", path, (long long)nv);
    const ply_meshes pm = {meshes, count, comment};
    return fm_export_with_body(path, ply_meshes_body, &pm, err);
}

/* ---------------------------------------------------------------- OBJ */

/* %.9g gives every float back bit for bit. */
static int obj_vertices(FILE *f, const float *v, size_t count)
{
    for (size_t i = 0; i < count; i++, v += 3)
        if (fprintf(f, "v %.9g %.9g %.9g\n", (double)v[0], (double)v[1], (double)v[2]) < 0) return -1;
    return 0;
}

/* Triangle meshes (an export's obstacles): an `o` line per mesh, its vertices and its faces, the
 * indices 1-based over the whole file. */
static int obj_meshes_body(FILE *f, const void *data)
{
    const ply_meshes *pm = data;
    if (fprintf(f, "# flockmorph %s: %d meshes\n", FM_VERSION_STRING, pm->count) < 0) return -1;
    if (pm->comment && (fputs("# ", f) < 0 || put_header_text(f, pm->comment) || fputc('\n', f) == EOF)) return -1;
    int64_t base = 1;
    for (int i = 0; i < pm->count; base += pm->m[i].nv, i++) {
        if (fputs("o ", f) < 0 || put_header_text(f, pm->m[i].name) || fputc('\n', f) == EOF) return -1;
        for (int64_t j = 0; j < pm->m[i].nv; j++) {
            const double *v = pm->m[i].v + 3 * j;
            if (fprintf(f, "v %.9g %.9g %.9g\n", (double)(float)v[0], (double)(float)v[1], (double)(float)v[2]) < 0)
                return -1;
        }
        for (int64_t t = 0; t < pm->m[i].nt; t++) {
            const int32_t *c = pm->m[i].tri + 3 * t;
            if (fprintf(f, "f %lld %lld %lld\n", (long long)(base + c[0]), (long long)(base + c[1]),
                        (long long)(base + c[2])) < 0)
                return -1;
        }
    }
    return 0;
}

fm_status fm_export_obj_meshes(const fm_ply_mesh *meshes, int count, const char *comment, const char *path,
                               fm_error *err)
{
    const ply_meshes pm = {meshes, count, comment};
    return fm_export_with_body(path, obj_meshes_body, &pm, err);
}

static int obj_tets_body(FILE *f, const void *data)
{
    const fm_export_frame *frame = data;
    size_t n = frame->n;
    if (fprintf(f, "# flockmorph %s: %zu tets, 4 vertices and 4 triangles each\n",
                FM_VERSION_STRING, n) < 0)
        return -1;
    if (obj_vertices(f, frame->tet_vertices, 4 * n)) return -1;
    for (size_t t = 0; t < n; t++) {
        size_t base = 4 * t + 1; /* OBJ indices are 1-based */
        for (int j = 0; j < 4; j++)
            if (fprintf(f, "f %zu %zu %zu\n", base + (size_t)fm_tet_faces[j][0],
                        base + (size_t)fm_tet_faces[j][1], base + (size_t)fm_tet_faces[j][2]) < 0)
                return -1;
    }
    return 0;
}

static int obj_points_body(FILE *f, const void *data)
{
    const fm_export_frame *frame = data;
    if (fprintf(f, "# flockmorph %s: %zu points in agent id order\n", FM_VERSION_STRING,
                frame->n) < 0)
        return -1;
    return obj_vertices(f, frame->positions, frame->n);
}

/* ---------------------------------------------------------------- shared frame plumbing */

fm_status fm_export_with_body(const char *path, fm_body_fn body, const void *data, fm_error *err)
{
    fm_output_file out;
    fm_status st = fm_output_open(&out, path, err);
    if (st != FM_OK) return st;
    errno = 0;
    if (body(out.f, data)) {
        int e = errno ? errno : EIO;
        fm_output_discard(&out);
        return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", path, strerror(e), fm_write_hint(e));
    }
    return fm_output_commit(&out, NULL, err);
}

void fm_export_up_y(float *xyz, size_t n)
{
    for (size_t i = 0; i < n; i++, xyz += 3) {
        float y = xyz[1];
        xyz[1] = xyz[2], xyz[2] = -y; /* exact: a permutation and a sign */
    }
}

void fm_export_scale(float *xyz, size_t n, double scale)
{
    if (scale == 1.0) return;
    for (size_t i = 0; i < 3 * n; i++) xyz[i] = (float)(scale * xyz[i]);
}

void fm_export_up_y_quaternions(float *q, size_t n)
{
    const double c = 0.70710678118654752440; /* r = (c, -c, 0, 0): -90 degrees about x */
    for (size_t i = 0; i < n; i++, q += 4) {
        double w = q[0], x = q[1], y = q[2], z = q[3];
        q[0] = (float)(c * (w + x)), q[1] = (float)(c * (x - w));
        q[2] = (float)(c * (y + z)), q[3] = (float)(c * (z - y));
    }
}

void fm_tet_centroids(const float *verts, size_t n, float *out)
{
    for (size_t t = 0; t < n; t++) {
        const float *v = verts + 12 * t;
        for (int k = 0; k < 3; k++)
            out[3 * t + k] = (float)(0.25 * ((double)v[k] + v[3 + k] + v[6 + k] + v[9 + k]));
    }
}

void fm_finite_difference(const float *before, const float *after, size_t n, double dt, float *out)
{
    for (size_t i = 0; i < 3 * n; i++) out[i] = (float)(((double)after[i] - before[i]) / dt);
}

/* The largest agent id a format holds: PLY's and VDB's ids are int32, VTK's UInt32, and a tet's
 * point ids (PLY, VTK) go up to 4 × its id + 3; *what names the limit. */
static uint32_t max_agent_id(const fm_export_frame *frame, fm_export_format format, const char **what)
{
    uint32_t most = format == FM_EXPORT_PLY || format == FM_EXPORT_VDB ? (uint32_t)INT32_MAX : UINT32_MAX;
    *what = most == UINT32_MAX ? "UInt32 id" : "int32 id";
    if (!frame->tet_vertices || (format != FM_EXPORT_PLY && format != FM_EXPORT_VTK)) return most;
    *what = most == UINT32_MAX ? "UInt32 point ids (4 x the tet's id + 3)" : "int32 point ids (4 x the tet's id + 3)";
    return (most - 3) / 4;
}

/* What a format can hold; an error names the limit. */
static fm_status check_frame(const fm_export_frame *frame, fm_export_format format, const char *path,
                             fm_error *err)
{
    if (!frame) return fm_fail(err, FM_ERR_USAGE, "export to '%s': no frame given", path);
    size_t n = frame->n;
    if (n > 0 && !frame->tet_vertices && !frame->positions)
        return fm_fail(err, FM_ERR_USAGE, "export to '%s': neither tet vertices nor positions", path);
    /* PLY's indices and ids and VDB's ids are int32; VTK's are Int64 and UInt32. */
    size_t limit = frame->tet_vertices ? ((size_t)INT32_MAX + 1) / 4 : (size_t)INT32_MAX;
    if (format == FM_EXPORT_PLY && n > limit)
        return fm_fail(err, FM_ERR_INPUT, "cannot export %zu agents to '%s': PLY int indices allow "
                       "at most %zu", n, path, limit);
    const char *what;
    const uint32_t most = max_agent_id(frame, format, &what);
    for (size_t i = 0; frame->ids && i < n; i++)
        if (frame->ids[i] > most)
            return fm_fail(err, FM_ERR_INPUT, "cannot export to '%s': agent %zu's id %u does not fit the format's "
                           "%s", path, i, (unsigned)frame->ids[i], what);
    return FM_OK;
}

/* VDB stores points: a tet's is its centroid. */
static fm_status write_vdb(const fm_export_frame *frame, const fm_export_options *opts,
                           const char *path, fm_error *err)
{
    if (!frame->tet_vertices || frame->positions)
        return fm_vdb_points_write(frame, frame->positions, opts, path, err);
    float *centroids = malloc(sizeof(float) * 3 * (frame->n ? frame->n : 1));
    if (!centroids)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for %zu centroids ('%s')", frame->n, path);
    fm_tet_centroids(frame->tet_vertices, frame->n, centroids);
    fm_status st = fm_vdb_points_write(frame, centroids, opts, path, err);
    free(centroids);
    return st;
}

static fm_status write_vtu(const fm_export_frame *frame, const fm_export_options *opts, const char *path,
                           fm_error *err)
{
    if (opts->vtk_zlib_level < 0 || opts->vtk_zlib_level > 9)
        return fm_fail(err, FM_ERR_USAGE, "cannot export to '%s': the zlib level %d is not 0 (raw) to 9",
                       path, opts->vtk_zlib_level);
    return fm_export_with_body(path, fm_vtu_body, &(fm_vtu_input){frame, opts->vtk_zlib_level}, err);
}

fm_status fm_export_frame_write(const fm_export_frame *frame, fm_export_format format,
                                const fm_export_options *opts, const char *path, fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "export: no output path given");
    fm_status st = check_frame(frame, format, path, err);
    if (st != FM_OK) return st;
    fm_export_options defaults = fm_default_export_options();
    const int tets = frame->tet_vertices != NULL;
    switch (format) {
    case FM_EXPORT_PLY:
        return fm_export_with_body(path, tets ? ply_tets_body : ply_points_body, frame, err);
    case FM_EXPORT_OBJ:
        return fm_export_with_body(path, tets ? obj_tets_body : obj_points_body, frame, err);
    case FM_EXPORT_VTK:
        return write_vtu(frame, opts ? opts : &defaults, path, err);
    case FM_EXPORT_VDB:
        return write_vdb(frame, opts ? opts : &defaults, path, err);
    case FM_EXPORT_PC2:
    case FM_EXPORT_MDD:
        return fm_fail(err, FM_ERR_USAGE, "cannot export one frame to '%s': %s holds a sequence "
                       "(fm_pointcache_create)", path, fm_export_extension(format));
    default:
        return fm_fail(err, FM_ERR_USAGE, "cannot export to '%s': unknown format", path);
    }
}

fm_status fm_export_tets(const float *verts, size_t n, const char *path, fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "export: no output path given");
    if (n > 0 && !verts) return fm_fail(err, FM_ERR_USAGE, "export to '%s': no vertices", path);
    fm_export_format format = fm_export_format_of_path(path);
    if (format == FM_EXPORT_UNKNOWN)
        return fm_fail(err, FM_ERR_USAGE, "cannot export to '%s': unknown extension (accepted: "
                       ".ply, .obj, .vtu, .vdb)", path);
    static const float no_tets[12]; /* tet_vertices set, even for n = 0, makes it a tet file */
    fm_export_frame frame = {.n = n, .tet_vertices = verts ? verts : no_tets};
    return fm_export_frame_write(&frame, format, NULL, path, err);
}

/* ---------------------------------------------------------------- ParaView collection */

/* XML attribute text: & < > " escaped. */
static int put_xml_text(FILE *f, const char *s)
{
    for (; *s; s++) {
        const char *e = *s == '&' ? "&amp;" : *s == '<' ? "&lt;" : *s == '>' ? "&gt;"
                        : *s == '"' ? "&quot;" : NULL;
        if (e ? fputs(e, f) < 0 : fputc(*s, f) == EOF) return -1;
    }
    return 0;
}

typedef struct pvd_list {
    const char *const *files;
    const double *times;
    size_t count;
} pvd_list;

static int pvd_body(FILE *f, const void *data)
{
    const pvd_list *list = data;
    if (fputs("<?xml version=\"1.0\"?>\n"
              "<VTKFile type=\"Collection\" version=\"1.0\" byte_order=\"LittleEndian\" "
              "header_type=\"UInt64\">\n  <Collection>\n", f) < 0)
        return -1;
    for (size_t i = 0; i < list->count; i++) {
        if (fprintf(f, "    <DataSet timestep=\"%.17g\" group=\"\" part=\"0\" file=\"", list->times[i]) < 0 ||
            put_xml_text(f, list->files[i]) || fputs("\"/>\n", f) < 0)
            return -1;
    }
    return fputs("  </Collection>\n</VTKFile>\n", f) < 0 ? -1 : 0;
}

fm_status fm_export_pvd(const char *path, const char *const *files, const double *times,
                        size_t count, fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "export: no .pvd path given");
    for (size_t i = 0; i < count; i++)
        if (!isfinite(times[i]))
            return fm_fail(err, FM_ERR_INPUT, "'%s': timestep %zu is not finite", path, i);
    pvd_list list = {files, times, count};
    return fm_export_with_body(path, pvd_body, &list, err);
}
