/* A target that moves (issue 38; docs/scene.md "target_motion"): the target tets follow a mesh
 * sequence with the target's connectivity and/or travel a path of their own, as a pure function of
 * the time since target_motion.start, so every thread and rank count sees the same target.
 *
 * Binding. Each target-tet vertex p is written once, at preparation, in the affine frame of its
 * nearest rest-surface triangle (a, b, c): p = a + b1 (b - a) + b2 (c - a) + h n, n = N / sqrt|N|,
 * N = (b - a) x (c - a). A frame later the same coordinates in the deformed triangle give p(t). The
 * vertices on the surface (h = 0 but for rounding) stay on the deformed surface exactly; the frame
 * follows every similarity of the triangle (rotation, translation, uniform scale: |n| grows as the
 * edges do), so the interior is carried as the nearest piece of surface moves, and vertices that tets
 * share keep one position (the same coordinates in the same triangle). Mean-value coordinates would
 * be smoother deep inside but cost every surface vertex per tet vertex and step; this costs one
 * triangle. Vertices bound to different triangles across the medial axis move apart only as far as
 * those triangles deform differently. */
#include "morph.h"
#include "closest.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct fm_morph_motion {
    fm_mesh rest;            /* sequence: the placed target surface, welded */
    int32_t *file_vertex;
    int64_t file_count;
    fm_mesh_sequence seq;
    int32_t *bind_tri;       /* sequence: 4 per slot, the triangle each target-tet vertex is bound to */
    double *bind;            /* sequence: 12 per slot, (b1, b2, h) of each vertex */
    int64_t bind_count;      /* slots bound (the model's n) */
};

static const double *tri_vertex(const double *v, const int32_t *tri, int64_t t, int i) { return v + 3 * (size_t)tri[3 * t + i]; }

/* N / sqrt|N| of triangle t over vertices v (zero for a degenerate one), and its edges. */
static void frame_of(const double *v, const int32_t *tri, int64_t t, double e1[3], double e2[3], double n[3])
{
    const double *a = tri_vertex(v, tri, t, 0), *b = tri_vertex(v, tri, t, 1), *c = tri_vertex(v, tri, t, 2);
    for (int k = 0; k < 3; k++) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k];
    double N[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double len = sqrt(N[0] * N[0] + N[1] * N[1] + N[2] * N[2]), s = len > 0 ? 1.0 / sqrt(len) : 0.0;
    for (int k = 0; k < 3; k++) n[k] = N[k] * s;
}

static double det3(const double a[3], const double b[3], const double c[3])
{
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

/* p's coordinates (b1, b2, h) in triangle t's frame at rest (Cramer's rule: the frame is a basis
 * unless the triangle is degenerate, which a closed target mesh has not got). */
static void bind_vertex(const fm_mesh *rest, int64_t t, const double p[3], double out[3])
{
    double e1[3], e2[3], n[3];
    frame_of(rest->v, rest->tri, t, e1, e2, n);
    const double *a = tri_vertex(rest->v, rest->tri, t, 0), d[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    const double det = det3(e1, e2, n);
    if (!(fabs(det) > 0)) {
        out[0] = out[1] = out[2] = 0;
        return;
    }
    out[0] = det3(d, e2, n) / det, out[1] = det3(e1, d, n) / det, out[2] = det3(e1, e2, d) / det;
}

static fm_status bind_targets(const fm_morph_model *m, fm_morph_motion *mo, fm_error *err)
{
    const int64_t n = m->n;
    mo->bind_count = n;
    mo->bind_tri = fm_alloc(sizeof(int32_t) * 4 * (size_t)n);
    mo->bind = fm_alloc(sizeof(double) * 12 * (size_t)n);
    if (!mo->bind_tri || !mo->bind) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the moving target's binding");
    fm_closest *c = fm_closest_build(&mo->rest, 1, "target", 0, err);
    if (!c) return err ? err->status : FM_ERR_INPUT;
    int64_t lost = -1;
#pragma omp parallel for num_threads(fm_threads(0)) schedule(dynamic, 1024) reduction(max : lost)
    for (int64_t j = 0; j < 4 * n; j++) {
        const float *f = m->tgt_f + 3 * j;
        const double p[3] = {f[0], f[1], f[2]};
        double closest[3];
        int64_t tri = -1;
        fm_closest_point(c, p, INFINITY, closest, &tri);
        if (tri < 0) lost = j;
        mo->bind_tri[j] = (int32_t)(tri < 0 ? 0 : tri);
        bind_vertex(&mo->rest, mo->bind_tri[j], p, mo->bind + 3 * j);
    }
    fm_closest_destroy(c);
    if (lost >= 0) return fm_fail(err, FM_ERR_INPUT, "target_motion: target tet vertex %lld has no nearest triangle", (long long)lost);
    return FM_OK;
}

fm_status fm_morph_motion_build(fm_morph_model *m, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    const struct fm_target_motion_def *tm = &def->target_motion;
    m->motion = NULL;
    if (!tm->sequence[0] && tm->path_count == 0) return FM_OK;
    fm_morph_motion *mo = calloc(1, sizeof *mo);
    if (!mo) return fm_fail(err, FM_ERR_MEMORY, "out of memory");
    m->motion = mo;
    if (!tm->sequence[0]) return FM_OK;
    fm_status st = fm_name_key(fm_mesh_load_mapped(def->target.path, &mo->rest, &mo->file_vertex, &mo->file_count, err),
                               "target.mesh", err);
    if (st != FM_OK) return st;
    fm_mesh_place(&mo->rest, &def->target);
    mo->seq = (fm_mesh_sequence){tm->sequence, tm->frames, tm->frame_rate, &mo->rest, &def->target, mo->file_vertex,
                                 mo->file_count, "target_motion.sequence", NULL};
    if ((st = fm_mesh_sequence_load(&mo->seq, err)) != FM_OK) return st;
    return bind_targets(m, mo, err);
}

void fm_morph_motion_destroy(fm_morph_motion *mo)
{
    if (!mo) return;
    fm_mesh_free(&mo->rest);
    free(mo->file_vertex);
    fm_mesh_sequence_free(&mo->seq);
    fm_free(mo->bind_tri), fm_free(mo->bind);
    free(mo);
}

void fm_morph_motion_hash(const fm_morph_motion *mo, fm_hash *h)
{
    if (mo->rest.nv == 0) return; /* a path alone is all in the scene */
    fm_hash_bytes(mo->seq.frames, sizeof(double) * 3 * (size_t)mo->rest.nv * (size_t)mo->seq.count, h);
    fm_hash_bytes(mo->bind_tri, sizeof(int32_t) * 4 * (size_t)(mo->bind_count), h);
    fm_hash_bytes(mo->bind, sizeof(double) * 12 * (size_t)(mo->bind_count), h);
}

/* The path's offset `along` units from its start ([0, 0, 0], then the points; it stops at the last). */
static void path_offset(const struct fm_target_motion_def *tm, double along, double out[3])
{
    double from[3] = {0, 0, 0};
    for (int32_t i = 0; i < tm->path_count; i++) {
        const double *to = tm->path[i], d[3] = {to[0] - from[0], to[1] - from[1], to[2] - from[2]};
        const double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (along < len) {
            for (int k = 0; k < 3; k++) out[k] = from[k] + d[k] * (along / len);
            return;
        }
        along -= len;
        memcpy(from, to, sizeof from);
    }
    memcpy(out, from, sizeof from);
}

fm_morph_motion_now *fm_morph_motion_now_create(const fm_morph_model *m, fm_error *err)
{
    const fm_morph_motion *mo = m->motion;
    fm_morph_motion_now *now = calloc(1, sizeof *now);
    int ok = now != NULL;
    if (ok && mo->rest.nv > 0) {
        now->v = malloc(sizeof(double) * 3 * (size_t)mo->rest.nv);
        now->frame = malloc(sizeof(double) * 9 * (size_t)mo->rest.nt);
        ok = now->v && now->frame;
    }
    for (int k = 0; k < 3 && ok && m->def.target_motion.path_count > 0; k++) {
        now->key_q[k] = malloc(sizeof(float) * (size_t)m->key_count);
        now->key_f[k] = malloc(sizeof(float) * (size_t)m->key_count);
        ok = now->key_q[k] && now->key_f[k];
    }
    if (!ok) {
        fm_morph_motion_now_free(now);
        fm_fail(err, FM_ERR_MEMORY, "out of memory for the moving target");
        return NULL;
    }
    now->time = NAN;
    return now;
}

void fm_morph_motion_now_free(fm_morph_motion_now *now)
{
    if (!now) return;
    free(now->v), free(now->frame);
    for (int k = 0; k < 3; k++) free(now->key_q[k]), free(now->key_f[k]);
    free(now);
}

/* The path's key points with the target's offset (FM eq 3): Q_i moves by i / (m + 1) of it, so Q_0 =
 * C_S stays and Q_{m+1} is the moved C_T that the last stretch of phase 1 heads for. */
static void move_key_points(const fm_morph_model *m, fm_morph_motion_now *now)
{
    const int32_t count = m->key_count;
    for (int32_t i = 0; i < count; i++) {
        const double w = count > 1 ? (double)i / (count - 1) : 1.0;
        for (int k = 0; k < 3; k++) now->key_q[k][i] = (float)(m->key_q[k][i] + w * now->offset[k]);
    }
    for (int32_t i = 0; i < count; i++) {
        const int32_t j = i + 1 < count ? i + 1 : i;
        double d[3], len = 0;
        for (int k = 0; k < 3; k++) d[k] = (double)now->key_q[k][j] - now->key_q[k][i], len += d[k] * d[k];
        len = sqrt(len);
        for (int k = 0; k < 3; k++) now->key_f[k][i] = len > 0 ? (float)(d[k] / len) : 0.0f;
    }
}

void fm_morph_motion_prepare(const fm_morph_model *m, fm_morph_motion_now *now, double time)
{
    if (now->time == time) return;
    const struct fm_target_motion_def *tm = &m->def.target_motion;
    const fm_morph_motion *mo = m->motion;
    const double tau = fmax(0.0, time - tm->start);
    path_offset(tm, tm->speed * tau, now->offset);
    if (tm->path_count > 0) move_key_points(m, now);
    if (mo->rest.nv > 0) {
        fm_mesh_sequence_at(&mo->seq, tau, now->v);
        for (int64_t i = 0; i < mo->rest.nv; i++)
            for (int k = 0; k < 3; k++) now->v[3 * i + k] += now->offset[k];
        for (int64_t t = 0; t < mo->rest.nt; t++) {
            double *f = now->frame + 9 * t;
            frame_of(now->v, mo->rest.tri, t, f, f + 3, f + 6);
        }
    }
    now->time = time;
}

void fm_morph_motion_tet(const fm_morph_model *m, const fm_morph_motion_now *now, int64_t slot, double out[12], double c[3])
{
    const fm_morph_motion *mo = m->motion;
    c[0] = c[1] = c[2] = 0;
    for (int i = 0; i < 4; i++) {
        const size_t j = 4 * (size_t)slot + (size_t)i;
        double *p = out + 3 * i;
        if (mo->rest.nv > 0) {
            const int32_t t = mo->bind_tri[j];
            const double *a = tri_vertex(now->v, mo->rest.tri, t, 0), *f = now->frame + 9 * (size_t)t, *w = mo->bind + 3 * j;
            for (int k = 0; k < 3; k++) p[k] = a[k] + w[0] * f[k] + w[1] * f[3 + k] + w[2] * f[6 + k];
        } else
            for (int k = 0; k < 3; k++) p[k] = (double)m->tgt_f[3 * j + (size_t)k] + now->offset[k];
        for (int k = 0; k < 3; k++) c[k] += 0.25 * p[k];
    }
}
