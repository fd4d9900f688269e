/* fm_morph_model_build: scene -> meshes -> TetGen -> subdivision -> orders -> path -> bounding sphere.
 * Everything here runs once; the result is immutable (MuJoCo's mjModel). */
#include "geom.h"
#include "morph.h"
#include "fm_math.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>


typedef struct prep_scratch {
    fm_mesh src_mesh, dst_mesh;
    fm_tets src, dst;
    fm_path path;
    int64_t *d1, *d2;
    fm_mesh *obstacles;  /* obstacle meshes, placed (def.obstacle_count) */
    const fm_morph_model *from; /* a shot's group from another's formed shape: its target tets are the source */
    int keep_targets;           /* keep the model's target tets in double (m->tgt) for a later group */
    fm_morph_keep *keep;        /* the studio's: the tets of the build before (NULL: none) */
    int made;                   /* TetGen runs and subdivisions this build made (none: all kept) */
    int path_in_keep;           /* the keep's route is this build's path (route_kept): its nav may be kept */
    fm_progress_fn progress;    /* the build's report, */
    void *user;
} prep_scratch;

/* A stage boundary: reported, and where the studio cancelled the build (its keep's flag), FM_STOPPED. */
static fm_status stage(const prep_scratch *s, const char *name, double fraction, fm_error *err)
{
    return fm_build_stage(s->progress, s->user, name, fraction, s->keep ? s->keep->cancel : NULL, err);
}

/* Records a warning ("FILE:LINE:COL: key: what") on the model. */
static void warn(fm_morph_model *m, const char *key, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void warn(fm_morph_model *m, const char *key, const char *fmt, ...)
{
    if (m->warning_count == FM_MODEL_MAX_WARNINGS) return;
    char what[768], where[FM_PATH_MAX + 64];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    fm_scene_key_location(&m->def, key, where, sizeof where);
    snprintf(m->warnings[m->warning_count++], sizeof m->warnings[0], "%.200s: %s", where, what);
}

/* TetGen's -a bounds every tet's volume, so a mesh of volume V gives more than V / max_volume tets;
 * measured, 1.9 to 2.5 times that (a sphere and a cylinder of 320 triangles and a cube, 10^4 to 3.2e6
 * tets; more below 10^4, where the surface's own tets dominate). TETS_PER_BOUND stays under every
 * measured ratio, so the count it implies is one TetGen reaches: a count whose run cannot fit the
 * machine (fm_morph_memory_check refuses it after TetGen) is refused before TetGen spends minutes
 * and gigabytes on it (issue 15: max_volume 1e-7 on a small cube ran for over 500 s). */
#define TETS_PER_BOUND 1.5

static fm_status check_tet_bound(const fm_scene_def *def, const fm_mesh_ref *ref, const fm_mesh *mesh, const char *key,
                                 fm_error *err)
{
    if (!(def->tet_max_volume > 0)) return FM_OK;
    const double volume = fabs(fm_mesh_signed_volume(mesh)), tets = TETS_PER_BOUND * volume / def->tet_max_volume;
    const fm_memory_estimate e = fm_morph_memory_estimate(def, (int64_t)fmin(tets, 1e15));
    if (fm_memory_fits(&e)) return FM_OK;
    const double fits = fm_memory_agents_that_fit(&e), gib = 1024.0 * 1024.0 * 1024.0;
    double least = fits > 0 ? TETS_PER_BOUND * volume / fits : INFINITY, mag = pow(10.0, floor(log10(least)) - 1);
    char where[FM_PATH_MAX + 64], bound[FM_DOUBLE_CHARS];
    fm_scene_key_location(def, "tetgen.max_volume", where, sizeof where);
    return fm_fail(err, FM_ERR_INPUT, "%s: %s over the volume %.6g of %s (%s) implies at least %.3g tets (volume / "
                   "max_volume x %.1f; TetGen makes 1.9 to 2.5 times volume / max_volume), and a run of that many agents "
                   "needs about %.1f GiB, more than this machine's %.1f GiB of physical memory (or ulimit -v): at most about %.3g agents "
                   "fit; use a tetgen.max_volume of at least %.2g (docs/limits.md)", where,
                   fm_shortest(bound, def->tet_max_volume), volume, key, ref->path, tets, TETS_PER_BOUND,
                   e.total / gib, fm_physical_memory() / gib, fits, ceil(least / mag) * mag);
}

/* TetGen's tets of the mesh, from the keep when it holds those of the same mesh and bounds. */
static fm_status tetrahedralize_kept(const fm_scene_def *def, const fm_mesh *mesh, const char *name, fm_kept_tets *kept,
                                     fm_tets *tets, int *made, fm_error *err)
{
    if (kept && kept->has_tetgen && kept->quality == def->tet_quality && kept->max_volume == def->tet_max_volume &&
        fm_mesh_same(&kept->mesh, mesh))
        return fm_tets_copy(&kept->tetgen, tets, err);
    ++*made;
    fm_status st = fm_tetrahedralize(mesh, def->tet_quality, def->tet_max_volume, name, tets, err);
    if (st != FM_OK || !kept) return st;
    fm_mesh_free(&kept->mesh), fm_tets_free(&kept->tetgen), fm_tets_free(&kept->at_n);
    kept->has_tetgen = kept->has_at_n = 0; /* the tets at n were of the TetGen tets before */
    if ((st = fm_mesh_copy(mesh, &kept->mesh, err)) != FM_OK || (st = fm_tets_copy(tets, &kept->tetgen, err)) != FM_OK)
        return st;
    kept->quality = def->tet_quality, kept->max_volume = def->tet_max_volume, kept->has_tetgen = 1;
    return FM_OK;
}

/* Loads, checks, places and tetrahedralizes one mesh. */
static fm_status prepare_mesh(const fm_scene_def *def, const fm_mesh_ref *ref, const char *key, fm_mesh *mesh,
                              fm_tets *tets, fm_kept_tets *kept, int *made, fm_error *err)
{
    fm_status st = fm_scene_mesh_load(def, ref, key, mesh, err);
    if (st == FM_OK) st = check_tet_bound(def, ref, mesh, key, err);
    if (st != FM_OK) return st;
    return fm_scene_name_key(def, tetrahedralize_kept(def, mesh, ref->path, kept, tets, made, err), key, err);
}

/* A shot's group from another's formed shape: that group's target mesh (placed) and its n target
 * tets, slot j as tet j. */
static fm_status source_from_targets(const fm_scene_def *def, const fm_morph_model *from, fm_mesh *mesh, fm_tets *tets,
                                     fm_error *err)
{
    fm_status st = fm_scene_mesh_load(def, &def->source, "source.mesh", mesh, err);
    if (st != FM_OK) return st;
    if (!from->tgt && from->shared) /* a machine's other rank: fm_dist_build_shared fell back to a model each */
        return fm_fail(err, FM_ERR_MEMORY, "%s: cannot build this group on every rank without shared memory: the group "
                       "it starts from is shared, and only each machine's first rank keeps its target tets (see the "
                       "warning before: free /dev/shm or raise ulimit -f)", def->group.name);
    if (!from->tgt) return fm_fail(err, FM_ERR_INTERNAL, "the group's source group was built without its targets");
    tets->v = malloc(sizeof(double) * 12 * (size_t)from->n);
    if (!tets->v) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld tets", (long long)from->n);
    memcpy(tets->v, from->tgt, sizeof(double) * 12 * (size_t)from->n);
    tets->n = from->n;
    return FM_OK;
}

/* A group from another's shape has that group's agents: its target must fit in as many tets. */
static fm_status check_group_target(const fm_morph_model *m, const fm_tets *dst, fm_error *err)
{
    char where[FM_PATH_MAX + 64];
    fm_scene_key_location(&m->def, "target.mesh", where, sizeof where);
    return fm_fail(err, FM_ERR_INPUT, "%s: TetGen made %lld tets of %s, more than the %lld agents this group takes over "
                   "from the group it starts from: give that group an n of at least %lld, or a coarser tetgen here",
                   where, (long long)dst->n, m->def.target.path, (long long)m->n, (long long)dst->n);
}

/* FM §4: n >= max(n1, n2); say which mesh needs more. */
static fm_status choose_n(fm_morph_model *m, const fm_tets *src, const fm_tets *dst, fm_error *err)
{
    int64_t most = FM_MAX(src->n, dst->n);
    if (m->def.group_index >= 0 && m->def.group.source_group >= 0) {
        m->n = src->n;
        return dst->n > m->n ? check_group_target(m, dst, err) : fm_morph_memory_check(&m->def, m->n, err);
    }
    m->n = m->def.n > 0 ? m->def.n : most;
    if (m->n < most) {
        char where[FM_PATH_MAX + 64];
        fm_scene_key_location(&m->def, "n", where, sizeof where);
        return fm_fail(err, FM_ERR_INPUT, "%s: %lld is smaller than the %lld tets TetGen made for %s; use n >= %lld "
                       "or leave n out (default max(n1, n2))", where, (long long)m->n, (long long)most,
                       src->n >= dst->n ? m->def.source.path : m->def.target.path, (long long)most);
    }
    return fm_morph_memory_check(&m->def, m->n, err);
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

/* The path's ends: C_S, C_T (FM eq 3's Q_0 and Q_{m+1}) and the first and last control points. */
static fm_status check_path_ends(const fm_scene_def *def, const fm_mesh *obstacle, const char *key, const double cs[3],
                                 const double ct[3], fm_error *err)
{
    int last = def->path_point_count - 1;
    const double *ends[4] = {cs, ct, last >= 0 ? def->path_points[0] : NULL, last >= 0 ? def->path_points[last] : NULL};
    static const char *const names[4] = {"the source centroid C_S (where the path starts)",
                                         "the target centroid C_T (where the path ends)", "the first path point",
                                         "the last path point"};
    for (int e = 0; e < 4; e++) {
        if (!ends[e] || fabs(fm_mesh_winding_number(obstacle, ends[e])) <= 0.5) continue;
        char where[FM_PATH_MAX + 64], point_key[32];
        snprintf(point_key, sizeof point_key, "path.points[%d]", e == 2 ? 0 : last);
        fm_scene_key_location(def, e < 2 ? key : point_key, where, sizeof where);
        return fm_fail(err, FM_ERR_INPUT, "%s: %s (%g, %g, %g) lies inside %s: the path must start and end in free "
                       "space", where, names[e], ends[e][0], ends[e][1], ends[e][2], key);
    }
    return FM_OK;
}

/* FM §4 assumes the source and target apart; overlapping ones still run (agents launched inside
 * the target's bounding sphere go straight to phase 2), so this only warns. */
static fm_status warn_if_shapes_overlap(fm_morph_model *m, const prep_scratch *s, fm_error *err)
{
    char how[512];
    int overlap = fm_meshes_overlap(&s->src_mesh, "the source", &s->dst_mesh, "the target", how, sizeof how, err);
    if (overlap < 0) return err ? err->status : FM_ERR_INTERNAL;
    if (overlap)
        warn(m, "target.translate", "the source and target overlap: %s. FM assumes they are apart; agents that "
             "launch inside the target's bounding sphere skip the path", how);
    return FM_OK;
}

/* The source half of the model: each agent's source tet in launch order (D1, FM eq 4), as centroid
 * + centroid-relative vertices. Then the subdivided source tets and D1 are freed, so the
 * preparation holds one tet set in double beside the model, not two (docs/limits.md). */
static fm_status store_sources(fm_morph_model *m, prep_scratch *s, fm_error *err)
{
    const size_t n = (size_t)m->n;
    s->d1 = malloc(sizeof(int64_t) * n);
    m->src_rel = fm_alloc(sizeof(float) * 12 * n);
    m->src_index = fm_alloc(sizeof(int64_t) * n);
    int ok = s->d1 && m->src_rel && m->src_index;
    for (int k = 0; k < 3; k++) ok = ok && (m->src_c[k] = fm_alloc(sizeof(float) * n)) != NULL;
    if (!ok) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)m->n);
    fm_status st = fm_order_d1(&s->src, &s->path, s->d1, err);
    for (int64_t a = 0; st == FM_OK && a < m->n; a++) {
        m->src_index[a] = s->d1[a];
        const double *t = s->src.v + 12 * s->d1[a];
        double c[3];
        fm_tet_centroid(t, c);
        for (int k = 0; k < 3; k++) m->src_c[k][a] = (float)c[k];
        for (int i = 0; i < 12; i++) m->src_rel[12 * a + i] = (float)(t[i] - c[i % 3]);
    }
    fm_tets_free(&s->src), free(s->d1), s->d1 = NULL;
    return st;
}

/* The target half: target slot k is the tet with the k-th smallest D2 (FM eq 4), in float, with
 * its centroid; in double too (tgt) for a shot's group that another starts from. */
static fm_status store_targets(fm_morph_model *m, prep_scratch *s, fm_error *err)
{
    const size_t n = (size_t)m->n;
    s->d2 = malloc(sizeof(int64_t) * n);
    m->tgt_f = fm_alloc(sizeof(float) * 12 * n);
    m->tgt = s->keep_targets ? fm_alloc(sizeof(double) * 12 * n) : NULL;
    int ok = s->d2 && m->tgt_f && (m->tgt || !s->keep_targets);
    for (int k = 0; k < 3; k++) ok = ok && (m->tgt_c[k] = fm_alloc(sizeof(float) * n)) != NULL;
    if (!ok) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)m->n);
    fm_status st = fm_order_d2(&s->dst, &s->path, s->d2, err);
    for (int64_t k = 0; st == FM_OK && k < m->n; k++) {
        const double *t = s->dst.v + 12 * s->d2[k];
        double c[3];
        fm_tet_centroid(t, c);
        if (m->tgt) memcpy(m->tgt + 12 * k, t, 12 * sizeof(double));
        for (int i = 0; i < 12; i++) m->tgt_f[12 * k + i] = (float)t[i];
        for (int j = 0; j < 3; j++) m->tgt_c[j][k] = (float)c[j];
    }
    fm_tets_free(&s->dst), free(s->d2), s->d2 = NULL;
    return st;
}

static fm_status store_path(fm_morph_model *m, const fm_path *path, fm_error *err)
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

static fm_status bounding_sphere(fm_morph_model *m, const fm_mesh *target, fm_error *err)
{
    double c[3], r;
    if (fm_min_sphere(target->v, (size_t)target->nv, m->def.seed, c, &r) != 0)
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the bounding sphere");
    for (int k = 0; k < 3; k++) m->info.sphere_center[k] = c[k], m->sphere_c[k] = (float)c[k];
    m->info.sphere_radius = r;
    m->sphere_r = (float)r;
    return FM_OK;
}

/* R_X of FM eq 8, at rest: the radius of the sphere about the tet's centroid that holds its four
 * vertices. The step tests d_t at the centroid (the point it moves) against R_X, so the sphere
 * must be centred there: the minimal bounding sphere's centre is not the centroid, and its radius
 * left vertices up to 1.44 R_X from the centroid (issue 14). A phase-1 tet is its rest shape
 * scaled about the centroid (FM §6 shrink), so R_X times the scale bounds every vertex in flight;
 * the relative 1e-6 covers the float rounding of the placed vertices. */
static float centroid_radius(const float *rel)
{
    double r2 = 0;
    for (int i = 0; i < 4; i++) {
        const float *v = rel + 3 * i;
        r2 = fmax(r2, (double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
    }
    return nextafterf((float)(sqrt(r2) * (1 + 1e-6)), INFINITY);
}

static fm_status tet_radii(fm_morph_model *m, float *max_radius, fm_error *err)
{
    m->src_radius = fm_alloc(sizeof(float) * (size_t)m->n);
    if (!m->src_radius) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)m->n);
    *max_radius = 0;
    for (int64_t a = 0; a < m->n; a++) {
        m->src_radius[a] = centroid_radius(m->src_rel + 12 * a);
        if (m->src_radius[a] > *max_radius) *max_radius = m->src_radius[a];
    }
    return FM_OK;
}

/* The scene's extent (source, target, path), padded: the style-field grid spans it. */
static void scene_bounds(fm_morph_model *m, const prep_scratch *s)
{
    for (int k = 0; k < 3; k++) m->scene_lo[k] = INFINITY, m->scene_hi[k] = -INFINITY;
    fm_grow_bounds(m->scene_lo, m->scene_hi, s->src_mesh.v, s->src_mesh.nv);
    fm_grow_bounds(m->scene_lo, m->scene_hi, s->dst_mesh.v, s->dst_mesh.nv);
    fm_grow_bounds(m->scene_lo, m->scene_hi, s->path.q, s->path.count);
    double pad = 0;
    for (int k = 0; k < 3; k++) pad = fmax(pad, 0.15 * (m->scene_hi[k] - m->scene_lo[k]));
    for (int k = 0; k < 3; k++) m->scene_lo[k] -= pad, m->scene_hi[k] += pad;
}

/* Loads the obstacle meshes and refuses obstacles that overlap the source or target, or that hold
 * an end of the path: the tets would start or finish inside them (FM §5.3 assumes free space). */
static fm_status load_obstacles(fm_morph_model *m, prep_scratch *s, int check_paths, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    s->obstacles = calloc((size_t)def->obstacle_count, sizeof *s->obstacles);
    if (!s->obstacles) return fm_fail(err, FM_ERR_MEMORY, "out of memory for obstacles");
    double cs[3], ct[3];
    if (check_paths) total_volume(&s->src, cs), total_volume(&s->dst, ct); /* subdivision keeps the centroids */
    fm_status st = FM_OK;
    for (int i = 0; i < def->obstacle_count && st == FM_OK; i++) {
        char key[48];
        snprintf(key, sizeof key, "obstacles.meshes[%d]", i);
        st = fm_obstacle_mesh_load(def, i, &s->src_mesh, &s->dst_mesh, &s->obstacles[i], err);
        if (st == FM_OK && check_paths) st = check_path_ends(def, &s->obstacles[i], key, cs, ct, err);
    }
    return st;
}

static void forget_route(fm_kept_route *k)
{
    fm_path_free(&k->path), fm_free(k->nav.u), fm_free(k->nav.g);
    memset(&k->nav, 0, sizeof k->nav);
    k->has_path = k->has_nav = 0;
}

/* The obstacles' grid, the keep's where it fits; a route the keep holds is forgotten with the grid
 * it was routed on. */
static fm_status build_obstacles(fm_morph_model *m, prep_scratch *s, float max_radius, fm_error *err)
{
    fm_kept_route *kept = s->keep ? &s->keep->route : NULL;
    int reused = 0;
    m->obstacles = fm_obstacles_grid_keeping(&m->def, s->obstacles, m->def.k_a + max_radius, kept ? &kept->grid : NULL,
                                             &reused, err);
    if (!m->obstacles) return err ? err->status : FM_ERR_INPUT;
    if (kept && !reused) forget_route(kept);
    if (kept) s->keep->grid_reused = reused;
    return FM_OK;
}

/* The largest R_X of the source tets (tet_radii's, before the tets are stored in launch order):
 * the obstacles' grid and the route need it before the path orders the tets. */
static float largest_radius(const fm_tets *src)
{
    float most = 0;
    for (int64_t t = 0; t < src->n; t++) {
        const double *v = src->v + 12 * t;
        double c[3];
        float rel[12];
        fm_tet_centroid(v, c);
        for (int i = 0; i < 12; i++) rel[i] = (float)(v[i] - c[i % 3]);
        most = fmaxf(most, centroid_radius(rel));
    }
    return most;
}

/* What the route and the navigation function read (issue 38): the obstacles inflated by the
 * largest tet radius, with k_a more clearance preferred, in the box of the source and target. */
static void path_route_of(const fm_morph_model *m, const prep_scratch *s, float max_radius, fm_path_route *r)
{
    memset(r, 0, sizeof *r);
    r->obstacles = m->obstacles, r->r_infl = max_radius, r->r_soft = m->def.k_a;
    for (int k = 0; k < 3; k++) r->lo[k] = r->obstacle_lo[k] = INFINITY, r->hi[k] = r->obstacle_hi[k] = -INFINITY;
    fm_grow_bounds(r->lo, r->hi, s->src_mesh.v, s->src_mesh.nv);
    fm_grow_bounds(r->lo, r->hi, s->dst_mesh.v, s->dst_mesh.nv);
    r->meshes = m->def.obstacle_count;
    for (int i = 0; i < m->def.obstacle_count; i++) {
        for (int k = 0; k < 3; k++) r->mesh_lo[i][k] = INFINITY, r->mesh_hi[i][k] = -INFINITY;
        fm_grow_bounds(r->mesh_lo[i], r->mesh_hi[i], s->obstacles[i].v, s->obstacles[i].nv);
        fm_grow_bounds(r->obstacle_lo, r->obstacle_hi, s->obstacles[i].v, s->obstacles[i].nv);
    }
}

static fm_status path_copy(const fm_path *from, fm_path *to, fm_error *err)
{
    to->q = malloc(sizeof(double) * 3 * (size_t)from->count);
    if (!to->q) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the path");
    memcpy(to->q, from->q, sizeof(double) * 3 * (size_t)from->count);
    to->count = from->count;
    return FM_OK;
}

/* The path routed round the obstacles (fm_path_build_routed), the keep's where its grid is this
 * build's (kept) and its key the same; else made, and kept. */
static fm_status route_kept(const fm_morph_model *m, prep_scratch *s, fm_path_route *r, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    fm_kept_route *kept = s->keep && s->keep->grid_reused ? &s->keep->route : NULL;
    fm_route_key key;
    fm_route_key_of(def, m->info.source_centroid, m->info.target_centroid, r, &key);
    if (kept && kept->has_path && memcmp(&kept->key, &key, sizeof key) == 0) {
        r->routed = kept->routed, r->unroutable = kept->unroutable;
        s->keep->route_reused = s->path_in_keep = 1;
        return path_copy(&kept->path, &s->path, err);
    }
    fm_status st = fm_path_build_routed(def, m->info.source_centroid, m->info.target_centroid, r, &s->path, err);
    if (st != FM_OK || !s->keep) return st;
    kept = &s->keep->route;
    forget_route(kept);
    if ((st = path_copy(&s->path, &kept->path, err)) != FM_OK) return st;
    kept->key = key, kept->routed = r->routed, kept->unroutable = r->unroutable, kept->has_path = 1;
    s->path_in_keep = 1;
    return FM_OK;
}

static void warn_route(fm_morph_model *m, const fm_path_route *r)
{
    m->info.path_routed = r->routed;
    if (r->unroutable)
        warn(m, "obstacles.meshes", "%d stretch%s of the path cross%s an obstacle with no way round at least the largest "
             "tet radius (%g) wide: %s kept as given, and tets may stall there", r->unroutable,
             r->unroutable > 1 ? "es" : "", r->unroutable > 1 ? "" : "es", r->r_infl, r->unroutable > 1 ? "they are" : "it is");
}

/* The navigation function for detours (issue 38), unless obstacles.detour_time turns them off. The
 * default wait is the time to cross the eq 7 band k_a eight times at the path's speed: a tet that
 * slides round an obstacle gains a grid cell of u well within it (the shipped castling rook: no
 * detour at 1.5 s, where 0.9 s sent tets that were sliding on detours), a stuck one never does. */
#define DETOUR_CROSSINGS 8

static fm_status nav_copy(const fm_nav *from, fm_nav *to, fm_error *err)
{
    const size_t nodes = (size_t)from->n[0] * (size_t)from->n[1] * (size_t)from->n[2];
    *to = *from;
    to->u = fm_alloc(sizeof(float) * nodes), to->g = fm_alloc(sizeof(float) * nodes);
    if (!to->u || !to->g) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the navigation function");
    memcpy(to->u, from->u, sizeof(float) * nodes), memcpy(to->g, from->g, sizeof(float) * nodes);
    return FM_OK;
}
static fm_status build_detour(fm_morph_model *m, const prep_scratch *s, const fm_path_route *r, fm_error *err)
{
    const double t = m->def.detour_time, guide = m->def.omega1 * m->def.speed0;
    m->detour_time = t < 0 ? 0 : t > 0 ? t : guide > 0 ? DETOUR_CROSSINGS * m->def.k_a / guide : 0;
    m->info.detour_time = m->detour_time;
    if (!(m->detour_time > 0)) return FM_OK;
    fm_kept_route *kept = s->keep ? &s->keep->route : NULL;
    if (kept && s->keep->route_reused && kept->has_nav) return nav_copy(&kept->nav, &m->nav, err);
    fm_status st = fm_nav_build(r, s->path.q, s->path.count, &m->nav, err);
    if (st != FM_OK || !kept || !s->path_in_keep) return st;
    if ((st = nav_copy(&m->nav, &kept->nav, err)) == FM_OK) kept->has_nav = 1;
    return st;
}

/* Beyond the paper (FM §8): the target's own signed distance decides the phase switch. */
/* About the voxels of the target's distance grid (obstacles_vdb.cpp's count, to a voxel) with this band. */
static double target_grid_voxels(const double lo[3], const double hi[3], double voxel, double band)
{
    double total = 1;
    for (int k = 0; k < 3; k++) total *= (hi[k] - lo[k]) / voxel + 2 * (band / voxel + 2) + 3;
    return total;
}

/* The switch distance is the grid's band, and the voxel 1/160 of the target: a distance of more than
 * about the target's size needs more voxels than any grid holds. Say so in the key's terms. */
static fm_status check_switch_distance(const fm_scene_def *def, const double lo[3], const double hi[3], double voxel,
                                       fm_error *err)
{
    double band = fabs(def->switch_distance) + 3 * voxel, most = 0, top = band;
    double voxels = target_grid_voxels(lo, hi, voxel, band);
    if (voxels <= (double)FM_OBSTACLE_MAX_VOXELS) return FM_OK;
    for (int i = 0; i < 60; i++) { /* the largest distance that fits, by bisection */
        double mid = 0.5 * (most + top);
        if (target_grid_voxels(lo, hi, voxel, mid + 3 * voxel) <= (double)FM_OBSTACLE_MAX_VOXELS) most = mid;
        else top = mid;
    }
    char where[FM_PATH_MAX + 64], d[FM_DOUBLE_CHARS];
    fm_scene_key_location(def, "phase2.switch_distance", where, sizeof where);
    return fm_fail(err, FM_ERR_INPUT, "%s: %s is too far for the target's distance grid (the distance switch reads "
                   "it): at voxels of %g (1/160 of the target's size %g) it needs about %.3g voxels, more than the "
                   "%lld supported; use a switch distance of at most %.3g", where, fm_shortest(d, def->switch_distance),
                   voxel, 160 * voxel, voxels, (long long)FM_OBSTACLE_MAX_VOXELS, most);
}

static fm_status build_target_sdf(fm_morph_model *m, const fm_mesh *target, fm_error *err)
{
    static const fm_sdf_names names = {"target", "the target"};
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, extent = 0;
    fm_grow_bounds(lo, hi, target->v, target->nv);
    for (int k = 0; k < 3; k++) extent = fmax(extent, hi[k] - lo[k]);
    double voxel = extent / 160, band = fabs(m->def.switch_distance) + 3 * voxel;
    fm_status st = check_switch_distance(&m->def, lo, hi, voxel, err);
    if (st != FM_OK) return st;
    m->target_sdf = fm_obstacles_build_named(target, 1, voxel, band, &names, err);
    return m->target_sdf ? FM_OK
                         : fm_scene_name_key(&m->def, err ? err->status : FM_ERR_INPUT, "phase2.switch_distance", err);
}

/* Bake the style fields only where the grid resolves them (fields.h); say so when it does not. */
static fm_status plan_fields(fm_morph_model *m, fm_error *err)
{
    fm_status st = fm_fields_plan(&m->def, m->scene_lo, m->scene_hi, &m->fields, err);
    if (st == FM_OK && m->fields.warning[0]) warn(m, "style.grid", "%s", m->fields.warning);
    m->info.fields_baked = m->fields.baked;
    m->info.field_bake_error = m->fields.bake_error;
    /* The fade (issue 38) spans the target's own size by default: the scale at which the flock,
       already inside the path's last stretch, is gathered onto the target. */
    const double fade = m->def.field_fade;
    m->field_fade = m->def.field_count == 0 || fade < 0 ? 0 : fade > 0 ? fade : m->info.sphere_radius;
    m->info.field_fade_distance = m->field_fade;
    /* ... and in time, so that no agent circles for ever where V_l holds it against V_g (an eddy of a
       strong curl noise far from the target): by default from twice the time the path takes. */
    double length = 0, guide = m->def.omega1 * m->def.speed0, after = m->def.field_fade_time;
    for (int32_t i = 0; i + 1 < m->key_count; i++) {
        const double dx = (double)m->key_q[0][i + 1] - m->key_q[0][i], dy = (double)m->key_q[1][i + 1] - m->key_q[1][i];
        const double dz = (double)m->key_q[2][i + 1] - m->key_q[2][i];
        length += sqrt(dx * dx + dy * dy + dz * dz);
    }
    m->field_fade_time = m->def.field_count == 0 || after < 0 ? 0 : after > 0 ? after : guide > 0 ? 2 * length / guide : 0;
    m->info.field_fade_time = m->field_fade_time;
    return st;
}

static void set_timing(fm_morph_model *m)
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

static void free_scratch(prep_scratch *s, int count)
{
    fm_mesh_free(&s->src_mesh), fm_mesh_free(&s->dst_mesh);
    fm_tets_free(&s->src), fm_tets_free(&s->dst);
    fm_path_free(&s->path);
    free(s->d1), free(s->d2);
    for (int i = 0; s->obstacles && i < count; i++) fm_mesh_free(&s->obstacles[i]);
    free(s->obstacles);
}

/* The quality of a tet set for fm_morph_model_info (one pass; the scene's bound). */
static fm_morph_tet_quality tet_quality(const fm_morph_model *m, const fm_tets *tets)
{
    fm_tet_quality q = fm_tets_quality(tets, m->def.tet_quality);
    double count = q.count > 0 ? (double)q.count : 1.0;
    return (fm_morph_tet_quality){q.bound, q.max_ratio, (double)q.above / count, (double)q.above_4 / count,
                                  q.median_ratio};
}

/* Issue 38: the paper's 1-to-4 centroid split turns every tet into four caps (radius-edge 1.5 from
 * a regular tet, worse at every level: 85 % of the moon's star above 2.0, max 38.6). Instead a
 * shape with fewer than n tets is tetrahedralized again with a volume bound (-a) chosen for a
 * little under n tets, which TetGen meets with tets of its own quality, and the rest are made by
 * longest-edge bisection (fm_bisect_to). TetGen makes 1.9 to 2.5 V / max_volume tets plus the
 * surface's, but not monotonically (the torus: 26,593 tets at 0.0224 and 16,834 at 0.0256), so the
 * bound is bracketed: each try scales 1 / max_volume by goal / count, kept inside the bracket, and
 * the first count in [REFINE_LOW n, n] (else the largest count up to n) is taken. Bisecting up to
 * a fifth of the tets costs little quality (docs/limits.md). */
#define REFINE_GOAL 0.9
#define REFINE_LOW 0.8
#define REFINE_TRIES 6

static fm_status refine_toward(const fm_morph_model *m, const fm_mesh *mesh, const char *name, fm_tets *tets,
                               fm_error *err)
{
    const double n = (double)m->n, goal = REFINE_GOAL * n, volume = fabs(fm_mesh_signed_volume(mesh));
    /* x = 1 / max_volume, bracketed by lo (too few tets; the scene's own bound, 0 for none) and hi */
    double lo = m->def.tet_max_volume > 0 ? 1.0 / m->def.tet_max_volume : 0.0, hi = INFINITY;
    double x = fmax(lo * 1.25, goal / (2.2 * volume));
    for (int t = 0; t < REFINE_TRIES && volume > 0; t++) {
        fm_tets tried;
        fm_status st = fm_tetrahedralize(mesh, m->def.tet_quality, 1.0 / x, name, &tried, err);
        if (st == FM_ERR_MEMORY) return st;
        if (st != FM_OK) break; /* TetGen met the mesh without the bound: bisect from the best so far */
        double count = (double)tried.n;
        if (count <= n && tried.n > tets->n) fm_tets_free(tets), *tets = tried; /* the most tets up to n */
        else fm_tets_free(&tried);
        if (count <= n && count >= REFINE_LOW * n) break;
        if (count > n) hi = fmin(hi, x);
        else lo = fmax(lo, x);
        double next = x * goal / fmax(count, 1.0);
        x = next > lo && next < hi ? next : lo > 0 && isfinite(hi) ? sqrt(lo * hi) : 0.5 * (lo + hi);
    }
    return FM_OK;
}

/* One shape to exactly n tets (FM §4). */
static fm_status tets_to_n(const fm_morph_model *m, const fm_mesh *mesh, const char *name, fm_tets *tets,
                           int64_t *refined, fm_error *err)
{
    *refined = tets->n;
    if (m->def.tet_subdivision == FM_SUBDIVIDE_PAPER) return fm_subdivide_to(tets, m->n, err);
    if (mesh && tets->n < REFINE_LOW * (double)m->n) {
        fm_status st = refine_toward(m, mesh, name, tets, err);
        if (st != FM_OK) return st;
        *refined = tets->n;
    }
    return fm_bisect_to(tets, m->n, err);
}

/* tets_to_n, or the keep's tets at n where they were made from the same TetGen tets (the keep's, as
 * tetrahedralize_kept leaves it) for the same subdivision and n. */
static fm_status tets_to_n_kept(const fm_morph_model *m, const fm_mesh *mesh, const char *name, fm_tets *tets,
                                int64_t *refined, fm_kept_tets *kept, int *made, fm_error *err)
{
    if (kept && kept->has_at_n && kept->subdivision == (int)m->def.tet_subdivision && kept->n == m->n) {
        fm_tets_free(tets);
        *refined = kept->refined;
        return fm_tets_copy(&kept->at_n, tets, err);
    }
    ++*made;
    fm_status st = tets_to_n(m, mesh, name, tets, refined, err);
    if (st != FM_OK || !kept || !kept->has_tetgen) return st;
    fm_tets_free(&kept->at_n);
    if ((st = fm_tets_copy(tets, &kept->at_n, err)) != FM_OK) return kept->has_at_n = 0, st;
    kept->subdivision = (int)m->def.tet_subdivision, kept->n = m->n, kept->refined = *refined, kept->has_at_n = 1;
    return FM_OK;
}

/* Everything checked before n-sized arrays exist: the meshes and their tets, overlaps, obstacles, n. */
static fm_status prepare_inputs(fm_morph_model *m, prep_scratch *s, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    fm_status st = stage(s, "tetrahedralize source", 0.0, err);
    if (st != FM_OK) return st;
    fm_kept_tets *kept = s->keep ? s->keep->shape : NULL;
    st = s->from ? source_from_targets(def, s->from, &s->src_mesh, &s->src, err)
                 : prepare_mesh(def, &def->source, "source.mesh", &s->src_mesh, &s->src, kept, &s->made, err);
    if (st != FM_OK || (st = stage(s, "tetrahedralize target", 0.3, err)) != FM_OK) return st;
    st = prepare_mesh(def, &def->target, "target.mesh", &s->dst_mesh, &s->dst, kept ? kept + 1 : NULL, &s->made, err);
    if (st != FM_OK) return st;
    m->info.source_tets = s->src.n;
    m->info.target_tets = s->dst.n;
    m->info.source_tetgen_quality = tet_quality(m, &s->src);
    m->info.target_tetgen_quality = tet_quality(m, &s->dst);
    if ((st = warn_if_shapes_overlap(m, s, err)) != FM_OK) return st;
    if (def->obstacle_count > 0 && (st = load_obstacles(m, s, 1, err)) != FM_OK) return st;
    return choose_n(m, &s->src, &s->dst, err);
}

/* The studio may cancel a build at every stage boundary (stage): before TetGen runs (a shot's group
 * after another's), between the shapes' TetGen runs and subdivisions, before the obstacles' grid,
 * the route, the detours' navigation function, the fields' plan and the target's distance grid. */
static fm_status build(fm_morph_model *m, prep_scratch *s, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    fm_status st = prepare_inputs(m, s, err);
    if (st != FM_OK || (st = stage(s, "subdivide", 0.6, err)) != FM_OK) return st;
    /* a group from another's shape has as many source tets as agents: its source is never refined */
    fm_kept_tets *kept = s->keep ? s->keep->shape : NULL;
    /* a group from another's shape: its source tets are that group's (already n), never the keep's */
    st = s->from ? tets_to_n(m, NULL, def->source.path, &s->src, &m->info.source_refined_tets, err)
                 : tets_to_n_kept(m, &s->src_mesh, def->source.path, &s->src, &m->info.source_refined_tets, kept,
                                  &s->made, err);
    if (st != FM_OK) return fm_scene_name_key(def, st, "source.mesh", err);
    if ((st = stage(s, NULL, 0, err)) != FM_OK) return st;
    st = tets_to_n_kept(m, &s->dst_mesh, def->target.path, &s->dst, &m->info.target_refined_tets, kept ? kept + 1 : NULL,
                        &s->made, err);
    if (st != FM_OK) return fm_scene_name_key(def, st, "target.mesh", err);
    m->info.agents = m->n;
    /* Subdividing can only worsen the shapes TetGen made: measure the tets the agents are. */
    m->info.source_quality = tet_quality(m, &s->src);
    m->info.target_quality = tet_quality(m, &s->dst);
    m->info.source_volume = total_volume(&s->src, m->info.source_centroid);
    m->info.target_volume = total_volume(&s->dst, m->info.target_centroid);
    /* the obstacles before the path, which is routed round them (issue 38) */
    if ((st = stage(s, "obstacles", 0.7, err)) != FM_OK) return st;
    const float radius = def->obstacle_count > 0 ? largest_radius(&s->src) : 0; /* tet_radii's max_radius */
    if (def->obstacle_count > 0 && (st = build_obstacles(m, s, radius, err)) != FM_OK) return st;
    if ((st = stage(s, "order", 0.8, err)) != FM_OK) return st;
    fm_path_route route;
    if (m->obstacles) path_route_of(m, s, radius, &route);
    st = m->obstacles && def->path_route
             ? route_kept(m, s, &route, err)
             : fm_path_build_routed(def, m->info.source_centroid, m->info.target_centroid, NULL, &s->path, err);
    if (st != FM_OK) return fm_scene_name_key(def, st, def->path_point_count > 0 ? "path.points" : "target.translate", err);
    m->info.key_points = s->path.count;
    if (m->obstacles && def->path_route) warn_route(m, &route);
    if ((st = store_sources(m, s, err)) != FM_OK || (st = store_targets(m, s, err)) != FM_OK) return st;
    if ((st = store_path(m, &s->path, err)) != FM_OK) return st;
    if ((st = stage(s, NULL, 0, err)) != FM_OK) return st;
    if (m->obstacles && (st = build_detour(m, s, &route, err)) != FM_OK) return st;
    if ((st = bounding_sphere(m, &s->dst_mesh, err)) != FM_OK) return st;
    scene_bounds(m, s);
    if ((st = stage(s, NULL, 0, err)) != FM_OK || (st = plan_fields(m, err)) != FM_OK) return st;
    float max_radius = 0;
    if ((st = tet_radii(m, &max_radius, err)) != FM_OK) return st;
    m->max_radius = max_radius;
    if ((st = stage(s, NULL, 0, err)) != FM_OK) return st;
    if (def->phase_switch == FM_SWITCH_DISTANCE && (st = build_target_sdf(m, &s->dst_mesh, err)) != FM_OK) return st;
    if ((st = fm_morph_motion_build(m, err)) != FM_OK) return st;
    set_timing(m);
    return stage(s, "ready", 1.0, err);
}

static fm_morph_model *build_model(const fm_scene_def *def, const fm_morph_model *from, int keep_targets,
                                   fm_morph_keep *keep, fm_progress_fn progress, void *user, fm_error *err)
{
    if (fm_scene_validate(def, err) != FM_OK) return NULL;
    if (def->group_count > 0 && def->group_index < 0) {
        fm_fail(err, FM_ERR_USAGE, "%s: the scene is a shot of %d groups: build each group (fm_scene_load_group) "
                "and run them together (fm_shot_build), as flockmorph run does", def->scene_path, def->group_count);
        return NULL;
    }
    if (def->n > 0 && fm_morph_memory_check(def, def->n, err) != FM_OK) return NULL; /* before TetGen runs */
    fm_morph_model *m = calloc(1, sizeof *m);
    if (!m) {
        fm_fail(err, FM_ERR_MEMORY, "out of memory");
        return NULL;
    }
    m->def = *def;
    prep_scratch scratch;
    memset(&scratch, 0, sizeof scratch);
    scratch.from = from, scratch.keep_targets = keep_targets; /* else no tgt: the run reads tgt_f */
    scratch.keep = keep, scratch.progress = progress, scratch.user = user;
    fm_status st = build(m, &scratch, err);
    if (keep) keep->reused = st == FM_OK && scratch.made == 0;
    free_scratch(&scratch, def->obstacle_count);
    if (st != FM_OK) {
        fm_morph_model_destroy(m);
        return NULL;
    }
    return m;
}

fm_morph_model *fm_morph_model_build(const fm_scene_def *def, fm_progress_fn progress, void *user, fm_error *err)
{
    return build_model(def, NULL, 0, NULL, progress, user, err);
}

fm_morph_model *fm_morph_model_build_group(const fm_scene_def *def, const fm_morph_model *from, int keep_targets,
                                           fm_progress_fn progress, void *user, fm_error *err)
{
    return build_model(def, from, keep_targets, NULL, progress, user, err);
}

fm_morph_model *fm_morph_model_build_keeping(const fm_scene_def *def, fm_morph_keep *keep, fm_progress_fn progress,
                                             void *user, fm_error *err)
{
    return fm_morph_model_build_group_keeping(def, NULL, 0, keep, progress, user, err);
}

fm_morph_model *fm_morph_model_build_group_keeping(const fm_scene_def *def, const fm_morph_model *from, int keep_targets,
                                                   fm_morph_keep *keep, fm_progress_fn progress, void *user,
                                                   fm_error *err)
{
    keep->reused = keep->grid_reused = keep->route_reused = 0;
    return build_model(def, from, keep_targets, keep, progress, user, err);
}

void fm_morph_keep_clear(fm_morph_keep *keep)
{
    for (int i = 0; keep && i < 2; i++) {
        fm_kept_tets *k = &keep->shape[i];
        fm_mesh_free(&k->mesh), fm_tets_free(&k->tetgen), fm_tets_free(&k->at_n);
        memset(k, 0, sizeof *k);
    }
    if (!keep) return;
    fm_kept_route *r = &keep->route;
    forget_route(r);
    fm_kept_grid_clear(&r->grid);
    memset(r, 0, sizeof *r);
}

void fm_morph_model_drop_targets(fm_morph_model *m)
{
    fm_free(m->tgt);
    m->tgt = NULL;
}

/* ---------------------------------------------------------------- one model per machine */

/* The model's arrays (all but a shot's tgt), by address and size: what a machine's ranks share. */
enum { MODEL_ARRAYS = 18 }; /* <= FM_DIST_MAX_ARRAYS */
static int model_arrays(void *model, void **p[], size_t bytes[])
{
    fm_morph_model *m = model;
    const size_t n = (size_t)m->n, keys = (size_t)m->key_count;
    const size_t nav = m->detour_time > 0 ? (size_t)m->nav.n[0] * (size_t)m->nav.n[1] * (size_t)m->nav.n[2] : 0;
    int c = 0;
    p[c] = (void **)&m->nav.u, bytes[c++] = sizeof(float) * nav;
    p[c] = (void **)&m->nav.g, bytes[c++] = sizeof(float) * nav;
    p[c] = (void **)&m->src_rel, bytes[c++] = sizeof(float) * 12 * n;
    p[c] = (void **)&m->tgt_f, bytes[c++] = sizeof(float) * 12 * n;
    p[c] = (void **)&m->src_index, bytes[c++] = sizeof(int64_t) * n;
    p[c] = (void **)&m->src_radius, bytes[c++] = sizeof(float) * n;
    for (int k = 0; k < 3; k++) {
        p[c] = (void **)&m->src_c[k], bytes[c++] = sizeof(float) * n;
        p[c] = (void **)&m->tgt_c[k], bytes[c++] = sizeof(float) * n;
        p[c] = (void **)&m->key_q[k], bytes[c++] = sizeof(float) * keys;
        p[c] = (void **)&m->key_f[k], bytes[c++] = sizeof(float) * keys;
    }
    return c;
}

/* The parts every rank builds for itself: the distance grids, objects of their libraries, from the
 * placed meshes (the machine's first rank checked them when it built the model). */
static fm_status build_replicated(void *model, fm_error *err)
{
    fm_morph_model *m = model;
    const fm_scene_def *def = &m->def;
    fm_status st = fm_morph_motion_build(m, err); /* from the shared tgt_f: the first rank's binding */
    if (st != FM_OK || (def->obstacle_count == 0 && def->phase_switch != FM_SWITCH_DISTANCE)) return st; /* no grid */
    prep_scratch s;
    memset(&s, 0, sizeof s);
    st = fm_scene_mesh_load(def, &def->source, "source.mesh", &s.src_mesh, err);
    if (st == FM_OK) st = fm_scene_mesh_load(def, &def->target, "target.mesh", &s.dst_mesh, err);
    if (st == FM_OK && def->obstacle_count > 0) st = load_obstacles(m, &s, 0, err);
    if (st == FM_OK && def->obstacle_count > 0) st = build_obstacles(m, &s, m->max_radius, err);
    if (st == FM_OK && def->phase_switch == FM_SWITCH_DISTANCE) st = build_target_sdf(m, &s.dst_mesh, err);
    free_scratch(&s, def->obstacle_count);
    return st;
}

/* A machine's other ranks: the first rank's model as broadcast, with this rank's own scene and
 * none of the first rank's objects (its arrays come from fm_dist_share_arrays). */
static void take_scalars(void *model, const fm_scene_def *def)
{
    fm_morph_model *m = model;
    m->def = *def;
    m->tgt = NULL, m->obstacles = m->target_sdf = NULL, m->shared = NULL, m->motion = NULL;
}

/* A shot's group: the group it starts from and whether to keep its target tets in double. */
typedef struct group_of_shot {
    const fm_morph_model *from;
    int keep_targets;
} group_of_shot;

static void *build_one(const fm_scene_def *def, const void *context, fm_progress_fn progress, void *user, fm_error *err)
{
    const group_of_shot *g = context;
    return g ? build_model(def, g->from, g->keep_targets, NULL, progress, user, err)
             : fm_morph_model_build(def, progress, user, err);
}

static void destroy_one(void *m) { fm_morph_model_destroy(m); }

static const fm_dist_model_ops SHARED_OPS = {sizeof(fm_morph_model), offsetof(fm_morph_model, shared), build_one,
                                             take_scalars, model_arrays, build_replicated, destroy_one};

fm_morph_model *fm_morph_model_build_shared(const fm_scene_def *def, const fm_dist *dist, fm_progress_fn progress,
                                            void *user, fm_error *err)
{
    return fm_dist_build_shared(dist, &SHARED_OPS, def, NULL, progress, user, err);
}

fm_morph_model *fm_morph_model_build_group_shared(const fm_scene_def *def, const fm_morph_model *from, int keep_targets,
                                                  const fm_dist *dist, fm_progress_fn progress, void *user, fm_error *err)
{
    const group_of_shot group = {from, keep_targets};
    return fm_dist_build_shared(dist, &SHARED_OPS, def, &group, progress, user, err);
}

void fm_morph_model_destroy(fm_morph_model *m)
{
    if (!m) return;
    fm_obstacles_destroy(m->obstacles); /* NULL-safe */
    fm_obstacles_destroy(m->target_sdf);
    fm_morph_motion_destroy(m->motion);
    fm_free(m->tgt);
    void **p[MODEL_ARRAYS];
    size_t bytes[MODEL_ARRAYS];
    for (int i = 0, count = model_arrays(m, p, bytes); i < count; i++) {
        if (!m->shared) fm_free(*p[i]); /* else the segment's */
    }
    fm_dist_shared_free(m->shared);
    free(m);
}

fm_morph_model_info fm_morph_model_get_info(const fm_morph_model *m) { return m->info; }

int fm_morph_model_warning_count(const fm_morph_model *m) { return m->warning_count; }

const char *fm_morph_model_warning(const fm_morph_model *m, int i) { return i >= 0 && i < m->warning_count ? m->warnings[i] : ""; }

const float *fm_morph_model_target_tet(const fm_morph_model *m, int64_t j) { return m->tgt_f + 12 * j; }
