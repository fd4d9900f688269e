/* Geometry: meshes in (assimp), closed-manifold checks, TetGen tetrahedralization and subdivision to
 * equal-sized tet sets (FM §4). */
#ifndef FM_GEOM_H
#define FM_GEOM_H

#include "fm_internal.h"

#include <stdint.h>

/* A closed triangle mesh with welded vertices. */
typedef struct fm_mesh {
    double *v;      /* 3 per vertex */
    int64_t nv;
    int32_t *tri;   /* 3 per triangle, 0-based */
    int64_t nt;
} fm_mesh;

/* A tet soup: 12 doubles per tet (4 vertices × xyz), every tet positively oriented. */
typedef struct fm_tets {
    double *v;
    int64_t n;
} fm_tets;

/* mesh_import.c (C linkage: tetra_tetgen.cpp uses the edge check) */
#ifdef __cplusplus
extern "C" {
#endif
fm_status fm_mesh_load(const char *path, fm_mesh *out, fm_error *err);
/* fm_mesh_load, and for each of the *file_count vertices as the importer reads them (for OBJ one
 * per face corner, in the file's face order) the welded vertex it became (*file_vertex, malloc'ed). */
fm_status fm_mesh_load_mapped(const char *path, fm_mesh *out, int32_t **file_vertex, int64_t *file_count,
                              fm_error *err);
/* The vertices as the importer reads them, not welded, with the triangles over them: a mesh
 * sequence's frame matches its rest mesh vertex for vertex this way, whatever the positions' order. */
fm_status fm_mesh_load_as_read(const char *path, fm_mesh *out, fm_error *err);
/* The same from len bytes in memory; format is the file extension ("obj", "ply", "off", "stl")
 * and name stands for the file in messages. */
fm_status fm_mesh_parse(const void *data, size_t len, const char *format, const char *name, fm_mesh *out,
                        fm_error *err);
void fm_mesh_free(fm_mesh *mesh);
/* mesh_counts.c: the element counts a PLY or OFF header or a binary STL declares, and the list
 * lengths of a binary PLY body, must fit in the file's bytes (data: the whole file, len bytes;
 * format: the extension), else FM_ERR_INPUT before assimp allocates from them.
 * fm_mesh_check_file_counts reads the file. */
fm_status fm_mesh_check_counts(const void *data, size_t len, const char *format, const char *name, fm_error *err);
fm_status fm_mesh_check_file_counts(const char *path, fm_error *err);
/* Every edge shared by exactly two faces with opposite directions, no zero-area triangle, and a
 * volume inside; names the first bad edge or triangle (numbered from 1 in file order). */
fm_status fm_mesh_check_closed(const fm_mesh *mesh, const char *path, fm_error *err);
/* The edge check alone, calling pair (if not NULL) for every edge with its two half-edges, each
 * numbered 3 * triangle + corner (the edge from corner k to corner k + 1). */
typedef void (*fm_edge_pair_fn)(int64_t half_a, int64_t half_b, void *user);
fm_status fm_mesh_pair_edges(const fm_mesh *mesh, const char *name, fm_edge_pair_fn pair, void *user,
                             fm_error *err);
void fm_mesh_place(fm_mesh *mesh, const fm_mesh_ref *ref);
/* A placed mesh must span at least FM_MESH_MIN_EXTENT, and FM_MESH_MIN_RELATIVE_EXTENT of its
 * largest coordinate; else FM_ERR_INPUT (mesh_import.c says why). */
#define FM_MESH_MIN_EXTENT 1e-9
#define FM_MESH_MIN_RELATIVE_EXTENT 1e-6
fm_status fm_mesh_check_extent(const fm_mesh *mesh, const char *path, fm_error *err);
double fm_mesh_signed_volume(const fm_mesh *mesh);

/* mesh_sequence.c: meshes pattern % 0 .. count-1, each with the rest mesh's vertices and triangles
 * as the file lists them (rest loaded by fm_mesh_load_mapped, whose file_vertex maps them), placed
 * like it, linear between meshes at frame_rate and looping. The caller fills the inputs. */
typedef struct fm_mesh_sequence {
    const char *pattern;          /* printf pattern with one integer conversion */
    int32_t count;
    double frame_rate;            /* meshes per second */
    const fm_mesh *rest;          /* placed */
    const fm_mesh_ref *place;     /* its placement (and path, for messages) */
    const int32_t *file_vertex;   /* fm_mesh_load_mapped's */
    int64_t file_count;
    const char *key;              /* the scene key messages name */
    double *frames;               /* out: 3 rest->nv doubles per mesh */
} fm_mesh_sequence;
fm_status fm_mesh_sequence_load(fm_mesh_sequence *q, fm_error *err);
/* The vertices at `time` (3 rest->nv doubles). */
void fm_mesh_sequence_at(const fm_mesh_sequence *q, double time, double *out);
void fm_mesh_sequence_free(fm_mesh_sequence *q);
#ifdef __cplusplus
}
#endif

/* tetra_tetgen.cpp: TetGen behind extern "C"; never throws, never exits. */
#ifdef __cplusplus
extern "C" {
#endif
fm_status fm_tetrahedralize(const fm_mesh *mesh, double quality, double max_volume,
                            const char *name, fm_tets *out, fm_error *err);
/* Do two meshes (each valid alone) share any volume? TetGen's self-intersection detection runs on
 * both surfaces together; if they do not cross, one may still hold the other, which a
 * winding-number test of one vertex decides. The shape flock samples open surfaces too: only a
 * closed mesh (fm_mesh_pair_edges) can hold the other. Returns 1 and describes the overlap in `how` (naming
 * triangles of a and b, numbered from 1), 0 if they are apart, -1 with err set if the check
 * itself failed. */
int fm_meshes_overlap(const fm_mesh *a, const char *name_a, const fm_mesh *b, const char *name_b, char *how,
                      size_t how_size, fm_error *err);
/* Generalised winding number of the closed surface around p: about +-1 inside, 0 outside. */
double fm_mesh_winding_number(const fm_mesh *mesh, const double p[3]);
#ifdef __cplusplus
}
#endif
void fm_tets_free(fm_tets *tets);

/* mesh_copy.c: copies (malloc'ed as the loaders' and TetGen's are; freed with fm_mesh_free and
 * fm_tets_free), and whether two meshes are the same bytes (vertices and triangles). */
fm_status fm_mesh_copy(const fm_mesh *from, fm_mesh *to, fm_error *err);
int fm_mesh_same(const fm_mesh *a, const fm_mesh *b);
fm_status fm_tets_copy(const fm_tets *from, fm_tets *to, fm_error *err);

/* subdivide.c (FM eqs 1-2) */
double fm_tet_signed_volume(const double *tet);
void fm_tet_centroid(const double *tet, double c[3]);
fm_status fm_subdivide_to(fm_tets *tets, int64_t n, fm_error *err);
/* Exactly n tets by splitting the largest tet at the midpoint of its longest edge, one at a time
 * (issue 38; the engine's default, fm_subdivide_to is the paper's scheme). */
fm_status fm_bisect_to(fm_tets *tets, int64_t n, fm_error *err);
/* The individual schemes, exposed for tests: write 4, 3 or 2 tets to out. */
void fm_split_1to4(const double *tet, double *out);
void fm_split_1to3(const double *tet, double *out);
void fm_split_1to2(const double *tet, double *out);

/* tet_quality.c: one pass over the tets and a selection for the median, serial (0.06 s per 10^6
 * tets for the pass on one core of a 2-vCPU Xeon). */
typedef struct fm_tet_quality {
    double bound;        /* the radius-edge bound asked of TetGen (-q) */
    double max_ratio;    /* the largest radius-edge ratio; 0 for no tets */
    int64_t above;       /* tets whose ratio exceeds the bound */
    int64_t above_4;     /* tets whose ratio exceeds 4.0 (issue 38's hard limit) */
    double median_ratio; /* the lower median; NaN for no tets (or no memory for the selection) */
    int64_t count;
} fm_tet_quality;
fm_tet_quality fm_tets_quality(const fm_tets *tets, double bound);

#endif
