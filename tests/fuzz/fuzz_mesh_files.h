/* The mesh file a mesh fuzz target's input stands for: the targets parse it from memory, and
 * tests/cli/test_corpus_memory.c writes it out for the CLI. Input formats (seeds: make_seeds.py):
 *   mesh        byte 0 picks the format ('0' OBJ, '1' PLY, '2' OFF, '3' STL; any byte, modulo 4),
 *               the rest is the file
 *   ply_binary  byte 0 the layout: bit 0 big-endian, bit 1 double coordinates, bit 2 uint32 list
 *               counts (else uchar), bit 3 an extra uchar vertex property; byte 1 the vertex count
 *               and byte 2 the face count the header declares; the rest is the body after
 *               end_header (int32 indices)
 *   stl_binary  a fixed 80-byte head that does not start with "solid" (so the file is binary);
 *               byte 0 bit 0 set: the next 4 bytes are the declared triangle count (any value),
 *               clear: the count is what the body holds; the rest is the triangles, 50 bytes each
 * fuzz_mesh_file returns the file (malloc'ed; *len bytes) and its extension, or NULL if the input
 * stands for none (too short) or memory ran out. */
#ifndef FM_FUZZ_MESH_FILES_H
#define FM_FUZZ_MESH_FILES_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static inline uint8_t *fuzz_concat(const void *head, size_t head_len, const uint8_t *body, size_t body_len, size_t *len)
{
    uint8_t *file = malloc(head_len + body_len + 1);
    if (!file) return NULL;
    memcpy(file, head, head_len);
    if (body_len) memcpy(file + head_len, body, body_len);
    *len = head_len + body_len;
    return file;
}

static inline uint8_t *fuzz_ply_binary_file(const uint8_t *data, size_t size, size_t *len)
{
    if (size < 3) return NULL;
    const uint8_t layout = data[0];
    const char *coord = layout & 2 ? "double" : "float", *count = layout & 4 ? "uint" : "uchar";
    char head[512];
    int h = snprintf(head, sizeof head,
                     "ply\nformat binary_%s_endian 1.0\ncomment fuzz_ply_binary\nelement vertex %u\n"
                     "property %s x\nproperty %s y\nproperty %s z\n%selement face %u\n"
                     "property list %s int vertex_indices\nend_header\n",
                     layout & 1 ? "big" : "little", (unsigned)data[1], coord, coord, coord,
                     layout & 8 ? "property uchar flags\n" : "", (unsigned)data[2], count);
    return fuzz_concat(head, (size_t)h, data + 3, size - 3, len);
}

static inline uint8_t *fuzz_stl_binary_file(const uint8_t *data, size_t size, size_t *len)
{
    enum { STL_HEAD = 80, STL_TRIANGLE = 50 };
    const int declared = size > 0 && (data[0] & 1);
    if (size < (declared ? 5u : 1u)) return NULL;
    const uint8_t *body = data + (declared ? 5 : 1);
    const size_t body_len = size - (size_t)(body - data);
    uint8_t head[STL_HEAD + 4] = "binary STL written by fuzz_stl_binary";
    uint32_t count = (uint32_t)(body_len / STL_TRIANGLE);
    if (declared) count = (uint32_t)data[1] | (uint32_t)data[2] << 8 | (uint32_t)data[3] << 16 | (uint32_t)data[4] << 24;
    for (int k = 0; k < 4; k++) head[STL_HEAD + k] = (uint8_t)(count >> (8 * k));
    return fuzz_concat(head, sizeof head, body, body_len, len);
}

static inline uint8_t *fuzz_mesh_file(const char *set, const uint8_t *data, size_t size, size_t *len, const char **ext)
{
    static const char *const formats[4] = {"obj", "ply", "off", "stl"};
    if (!strcmp(set, "ply_binary")) return *ext = "ply", fuzz_ply_binary_file(data, size, len);
    if (!strcmp(set, "stl_binary")) return *ext = "stl", fuzz_stl_binary_file(data, size, len);
    if (size < 1) return NULL;
    *ext = formats[data[0] % 4];
    return fuzz_concat("", 0, data + 1, size - 1, len);
}

#endif
