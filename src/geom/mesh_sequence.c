/* A mesh sequence over a rest mesh: meshes 0 .. frames-1 with the rest mesh's connectivity, read
 * vertex for vertex as the file lists them, placed like the rest mesh, and interpolated linearly in
 * time. The shape flock's deforming target (shape_flock.deform.sequence) and the tetra morph's moving
 * target (target_motion.sequence) read the same files this way. */
#include "geom.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Frame is the rest mesh as read, vertex for vertex (the same count and triangles over the same
 * file vertices, which welding maps onto the rest mesh's)? Welding alone cannot tell: it orders the
 * vertices by position, and a deformation changes that order. */
static int same_connectivity(const fm_mesh_sequence *q, const fm_mesh *frame)
{
    if (frame->nv != q->file_count || frame->nt != q->rest->nt) return 0;
    for (int64_t k = 0; k < 3 * frame->nt; k++)
        if (q->file_vertex[frame->tri[k]] != q->rest->tri[k]) return 0;
    return 1;
}

/* Mesh i of the sequence, placed like the rest mesh, checked to have its connectivity; its vertices
 * as read go where the rest mesh's went (vertices welded in the rest mesh move as one: the first of
 * them read). */
static fm_status load_frame(const fm_mesh_sequence *q, int32_t i, double *out, fm_error *err)
{
    char path[FM_PATH_MAX + 32];
    snprintf(path, sizeof path, q->pattern, i);
    fm_mesh frame;
    char key[160];
    snprintf(key, sizeof key, "%s: mesh %d", q->key, i);
    fm_status st = fm_name_key(fm_mesh_load_as_read(path, &frame, err), key, err);
    if (st != FM_OK) return st;
    if (same_connectivity(q, &frame)) {
        fm_mesh_place(&frame, q->place);
        for (int64_t v = frame.nv - 1; v >= 0; v--) /* backwards: the first one read is written last */
            memcpy(out + 3 * (size_t)q->file_vertex[v], frame.v + 3 * v, 3 * sizeof(double));
    } else
        st = fm_fail(err, FM_ERR_INPUT, "%s: %s has other vertices or triangles than the target %s (as read: %lld "
                     "vertices and %lld triangles, against %lld and %lld): a sequence keeps the target's connectivity",
                     q->key, path, q->place->path, (long long)frame.nv, (long long)frame.nt, (long long)q->file_count,
                     (long long)q->rest->nt);
    fm_mesh_free(&frame);
    return st;
}

fm_status fm_mesh_sequence_load(fm_mesh_sequence *q, fm_error *err)
{
    const size_t per_frame = 3 * (size_t)q->rest->nv;
    q->frames = malloc(sizeof(double) * per_frame * (size_t)FM_MAX(q->count, 1));
    if (!q->frames) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %d target meshes", q->count);
    fm_status st = FM_OK;
    for (int32_t i = 0; i < q->count && st == FM_OK; i++) st = load_frame(q, i, q->frames + per_frame * (size_t)i, err);
    return st;
}

void fm_mesh_sequence_at(const fm_mesh_sequence *q, double time, double *out)
{
    const size_t count = 3 * (size_t)q->rest->nv;
    double f = time * q->frame_rate;
    double whole = floor(f), w = f - whole;
    int32_t i0 = (int32_t)fmod(whole, q->count), i1 = (i0 + 1) % q->count;
    const double *a = q->frames + count * (size_t)i0, *b = q->frames + count * (size_t)i1;
    for (size_t j = 0; j < count; j++) out[j] = a[j] + w * (b[j] - a[j]);
}

void fm_mesh_sequence_free(fm_mesh_sequence *q)
{
    free(q->frames);
    q->frames = NULL;
}
