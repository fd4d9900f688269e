/* What the mesh fuzz targets (fuzz_mesh.c, fuzz_ply_binary.c, fuzz_stl_binary.c) do with an input:
 * the mesh file it stands for (fuzz_mesh_files.h) is parsed from memory, and a mesh the loader
 * accepts is welded (triangles index existing vertices, coordinates are finite) and answers the
 * closed-manifold check cleanly, with a finite volume for a closed one. */
#ifndef FM_FUZZ_MESH_CHECK_H
#define FM_FUZZ_MESH_CHECK_H

#include "fuzz_check.h"
#include "fuzz_mesh_files.h"
#include "geom.h"

#include <math.h>

static inline void fuzz_check_parsed_mesh(fm_status st, fm_mesh *mesh, fm_error *err)
{
    fuzz_expect_clean(st, err);
    if (st != FM_OK) return;
    FUZZ_ASSERT(mesh->nt > 0 && mesh->nv > 0);
    for (int64_t i = 0; i < 3 * mesh->nt; i++) FUZZ_ASSERT(mesh->tri[i] >= 0 && mesh->tri[i] < mesh->nv);
    for (int64_t i = 0; i < 3 * mesh->nv; i++) FUZZ_ASSERT(isfinite(mesh->v[i]));
    st = fm_mesh_check_closed(mesh, "fuzz-mesh", err);
    fuzz_expect_clean(st, err);
    if (st == FM_OK) FUZZ_ASSERT(isfinite(fm_mesh_signed_volume(mesh)));
    fm_mesh_free(mesh);
}

static inline int fuzz_mesh_input(const char *set, const uint8_t *data, size_t size)
{
    size_t len;
    const char *format;
    uint8_t *file = fuzz_mesh_file(set, data, size, &len, &format);
    if (!file) return 0;
    fm_mesh mesh;
    fm_error err = {0};
    fuzz_check_parsed_mesh(fm_mesh_parse(file, len, format, set, &mesh, &err), &mesh, &err);
    free(file);
    return 0;
}

#endif
