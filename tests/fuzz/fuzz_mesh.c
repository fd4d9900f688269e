/* libFuzzer target: mesh loading (assimp import from memory, welding, the closed-manifold check).
 * The first byte picks the format, the rest is the file: '0' OBJ, '1' PLY, '2' OFF, '3' STL (any
 * byte works, modulo 4). */
#include "fuzz_check.h"
#include "geom.h"

#include <math.h>
#include <stdint.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char *const FORMATS[4] = {"obj", "ply", "off", "stl"};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    fm_mesh mesh;
    fm_error err = {0};
    fm_status st = fm_mesh_parse(data + 1, size - 1, FORMATS[data[0] % 4], "fuzz-mesh", &mesh, &err);
    fuzz_expect_clean(st, &err);
    if (st != FM_OK) return 0;
    /* A loaded mesh is welded: triangles index existing vertices, coordinates are finite. */
    FUZZ_ASSERT(mesh.nt > 0 && mesh.nv > 0);
    for (int64_t i = 0; i < 3 * mesh.nt; i++) FUZZ_ASSERT(mesh.tri[i] >= 0 && mesh.tri[i] < mesh.nv);
    for (int64_t i = 0; i < 3 * mesh.nv; i++) FUZZ_ASSERT(isfinite(mesh.v[i]));
    st = fm_mesh_check_closed(&mesh, "fuzz-mesh", &err);
    fuzz_expect_clean(st, &err);
    if (st == FM_OK) FUZZ_ASSERT(isfinite(fm_mesh_signed_volume(&mesh)));
    fm_mesh_free(&mesh);
    return 0;
}
