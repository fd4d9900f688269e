/* Helpers the export tests share: scratch paths, assimp re-import compared with what was written,
 * and tests/check_vtk.py (Python's xml module) run on VTK output. */
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

/* A point PLY: the exact header, then per point x y z, vx vy vz (when vel is not NULL) and the
 * int32 id, byte for byte. */
static inline void export_check_ply_points(const char *path, const float *pos, const float *vel,
                                           const uint32_t *ids, size_t n)
{
    char header[1024];
    snprintf(header, sizeof header,
             "ply\nformat binary_little_endian 1.0\ncomment flockmorph " FM_VERSION_STRING " points\n"
             "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n%sproperty int id\n"
             "end_header\n", n, vel ? "property float vx\nproperty float vy\nproperty float vz\n" : "");
    size_t hl = strlen(header), record = vel ? 28 : 16, size = hl + record * n;
    unsigned char *buf = malloc(size + 1);
    FILE *fp = fopen(path, "rb");
    size_t got = fp && buf ? fread(buf, 1, size + 1, fp) : 0;
    if (fp) fclose(fp);
    ENSURE_MSG(got == size, "%s: %zu bytes, expected %zu", path, got, size);
    if (got == size) {
        ENSURE_MSG(memcmp(buf, header, hl) == 0, "%s: header %.*s", path, (int)hl, (const char *)buf);
        size_t bad = 0;
        for (size_t i = 0; i < n; i++) {
            const unsigned char *r = buf + hl + record * i;
            int32_t id;
            memcpy(&id, r + record - 4, 4);
            bad += memcmp(r, pos + 3 * i, 12) != 0 || (uint32_t)id != (ids ? ids[i] : (uint32_t)i);
            bad += vel && memcmp(r + 12, vel + 3 * i, 12) != 0;
        }
        ENSURE_MSG(bad == 0, "%s: %zu records differ", path, bad);
    }
    free(buf);
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
