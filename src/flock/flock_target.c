/* The shape flock's target surface over time: static, a procedural wave or pulse, or a sequence of
 * meshes with the target's connectivity (SCF "Shape Constraints": samples are drawn on the first
 * shape and follow its vertices). */
#include "flock.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double TWO_PI = 6.283185307179586;

/* Unit vertex normals: the area-weighted sum of the faces around each vertex. */
static fm_status vertex_normals(fm_flock_target *t, fm_error *err)
{
    const fm_mesh *m = &t->mesh;
    t->normals = calloc((size_t)m->nv * 3, sizeof(double));
    if (!t->normals) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the target's normals");
    for (int64_t f = 0; f < m->nt; f++) {
        const int32_t *tri = m->tri + 3 * f;
        const double *a = m->v + 3 * tri[0], *b = m->v + 3 * tri[1], *c = m->v + 3 * tri[2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++) t->normals[3 * tri[i] + k] += n[k]; /* |n| = twice the area */
    }
    for (int64_t i = 0; i < m->nv; i++) {
        double *n = t->normals + 3 * i, len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int k = 0; k < 3; k++) n[k] = len > 0 ? n[k] / len : 0;
    }
    return FM_OK;
}

/* The sequence over the target (geom.h), its meshes in t->frames once loaded. */
static fm_mesh_sequence sequence_of(const fm_flock_target *t, const fm_scene_def *def)
{
    return (fm_mesh_sequence){def->flock.deform_sequence, def->flock.deform_frames, def->flock.deform_frame_rate,
                              &t->mesh, &def->target, t->file_vertex, t->file_count, "shape_flock.deform.sequence",
                              t->frames};
}

fm_status fm_flock_target_build(fm_flock_target *t, const fm_scene_def *def, fm_error *err)
{
    memset(t, 0, sizeof *t);
    t->kind = def->flock.deform;
    fm_status st = t->kind == FM_DEFORM_SEQUENCE
                       ? fm_mesh_load_mapped(def->target.path, &t->mesh, &t->file_vertex, &t->file_count, err)
                       : fm_mesh_load(def->target.path, &t->mesh, err);
    st = fm_name_key(st, "target.mesh", err);
    if (st != FM_OK) return st;
    fm_mesh_place(&t->mesh, &def->target);
    if ((st = fm_scene_name_key(def, fm_mesh_check_extent(&t->mesh, def->target.path, err), "target.mesh", err)))
        return st;
    if (t->kind == FM_DEFORM_WAVE) return vertex_normals(t, err);
    if (t->kind == FM_DEFORM_PULSE) {
        for (int64_t i = 0; i < t->mesh.nv; i++)
            for (int k = 0; k < 3; k++) t->center[k] += t->mesh.v[3 * i + k] / (double)t->mesh.nv;
        return FM_OK;
    }
    if (t->kind != FM_DEFORM_SEQUENCE) return FM_OK;
    fm_mesh_sequence q = sequence_of(t, def);
    st = fm_mesh_sequence_load(&q, err);
    t->frames = q.frames;
    return st;
}

void fm_flock_target_free(fm_flock_target *t)
{
    fm_mesh_free(&t->mesh);
    free(t->normals), free(t->frames), free(t->file_vertex);
    fm_samples_free(&t->dest);
    t->normals = t->frames = NULL;
    t->file_vertex = NULL;
}

void fm_flock_target_vertices(const fm_flock_target *t, const fm_flock_def *def, double time, double *out)
{
    const fm_mesh *m = &t->mesh;
    const size_t count = 3 * (size_t)m->nv;
    if (t->kind == FM_DEFORM_WAVE) { /* x + A sin(2 pi (x.dir / wavelength - t / period)) n */
        const double *d = def->deform_direction;
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int64_t i = 0; i < m->nv; i++) {
            const double *x = m->v + 3 * i;
            double along = (x[0] * d[0] + x[1] * d[1] + x[2] * d[2]) / len;
            double h = def->deform_amplitude * sin(TWO_PI * (along / def->deform_wavelength - time / def->deform_period));
            for (int k = 0; k < 3; k++) out[3 * i + k] = x[k] + h * t->normals[3 * i + k];
        }
    } else if (t->kind == FM_DEFORM_PULSE) { /* c + (x - c)(1 + A sin(2 pi t / period)) */
        double s = 1 + def->deform_amplitude * sin(TWO_PI * time / def->deform_period);
        for (size_t j = 0; j < count; j++) out[j] = t->center[j % 3] + (m->v[j] - t->center[j % 3]) * s;
    } else if (t->kind == FM_DEFORM_SEQUENCE) { /* linear between meshes, looping */
        const fm_mesh_sequence q = {.count = def->deform_frames, .frame_rate = def->deform_frame_rate, .rest = m,
                                    .frames = t->frames};
        fm_mesh_sequence_at(&q, time, out);
    } else
        memcpy(out, m->v, sizeof(double) * count);
}
