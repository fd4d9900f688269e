/* flockmorph exporters: one frame of agents, given as plain arrays, to the formats animation
 * and analysis tools read (docs/export.md).
 *
 *   PLY   binary little-endian; tets as 4 triangles each (vertex properties vx vy vz and an id
 *         unique per vertex, face properties agent_id, phase, group), points as vertices with
 *         vx vy vz, orientx .. orientw, pscale, age, id, phase, group
 *   OBJ   tets as 4 triangles each, points as `v` lines
 *   VTK   XML UnstructuredGrid (.vtu, appended data zlib-compressed as VTK's writer does):
 *         VTK_TETRA cells (cell data agent_id, velocity, phase, group) or VTK_VERTEX cells (point
 *         data id, velocity, orient, phase, group)
 *   VDB   OpenVDB PointDataGrid: P, v, orient, pscale, age, id, phase, group (Houdini's names)
 *   PC2   point cache (Blender's Mesh Cache modifier, Maya, 3ds Max): every frame in one file
 *   MDD   the same, big-endian, with frame times (fm_pointcache_create)
 *
 * Every writer writes PATH.partial and renames it to PATH only when complete. Included by
 * flockmorph.h; C++ only inside the engine (src/io/export_vdb.cpp). */
#ifndef FLOCKMORPH_EXPORT_H
#define FLOCKMORPH_EXPORT_H

#include "flockmorph/core.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Writes tets (n × 12 floats) in the format of path's extension: .ply (binary little-endian)
 * or .obj (4 triangles per tet), .vtu or .vdb (include/flockmorph/export.h, docs/export.md). */
fm_status fm_export_tets(const float *verts, size_t n, const char *path, fm_error *err);

typedef enum fm_export_format {
    FM_EXPORT_UNKNOWN = 0,
    FM_EXPORT_PLY = 1,
    FM_EXPORT_OBJ = 2,
    FM_EXPORT_VTK = 3, /* one .vtu per frame; fm_export_pvd lists a sequence */
    FM_EXPORT_VDB = 4,
    FM_EXPORT_PC2 = 5, /* point caches: one file for a whole sequence (fm_pointcache_create) */
    FM_EXPORT_MDD = 6
} fm_export_format;

/* "ply", "obj", "vtk", "vdb", "pc2", "mdd" (any case); FM_EXPORT_UNKNOWN otherwise. */
fm_export_format fm_export_format_named(const char *name);
/* From the extension of path's last component (.ply .obj .vtu .vdb .pc2 .mdd, any case). */
fm_export_format fm_export_format_of_path(const char *path);
/* The file extension without the dot: "ply", "obj", "vtu", "vdb", "pc2", "mdd"; "" for
 * FM_EXPORT_UNKNOWN. */
const char *fm_export_extension(fm_export_format format);

/* One frame, agents in id order. Either tet_vertices (a tet morph) or positions (a point flock)
 * is set, and which one says what the file holds, also when n is 0; the optional arrays may be
 * NULL. */
typedef struct fm_export_frame {
    size_t n;                  /* agents */
    const float *tet_vertices; /* n × 12: 4 vertices × xyz per tet; NULL for a point flock */
    const float *positions;    /* n × 3: points; for tets the centroids (VDB only; computed if NULL) */
    const float *velocities;   /* n × 3: written for points (PLY, VTK), for tets by VTK (cell data)
                                  and by VDB; NULL: none (VDB: zero) */
    const uint32_t *ids;       /* n stable agent ids; NULL: 0 .. n-1 (tet PLY: no ids written). A
                                  tet's 4 points get the ids 4 id + 0 ... 3 (PLY's id, VTK's point
                                  data id), and its faces or cell the agent id */
    const uint8_t *phases;     /* n fm_phase values; NULL: not written */
    const uint8_t *groups;     /* n: the scene group that moves each agent (a shot's cache); NULL: not written */
    /* Houdini's point attributes (PLY and VDB points, orientations also VTK; NULL: not written): */
    const float *orientations; /* n × 4: unit quaternions w, x, y, z as the cache stores them;
                                  written as Houdini's orient, x, y, z, w */
    const float *pscales;      /* n: the agent's radius in world units */
    const float *ages;         /* n: seconds the agent has existed */
    const float *vertex_velocities; /* tets: n × 12, each vertex's velocity (PLY's vx vy vz); NULL: none */
} fm_export_frame;

/* VTK's default zlib level: level 1 gives nearly the size of 6 and 9 on a frame's floats (they
 * hardly compress; the connectivity and ids compress at any level) in a fraction of the time
 * (docs/export.md has the measurements). */
#define FM_EXPORT_VTK_ZLIB_DEFAULT 1

typedef struct fm_export_options {
    double voxel_size;      /* VDB: voxel size in world units; 0 = chosen from the point density */
    int points_per_voxel;   /* VDB: the density target when voxel_size is 0 (default 8) */
    int vtk_zlib_level;     /* VTK: zlib level of the appended data, 1 (fastest) to 9 (smallest),
                               or 0 for raw, uncompressed data (default FM_EXPORT_VTK_ZLIB_DEFAULT) */
} fm_export_options;

fm_export_options fm_default_export_options(void);

/* Writes one frame to path in the given format. opts may be NULL for the defaults. */
fm_status fm_export_frame_write(const fm_export_frame *frame, fm_export_format format,
                                const fm_export_options *opts, const char *path, fm_error *err);

/* A ParaView collection (.pvd) listing files[i] (relative to the .pvd's directory) at
 * timestep times[i] seconds. */
fm_status fm_export_pvd(const char *path, const char *const *files, const double *times,
                        size_t count, fm_error *err);

/* A point cache (PC2 or MDD): `points` points in every one of `frames` frames, frame j being
 * frame number start_frame + j * frame_step, at (start_frame + j * frame_step) / frame_rate
 * seconds (MDD's frame times; PC2 stores the start frame and the step, its "sample rate"). */
typedef struct fm_pointcache_options {
    fm_export_format format; /* FM_EXPORT_PC2 or FM_EXPORT_MDD */
    size_t points, frames;   /* each at most INT32_MAX, the headers' int32 */
    double start_frame, frame_step, frame_rate;
} fm_pointcache_options;

typedef struct fm_pointcache_writer fm_pointcache_writer;

/* Opens path.partial and writes the header; NULL with err set on failure. */
fm_pointcache_writer *fm_pointcache_create(const char *path, const fm_pointcache_options *opts,
                                           fm_error *err);
/* Appends the next frame: points x 3 floats, written bit for bit (non-finite values refused). */
fm_status fm_pointcache_add(fm_pointcache_writer *w, const float *xyz, fm_error *err);
/* Checks that every announced frame was added, renames the file into place and frees w; on
 * failure removes the partial file. */
fm_status fm_pointcache_finish(fm_pointcache_writer *w, fm_error *err);
/* Removes the partial file and frees w (NULL is allowed). */
void fm_pointcache_abort(fm_pointcache_writer *w);

/* Z-up to Y-up (`export --up y`): the rotation by -90 degrees about x, (x, y, z) -> (x, z, -y),
 * in place on n vectors (positions, velocities; tet vertices are 4n of them), and the same
 * rotation applied to n quaternions w, x, y, z (r * q in double, r = (cos 45, -sin 45, 0, 0)). */
void fm_export_up_y(float *xyz, size_t n);
void fm_export_up_y_quaternions(float *wxyz, size_t n);

/* `export --scale S`: n vectors (positions, tet vertices, velocities) multiplied by scale in place,
 * each product computed in double and rounded to float once; scale 1 changes nothing. */
void fm_export_scale(float *xyz, size_t n, double scale);

/* Each tet's centroid (the mean of its 4 vertices, in double): n × 12 floats in, n × 3 out. */
void fm_tet_centroids(const float *verts, size_t n, float *out);

/* Velocity by finite difference: out = (after - before) / dt, n × 3 floats, in double. With
 * before and after one frame apart on either side this is the central difference; with one of
 * them the current frame, the one-sided difference at the ends of a sequence. */
void fm_finite_difference(const float *before, const float *after, size_t n, double dt, float *out);

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_EXPORT_H */
