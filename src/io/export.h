/* Internal pieces of the exporters (include/flockmorph/export.h): the little-endian byte writer
 * the binary formats share, the per-format writers, and the OpenVDB adapter. */
#ifndef FM_EXPORT_H
#define FM_EXPORT_H

#include "fm_internal.h"

#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The 4 outward triangles of a positively oriented tet (docs/cache-format.md). */
extern const int fm_tet_faces[4][3];

/* Buffered little-endian output to a FILE; `failed` latches the first failed write (errno
 * then says why). The engine runs on little-endian hosts only (docs/cache-format.md), but the
 * bytes are put one by one so the files do not depend on that. */
typedef struct fm_le_writer {
    FILE *f;
    size_t used;
    int failed;
    unsigned char buf[1 << 16];
} fm_le_writer;

/* v as 8 little-endian bytes at p (fm_le_u64 and headers built in memory). */
void fm_le_store_u64(unsigned char *p, uint64_t v);

void fm_le_u8(fm_le_writer *w, uint8_t v);
void fm_le_u32(fm_le_writer *w, uint32_t v);
void fm_le_u64(fm_le_writer *w, uint64_t v);
void fm_le_f32(fm_le_writer *w, float v);

/* Runs emit(w, data) on a writer over f and writes out what it buffered; 0, or -1 if a write
 * failed (errno says why). */
typedef void (*fm_le_emit_fn)(fm_le_writer *w, const void *data);
int fm_le_write(FILE *f, fm_le_emit_fn emit, const void *data);

/* A file's body: writes data to f, returns 0 or -1 on a failed write (errno says why). */
typedef int (*fm_body_fn)(FILE *f, const void *data);

/* Opens path.partial, runs body, commits or discards: the one place write errors become messages. */
fm_status fm_export_with_body(const char *path, fm_body_fn body, const void *data, fm_error *err);

/* One triangle mesh of fm_export_ply_meshes: nv vertices (3 doubles each) and nt triangles (3
 * 0-based indices into its own vertices); name (a line of text) goes into a header comment. */
typedef struct fm_ply_mesh {
    const char *name;
    const double *v;
    int64_t nv;
    const int32_t *tri;
    int64_t nt;
} fm_ply_mesh;

/* Writes the meshes as one binary little-endian PLY through PATH.partial and rename(): float x y z
 * per vertex and a uchar-counted int list per face, each mesh's indices offset by the vertices of
 * those before it, a comment per mesh naming its vertex and face ranges, and `comment` (one line of
 * text, NULL for none) as a comment of its own after the first. It is how `flockmorph run` writes
 * the placed obstacles (OUTDIR/obstacles.ply), with a comment naming their axes and scale. */
fm_status fm_export_ply_meshes(const fm_ply_mesh *meshes, int count, const char *comment, const char *path,
                               fm_error *err);
/* The same meshes as OBJ (`export --format obj`'s obstacles): `# comment` after the first line when
 * comment is not NULL, an `o NAME` line per mesh, `v` lines printed with %.9g of the float (every
 * float read back exactly), `f` lines 1-based over the file. */
fm_status fm_export_obj_meshes(const fm_ply_mesh *meshes, int count, const char *comment, const char *path,
                               fm_error *err);

/* Component c (0 x, 1 y, 2 z, 3 w) of the quaternion q stored as the cache stores it, w, x, y, z:
 * Houdini's orient (PLY, VTK) is x, y, z, w. */
static inline float fm_orient_xyzw(const float *q, int c) { return q[(c + 1) % 4]; }

/* The point id of vertex j (0 ... 3) of the tet with agent id `id` (PLY's `id`, VTK's point data
 * `id`): unique per point, and the tet's own id is point id / 4. */
static inline uint32_t fm_tet_point_id(uint32_t id, int j) { return 4 * id + (uint32_t)j; }

/* export_vtk.c: the .vtu body (tets as VTK_TETRA, points as VTK_VERTEX) of a frame, its appended
 * data zlib-compressed at zlib_level (1..9), or raw for 0. */
typedef struct fm_vtu_input {
    const fm_export_frame *frame;
    int zlib_level;
} fm_vtu_input;
int fm_vtu_body(FILE *f, const void *input);

/* export_vdb.cpp: the frame's points at `positions` (its own, or its tets' centroids) as an
 * OpenVDB PointDataGrid named "points" with the attributes P, v (vec3s; zero without
 * velocities) and id (int32; ids at most INT32_MAX, as fm_export_frame_write checks), and
 * orient (quats x, y, z, w), pscale and age (float) and phase (int32) when the frame has them. */
fm_status fm_vdb_points_write(const fm_export_frame *frame, const float *positions,
                              const fm_export_options *opts, const char *path, fm_error *err);

/* Reads the points back (for tests): malloc'ed arrays in the file's (leaf) order, which the ids
 * identify; voxel_size (may be NULL) receives the grid's voxel size. */
fm_status fm_vdb_points_read(const char *path, size_t *n, float **positions, float **velocities,
                             int32_t **ids, double *voxel_size, fm_error *err);

/* One attribute back (for tests), as floats in the order fm_vdb_points_read gives the points:
 * *components is 1 (float, int32), 3 (vec3s) or 4 (quats, x y z w). */
fm_status fm_vdb_points_read_attr(const char *path, const char *name, size_t *n, int *components,
                                  float **values, fm_error *err);

/* "NAME:TYPE" of every point attribute in the file's order, space-separated, into out (for
 * tests: vdb_print does not list point attributes): "P:vec3s v:vec3s id:int32 ...". */
fm_status fm_vdb_points_list_attrs(const char *path, char *out, size_t size, fm_error *err);

#ifdef __cplusplus
}
#endif

#endif
