/* Copies of meshes and tet sets, and byte equality of meshes: what a model build keeps for the next
 * build of an edited scene compares and holds (flockmorph studio, docs/studio.md). */
#include "geom.h"

#include <stdlib.h>
#include <string.h>

static void *copy_bytes(const void *from, size_t bytes)
{
    void *to = malloc(bytes ? bytes : 1);
    if (to && bytes) memcpy(to, from, bytes);
    return to;
}

fm_status fm_mesh_copy(const fm_mesh *from, fm_mesh *to, fm_error *err)
{
    fm_mesh m = {copy_bytes(from->v, sizeof(double) * 3 * (size_t)from->nv), from->nv,
                 copy_bytes(from->tri, sizeof(int32_t) * 3 * (size_t)from->nt), from->nt};
    if (!m.v || !m.tri) {
        fm_mesh_free(&m);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for a mesh of %lld triangles", (long long)from->nt);
    }
    *to = m;
    return FM_OK;
}

int fm_mesh_same(const fm_mesh *a, const fm_mesh *b)
{
    return a->nv == b->nv && a->nt == b->nt && (!a->nv || !memcmp(a->v, b->v, sizeof(double) * 3 * (size_t)a->nv)) &&
           (!a->nt || !memcmp(a->tri, b->tri, sizeof(int32_t) * 3 * (size_t)a->nt));
}

fm_status fm_tets_copy(const fm_tets *from, fm_tets *to, fm_error *err)
{
    fm_tets t = {copy_bytes(from->v, sizeof(double) * 12 * (size_t)from->n), from->n};
    if (!t.v) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld tets", (long long)from->n);
    *to = t;
    return FM_OK;
}
