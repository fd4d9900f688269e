/* libFuzzer target: binary STL (assimp's binary reader, the triangle count against the file's size
 * in mesh_counts.c, welding, the closed-manifold check). The head is fixed and binary; the fuzzer
 * varies the declared count and the triangles (the input format is in fuzz_mesh_files.h). A count
 * the file cannot hold must be refused, never read or allocated. */
#include "fuzz_mesh_check.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fuzz_mesh_input("stl_binary", data, size); }
