/* Export of tets as a triangle mesh: binary little-endian PLY or Wavefront OBJ.
 *
 * Each tet becomes 4 vertices and 4 triangles (0,2,1), (0,1,3), (0,3,2), (1,2,3), which face
 * outward when the tet has positive signed volume det[v1-v0, v2-v0, v3-v0] > 0. The file is
 * written as PATH.partial and renamed to PATH only when every write succeeded. */
#define _POSIX_C_SOURCE 200809L
#include "fm_internal.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const int fm_tet_faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

typedef enum { FMT_UNKNOWN, FMT_PLY, FMT_OBJ } mesh_format;

/* Case-insensitive comparison of the extension of path's last component with ext ("ply"). */
static int has_extension(const char *path, const char *ext)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    if (!dot) return 0;
    const char *a = dot + 1;
    for (; *a && *ext; a++, ext++) {
        char c = *a;
        if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
        if (c != *ext) return 0;
    }
    return *a == '\0' && *ext == '\0';
}

static mesh_format format_of(const char *path)
{
    if (has_extension(path, "ply")) return FMT_PLY;
    if (has_extension(path, "obj")) return FMT_OBJ;
    return FMT_UNKNOWN;
}

static void put_u32le(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)(v & 0xffu);
    p[1] = (unsigned char)((v >> 8) & 0xffu);
    p[2] = (unsigned char)((v >> 16) & 0xffu);
    p[3] = (unsigned char)((v >> 24) & 0xffu);
}

static void put_f32le(unsigned char *p, float f)
{
    uint32_t bits;
    memcpy(&bits, &f, sizeof bits);
    put_u32le(p, bits);
}

/* Both writers return 0 on success, -1 on a failed write (errno says why). */
static int write_ply(FILE *f, const float *verts, size_t n)
{
    if (fprintf(f,
                "ply\n"
                "format binary_little_endian 1.0\n"
                "comment flockmorph " FM_VERSION_STRING " tets\n"
                "element vertex %zu\n"
                "property float x\n"
                "property float y\n"
                "property float z\n"
                "element face %zu\n"
                "property list uchar int vertex_indices\n"
                "end_header\n",
                4 * n, 4 * n) < 0)
        return -1;

    unsigned char buf[52]; /* 4 vertices × 12 bytes, or 4 faces × 13 bytes */
    for (size_t t = 0; t < n; t++) {
        for (int k = 0; k < 12; k++) put_f32le(buf + 4 * k, verts[12 * t + (size_t)k]);
        if (fwrite(buf, 1, 48, f) != 48) return -1;
    }
    for (size_t t = 0; t < n; t++) {
        for (int j = 0; j < 4; j++) {
            unsigned char *p = buf + 13 * j;
            p[0] = 3;
            for (int k = 0; k < 3; k++)
                put_u32le(p + 1 + 4 * k, (uint32_t)(4 * t + (size_t)fm_tet_faces[j][k]));
        }
        if (fwrite(buf, 1, 52, f) != 52) return -1;
    }
    return 0;
}

static int write_obj(FILE *f, const float *verts, size_t n)
{
    if (fprintf(f, "# flockmorph %s: %zu tets, 4 vertices and 4 triangles each\n",
                FM_VERSION_STRING, n) < 0)
        return -1;
    for (size_t i = 0; i < 4 * n; i++) {
        const float *v = verts + 3 * i;
        if (fprintf(f, "v %.9g %.9g %.9g\n", (double)v[0], (double)v[1], (double)v[2]) < 0)
            return -1;
    }
    for (size_t t = 0; t < n; t++) {
        for (int j = 0; j < 4; j++) {
            size_t base = 4 * t + 1; /* OBJ indices are 1-based */
            if (fprintf(f, "f %zu %zu %zu\n", base + (size_t)fm_tet_faces[j][0],
                        base + (size_t)fm_tet_faces[j][1], base + (size_t)fm_tet_faces[j][2]) < 0)
                return -1;
        }
    }
    return 0;
}

fm_status fm_export_tets(const float *verts, size_t n, const char *path, fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "export: no output path given");
    if (n > 0 && !verts) return fm_fail(err, FM_ERR_USAGE, "export to '%s': no vertices", path);

    mesh_format fmt = format_of(path);
    if (fmt == FMT_UNKNOWN)
        return fm_fail(err, FM_ERR_USAGE,
                       "cannot export to '%s': unknown extension (accepted: .ply, .obj)", path);
    if (fmt == FMT_PLY && n > ((size_t)INT32_MAX + 1) / 4)
        return fm_fail(err, FM_ERR_INPUT,
                       "cannot export %zu tets to '%s': PLY int indices allow at most %zu", n,
                       path, ((size_t)INT32_MAX + 1) / 4);

    fm_output_file out;
    fm_status st = fm_output_open(&out, path, err);
    if (st != FM_OK) return st;
    errno = 0;
    int bad = fmt == FMT_PLY ? write_ply(out.f, verts, n) : write_obj(out.f, verts, n);
    if (bad) {
        int e = errno;
        fm_output_discard(&out);
        return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s", path, strerror(e ? e : EIO));
    }
    return fm_output_commit(&out, NULL, err);
}
