/* Helpers the export tests share: scratch paths, assimp re-import compared with what was written,
 * and tests/check_vtk.py (Python's xml and zlib modules) run on VTK output. */
#ifndef FM_TEST_EXPORT_HELPERS_H
#define FM_TEST_EXPORT_HELPERS_H

#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <assimp/cimport.h>
#include <assimp/scene.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>

static const int export_tet_faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

static inline char *export_tmp(char *buf, const char *name)
{
    snprintf(buf, FM_PATH_MAX, "%s/%s", FM_TEST_TMP, name);
    return buf;
}

static inline int export_file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* a == b, or within tol * max(1, |b|) when tol > 0 (OBJ's printed digits through assimp's parser). */
static inline int export_close(float a, float b, double tol)
{
    if (tol <= 0) return memcmp(&a, &b, sizeof a) == 0;
    return fabs((double)a - b) <= tol * fmax(1.0, fabs((double)b));
}

/* Imports path with assimp (no post-processing) and checks it holds the n tets of verts: 4n
 * triangles, face j of tet t through the vertices export_tet_faces[j] of verts' tet t. */
static inline void export_check_assimp_tets(const char *path, const float *verts, size_t n, double tol)
{
    const struct aiScene *scene = aiImportFile(path, 0);
    ENSURE_MSG(scene != NULL, "assimp cannot read %s: %s", path, aiGetErrorString());
    if (!scene) return;
    size_t faces = 0, bad = 0;
    for (unsigned m = 0; m < scene->mNumMeshes; m++) faces += scene->mMeshes[m]->mNumFaces;
    ENSURE_MSG(faces == 4 * n, "%s: assimp read %zu triangles, expected %zu", path, faces, 4 * n);
    size_t face = 0;
    for (unsigned m = 0; m < scene->mNumMeshes && faces == 4 * n; m++) {
        const struct aiMesh *mesh = scene->mMeshes[m];
        for (unsigned f = 0; f < mesh->mNumFaces; f++, face++) {
            const struct aiFace *af = &mesh->mFaces[f];
            for (unsigned k = 0; k < af->mNumIndices; k++) {
                const struct aiVector3D *p = &mesh->mVertices[af->mIndices[k]];
                const float *want = verts + 12 * (face / 4) + 3 * export_tet_faces[face % 4][k % 3];
                if (af->mNumIndices != 3 || !export_close(p->x, want[0], tol) ||
                    !export_close(p->y, want[1], tol) || !export_close(p->z, want[2], tol))
                    bad++;
            }
        }
    }
    ENSURE_MSG(bad == 0, "%s: %zu corners differ from the tets written", path, bad);
    aiReleaseImport(scene);
}

/* Imports a point file with assimp and checks its vertices are positions (n × 3), in order. */
static inline void export_check_assimp_points(const char *path, const float *pos, size_t n, double tol)
{
    const struct aiScene *scene = aiImportFile(path, 0);
    ENSURE_MSG(scene != NULL, "assimp cannot read %s: %s", path, aiGetErrorString());
    if (!scene) return;
    size_t seen = 0, bad = 0;
    for (unsigned m = 0; m < scene->mNumMeshes; m++) {
        const struct aiMesh *mesh = scene->mMeshes[m];
        for (unsigned i = 0; i < mesh->mNumVertices; i++, seen++) {
            const struct aiVector3D *p = &mesh->mVertices[i];
            const float *want = pos + 3 * seen;
            if (seen >= n || !export_close(p->x, want[0], tol) || !export_close(p->y, want[1], tol) ||
                !export_close(p->z, want[2], tol))
                bad++;
        }
    }
    ENSURE_MSG(seen == n, "%s: assimp read %zu points, expected %zu", path, seen, n);
    ENSURE_MSG(bad == 0, "%s: %zu points differ from those written", path, bad);
    aiReleaseImport(scene);
}

/* What a point PLY should hold: positions, and each optional property when not NULL (orient
 * given as the cache's w, x, y, z; pscale and age one value for every point when has_*). */
typedef struct export_ply_points {
    const float *pos, *vel, *orient;
    int has_pscale, has_age;
    float pscale, age;
    const uint32_t *ids; /* NULL: 0 .. n-1 */
    const uint8_t *phases;
    const uint8_t *groups; /* NULL: none (a shot's cache has them) */
} export_ply_points;

/* Appends a value's 4 bytes (or 1 for the phase) to a record. */
static inline size_t export_put(unsigned char *r, size_t at, const void *v, size_t bytes)
{
    memcpy(r + at, v, bytes);
    return at + bytes;
}

/* Point i's record as the PLY should have it: x y z, vx vy vz, orientx..w (x, y, z, w), pscale,
 * age, id, phase, group. */
static inline size_t export_ply_record(const export_ply_points *e, size_t i, unsigned char *r)
{
    size_t at = export_put(r, 0, e->pos + 3 * i, 12);
    if (e->vel) at = export_put(r, at, e->vel + 3 * i, 12);
    for (int c = 0; e->orient && c < 4; c++) at = export_put(r, at, e->orient + 4 * i + (c + 1) % 4, 4);
    if (e->has_pscale) at = export_put(r, at, &e->pscale, 4);
    if (e->has_age) at = export_put(r, at, &e->age, 4);
    uint32_t id = e->ids ? e->ids[i] : (uint32_t)i;
    at = export_put(r, at, &id, 4);
    if (e->phases) at = export_put(r, at, e->phases + i, 1);
    return e->groups ? export_put(r, at, e->groups + i, 1) : at;
}

/* A point PLY: the exact header, then every record byte for byte. */
static inline void export_check_ply(const char *path, const export_ply_points *e, size_t n)
{
    char header[2048];
    snprintf(header, sizeof header,
             "ply\nformat binary_little_endian 1.0\ncomment flockmorph " FM_VERSION_STRING " points\n"
             "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n%s%s%s%s"
             "property int id\n%s%send_header\n", n,
             e->vel ? "property float vx\nproperty float vy\nproperty float vz\n" : "",
             e->orient ? "property float orientx\nproperty float orienty\nproperty float orientz\n"
                         "property float orientw\n" : "",
             e->has_pscale ? "property float pscale\n" : "", e->has_age ? "property float age\n" : "",
             e->phases ? "property uchar phase\n" : "", e->groups ? "property uchar group\n" : "");
    unsigned char want[64];
    size_t hl = strlen(header), record = export_ply_record(e, 0, want), size = hl + record * n;
    unsigned char *buf = malloc(size + 1);
    FILE *fp = fopen(path, "rb");
    size_t got = fp && buf ? fread(buf, 1, size + 1, fp) : 0;
    if (fp) fclose(fp);
    ENSURE_MSG(got == size, "%s: %zu bytes, expected %zu", path, got, size);
    if (got == size) {
        ENSURE_MSG(memcmp(buf, header, hl) == 0, "%s: header %.*s", path, (int)hl, (const char *)buf);
        size_t bad = 0;
        for (size_t i = 0; i < n; i++) bad += memcmp(buf + hl + record * i, want, export_ply_record(e, i, want)) != 0;
        ENSURE_MSG(bad == 0, "%s: %zu records differ", path, bad);
    }
    free(buf);
}

/* x y z, vx vy vz (when vel is not NULL) and the int32 id. */
static inline void export_check_ply_points(const char *path, const float *pos, const float *vel,
                                           const uint32_t *ids, size_t n)
{
    export_ply_points e = {.pos = pos, .vel = vel, .ids = ids};
    export_check_ply(path, &e, n);
}

/* One element of a binary little-endian PLY read back from its header alone, not from what the
 * writer meant to write: its rows, and per row a value per column, as doubles (floats, ints and
 * uchars convert exactly). A list property (3 items, as triangles have) gives the columns NAME#
 * (its count) and NAME0, NAME1, NAME2. */
typedef struct export_ply_table {
    long rows;
    int cols;
    char names[24][48];
    char types[24][16];
    double *v; /* rows x cols */
} export_ply_table;

static inline int export_ply_type_size(const char *type)
{
    return !strcmp(type, "uchar") ? 1 : !strcmp(type, "float") || !strcmp(type, "int") ? 4 : 0;
}

static inline double export_ply_value(const unsigned char *p, const char *type)
{
    if (!strcmp(type, "uchar")) return p[0];
    uint32_t bits = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    if (!strcmp(type, "int")) return (double)(int32_t)bits;
    float f;
    memcpy(&f, &bits, 4);
    return f;
}

/* The columns of one element's header lines; *record its bytes per row (lists of 3 int items). */
static inline void export_ply_columns(export_ply_table *t, char *line, size_t *record)
{
    char a[16], b[16], c[16], name[40];
    if (sscanf(line, "property list %15s %15s %39s", a, b, name) == 3) {
        static const char suffix[] = "#012";
        for (int k = 0; k < 4 && t->cols < 24; k++, t->cols++) {
            snprintf(t->names[t->cols], sizeof t->names[0], "%s%c", name, suffix[k]);
            snprintf(t->types[t->cols], sizeof t->types[0], "%s", k ? b : a);
        }
        *record += (size_t)export_ply_type_size(a) + 3 * (size_t)export_ply_type_size(b);
    } else if (sscanf(line, "property %15s %39s", c, name) == 2 && t->cols < 24) {
        snprintf(t->names[t->cols], sizeof t->names[0], "%s", name);
        snprintf(t->types[t->cols++], sizeof t->types[0], "%s", c);
        *record += (size_t)export_ply_type_size(c);
    }
}

/* Element `which` of the PLY at path; 0, or -1 (a failed ENSURE says why). */
static inline int export_ply_read(const char *path, const char *which, export_ply_table *out)
{
    memset(out, 0, sizeof *out);
    FILE *f = fopen(path, "rb");
    ENSURE_MSG(f != NULL, "cannot open %s", path);
    if (!f) return -1;
    char line[256], name[40];
    long count = 0, rows_before = 0;
    size_t skip = 0, record = 0, record_before = 0; /* the bytes of the elements before `which`, one row */
    int state = 0, ok = fgets(line, sizeof line, f) && !strcmp(line, "ply\n"); /* state 1: in `which` */
    while (ok && fgets(line, sizeof line, f) && strcmp(line, "end_header\n")) {
        if (sscanf(line, "element %39s %ld", name, &count) == 2) {
            if (state == 0) skip += record_before * (size_t)rows_before;
            if (state == 1) state = 2;
            if (state == 0 && !strcmp(name, which)) state = 1, out->rows = count;
            rows_before = count, record_before = 0;
        } else if (!strncmp(line, "property", 8)) {
            export_ply_table scratch = {0};
            export_ply_columns(state == 1 ? out : &scratch, line, state == 1 ? &record : &record_before);
        }
    }
    int found = state > 0;
    ok = ok && found && fseek(f, (long)skip, SEEK_CUR) == 0;
    unsigned char *body = ok ? malloc(record * (size_t)out->rows + 1) : NULL;
    ok = body && fread(body, 1, record * (size_t)out->rows, f) == record * (size_t)out->rows;
    fclose(f);
    ENSURE_MSG(ok, "%s: no element %s, or its body is cut short", path, which);
    out->v = ok ? malloc(sizeof(double) * (size_t)(out->rows * out->cols + 1)) : NULL;
    for (long r = 0; ok && r < out->rows; r++) {
        const unsigned char *p = body + record * (size_t)r;
        for (int c = 0; c < out->cols; p += export_ply_type_size(out->types[c]), c++)
            out->v[r * out->cols + c] = export_ply_value(p, out->types[c]);
    }
    free(body);
    return ok ? 0 : -1;
}

/* The column named name, or -1. */
static inline int export_ply_col(const export_ply_table *t, const char *name)
{
    for (int c = 0; c < t->cols; c++)
        if (!strcmp(t->names[c], name)) return c;
    return -1;
}

/* The column names joined by spaces. */
static inline void export_ply_col_names(const export_ply_table *t, char *out, size_t size)
{
    out[0] = 0;
    for (int c = 0; c < t->cols; c++) snprintf(out + strlen(out), size - strlen(out), "%s%s", c ? " " : "", t->names[c]);
}

/* Runs tests/check_vtk.py with args; returns its exit status (-1 if it did not exit). quiet
 * hides its messages (for the checks meant to fail). */
static inline int export_run_check_vtk(const char *args, int quiet)
{
    char cmd[4 * FM_PATH_MAX];
    snprintf(cmd, sizeof cmd, "python3 '%s/tests/check_vtk.py' %s%s", FM_SOURCE_DIR, args,
             quiet ? " 2>/dev/null" : "");
    int status = system(cmd);
    return status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* Writes values as raw little-endian bytes (the tests run on little-endian hosts only, like the
 * engine); appends when append is set. */
static inline void export_write_raw(const char *path, const void *data, size_t bytes, int append)
{
    FILE *f = fopen(path, append ? "ab" : "wb");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (!f) return;
    ENSURE(fwrite(data, 1, bytes, f) == bytes);
    fclose(f);
}

#endif
