/* libFuzzer target: binary PLY (assimp's binary reader, the header's counts against the file's size
 * in mesh_counts.c, welding, the closed-manifold check). The fuzzer varies the layout, the declared
 * counts and the body, not the words of the header, which fuzz_mesh's PLY inputs already reach; the
 * input format is in fuzz_mesh_files.h. Counts past what the body holds must be refused (damaged or
 * cut short), never read or allocated. */
#include "fuzz_mesh_check.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fuzz_mesh_input("ply_binary", data, size); }
