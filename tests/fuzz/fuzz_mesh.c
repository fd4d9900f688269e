/* libFuzzer target: mesh loading (assimp import from memory, welding, the closed-manifold check).
 * The first byte picks the format, the rest is the file: '0' OBJ, '1' PLY, '2' OFF, '3' STL (any
 * byte works, modulo 4). */
#include "fuzz_mesh_check.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fuzz_mesh_input("mesh", data, size); }
