/* fm_export_tets: PLY and OBJ output read back with small independent parsers. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "test_macros.h"
#include "full_disk.h"

#include <float.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#ifndef FM_TEST_TMP
#error "FM_TEST_TMP must name a scratch directory"
#endif

#define NTETS 3

/* ---------------------------------------------------------------- helpers */

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;

static uint64_t rng_next(void) { return test_next_u64(&rng_state); }

/* Uniform in [-1, 1) with a full 24-bit mantissa once rounded to float. */
static double rng_unit(void) { return (double)(rng_next() >> 11) * 0x1p-52 - 1.0; }

static double det3(const double a[3], const double b[3], const double c[3])
{
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
           a[2] * (b[0] * c[1] - b[1] * c[0]);
}

static double signed_volume6(const float *t)
{
    double e[3][3];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) e[i][k] = (double)t[3 * (i + 1) + k] - t[k];
    return det3(e[0], e[1], e[2]);
}

/* n random tets with positive signed volume, at very different scales so %.9g has to use
 * exponents: tet i has coordinates of magnitude scales[i % 3]. */
static void random_tets(float *out, size_t n)
{
    static const double scales[3] = {10.0, 1e-20, 3e20};
    for (size_t t = 0; t < n; t++) {
        float *tv = out + 12 * t;
        do {
            for (int k = 0; k < 12; k++) tv[k] = (float)(scales[t % 3] * rng_unit());
        } while (!(fabs(signed_volume6(tv)) > 0.0));
        if (signed_volume6(tv) < 0.0) { /* swap v1 and v2 */
            for (int k = 0; k < 3; k++) {
                float tmp = tv[3 + k];
                tv[3 + k] = tv[6 + k];
                tv[6 + k] = tmp;
            }
        }
    }
}

static int file_exists(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (f) fclose(f);
    return f != NULL;
}

static char *read_all(const char *path, size_t *len)
{
    *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 1 << 16, n = 0, got;
    char *buf = malloc(cap + 1);
    while (buf && (got = fread(buf + n, 1, cap - n, f)) > 0) {
        n += got;
        if (n == cap) {
            char *grown = realloc(buf, 2 * cap + 1);
            if (!grown) free(buf);
            buf = grown;
            cap *= 2;
        }
    }
    fclose(f);
    if (buf) buf[n] = '\0';
    *len = n;
    return buf;
}

static char *tmp_path(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s/%s", FM_TEST_TMP, name);
    return buf;
}

static char *partial_path(char *buf, size_t size, const char *path)
{
    snprintf(buf, size, "%s.partial", path);
    return buf;
}

/* A parsed mesh: nv vertices (3 floats each), nf triangles (3 zero-based indices each). */
typedef struct mesh {
    size_t nv, nf;
    float *v;
    int64_t *f;
} mesh;

static void mesh_free(mesh *m)
{
    free(m->v);
    free(m->f);
    memset(m, 0, sizeof *m);
}

/* ---------------------------------------------------------------- PLY reader */

static uint32_t get_u32le(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Next header line into line[]; returns the offset after it or 0 at the end of the buffer. */
static size_t next_line(const char *buf, size_t len, size_t at, char *line, size_t size)
{
    size_t i = at;
    while (i < len && buf[i] != '\n') i++;
    if (i >= len) return 0;
    size_t n = i - at < size - 1 ? i - at : size - 1;
    memcpy(line, buf + at, n);
    line[n] = '\0';
    return i + 1;
}

/* Parses the exact header fm_export_tets promises; 0 on success, else the failing step. */
static int parse_ply(const char *path, mesh *m)
{
    memset(m, 0, sizeof *m);
    size_t len;
    char *buf = read_all(path, &len);
    if (!buf) return 1;
    static const char *const expected[] = {
        "ply", "format binary_little_endian 1.0", NULL /* element vertex */, "property float x",
        "property float y", "property float z", NULL /* element face */,
        "property list uchar int vertex_indices", "end_header"};
    char line[256];
    size_t at = 0;
    int step = 0;
    int rc = 0;
    while (step < 9) {
        at = next_line(buf, len, at, line, sizeof line);
        if (at == 0) {
            rc = 2;
            goto done;
        }
        if (strncmp(line, "comment", 7) == 0 && step > 1) continue;
        if (step == 2) {
            if (sscanf(line, "element vertex %zu", &m->nv) != 1) {
                rc = 3;
                goto done;
            }
        } else if (step == 6) {
            if (sscanf(line, "element face %zu", &m->nf) != 1) {
                rc = 4;
                goto done;
            }
        } else if (strcmp(line, expected[step]) != 0) {
            rc = 10 + step;
            goto done;
        }
        step++;
    }
    if (len - at != m->nv * 12 + m->nf * 13) {
        rc = 5;
        goto done;
    }
    m->v = malloc(sizeof(float) * 3 * (m->nv ? m->nv : 1));
    m->f = malloc(sizeof(int64_t) * 3 * (m->nf ? m->nf : 1));
    const unsigned char *p = (const unsigned char *)buf + at;
    for (size_t i = 0; i < 3 * m->nv; i++, p += 4) {
        uint32_t bits = get_u32le(p);
        memcpy(&m->v[i], &bits, sizeof bits);
    }
    for (size_t j = 0; j < m->nf; j++, p += 13) {
        if (p[0] != 3) {
            rc = 6;
            goto done;
        }
        for (int k = 0; k < 3; k++) m->f[3 * j + k] = (int32_t)get_u32le(p + 1 + 4 * k);
    }
done:
    free(buf);
    return rc;
}

/* ---------------------------------------------------------------- OBJ reader */

static int parse_obj(const char *path, mesh *m)
{
    memset(m, 0, sizeof *m);
    size_t len;
    char *buf = read_all(path, &len);
    if (!buf) return 1;
    size_t capv = 16, capf = 16;
    m->v = malloc(sizeof(float) * 3 * capv);
    m->f = malloc(sizeof(int64_t) * 3 * capf);
    int rc = 0;
    for (char *line = strtok(buf, "\n"); line; line = strtok(NULL, "\n")) {
        char *end;
        if (line[0] == '#') continue;
        if (line[0] == 'v' && line[1] == ' ') {
            if (m->nv == capv) {
                capv *= 2;
                m->v = realloc(m->v, sizeof(float) * 3 * capv);
            }
            char *s = line + 2;
            for (int k = 0; k < 3; k++) {
                m->v[3 * m->nv + k] = strtof(s, &end);
                if (end == s) rc = 2;
                s = end;
            }
            while (*s == ' ') s++;
            if (*s) rc = 3; /* trailing garbage */
            m->nv++;
        } else if (line[0] == 'f' && line[1] == ' ') {
            if (m->nf == capf) {
                capf *= 2;
                m->f = realloc(m->f, sizeof(int64_t) * 3 * capf);
            }
            char *s = line + 2;
            for (int k = 0; k < 3; k++) {
                m->f[3 * m->nf + k] = strtoll(s, &end, 10) - 1; /* 1-based in the file */
                if (end == s) rc = 4;
                s = end;
            }
            while (*s == ' ') s++;
            if (*s) rc = 5; /* more than 3 indices or slashes */
            m->nf++;
        } else {
            rc = 6;
        }
    }
    free(buf);
    return rc;
}

/* ---------------------------------------------------------------- checks */

/* Vertex values equal the input bit for bit, 4n faces, indices in range and within their
 * tet, and every face's normal points away from its tet's centroid. */
static void check_mesh(const mesh *m, const float *verts, size_t n, const char *what)
{
    ENSURE_MSG(m->nv == 4 * n, "%s: %zu vertices, expected %zu", what, m->nv, 4 * n);
    ENSURE_MSG(m->nf == 4 * n, "%s: %zu faces, expected %zu", what, m->nf, 4 * n);
    if (m->nv != 4 * n || m->nf != 4 * n) return;
    ENSURE_MSG(memcmp(m->v, verts, sizeof(float) * 12 * n) == 0, "%s: vertex values differ",
               what);
    for (size_t j = 0; j < m->nf; j++) {
        size_t t = j / 4; /* faces come in tet order, 4 per tet */
        const int64_t *ix = m->f + 3 * j;
        int ok = 1;
        for (int k = 0; k < 3; k++) {
            ENSURE_MSG(ix[k] >= 0 && ix[k] < (int64_t)m->nv, "%s: face %zu index %lld", what, j,
                       (long long)ix[k]);
            ENSURE_MSG(ix[k] >= (int64_t)(4 * t) && ix[k] < (int64_t)(4 * t + 4),
                       "%s: face %zu uses vertex %lld outside its tet %zu", what, j,
                       (long long)ix[k], t);
            if (!(ix[k] >= (int64_t)(4 * t) && ix[k] < (int64_t)(4 * t + 4))) ok = 0;
        }
        if (!ok) continue;
        ENSURE_MSG(ix[0] != ix[1] && ix[1] != ix[2] && ix[0] != ix[2], "%s: face %zu repeats",
                   what, j);
        double a[3], b[3], c[3], centroid[3] = {0, 0, 0}, e1[3], e2[3], nrm[3], out[3];
        for (int k = 0; k < 3; k++) {
            a[k] = m->v[3 * ix[0] + k];
            b[k] = m->v[3 * ix[1] + k];
            c[k] = m->v[3 * ix[2] + k];
            for (int v = 0; v < 4; v++) centroid[k] += 0.25 * m->v[3 * (4 * t + v) + k];
        }
        for (int k = 0; k < 3; k++) {
            e1[k] = b[k] - a[k];
            e2[k] = c[k] - a[k];
            out[k] = (a[k] + b[k] + c[k]) / 3.0 - centroid[k];
        }
        nrm[0] = e1[1] * e2[2] - e1[2] * e2[1];
        nrm[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nrm[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double d = nrm[0] * out[0] + nrm[1] * out[1] + nrm[2] * out[2];
        ENSURE_MSG(d > 0.0, "%s: face %zu of tet %zu points inward (n.out = %g)", what, j, t, d);
    }
    /* The four faces of each tet cover all four vertices, each exactly three times. */
    for (size_t t = 0; t < n; t++) {
        int uses[4] = {0, 0, 0, 0};
        for (size_t j = 4 * t; j < 4 * t + 4; j++)
            for (int k = 0; k < 3; k++) {
                int64_t local = m->f[3 * j + k] - (int64_t)(4 * t);
                if (local >= 0 && local < 4) uses[local]++;
            }
        ENSURE_MSG(uses[0] == 3 && uses[1] == 3 && uses[2] == 3 && uses[3] == 3,
                   "%s: tet %zu faces do not close it", what, t);
    }
}

/* ---------------------------------------------------------------- tests */

static void test_ply_round_trip(void)
{
    float verts[12 * NTETS];
    random_tets(verts, NTETS);
    for (size_t t = 0; t < NTETS; t++) ENSURE(signed_volume6(verts + 12 * t) > 0.0);
    char path[512], partial[600];
    tmp_path(path, sizeof path, "fm_test_export.ply");
    remove(path);
    fm_error err = {0};
    fm_status s = fm_export_tets(verts, NTETS, path, &err);
    ENSURE_MSG(s == FM_OK, "status %d: %s", (int)s, err.message);
    ENSURE(!file_exists(partial_path(partial, sizeof partial, path)));
    mesh m;
    int rc = parse_ply(path, &m);
    ENSURE_MSG(rc == 0, "PLY parse failed at step %d", rc);
    if (rc == 0) check_mesh(&m, verts, NTETS, "ply");
    mesh_free(&m);
    remove(path);
}

static void test_obj_round_trip(void)
{
    float verts[12 * NTETS];
    random_tets(verts, NTETS);
    char path[512], partial[600];
    tmp_path(path, sizeof path, "fm_test_export.obj");
    remove(path);
    fm_error err = {0};
    fm_status s = fm_export_tets(verts, NTETS, path, &err);
    ENSURE_MSG(s == FM_OK, "status %d: %s", (int)s, err.message);
    ENSURE(!file_exists(partial_path(partial, sizeof partial, path)));
    mesh m;
    int rc = parse_obj(path, &m);
    ENSURE_MSG(rc == 0, "OBJ parse failed with %d", rc);
    if (rc == 0) check_mesh(&m, verts, NTETS, "obj");
    mesh_free(&m);
    remove(path);
}

/* %.9g must round-trip every float: random values over many binades (those just above a
 * power of ten, e.g. [10, 16), need all 9 digits), extremes, subnormals and -0 must come back
 * bit for bit. */
static void test_obj_float_precision(void)
{
    enum { NT = 200 };
    float *verts = malloc(sizeof(float) * 12 * NT);
    static const float specials[] = {FLT_MAX, -FLT_MAX, FLT_MIN, FLT_TRUE_MIN, -FLT_TRUE_MIN,
                                     -0.0f, 0.0f, 1.0f, 16777215.0f, 0.1f, 1e-45f, 3.4e38f};
    size_t ns = sizeof specials / sizeof specials[0];
    for (size_t i = 0; i < 12 * NT; i++) {
        if (i < ns) {
            verts[i] = specials[i];
        } else {
            /* [1, 2) * 2^e, e in [-100, 100] */
            double m = 1.0 + 0.5 * (rng_unit() + 1.0);
            int e = (int)(rng_next() % 201) - 100;
            verts[i] = (float)ldexp((rng_next() & 1) ? -m : m, e);
        }
    }
    char path[512];
    tmp_path(path, sizeof path, "fm_test_export_precision.obj");
    fm_error err = {0};
    ENSURE_MSG(fm_export_tets(verts, NT, path, &err) == FM_OK, "%s", err.message);
    mesh m;
    int rc = parse_obj(path, &m);
    ENSURE_MSG(rc == 0, "OBJ parse failed with %d", rc);
    ENSURE(m.nv == 4 * NT);
    if (rc == 0 && m.nv == 4 * NT) {
        size_t bad = 0;
        for (size_t i = 0; i < 12 * NT; i++) {
            uint32_t a, b;
            memcpy(&a, &verts[i], 4);
            memcpy(&b, &m.v[i], 4);
            if (a != b && bad++ < 3)
                fprintf(stderr, "  value %zu: wrote %.9g (0x%08x), read 0x%08x\n", i,
                        (double)verts[i], (unsigned)a, (unsigned)b);
        }
        ENSURE_MSG(bad == 0, "%zu of %d values did not round-trip", bad, 12 * NT);
    }
    mesh_free(&m);
    remove(path);
    free(verts);
}

/* Extensions are case-insensitive, and a second export replaces the first file. */
static void test_extension_case_and_overwrite(void)
{
    float verts[24];
    random_tets(verts, 2);
    static const char *const names[] = {"fm_test_export_upper.PLY", "fm_test_export_mixed.Obj"};
    for (int i = 0; i < 2; i++) {
        char path[512];
        tmp_path(path, sizeof path, names[i]);
        remove(path);
        fm_error err = {0};
        ENSURE_MSG(fm_export_tets(verts, 2, path, &err) == FM_OK, "%s: %s", names[i],
                   err.message);
        ENSURE_MSG(fm_export_tets(verts, 1, path, &err) == FM_OK, "%s: %s", names[i],
                   err.message);
        mesh m;
        int rc = i == 0 ? parse_ply(path, &m) : parse_obj(path, &m);
        ENSURE_MSG(rc == 0, "%s: parse failed with %d", names[i], rc);
        if (rc == 0) check_mesh(&m, verts, 1, names[i]);
        mesh_free(&m);
        remove(path);
    }
}

static void test_empty(void)
{
    char path[512];
    tmp_path(path, sizeof path, "fm_test_export_empty.ply");
    fm_error err = {0};
    ENSURE_MSG(fm_export_tets(NULL, 0, path, &err) == FM_OK, "%s", err.message);
    mesh m;
    int rc = parse_ply(path, &m);
    ENSURE_MSG(rc == 0, "empty PLY parse failed at step %d", rc);
    ENSURE(m.nv == 0 && m.nf == 0);
    mesh_free(&m);
    remove(path);
}

static void test_bad_extension(void)
{
    float verts[12];
    random_tets(verts, 1);
    /* The extension is that of the last path component: "x.ply/out" has none. */
    static const char *const names[] = {"fm_test_export.stl", "fm_test_export",
                                        "fm_test_export.plyx", "fm_test_export.",
                                        "fm_test_export_dir.ply/out"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        char path[512], partial[600];
        tmp_path(path, sizeof path, names[i]);
        remove(path);
        fm_error err = {0};
        fm_status s = fm_export_tets(verts, 1, path, &err);
        ENSURE_MSG(s == FM_ERR_USAGE, "%s: status %d", names[i], (int)s);
        ENSURE(err.status == FM_ERR_USAGE);
        ENSURE_MSG(strstr(err.message, path) != NULL, "message does not name the path: %s",
                   err.message);
        ENSURE_MSG(strstr(err.message, ".ply") && strstr(err.message, ".obj"),
                   "message does not list the extensions: %s", err.message);
        ENSURE(!file_exists(path));
        ENSURE(!file_exists(partial_path(partial, sizeof partial, path)));
    }
}

static void test_unwritable_path(void)
{
    float verts[12];
    random_tets(verts, 1);
    static const char *const names[] = {"fm_no_such_dir/out.ply", "fm_no_such_dir/out.obj"};
    for (int i = 0; i < 2; i++) {
        char path[512], partial[600];
        tmp_path(path, sizeof path, names[i]);
        fm_error err = {0};
        fm_status s = fm_export_tets(verts, 1, path, &err);
        ENSURE_MSG(s == FM_ERR_IO, "%s: status %d", names[i], (int)s);
        ENSURE(err.status == FM_ERR_IO);
        ENSURE_MSG(strstr(err.message, path) != NULL, "message does not name the path: %s",
                   err.message);
        ENSURE_MSG(strstr(err.message, "No such file") != NULL,
                   "message lacks strerror(ENOENT): %s", err.message);
        ENSURE(!file_exists(path));
        ENSURE(!file_exists(partial_path(partial, sizeof partial, path)));
    }
}

/* A directory where the file goes: FM_ERR_IO naming the path, the directory left alone and no
 * temporary file left. One at PATH.partial is in nobody's way: the temporary file has a name of
 * its own (issue 42). */
static void test_partial_is_directory(void)
{
    char path[512], partial[600];
    tmp_path(path, sizeof path, "fm_test_export_blocked.ply");
    partial_path(partial, sizeof partial, path);
    remove(path), rmdir(path);
    rmdir(partial);
    ENSURE(mkdir(partial, 0700) == 0);
    float verts[12];
    random_tets(verts, 1);
    fm_error err = {0};
    ENSURE_MSG(fm_export_tets(verts, 1, path, &err) == FM_OK, "%s", err.message);
    ENSURE(file_exists(path) && remove(path) == 0);
    ENSURE_MSG(rmdir(partial) == 0, "the directory at the .partial name was not left alone");
    ENSURE(mkdir(path, 0700) == 0);
    fm_status s = fm_export_tets(verts, 1, path, &err);
    ENSURE_MSG(s == FM_ERR_IO, "status %d", (int)s);
    ENSURE_MSG(strstr(err.message, path) != NULL, "message does not name the path: %s",
               err.message);
    ENSURE_MSG(rmdir(path) == 0, "the directory in the way was not left alone");
}

/* Writes that fail after a successful open (a full disk, tests/helpers/full_disk.h): small
 * files fail in fclose's flush, large ones in fwrite/fprintf. Either way FM_ERR_IO naming the path
 * and ENOSPC, no final file, and no partial file left. */
static void test_write_failure(void)
{
    char dir[512];
    if (full_disk_mount(tmp_path(dir, sizeof dir, "export_full_disk"), 0) != 0) return;
    enum { BIG = 4000 };
    float *verts = malloc(sizeof(float) * 12 * BIG);
    random_tets(verts, BIG);
    static const char *const names[] = {"export_full_disk/full.ply", "export_full_disk/full.obj"};
    static const size_t counts[] = {1, BIG};
    for (int i = 0; i < 2; i++) {
        for (int c = 0; c < 2; c++) {
            char path[512];
            tmp_path(path, sizeof path, names[i]);
            fm_error err = {0};
            fm_status s = fm_export_tets(verts, counts[c], path, &err);
            ENSURE_MSG(s == FM_ERR_IO, "%s, %zu tets: status %d", names[i], counts[c], (int)s);
            ENSURE_MSG(strstr(err.message, path) != NULL, "message does not name the path: %s",
                       err.message);
            ENSURE_MSG(strstr(err.message, "No space left") != NULL,
                       "message lacks strerror(ENOSPC): %s", err.message);
            ENSURE(!file_exists(path));
            ENSURE_MSG(files_in(dir) == 1, "a partial file of %s was left beside the filler", path);
        }
    }
    free(verts);
    full_disk_unmount(dir);
}

int main(void)
{
    RUN_TEST(test_ply_round_trip);
    RUN_TEST(test_obj_round_trip);
    RUN_TEST(test_obj_float_precision);
    RUN_TEST(test_extension_case_and_overwrite);
    RUN_TEST(test_empty);
    RUN_TEST(test_bad_extension);
    RUN_TEST(test_unwritable_path);
    RUN_TEST(test_partial_is_directory);
    RUN_TEST(test_write_failure);
    return test_result();
}
