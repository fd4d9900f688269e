/* Mesh import through the public API: fm_morph_model_build on small meshes written here in OBJ, PLY,
 * STL, OFF and glTF, and the closed-manifold and self-intersection checks with their messages. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "geom.h"
#include "test_macros.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A small triangle mesh built in the test. */
typedef struct tmesh {
    int nv, nf;
    double v[64][3];
    int f[64][3];
} tmesh;

/* Appends the cube [o, o + size]^3 with outward-facing counter-clockwise triangles. */
static void add_cube(tmesh *m, double ox, double oy, double oz, double size)
{
    static const int faces[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                     {3, 7, 6}, {3, 6, 2}, {0, 4, 7}, {0, 7, 3}, {1, 2, 6}, {1, 6, 5}};
    static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                     {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    int base = m->nv;
    for (int i = 0; i < 8; i++) {
        m->v[m->nv][0] = ox + size * corner[i][0];
        m->v[m->nv][1] = oy + size * corner[i][1];
        m->v[m->nv][2] = oz + size * corner[i][2];
        m->nv++;
    }
    for (int t = 0; t < 12; t++, m->nf++)
        for (int k = 0; k < 3; k++) m->f[m->nf][k] = base + faces[t][k];
}

static tmesh cube(void)
{
    tmesh m = {0};
    add_cube(&m, 0, 0, 0, 2);
    return m;
}

static char *tmp_path(char *buf, const char *name)
{
    snprintf(buf, FM_PATH_MAX, "%s/mesh_%s", FM_TEST_TMP, name);
    return buf;
}

static FILE *create(const char *path)
{
    FILE *f = fopen(path, "w");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    return f;
}

static void write_obj(const char *path, const tmesh *m)
{
    FILE *f = create(path);
    if (!f) return;
    for (int i = 0; i < m->nv; i++) fprintf(f, "v %.17g %.17g %.17g\n", m->v[i][0], m->v[i][1], m->v[i][2]);
    for (int t = 0; t < m->nf; t++) fprintf(f, "f %d %d %d\n", m->f[t][0] + 1, m->f[t][1] + 1, m->f[t][2] + 1);
    fclose(f);
}

static void write_ply(const char *path, const tmesh *m)
{
    FILE *f = create(path);
    if (!f) return;
    fprintf(f, "ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
               "property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n",
            m->nv, m->nf);
    for (int i = 0; i < m->nv; i++) fprintf(f, "%.9g %.9g %.9g\n", m->v[i][0], m->v[i][1], m->v[i][2]);
    for (int t = 0; t < m->nf; t++) fprintf(f, "3 %d %d %d\n", m->f[t][0], m->f[t][1], m->f[t][2]);
    fclose(f);
}

/* ASCII STL repeats the corners per facet; the importer has to weld them. */
static void write_stl(const char *path, const tmesh *m)
{
    FILE *f = create(path);
    if (!f) return;
    fprintf(f, "solid test\n");
    for (int t = 0; t < m->nf; t++) {
        const double *a = m->v[m->f[t][0]], *b = m->v[m->f[t][1]], *c = m->v[m->f[t][2]];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        fprintf(f, " facet normal %g %g %g\n  outer loop\n", u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0]);
        for (int k = 0; k < 3; k++) {
            const double *p = m->v[m->f[t][k]];
            fprintf(f, "   vertex %.9g %.9g %.9g\n", p[0], p[1], p[2]);
        }
        fprintf(f, "  endloop\n endfacet\n");
    }
    fprintf(f, "endsolid test\n");
    fclose(f);
}

static void write_off(const char *path, const tmesh *m)
{
    FILE *f = create(path);
    if (!f) return;
    fprintf(f, "OFF\n%d %d 0\n", m->nv, m->nf);
    for (int i = 0; i < m->nv; i++) fprintf(f, "%.17g %.17g %.17g\n", m->v[i][0], m->v[i][1], m->v[i][2]);
    for (int t = 0; t < m->nf; t++) fprintf(f, "3 %d %d %d\n", m->f[t][0], m->f[t][1], m->f[t][2]);
    fclose(f);
}

static void base64(const unsigned char *in, size_t n, char *out)
{
    static const char alphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    size_t o = 0;
    for (size_t i = 0; i < n; i += 3) {
        unsigned v = (unsigned)in[i] << 16 | (i + 1 < n ? (unsigned)in[i + 1] << 8 : 0) | (i + 2 < n ? in[i + 2] : 0);
        out[o++] = alphabet[v >> 18 & 63];
        out[o++] = alphabet[v >> 12 & 63];
        out[o++] = i + 1 < n ? alphabet[v >> 6 & 63] : '=';
        out[o++] = i + 2 < n ? alphabet[v & 63] : '=';
    }
    out[o] = 0;
}

/* glTF 2.0 with one triangle mesh; the buffer (float32 positions, uint32 indices) is embedded. */
static void write_gltf(const char *path, const tmesh *m)
{
    unsigned char buf[64 * 12 + 64 * 12];
    size_t vbytes = (size_t)m->nv * 12, ibytes = (size_t)m->nf * 12;
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    for (int i = 0; i < m->nv; i++)
        for (int k = 0; k < 3; k++) {
            float x = (float)m->v[i][k];
            memcpy(buf + 12 * i + 4 * k, &x, 4);
            lo[k] = x < lo[k] ? x : lo[k], hi[k] = x > hi[k] ? x : hi[k];
        }
    for (int t = 0; t < m->nf; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t idx = (uint32_t)m->f[t][k];
            memcpy(buf + vbytes + 12 * t + 4 * k, &idx, 4);
        }
    char b64[2200];
    base64(buf, vbytes + ibytes, b64);
    FILE *f = create(path);
    if (!f) return;
    fprintf(f, "{\"asset\": {\"version\": \"2.0\"}, \"scene\": 0, \"scenes\": [{\"nodes\": [0]}], \"nodes\": [{\"mesh\": 0}],\n"
               " \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}, \"indices\": 1}]}],\n"
               " \"buffers\": [{\"byteLength\": %zu, \"uri\": \"data:application/octet-stream;base64,%s\"}],\n"
               " \"bufferViews\": [{\"buffer\": 0, \"byteOffset\": 0, \"byteLength\": %zu},"
               " {\"buffer\": 0, \"byteOffset\": %zu, \"byteLength\": %zu}],\n"
               " \"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": %d, \"type\": \"VEC3\","
               " \"min\": [%g, %g, %g], \"max\": [%g, %g, %g]},"
               " {\"bufferView\": 1, \"componentType\": 5125, \"count\": %d, \"type\": \"SCALAR\"}]}\n",
            vbytes + ibytes, b64, vbytes, vbytes, ibytes, m->nv, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], 3 * m->nf);
    fclose(f);
}

static void write_raw(const char *path, const char *text)
{
    FILE *f = create(path);
    if (!f) return;
    fputs(text, f);
    fclose(f);
}

/* A scene with source and target from the given files, 10 units apart along x. */
static fm_scene_def scene(const char *source, const char *target)
{
    fm_scene_def d = fm_default_scene_def();
    snprintf(d.source.path, sizeof d.source.path, "%s", source);
    snprintf(d.target.path, sizeof d.target.path, "%s", target);
    d.source.translate[0] = -5;
    d.target.translate[0] = 5;
    d.target.translate[2] = 1.5;
    return d;
}

/* Builds a model from a good cube file used as both source and target. */
static void expect_cube_builds(const char *path)
{
    fm_scene_def d = scene(path, path);
    fm_error err = {0};
    fm_morph_model *m = fm_morph_model_build(&d, NULL, NULL, &err);
    ENSURE_MSG(m != NULL, "%s: %s", path, err.message);
    if (!m) return;
    fm_morph_model_info mi = fm_morph_model_get_info(m);
    ENSURE(mi.source_tets > 0 && mi.target_tets > 0);
    ENSURE_MSG(mi.agents == (mi.source_tets > mi.target_tets ? mi.source_tets : mi.target_tets),
               "%s: %lld agents, %lld and %lld tets", path, (long long)mi.agents, (long long)mi.source_tets,
               (long long)mi.target_tets);
    ENSURE_NEAR(mi.source_volume, 8.0, 8e-9);
    ENSURE_NEAR(mi.target_volume, 8.0, 8e-9);
    /* the cube [0, 2]^3 has its centroid at (1, 1, 1) before placement */
    ENSURE_NEAR(mi.source_centroid[0], -4.0, 1e-9);
    ENSURE_NEAR(mi.source_centroid[1], 1.0, 1e-9);
    ENSURE_NEAR(mi.target_centroid[0], 6.0, 1e-9);
    ENSURE_NEAR(mi.target_centroid[2], 2.5, 1e-9);
    fm_morph_model_destroy(m);
}

/* Builds with `bad` as the source (or the target) and a good cube as the other; expects failure
 * with `status`, the bad file's path and `what` in the message. */
static void expect_mesh_error(const char *bad, int as_target, fm_status status, const char *what)
{
    char good[FM_PATH_MAX];
    tmesh c = cube();
    write_obj(tmp_path(good, "good.obj"), &c);
    fm_scene_def d = as_target ? scene(good, bad) : scene(bad, good);
    fm_error err = {0};
    fm_morph_model *m = fm_morph_model_build(&d, NULL, NULL, &err);
    ENSURE_MSG(m == NULL, "%s built a model", bad);
    fm_morph_model_destroy(m);
    ENSURE_MSG(err.status == status, "%s: status %d, expected %d (%s)", bad, (int)err.status, (int)status, err.message);
    ENSURE_MSG(strstr(err.message, bad) != NULL, "the path is not in '%s'", err.message);
    ENSURE_MSG(strstr(err.message, what) != NULL, "'%s' not in '%s'", what, err.message);
}

/* ---------------------------------------------------------------- formats */

static void test_cube_gltf(void)
{
    char path[FM_PATH_MAX];
    tmesh c = cube();
    write_gltf(tmp_path(path, "cube.gltf"), &c);
    expect_cube_builds(path);
}

static void test_cube_obj(void)
{
    char path[FM_PATH_MAX];
    tmesh c = cube();
    write_obj(tmp_path(path, "cube.obj"), &c);
    expect_cube_builds(path);
}

static void test_cube_ply_ascii(void)
{
    char path[FM_PATH_MAX];
    tmesh c = cube();
    write_ply(tmp_path(path, "cube.ply"), &c);
    expect_cube_builds(path);
}

static void test_cube_stl_ascii(void)
{
    char path[FM_PATH_MAX];
    tmesh c = cube();
    write_stl(tmp_path(path, "cube.stl"), &c);
    expect_cube_builds(path);
}

/* Binary PLY (little endian floats, uchar-counted int lists) and binary STL (80-byte header that
 * starts with "solid", as some exporters write, the count, 50 bytes a facet): files that hold
 * exactly what their counts declare pass the count check (mesh_counts.c). */
static void test_cube_binary_ply_and_stl(void)
{
    char path[FM_PATH_MAX];
    tmesh c = cube();
    FILE *f = create(tmp_path(path, "cube_binary.ply"));
    if (!f) return;
    fprintf(f, "ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
               "property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n", c.nv, c.nf);
    for (int i = 0; i < c.nv; i++)
        for (int k = 0; k < 3; k++) fwrite(&(float){(float)c.v[i][k]}, 4, 1, f);
    for (int t = 0; t < c.nf; t++) {
        fputc(3, f);
        for (int k = 0; k < 3; k++) fwrite(&(int32_t){c.f[t][k]}, 4, 1, f);
    }
    fclose(f);
    expect_cube_builds(path);
    f = create(tmp_path(path, "cube_binary.stl"));
    if (!f) return;
    char header[80] = "solid binary, not ASCII";
    fwrite(header, 1, 80, f);
    fwrite(&(uint32_t){(uint32_t)c.nf}, 4, 1, f);
    for (int t = 0; t < c.nf; t++) {
        float facet[12] = {0};
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++) facet[3 + 3 * k + j] = (float)c.v[c.f[t][k]][j];
        fwrite(facet, 4, 12, f);
        fwrite(&(uint16_t){0}, 2, 1, f);
    }
    fclose(f);
    expect_cube_builds(path);
}

/* A header that declares more elements than the file holds is refused before assimp allocates. */
static void test_counts_beyond_data(void)
{
    static const char ply[] = "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty float x\n"
                              "property float y\nproperty float z\nend_header\n";
    fm_mesh m;
    fm_error err = {0};
    ENSURE(fm_mesh_parse(ply, sizeof ply - 1, "ply", "huge.ply", &m, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "huge.ply: ") && strstr(err.message, "damaged or cut short"), "%s", err.message);
    static const char off[] = "OFF 8 2000000000 0\n";
    ENSURE(fm_mesh_parse(off, sizeof off - 1, "off", "huge.off", &m, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "2000000000 faces"), "%s", err.message);
}

static void test_cube_off(void)
{
    char path[FM_PATH_MAX];
    tmesh c = cube();
    write_off(tmp_path(path, "cube.off"), &c);
    expect_cube_builds(path);
}

/* ---------------------------------------------------------------- broken surfaces */

static void test_hole(void)
{
    char path[FM_PATH_MAX];
    tmesh c = cube();
    c.nf--; /* drop the last triangle */
    write_obj(tmp_path(path, "hole.obj"), &c);
    expect_mesh_error(path, 0, FM_ERR_INPUT, "hole");
    expect_mesh_error(path, 1, FM_ERR_INPUT, "hole");
}

/* Two closed cubes that share exactly one edge: four triangles meet there. */
static void test_non_manifold_edge(void)
{
    char path[FM_PATH_MAX];
    tmesh m = {0};
    add_cube(&m, 0, 0, 0, 1);
    add_cube(&m, 1, 1, 0, 1);
    write_obj(tmp_path(path, "shared_edge.obj"), &m);
    expect_mesh_error(path, 0, FM_ERR_INPUT, "more than two");
}

static void test_flipped_face(void)
{
    char path[FM_PATH_MAX];
    tmesh c = cube();
    int t = c.f[5][1];
    c.f[5][1] = c.f[5][2];
    c.f[5][2] = t;
    write_obj(tmp_path(path, "flipped.obj"), &c);
    expect_mesh_error(path, 0, FM_ERR_INPUT, "disagree");
}

static void test_nonfinite_vertex(void)
{
    char path[FM_PATH_MAX];
    write_raw(tmp_path(path, "nonfinite.obj"),
              "v 0 0 0\nv 1e999 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    expect_mesh_error(path, 0, FM_ERR_INPUT, "non-finite");
}

static void test_degenerate_triangle(void)
{
    char path[FM_PATH_MAX];
    write_raw(tmp_path(path, "degenerate.obj"),
              "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 0 0\n"
              "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\nf 2 5 4\n");
    expect_mesh_error(path, 0, FM_ERR_INPUT, "degenerate");
}

/* Two closed, overlapping cubes: every edge is fine, but the surface intersects itself. */
static void test_self_intersection(void)
{
    char path[FM_PATH_MAX];
    tmesh m = {0};
    add_cube(&m, 0, 0, 0, 2);
    add_cube(&m, 1, 1, 1, 2);
    write_obj(tmp_path(path, "overlap.obj"), &m);
    expect_mesh_error(path, 0, FM_ERR_INPUT, "intersects itself");
    expect_mesh_error(path, 1, FM_ERR_INPUT, "intersects itself");
}

/* Two disjoint closed cubes in one file are one valid (two-part) solid. */
static void test_two_disjoint_cubes(void)
{
    char path[FM_PATH_MAX];
    tmesh m = {0};
    add_cube(&m, 0, 0, 0, 1);
    add_cube(&m, 3, 0, 0, 1);
    write_obj(tmp_path(path, "two_cubes.obj"), &m);
    fm_scene_def d = scene(path, path);
    fm_error err = {0};
    fm_morph_model *model = fm_morph_model_build(&d, NULL, NULL, &err);
    ENSURE_MSG(model != NULL, "%s", err.message);
    if (!model) return;
    ENSURE_NEAR(fm_morph_model_get_info(model).source_volume, 2.0, 2e-9);
    fm_morph_model_destroy(model);
}

/* A cube with a cubic cavity: the inner surface faces inward, so the solid is 4^3 - 2^3 = 56.
 * The cavity must not be filled with tets (rejecting the mesh would also be honest). */
static void test_cavity_not_filled(void)
{
    char path[FM_PATH_MAX];
    tmesh m = {0};
    add_cube(&m, 0, 0, 0, 4);
    add_cube(&m, 1, 1, 1, 2);
    for (int t = 12; t < 24; t++) {
        int k = m.f[t][1];
        m.f[t][1] = m.f[t][2], m.f[t][2] = k;
    }
    write_obj(tmp_path(path, "cavity.obj"), &m);
    fm_scene_def d = scene(path, path);
    fm_error err = {0};
    fm_morph_model *model = fm_morph_model_build(&d, NULL, NULL, &err);
    if (!model) {
        ENSURE_MSG(err.status == FM_ERR_INPUT && strstr(err.message, path), "%s", err.message);
        return;
    }
    ENSURE_NEAR(fm_morph_model_get_info(model).source_volume, 56.0, 56e-9);
    ENSURE_NEAR(fm_morph_model_get_info(model).target_volume, 56.0, 56e-9);
    fm_morph_model_destroy(model);
}

/* ---------------------------------------------------------------- unreadable files */

static void test_empty_file(void)
{
    char path[FM_PATH_MAX];
    write_raw(tmp_path(path, "empty.obj"), "");
    expect_mesh_error(path, 0, FM_ERR_INPUT, "");
    write_raw(tmp_path(path, "empty.ply"), "");
    expect_mesh_error(path, 1, FM_ERR_INPUT, "");
}

static void test_garbage_file(void)
{
    static const char *names[] = {"garbage.obj", "garbage.ply", "garbage.stl", "garbage.off", "garbage.txt"};
    char path[FM_PATH_MAX];
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        write_raw(tmp_path(path, names[i]), "this is not a mesh\n%%% 12 ) ( ]] garbage\n\x01\x02 more\n");
        expect_mesh_error(path, 0, FM_ERR_INPUT, "");
    }
}

static void test_missing_file(void)
{
    char path[FM_PATH_MAX], good[FM_PATH_MAX];
    tmesh c = cube();
    write_obj(tmp_path(good, "good_missing.obj"), &c);
    tmp_path(path, "does_not_exist.obj");
    fm_scene_def d = scene(path, good);
    fm_error err = {0};
    fm_morph_model *m = fm_morph_model_build(&d, NULL, NULL, &err);
    ENSURE(m == NULL);
    fm_morph_model_destroy(m);
    ENSURE_MSG(err.status == FM_ERR_IO || err.status == FM_ERR_INPUT, "status %d", (int)err.status);
    ENSURE_MSG(strstr(err.message, path) != NULL, "'%s'", err.message);
}

int main(void)
{
    RUN_TEST(test_cube_obj);
    RUN_TEST(test_cube_ply_ascii);
    RUN_TEST(test_cube_stl_ascii);
    RUN_TEST(test_cube_off);
    RUN_TEST(test_cube_binary_ply_and_stl);
    RUN_TEST(test_counts_beyond_data);
    RUN_TEST(test_cube_gltf);
    RUN_TEST(test_hole);
    RUN_TEST(test_non_manifold_edge);
    RUN_TEST(test_flipped_face);
    RUN_TEST(test_nonfinite_vertex);
    RUN_TEST(test_degenerate_triangle);
    RUN_TEST(test_self_intersection);
    RUN_TEST(test_two_disjoint_cubes);
    RUN_TEST(test_cavity_not_filled);
    RUN_TEST(test_empty_file);
    RUN_TEST(test_garbage_file);
    RUN_TEST(test_missing_file);
    return test_result();
}
