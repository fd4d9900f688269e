/* fm_model_build: scene -> meshes -> TetGen -> subdivision -> orders -> path -> bounding sphere.
 * Everything here runs once; the result is immutable (MuJoCo's mjModel). */
#include "prep.h"
#include "sim.h"
#include "fm_math.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void report(fm_progress_fn progress, void *user, const char *stage, double fraction)
{
    if (progress) progress(stage, fraction, user);
}

typedef struct prep_scratch {
    fm_mesh src_mesh, dst_mesh;
    fm_tets src, dst;
    fm_path path;
    int64_t *d1, *d2;
} prep_scratch;

/* Loads, checks, places and tetrahedralizes one mesh. */
static fm_status prepare_mesh(const fm_scene_def *def, const fm_mesh_ref *ref, const char *key, fm_mesh *mesh,
                              fm_tets *tets, fm_error *err)
{
    fm_status st = fm_mesh_load(ref->path, mesh, err);
    if (st == FM_OK) st = fm_mesh_check_closed(mesh, ref->path, err);
    if (st != FM_OK) return fm_name_key(st, key, err);
    fm_mesh_place(mesh, ref);
    return fm_name_key(fm_tetrahedralize(mesh, def->tet_quality, def->tet_max_volume, ref->path, tets, err), key, err);
}

/* FM §4: n >= max(n1, n2); say which mesh needs more. */
static fm_status choose_n(fm_model *m, const fm_tets *src, const fm_tets *dst, fm_error *err)
{
    int64_t most = FM_MAX(src->n, dst->n);
    m->n = m->def.n > 0 ? m->def.n : most;
    if (m->n >= most) return FM_OK;
    return fm_fail(err, FM_ERR_INPUT, "%s: n: %lld is smaller than the %lld tets TetGen made for %s; use n >= %lld "
                   "or leave n out (default max(n1, n2))", m->def.scene_path[0] ? m->def.scene_path : "scene",
                   (long long)m->n, (long long)most, src->n >= dst->n ? m->def.source.path : m->def.target.path,
                   (long long)most);
}

static double total_volume(const fm_tets *tets, double centroid[3])
{
    double vol = 0, c[3] = {0, 0, 0};
    for (int64_t i = 0; i < tets->n; i++) {
        double v = fm_tet_signed_volume(tets->v + 12 * i), tc[3];
        fm_tet_centroid(tets->v + 12 * i, tc);
        vol += v;
        for (int k = 0; k < 3; k++) c[k] += v * tc[k];
    }
    for (int k = 0; k < 3; k++) centroid[k] = vol > 0 ? c[k] / vol : 0;
    return vol;
}

static fm_status alloc_model_arrays(fm_model *m, fm_error *err)
{
    size_t n = (size_t)m->n;
    m->src_rel = fm_alloc(sizeof(float) * 12 * n);
    m->tgt = fm_alloc(sizeof(double) * 12 * n);
    m->tgt_f = fm_alloc(sizeof(float) * 12 * n);
    int ok = m->src_rel && m->tgt && m->tgt_f;
    for (int k = 0; k < 3; k++) {
        m->src_c[k] = fm_alloc(sizeof(float) * n);
        m->tgt_c[k] = fm_alloc(sizeof(float) * n);
        ok = ok && m->src_c[k] && m->tgt_c[k];
    }
    return ok ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)m->n);
}

/* Stores source tets in launch order, as centroid + centroid-relative vertices. */
static void store_sources(fm_model *m, const fm_tets *src, const int64_t *d1)
{
    for (int64_t a = 0; a < m->n; a++) {
        const double *t = src->v + 12 * d1[a];
        double c[3];
        fm_tet_centroid(t, c);
        for (int k = 0; k < 3; k++) m->src_c[k][a] = (float)c[k];
        for (int i = 0; i < 12; i++) m->src_rel[12 * a + i] = (float)(t[i] - c[i % 3]);
    }
}

static void store_targets(fm_model *m, const fm_tets *dst, const int64_t *d2)
{
    for (int64_t s = 0; s < m->n; s++) {
        const double *t = dst->v + 12 * d2[s];
        double c[3];
        fm_tet_centroid(t, c);
        memcpy(m->tgt + 12 * s, t, 12 * sizeof(double));
        for (int i = 0; i < 12; i++) m->tgt_f[12 * s + i] = (float)t[i];
        for (int k = 0; k < 3; k++) m->tgt_c[k][s] = (float)c[k];
    }
}

static fm_status store_path(fm_model *m, const fm_path *path, fm_error *err)
{
    m->key_count = path->count;
    for (int k = 0; k < 3; k++) {
        m->key_q[k] = fm_alloc(sizeof(float) * (size_t)path->count);
        m->key_f[k] = fm_alloc(sizeof(float) * (size_t)path->count);
        if (!m->key_q[k] || !m->key_f[k]) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the path");
    }
    for (int32_t i = 0; i < path->count; i++) {
        const double *q = path->q + 3 * i;
        /* f_i runs from Q_i to Q_{i+1}; the last key point has none (the kernel heads for C_T). */
        const double *next = path->q + 3 * (i + 1 < path->count ? i + 1 : i);
        double d[3] = {next[0] - q[0], next[1] - q[1], next[2] - q[2]};
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int k = 0; k < 3; k++) {
            m->key_q[k][i] = (float)q[k];
            m->key_f[k][i] = len > 0 ? (float)(d[k] / len) : 0.0f;
        }
    }
    return FM_OK;
}

static fm_status bounding_sphere(fm_model *m, const fm_mesh *target, fm_error *err)
{
    double c[3], r;
    if (fm_min_sphere(target->v, (size_t)target->nv, m->def.seed, c, &r) != 0)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the bounding sphere");
    for (int k = 0; k < 3; k++) m->info.sphere_center[k] = c[k], m->sphere_c[k] = (float)c[k];
    m->info.sphere_radius = r;
    m->sphere_r = (float)r;
    return FM_OK;
}

/* R_X of FM eq 8: the radius of each source tet's minimal bounding sphere, at rest. */
static fm_status tet_radii(fm_model *m, float *max_radius, fm_error *err)
{
    m->src_radius = fm_alloc(sizeof(float) * (size_t)m->n);
    if (!m->src_radius) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)m->n);
    *max_radius = 0;
    for (int64_t a = 0; a < m->n; a++) {
        double pts[12], c[3], r;
        for (int i = 0; i < 12; i++) pts[i] = m->src_rel[12 * a + i];
        if (fm_min_sphere(pts, 4, (uint64_t)a, c, &r) != 0) return fm_fail(err, FM_ERR_MEMORY, "out of memory");
        m->src_radius[a] = (float)r;
        if ((float)r > *max_radius) *max_radius = (float)r;
    }
    return FM_OK;
}

static void grow_bounds(double lo[3], double hi[3], const double *pts, int64_t count)
{
    for (int64_t i = 0; i < count; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], pts[3 * i + k]), hi[k] = fmax(hi[k], pts[3 * i + k]);
}

/* The scene's extent (source, target, path), padded: the style-field grid spans it. */
static void scene_bounds(fm_model *m, const prep_scratch *s)
{
    for (int k = 0; k < 3; k++) m->scene_lo[k] = INFINITY, m->scene_hi[k] = -INFINITY;
    grow_bounds(m->scene_lo, m->scene_hi, s->src_mesh.v, s->src_mesh.nv);
    grow_bounds(m->scene_lo, m->scene_hi, s->dst_mesh.v, s->dst_mesh.nv);
    grow_bounds(m->scene_lo, m->scene_hi, s->path.q, s->path.count);
    double pad = 0;
    for (int k = 0; k < 3; k++) pad = fmax(pad, 0.15 * (m->scene_hi[k] - m->scene_lo[k]));
    for (int k = 0; k < 3; k++) m->scene_lo[k] -= pad, m->scene_hi[k] += pad;
}

fm_obstacles *fm_obstacles_from_scene(const fm_scene_def *def, double reach, fm_error *err)
{
    int count = def->obstacle_count;
    fm_mesh *meshes = calloc((size_t)count, sizeof *meshes);
    if (!meshes) return fm_fail(err, FM_ERR_MEMORY, "out of memory for obstacles"), NULL;
    fm_status st = FM_OK;
    fm_obstacles *out = NULL;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < count && st == FM_OK; i++) {
        char key[48];
        snprintf(key, sizeof key, "obstacles.meshes[%d]", i);
        st = fm_name_key(fm_mesh_load(def->obstacles[i].path, &meshes[i], err), key, err);
        if (st == FM_OK) st = fm_name_key(fm_mesh_check_closed(&meshes[i], def->obstacles[i].path, err), key, err);
        if (st == FM_OK) fm_mesh_place(&meshes[i], &def->obstacles[i]), grow_bounds(lo, hi, meshes[i].v, meshes[i].nv);
    }
    if (st == FM_OK) {
        double extent = 0;
        for (int k = 0; k < 3; k++) extent = fmax(extent, hi[k] - lo[k] + 2 * reach);
        double voxel = def->obstacle_voxel > 0 ? def->obstacle_voxel : extent / 160;
        out = fm_obstacles_build(meshes, count, voxel, reach + 2 * voxel, err);
    }
    for (int i = 0; i < count; i++) fm_mesh_free(&meshes[i]);
    free(meshes);
    return out;
}

/* Beyond the paper (FM §8): the target's own signed distance decides the phase switch. */
static fm_status build_target_sdf(fm_model *m, const fm_mesh *target, fm_error *err)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, extent = 0;
    grow_bounds(lo, hi, target->v, target->nv);
    for (int k = 0; k < 3; k++) extent = fmax(extent, hi[k] - lo[k]);
    double voxel = extent / 160, band = fabs(m->def.switch_distance) + 3 * voxel;
    m->target_sdf = fm_obstacles_build(target, 1, voxel, band, err);
    return m->target_sdf ? FM_OK : fm_name_key(err ? err->status : FM_ERR_INPUT, "phase2.switch", err);
}

static void set_timing(fm_model *m)
{
    double frame = 1.0 / m->def.frame_rate;
    /* the scene's time_step divides the frame interval (validated); snap it so frames land on k/frame_rate */
    m->steps_per_frame = m->def.time_step > 0 ? (int32_t)llround(frame / m->def.time_step) : 1;
    m->dt = frame / m->steps_per_frame;
    m->launch_rate = m->def.launch_rate > 0 ? m->def.launch_rate : (double)m->n / 2.0;
    m->info.time_step = m->dt;
    m->info.steps_per_frame = m->steps_per_frame;
    m->info.launch_rate = m->launch_rate;
}

static void free_scratch(prep_scratch *s)
{
    fm_mesh_free(&s->src_mesh), fm_mesh_free(&s->dst_mesh);
    fm_tets_free(&s->src), fm_tets_free(&s->dst);
    fm_path_free(&s->path);
    free(s->d1), free(s->d2);
}

static fm_status build(fm_model *m, prep_scratch *s, fm_progress_fn progress, void *user, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    report(progress, user, "tetrahedralize source", 0.0);
    fm_status st = prepare_mesh(def, &def->source, "source.mesh", &s->src_mesh, &s->src, err);
    if (st != FM_OK) return st;
    report(progress, user, "tetrahedralize target", 0.3);
    if ((st = prepare_mesh(def, &def->target, "target.mesh", &s->dst_mesh, &s->dst, err)) != FM_OK) return st;
    m->info.source_tets = s->src.n;
    m->info.target_tets = s->dst.n;
    if ((st = choose_n(m, &s->src, &s->dst, err)) != FM_OK) return st;
    report(progress, user, "subdivide", 0.6);
    if ((st = fm_subdivide_to(&s->src, m->n, err)) != FM_OK) return st;
    if ((st = fm_subdivide_to(&s->dst, m->n, err)) != FM_OK) return st;
    m->info.agents = m->n;
    m->info.source_volume = total_volume(&s->src, m->info.source_centroid);
    m->info.target_volume = total_volume(&s->dst, m->info.target_centroid);
    report(progress, user, "order", 0.8);
    if ((st = fm_path_build(def, m->info.source_centroid, m->info.target_centroid, &s->path, err)) != FM_OK) return st;
    m->info.key_points = s->path.count;
    s->d1 = malloc(sizeof(int64_t) * (size_t)m->n);
    s->d2 = malloc(sizeof(int64_t) * (size_t)m->n);
    if (!s->d1 || !s->d2) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)m->n);
    if ((st = fm_order_d1(&s->src, &s->path, s->d1, err)) != FM_OK) return st;
    if ((st = fm_order_d2(&s->dst, &s->path, s->d2, err)) != FM_OK) return st;
    if ((st = alloc_model_arrays(m, err)) != FM_OK) return st;
    store_sources(m, &s->src, s->d1);
    store_targets(m, &s->dst, s->d2);
    if ((st = store_path(m, &s->path, err)) != FM_OK) return st;
    if ((st = bounding_sphere(m, &s->dst_mesh, err)) != FM_OK) return st;
    scene_bounds(m, s);
    float max_radius = 0;
    if ((st = tet_radii(m, &max_radius, err)) != FM_OK) return st;
    m->max_radius = max_radius;
    report(progress, user, "obstacles", 0.9);
    if (def->obstacle_count > 0 && !(m->obstacles = fm_obstacles_from_scene(def, def->k_a + max_radius, err)))
        return err ? err->status : FM_ERR_INPUT;
    if (def->phase_switch == FM_SWITCH_DISTANCE && (st = build_target_sdf(m, &s->dst_mesh, err)) != FM_OK) return st;
    set_timing(m);
    report(progress, user, "ready", 1.0);
    return FM_OK;
}

fm_model *fm_model_build(const fm_scene_def *def, fm_progress_fn progress, void *user, fm_error *err)
{
    if (fm_scene_validate(def, err) != FM_OK) return NULL;
    fm_model *m = calloc(1, sizeof *m);
    if (!m) {
        fm_fail(err, FM_ERR_MEMORY, "out of memory");
        return NULL;
    }
    m->def = *def;
    prep_scratch scratch;
    memset(&scratch, 0, sizeof scratch);
    fm_status st = build(m, &scratch, progress, user, err);
    free_scratch(&scratch);
    if (st != FM_OK) {
        fm_model_destroy(m);
        return NULL;
    }
    return m;
}

void fm_model_destroy(fm_model *m)
{
    if (!m) return;
    fm_free(m->src_rel), fm_free(m->tgt), fm_free(m->tgt_f), fm_free(m->src_radius);
    fm_obstacles_destroy(m->obstacles); /* NULL-safe */
    fm_obstacles_destroy(m->target_sdf);
    for (int k = 0; k < 3; k++) {
        fm_free(m->src_c[k]), fm_free(m->tgt_c[k]);
        fm_free(m->key_q[k]), fm_free(m->key_f[k]);
    }
    free(m);
}

fm_model_info fm_model_get_info(const fm_model *m) { return m->info; }

const float *fm_model_target_tet(const fm_model *m, int64_t j) { return m->tgt_f + 12 * j; }
