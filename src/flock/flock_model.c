/* fm_flock_model_build: the shape flock's preprocessing. Source and target are sampled (SCF
 * "Shape Constraints"), agents are matched to destinations ("Point Correspondence"), the global
 * path is built (eqs 10-12), and each agent draws its boids parameters from the scene's ranges
 * (eq 6). Everything here runs once; the result is immutable. */
#include "flock.h"
#include "fm_math.h"
#include "path_route.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Random streams of the scene seed (fm_random_unit), one per use. */
enum { STREAM_SOURCE = 1, STREAM_TARGET, STREAM_MATCH, STREAM_PARAMS = 16 };

/* The build's progress report and the studio's cancel flag (the keep's; NULL: none), checked at
 * the stage boundaries (fm_build_stage) and between the mosaic's iterations. */
typedef struct build_ctx {
    fm_progress_fn progress;
    void *user;
    const volatile sig_atomic_t *cancel;
} build_ctx;

static fm_status stage(const build_ctx *b, const char *name, double fraction, fm_error *err)
{
    return fm_build_stage(b->progress, b->user, name, fraction, b->cancel, err);
}

static fm_sample_opts sample_opts(const fm_flock_model *m, uint64_t stream, const build_ctx *b)
{
    fm_sample_opts opts = fm_default_sample_opts();
    opts.cancel = b->cancel;
    opts.method = (fm_sample_method)m->def.flock.sampling;
    opts.seed = fm_random_bits(m->def.seed, stream, 0);
    const fm_flock_def *f = &m->def.flock;
    opts.iterations = f->mosaic_iterations, opts.manhattan = f->mosaic_distance == FM_MOSAIC_MANHATTAN;
    opts.k = f->mosaic_k, opts.w = f->mosaic_w, opts.step = f->mosaic_step;
    opts.lambda = f->stratified_lambda, opts.oversample = f->stratified_oversample;
    return opts;
}

static fm_status sample(const fm_mesh *mesh, const fm_flock_model *m, uint64_t stream, const build_ctx *b, fm_samples *out,
                        fm_error *err)
{
    const fm_sample_opts opts = sample_opts(m, stream, b);
    return fm_name_key(fm_sample_surface(mesh, m->n, &opts, out, err), "shape_flock.sampling", err);
}

/* match "projected" (SCF "Point Correspondence"): the target's points are the source samples
 * projected onto it and relaxed by the mosaic's energy (the shape_flock.mosaic keys), agent a keeping
 * its own: match[a] = a. */
static fm_status sample_projected(const fm_mesh *mesh, const fm_flock_model *m, const build_ctx *b, const fm_samples *src,
                                  fm_samples *out, int64_t *match, fm_error *err)
{
    const fm_sample_opts opts = sample_opts(m, STREAM_TARGET, b);
    fm_status st = fm_name_key(fm_sample_projected(mesh, src->p, m->n, &opts, out, err), "shape_flock.match", err);
    for (int64_t a = 0; st == FM_OK && a < m->n; a++) match[a] = a;
    return st;
}

/* A group of a shot that starts from the shape `from` formed: the agents start where they are bound,
 * on from's destinations (a static target that binds: fm_flock_shot_build checks it). */
static fm_status formed_shape(const fm_flock_model *from, fm_samples *out, fm_error *err)
{
    out->n = from->n;
    out->p = malloc(sizeof(float) * 3 * (size_t)from->n);
    if (!out->p) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)from->n);
    memcpy(out->p, from->target.dest.p, sizeof(float) * 3 * (size_t)from->n);
    return FM_OK;
}

static fm_status alloc_agent_arrays(fm_flock_model *m, fm_error *err)
{
    size_t n = (size_t)m->n;
    int ok = (m->max_speed = fm_alloc(sizeof(float) * n)) && (m->max_force = fm_alloc(sizeof(float) * n));
    ok = ok && (m->max_accel = fm_alloc(sizeof(float) * n));
    for (int k = 0; k < 3; k++) {
        ok = ok && (m->start[k] = fm_alloc(sizeof(float) * n)) && (m->dest0[k] = fm_alloc(sizeof(float) * n));
        ok = ok && (m->radius[k] = fm_alloc(sizeof(float) * n)) && (m->cos_half[k] = fm_alloc(sizeof(float) * n));
        ok = ok && (m->weight[k] = fm_alloc(sizeof(float) * n));
    }
    return ok ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)m->n);
}

/* Agent a starts on source sample a and flies to target sample match[a]: its destination keeps
 * that sample's triangle and barycentric coordinates, so it follows a deforming target. */
static fm_status assign(fm_flock_model *m, const fm_samples *src, const fm_samples *tgt, const int64_t *match, fm_error *err)
{
    fm_samples *dest = &m->target.dest;
    dest->n = m->n;
    dest->p = fm_alloc(sizeof(float) * 3 * (size_t)m->n);
    dest->bary = fm_alloc(sizeof(float) * 3 * (size_t)m->n);
    dest->tri = fm_alloc(sizeof(int32_t) * (size_t)m->n);
    if (!dest->p || !dest->bary || !dest->tri) return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld agents", (long long)m->n);
    for (int64_t a = 0; a < m->n; a++) {
        int64_t j = match[a];
        dest->tri[a] = tgt->tri[j];
        for (int k = 0; k < 3; k++) {
            dest->p[3 * a + k] = tgt->p[3 * j + k], dest->bary[3 * a + k] = tgt->bary[3 * j + k];
            m->start[k][a] = src->p[3 * a + k], m->dest0[k][a] = tgt->p[3 * j + k];
        }
    }
    return FM_OK;
}

static void mean_point(const float *p, int64_t n, double out[3])
{
    double sum[3] = {0, 0, 0};
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) sum[k] += p[3 * i + k];
    for (int k = 0; k < 3; k++) out[k] = sum[k] / (double)n;
}

/* Beyond SCF, which has no obstacles (issue 38, as the tetra morph's path, path_route.c): R sampled
 * ROUTE_SAMPLES_PER_SEGMENT times a segment of the spline; where it passes closer than
 * k_a + route_margin to an obstacle, that stretch goes round the obstacles (A* on the distance
 * field, taut, corner-cut), preferring k_a more clearance; then R is the B-spline through the
 * rerouted polyline resampled by arc length every ROUTE_SPACING_OF_INFLATION of that inflation
 * radius (at most ROUTE_POINTS_MAX points). A path that nowhere comes that close is left as it
 * is, bit for bit. */
enum { ROUTE_SAMPLES_PER_SEGMENT = 128, ROUTE_POINTS_MAX = 512 };
#define ROUTE_SPACING_OF_INFLATION 0.5
/* The margin: rho, the larger of the source's and the target's bounding radius about its centre
 * (the agents' C1 about O1, C2 about O2) times ROUTE_MARGIN_OF_RADIUS. Eq 12 carries each agent's
 * offset from O(s) along R, so each agent rides its own copy of R up to rho aside; a route that
 * clears only the core leaves the copies of the agents on the obstacle's side through it. Eq 7's
 * push does not keep them out: measured from the caches of tests/flock/route (test_flock_route.py),
 * R through the wall leaves 995 of 1,500 agents unbound at the frame limit and 17,923
 * position-frames inside the 0.8-thick wall (0.4 deep: through it); routed with rho / 4, 98
 * unbound and 1,550 inside; rho / 2 binds all but leaves 9 position-frames inside the ball; rho / 1.5
 * and rho, none in either. So the whole radius: every agent's copy of R keeps about k_a clear and
 * the push has only the flock's deformation to handle; the cost is a detour wider by the flock's
 * radius round a small obstacle. */
#define ROUTE_MARGIN_OF_RADIUS 1.0

static double spread_of(float *const p[3], int64_t n, const double centre[3])
{
    double most = 0;
    for (int64_t a = 0; a < n; a++) {
        const double d[3] = {p[0][a] - centre[0], p[1][a] - centre[1], p[2][a] - centre[2]};
        most = fmax(most, d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    }
    return sqrt(most);
}

/* The route's distance grid: the flock's own (m->obstacles) has a band of k_a, too narrow to tell
 * k_a + margin of clearance, and its voxel follows its band, so a wider one here would change the
 * push's bytes; this one is built for the route alone (or is the keep's, kept: may be NULL) and
 * freed with it. */
static fm_status route_setup(const fm_flock_model *m, fm_path_route *r, fm_obstacles **grid, fm_kept_grid *kept,
                             int *grid_kept, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    memset(r, 0, sizeof *r);
    r->r_infl = def->k_a + m->route_margin, r->r_soft = def->k_a;
    for (int k = 0; k < 3; k++) r->lo[k] = r->obstacle_lo[k] = INFINITY, r->hi[k] = r->obstacle_hi[k] = -INFINITY;
    const double rho = m->route_margin / ROUTE_MARGIN_OF_RADIUS; /* the box of the source and target */
    for (int e = 0; e < 2; e++) {
        const double *o = e ? m->o2 : m->o1;
        const double lo[3] = {o[0] - rho, o[1] - rho, o[2] - rho}, hi[3] = {o[0] + rho, o[1] + rho, o[2] + rho};
        fm_grow_bounds(r->lo, r->hi, lo, 1), fm_grow_bounds(r->lo, r->hi, hi, 1);
    }
    fm_mesh *meshes = calloc((size_t)def->obstacle_count, sizeof *meshes);
    if (!meshes) return fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    fm_status st = FM_OK;
    for (int i = 0; i < def->obstacle_count && st == FM_OK; i++) { /* checked against the shapes already */
        st = fm_obstacle_mesh_load(def, i, NULL, NULL, &meshes[i], err);
        for (int k = 0; st == FM_OK && k < 3; k++) r->mesh_lo[i][k] = INFINITY, r->mesh_hi[i][k] = -INFINITY;
        if (st != FM_OK) break;
        fm_grow_bounds(r->mesh_lo[i], r->mesh_hi[i], meshes[i].v, meshes[i].nv);
        fm_grow_bounds(r->obstacle_lo, r->obstacle_hi, meshes[i].v, meshes[i].nv);
    }
    r->meshes = def->obstacle_count;
    *grid = st == FM_OK ? fm_obstacles_grid_keeping(def, meshes, r->r_infl + r->r_soft, kept, grid_kept, err) : NULL;
    if (st == FM_OK && !*grid) st = err ? err->status : FM_ERR_INPUT;
    r->obstacles = *grid;
    for (int i = 0; i < def->obstacle_count; i++) fm_mesh_free(&meshes[i]);
    free(meshes);
    return st;
}

static double dist3(const double *a, const double *b)
{
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/* pts (n points) resampled by arc length to `count` points into out, the ends exactly o1 and o2. */
static void resample(const double *pts, int64_t n, int32_t count, const double o1[3], const double o2[3], double *out)
{
    double total = 0;
    for (int64_t i = 0; i + 1 < n; i++) total += dist3(pts + 3 * i, pts + 3 * (i + 1));
    int64_t i = 0;
    double at = 0; /* arc length at pts[i] */
    for (int32_t j = 1; j + 1 < count; j++) {
        const double s = total * (double)j / (double)(count - 1);
        double len = dist3(pts + 3 * i, pts + 3 * (i + 1));
        while (i + 2 < n && at + len < s) at += len, i++, len = dist3(pts + 3 * i, pts + 3 * (i + 1));
        const double t = len > 0 ? fmin(fmax((s - at) / len, 0), 1) : 0;
        for (int k = 0; k < 3; k++) out[3 * j + k] = pts[3 * i + k] + t * (pts[3 * (i + 1) + k] - pts[3 * i + k]);
    }
    memcpy(out, o1, 3 * sizeof(double)), memcpy(out + 3 * (count - 1), o2, 3 * sizeof(double));
}

static void set_route_margin(fm_flock_model *m)
{
    m->route_margin = ROUTE_MARGIN_OF_RADIUS * fmax(spread_of(m->start, m->n, m->o1), spread_of(m->dest0, m->n, m->o2));
}

/* R through count points (the routed polyline resampled) in place of the user's. */
static fm_status rebuild_path(fm_flock_model *m, const double *pts, int32_t count, fm_error *err)
{
    fm_bspline_free(&m->path);
    return fm_bspline_build(pts, count, &m->path, err);
}

/* R rerouted round the obstacles (fm_path_route_dense on R's dense samples), then resampled by arc
 * length; pts and count: the points R was rebuilt through (NULL where no stretch was rerouted). */
static fm_status route_dense(fm_flock_model *m, fm_path_route *r, double **pts, int32_t *count, fm_error *err)
{
    int64_t n = (int64_t)ROUTE_SAMPLES_PER_SEGMENT * (m->path.count - 1) + 1;
    double *dense = malloc(sizeof(double) * 3 * (size_t)n);
    fm_status st = dense ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    for (int64_t i = 0; st == FM_OK && i < n; i++)
        fm_bspline_eval_arc(&m->path, (double)i / (double)(n - 1), dense + 3 * i, NULL);
    if (st == FM_OK) memcpy(dense, m->o1, sizeof m->o1), memcpy(dense + 3 * (n - 1), m->o2, sizeof m->o2);
    if (st == FM_OK) st = fm_path_route_dense(r, &dense, &n, err);
    if (st == FM_OK && r->routed) {
        double total = 0;
        for (int64_t i = 0; i + 1 < n; i++) total += dist3(dense + 3 * i, dense + 3 * (i + 1));
        const double spacing = ROUTE_SPACING_OF_INFLATION * r->r_infl;
        *count = (int32_t)fmin(ceil(total / spacing) + 1, ROUTE_POINTS_MAX);
        if (!(*pts = malloc(sizeof(double) * 3 * (size_t)*count)))
            st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
        if (st == FM_OK) resample(dense, n, *count, m->o1, m->o2, *pts);
        if (st == FM_OK) st = rebuild_path(m, *pts, *count, err);
    }
    free(dense);
    return st;
}

static void forget_route(fm_flock_keep *k)
{
    free(k->route_points);
    k->route_points = NULL, k->route_count = 0, k->has_route = k->routed = 0;
}

/* The keep's routed R, where its route grid was this build's and its key is this route's. */
static int route_fits(const fm_flock_keep *k, int grid_kept, const fm_route_key *key)
{
    return k && grid_kept && k->has_route && memcmp(&k->route_key, key, sizeof *key) == 0;
}

static fm_status route_path(fm_flock_model *m, fm_flock_keep *keep, fm_error *err)
{
    fm_path_route r;
    fm_obstacles *grid = NULL;
    int grid_kept = 0;
    fm_status st = route_setup(m, &r, &grid, keep ? &keep->route_grid : NULL, &grid_kept, err);
    if (st == FM_OK && keep) st = fm_build_stage(NULL, NULL, NULL, 0, keep->cancel, err); /* before the search */
    fm_route_key *key = st == FM_OK && keep ? malloc(sizeof *key) : NULL; /* 7 KiB: off the loader's deep stack */
    if (st == FM_OK && keep && !key) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    if (key) fm_route_key_of(&m->def, m->o1, m->o2, &r, key);
    double *pts = NULL;
    int32_t count = 0;
    if (st == FM_OK && route_fits(keep, grid_kept, key)) {
        keep->route_reused = 1;
        if (keep->routed) st = rebuild_path(m, keep->route_points, keep->route_count, err);
    } else if (st == FM_OK) {
        if (keep) forget_route(keep);
        st = route_dense(m, &r, &pts, &count, err);
    }
    if (st == FM_OK && key && !keep->route_reused) { /* the keep takes the points */
        keep->route_key = *key, keep->route_points = pts, keep->route_count = count;
        keep->routed = r.routed, keep->has_route = 1, pts = NULL;
    }
    free(pts), free(key);
    fm_obstacles_destroy(grid);
    return st;
}

/* SCF "Global Path Control": R from O1 (the source's centre) through path.points to O2. */
static fm_status build_path(fm_flock_model *m, fm_flock_keep *keep, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    int32_t count = def->path_point_count + 2;
    double *pts = malloc(sizeof(double) * 3 * (size_t)count);
    if (!pts) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the path");
    memcpy(pts, m->o1, sizeof m->o1);
    memcpy(pts + 3, def->path_points, sizeof(double) * 3 * (size_t)def->path_point_count);
    memcpy(pts + 3 * (count - 1), m->o2, sizeof m->o2);
    int distinct = 0;
    for (int32_t i = 1; i < count; i++) distinct |= memcmp(pts, pts + 3 * i, sizeof m->o1) != 0;
    fm_status st = distinct ? fm_bspline_build(pts, count, &m->path, err) : FM_OK; /* in place: no path */
    free(pts);
    if (st == FM_OK && distinct && m->obstacles && def->path_route) st = route_path(m, keep, err);
    /* speed0 is the leaders' cruise: the ramps of set_ease take half their length more */
    const double ramps = 0.5 * (def->flock.ease_in + def->flock.ease_out);
    m->path_time = def->flock.path_time > 0 ? def->flock.path_time : distinct ? m->path.length / def->speed0 + ramps : 0;
    return fm_name_key(st, "path.points", err);
}

/* Each agent draws every parameter uniformly from its range (SCF: "every agent maintains its own
 * attribute list"); radii are in spacings sqrt(A / N), A the mean of the two surfaces' areas, or
 * r = J / sqrt(N) (eq 6) where the scene gives J. */
static void draw_parameters(fm_flock_model *m, double area)
{
    const fm_flock_def *f = &m->def.flock;
    const fm_boid_rule_def *rules[FM_BOIDS_RULES] = {&f->separation, &f->cohesion, &f->alignment};
    const double inv_sqrt_n = 1.0 / sqrt((double)m->n), deg = 3.14159265358979323846 / 180;
    const double spacing = sqrt(area) * inv_sqrt_n;
    m->max_radius = 0;
    for (int64_t a = 0; a < m->n; a++) {
        uint64_t stream = STREAM_PARAMS;
#define DRAW(range) ((range)[0] + ((range)[1] - (range)[0]) * fm_random_unit(m->def.seed, stream++, (uint64_t)a))
        for (int r = 0; r < FM_BOIDS_RULES; r++) {
            m->radius[r][a] = (float)(rules[r]->by_j ? DRAW(rules[r]->radius_j) * inv_sqrt_n : DRAW(rules[r]->radius) * spacing);
            double angle = DRAW(rules[r]->angle_deg);
            m->cos_half[r][a] = angle >= 360 ? -1.0f : (float)cos(0.5 * angle * deg);
            m->weight[r][a] = (float)DRAW(rules[r]->weight);
            m->max_radius = fmaxf(m->max_radius, m->radius[r][a]);
        }
        m->max_speed[a] = (float)DRAW(f->max_speed);
        m->max_force[a] = (float)DRAW(f->max_force);
        m->max_accel[a] = (float)(m->max_force[a] / f->mass);
#undef DRAW
    }
}

/* Source, target and path, padded by 15 % of the largest extent (as the tetra morph's grid). */
static void scene_bounds(fm_flock_model *m, const fm_mesh *source)
{
    for (int k = 0; k < 3; k++) m->scene_lo[k] = INFINITY, m->scene_hi[k] = -INFINITY;
    fm_grow_bounds(m->scene_lo, m->scene_hi, source->v, source->nv);
    fm_grow_bounds(m->scene_lo, m->scene_hi, m->target.mesh.v, m->target.mesh.nv);
    fm_grow_bounds(m->scene_lo, m->scene_hi, &m->def.path_points[0][0], m->def.path_point_count);
    fm_flock_target_grow_bounds(&m->target, m->scene_lo, m->scene_hi);
    double pad = 0;
    for (int k = 0; k < 3; k++) pad = fmax(pad, 0.15 * (m->scene_hi[k] - m->scene_lo[k]));
    for (int k = 0; k < 3; k++) m->scene_lo[k] -= pad, m->scene_hi[k] += pad;
}

/* Bake the style fields only where the grid resolves them (fields.h); the warning says so when it
 * does not, naming where the scene sets style.grid. */
static fm_status plan_fields(fm_flock_model *m, fm_error *err)
{
    fm_status st = fm_fields_plan(&m->def, m->scene_lo, m->scene_hi, &m->fields, err);
    if (st == FM_OK && m->fields.warning[0]) {
        char where[FM_PATH_MAX + 64];
        fm_scene_key_location(&m->def, "style.grid", where, sizeof where);
        snprintf(m->warning, sizeof m->warning, "%.200s: %s", where, m->fields.warning);
    }
    m->info.fields_baked = m->fields.baked;
    m->info.field_bake_error = m->fields.bake_error;
    return st;
}

/* SCF "Fuzzy Control Logic": the static strategy's curves for a static target, the tracking
 * strategy's for a moving one (deforming or travelling), unless the scene chooses. */
static fm_status init_fuzzy(fm_flock_model *m, fm_error *err)
{
    static const char *const names[FM_FUZZY_FORCES] = {"steering", "homing", "damping", "external"};
    const int tracking = fm_flock_tracking_strategy(&m->def.flock);
    m->tracking = tracking;
    const fm_fuzzy_def *curves = tracking ? m->def.flock.fuzzy_tracking : m->def.flock.fuzzy;
    fm_status st = FM_OK;
    for (int f = 0; f < FM_FUZZY_FORCES && st == FM_OK; f++) {
        char key[64];
        snprintf(key, sizeof key, "shape_flock.fuzzy.%s%s", tracking ? "tracking." : "", names[f]);
        st = fm_fuzzy_init(&m->fuzzy[f], &curves[f], key, err);
    }
    if (st == FM_OK) st = fm_fuzzy_init(&m->r_scale, &m->def.flock.kalman_r_scale, "shape_flock.kalman.r_scale.points", err);
    return st;
}

/* The leaders' timing (issue 37: leaders at constant arc-length speed stopped the whole flock dead at
 * once). Each leader speeds up from rest over ease_in, cruises, and slows to rest over ease_out,
 * with raised-cosine ramps of its speed (so its acceleration is continuous), in path_time; and
 * starts after a delay that grows from 0 at the front of the source (along the path's first
 * direction) to ease_spread at its back, so neighbours keep nearly the same timing (they start
 * together and stay neighbours) while the flock streams out of the source and arrivals spread over
 * ease_spread instead of one common stop. Ramps longer than the path time share it. */
static void set_ease(fm_flock_model *m)
{
    const fm_flock_def *f = &m->def.flock;
    m->ease_in = m->ease_out = m->ease_spread = 0, m->ease_lo = 0, m->ease_inv_range = 0;
    memset(m->ease_axis, 0, sizeof m->ease_axis);
    if (!(m->path_time > 0)) return;
    const double ramps = f->ease_in + f->ease_out, fit = ramps > m->path_time ? m->path_time / ramps : 1.0;
    m->ease_in = f->ease_in * fit / m->path_time, m->ease_out = f->ease_out * fit / m->path_time;
    m->ease_spread = f->ease_spread;
    double p[3], d[3], len = 0;
    fm_bspline_eval_arc(&m->path, 0, p, d);
    for (int k = 0; k < 3; k++) len += d[k] * d[k];
    if (!(len > 0) || m->ease_spread == 0) return;
    for (int k = 0; k < 3; k++) m->ease_axis[k] = d[k] / sqrt(len);
    double lo = INFINITY, hi = -INFINITY;
    for (int64_t a = 0; a < m->n; a++) {
        const double x = m->ease_axis[0] * m->start[0][a] + m->ease_axis[1] * m->start[1][a] + m->ease_axis[2] * m->start[2][a];
        lo = fmin(lo, x), hi = fmax(hi, x);
    }
    m->ease_lo = lo, m->ease_inv_range = hi > lo ? 1.0 / (hi - lo) : 0.0;
}

/* The eased fraction of the path at normalised time x in [0, 1] (see set_ease): the integral of a
 * speed that rises as (1 - cos) over [0, e_in], is flat, and falls as (1 - cos) over [1 - e_out, 1]. */
static double eased(double x, double e_in, double e_out)
{
    static const double PI = 3.14159265358979323846;
    const double top = 1.0 / (1.0 - 0.5 * (e_in + e_out)); /* the cruise speed, so that the whole is 1 */
    if (x <= 0) return 0;
    if (x >= 1) return 1;
    if (x < e_in) return top * (0.5 * x - e_in / (2 * PI) * sin(PI * x / e_in));
    const double y = 1 - x;
    if (y < e_out) return 1 - top * (0.5 * y - e_out / (2 * PI) * sin(PI * y / e_out));
    return top * (0.5 * e_in + x - e_in);
}

/* The formation's blend f (fm_path_map_blend) at path fraction u: eq 11's f = u, or with
 * shape_flock.reform the source's layout kept until the last `reform` of the path. */
static double layout_blend(const fm_flock_model *m, double u)
{
    const double reform = m->def.flock.reform;
    if (!(reform > 0)) return u;
    const double x = (u - (1 - reform)) / reform;
    return x <= 0 ? 0 : x >= 1 ? 1 : x * x * (3 - 2 * x);
}

double fm_flock_leader(const fm_flock_model *m, const float *const start[3], int64_t a, double t, double *blend)
{
    if (!(m->path_time > 0)) {
        *blend = 1.0;
        return 1.0;
    }
    double delay = 0;
    if (m->ease_inv_range > 0) {
        const double x = m->ease_axis[0] * start[0][a] + m->ease_axis[1] * start[1][a] + m->ease_axis[2] * start[2][a];
        const double back = 1 - (x - m->ease_lo) * m->ease_inv_range;
        delay = m->ease_spread * (back < 0 ? 0 : back > 1 ? 1 : back);
    }
    const double x = (t - delay) / m->path_time, u = eased(x, m->ease_in, m->ease_out);
    *blend = layout_blend(m, u);
    return u;
}

double fm_flock_leaders_end(const fm_flock_model *m) { return m->path_time > 0 ? m->path_time + m->ease_spread : 0; }

static void set_info(fm_flock_model *m)
{
    const fm_scene_def *def = &m->def;
    double frame = 1.0 / def->frame_rate;
    m->steps_per_frame = def->time_step > 0 ? (int32_t)llround(frame / def->time_step) : 1;
    m->dt = frame / m->steps_per_frame;
    fm_flock_model_info *i = &m->info;
    i->agents = m->n;
    memcpy(i->source_center, m->o1, sizeof m->o1);
    memcpy(i->target_center, m->o2, sizeof m->o2);
    i->path_length = m->path.length;
    i->path_time = m->path_time;
    i->leaders_end = fm_flock_leaders_end(m);
    i->time_step = m->dt;
    i->steps_per_frame = m->steps_per_frame;
    i->max_radius = m->max_radius;
    i->deforming = fm_flock_target_moves(&def->flock);
    i->travel_length = m->target.route.length;
    i->travel_start = m->target.route.count > 0 ? m->target.route_start : NAN;
    i->travel_end = m->target.route.count > 0 ? fm_flock_target_travel_end(&m->target) : NAN;
}

/* Samples both surfaces and matches them: agent a starts on src's sample a and flies to tgt's match[a]. */
static fm_status sample_and_match(const fm_flock_model *m, const fm_mesh *source, fm_samples *src, fm_samples *tgt,
                                  int64_t *match, const build_ctx *b, fm_error *err)
{
    fm_status st = stage(b, "sample source", 0.1, err);
    if (st == FM_OK) st = m->from ? formed_shape(m->from, src, err) : sample(source, m, STREAM_SOURCE, b, src, err);
    if (st == FM_OK) st = stage(b, "sample target", 0.4, err);
    const int projected = m->def.flock.match == FM_FLOCK_MATCH_PROJECTED;
    if (st == FM_OK && projected) st = sample_projected(&m->target.mesh, m, b, src, tgt, match, err);
    else if (st == FM_OK) st = sample(&m->target.mesh, m, STREAM_TARGET, b, tgt, err);
    if (st == FM_OK) st = stage(b, "match", 0.7, err);
    if (st == FM_OK && !projected)
        st = fm_name_key(fm_match_agents(src->p, tgt->p, m->n, (fm_match_method)m->def.flock.match,
                                      fm_random_bits(m->def.seed, STREAM_MATCH, 0), match, err), "shape_flock.match", err);
    if (st == FM_OK && m->def.flock.uncross && m->def.flock.match != FM_FLOCK_MATCH_RANDOM)
        st = fm_match_uncross(src->p, tgt->p, m->n, match, err);
    return st;
}

/* ---------------------------------------------------------------- the studio's keep */

static void *copy_array(const void *from, size_t bytes, int *ok)
{
    if (!from) return NULL;
    void *to = fm_alloc(bytes ? bytes : 1);
    if (to) memcpy(to, from, bytes);
    else *ok = 0;
    return to;
}

static fm_status copy_samples(const fm_samples *from, fm_samples *to, fm_error *err)
{
    int ok = 1;
    const size_t n = (size_t)from->n;
    fm_samples c = {copy_array(from->p, sizeof(float) * 3 * n, &ok), copy_array(from->tri, sizeof(int32_t) * n, &ok),
                    copy_array(from->bary, sizeof(float) * 3 * n, &ok), from->n};
    if (!ok) return fm_samples_free(&c), fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld samples", (long long)from->n);
    *to = c;
    return FM_OK;
}

/* What sample_and_match reads of the scene: the shape_flock keys of the sampling and the match. */
static int same_sampling(const fm_flock_def *a, const fm_flock_def *b)
{
    return a->sampling == b->sampling && a->match == b->match && a->mosaic_iterations == b->mosaic_iterations &&
           a->mosaic_distance == b->mosaic_distance && a->mosaic_k == b->mosaic_k && a->mosaic_w == b->mosaic_w &&
           a->mosaic_step == b->mosaic_step && a->stratified_lambda == b->stratified_lambda &&
           a->stratified_oversample == b->stratified_oversample && a->uncross == b->uncross;
}

/* A group from another's shape samples no source: its source samples are from's destinations. */
static int same_formed_shape(const fm_flock_keep *k, const fm_flock_model *m)
{
    return !m->from || (k->src.n == m->n && !memcmp(k->src.p, m->from->target.dest.p, sizeof(float) * 3 * (size_t)m->n));
}

static int keep_fits(const fm_flock_keep *k, const fm_flock_model *m, const fm_mesh *source)
{
    return k->has && k->n == m->n && k->seed == m->def.seed && same_sampling(&k->flock, &m->def.flock) &&
           fm_mesh_same(&k->source, source) && fm_mesh_same(&k->target, &m->target.mesh) && same_formed_shape(k, m);
}

static fm_status from_keep(const fm_flock_keep *k, fm_samples *src, fm_samples *tgt, int64_t *match, fm_error *err)
{
    fm_status st = copy_samples(&k->src, src, err);
    if (st == FM_OK) st = copy_samples(&k->tgt, tgt, err);
    if (st == FM_OK) memcpy(match, k->match, sizeof(int64_t) * (size_t)k->n);
    return st;
}

/* The keep's samples and match dropped; its grids and route stay. */
static void forget_samples(fm_flock_keep *k)
{
    fm_mesh_free(&k->source), fm_mesh_free(&k->target);
    fm_samples_free(&k->src), fm_samples_free(&k->tgt);
    fm_free(k->match);
    k->match = NULL, k->has = 0, k->n = 0, k->seed = 0;
    memset(&k->flock, 0, sizeof k->flock);
}

static fm_status into_keep(fm_flock_keep *k, const fm_flock_model *m, const fm_mesh *source, const fm_samples *src,
                           const fm_samples *tgt, const int64_t *match, fm_error *err)
{
    forget_samples(k);
    int ok = 1;
    k->match = copy_array(match, sizeof(int64_t) * (size_t)m->n, &ok);
    fm_status st = ok ? fm_mesh_copy(source, &k->source, err) : fm_fail(err, FM_ERR_MEMORY, "out of memory");
    if (st == FM_OK) st = fm_mesh_copy(&m->target.mesh, &k->target, err);
    if (st == FM_OK) st = copy_samples(src, &k->src, err);
    if (st == FM_OK) st = copy_samples(tgt, &k->tgt, err);
    if (st != FM_OK) return forget_samples(k), st;
    k->n = m->n, k->seed = m->def.seed, k->flock = m->def.flock, k->has = 1;
    return FM_OK;
}

void fm_flock_keep_clear(fm_flock_keep *keep)
{
    if (!keep) return;
    forget_samples(keep);
    fm_kept_grid_clear(&keep->grid), fm_kept_grid_clear(&keep->route_grid);
    forget_route(keep);
    memset(keep, 0, sizeof *keep);
}

/* Samples both surfaces (or takes the keep's samples, where they fit) and assigns each agent its
 * start and destination. */
static fm_status place_agents(fm_flock_model *m, const fm_mesh *source, fm_flock_keep *keep, const build_ctx *b,
                              fm_error *err)
{
    fm_samples src = {0}, tgt = {0};
    int64_t *match = malloc(sizeof(int64_t) * (size_t)m->n);
    const int kept = keep && keep_fits(keep, m, source);
    fm_status st = !match ? fm_fail(err, FM_ERR_MEMORY, "out of memory")
                   : kept ? from_keep(keep, &src, &tgt, match, err)
                          : sample_and_match(m, source, &src, &tgt, match, b, err);
    if (st == FM_OK && keep && !kept) st = into_keep(keep, m, source, &src, &tgt, match, err);
    if (keep) keep->reused = kept;
    if (st == FM_OK) st = assign(m, &src, &tgt, match, err);
    if (st == FM_OK) mean_point(src.p, m->n, m->o1), mean_point(tgt.p, m->n, m->o2);
    fm_samples_free(&src), fm_samples_free(&tgt);
    free(match);
    return st;
}

static fm_status load_source(const fm_scene_def *def, fm_mesh *source, fm_error *err)
{
    fm_status st = fm_name_key(fm_mesh_load(def->source.path, source, err), "source.mesh", err);
    if (st == FM_OK) fm_mesh_place(source, &def->source);
    return st == FM_OK ? fm_scene_name_key(def, fm_mesh_check_extent(source, def->source.path, err), "source.mesh", err)
                       : st;
}

/* agents start and end on the surfaces: an obstacle may overlap neither (the target at rest) */
static fm_status build_obstacles(fm_flock_model *m, const fm_mesh *source, fm_flock_keep *keep, fm_error *err)
{
    if (m->def.obstacle_count == 0) return FM_OK;
    m->obstacles = fm_obstacles_from_scene_keeping(&m->def, m->def.k_a, source, &m->target.mesh, keep ? &keep->grid : NULL,
                                                   keep ? &keep->grid_reused : NULL, err);
    return m->obstacles ? FM_OK : err ? err->status : FM_ERR_INPUT;
}

/* The studio may cancel a build at every stage boundary (stage): before it starts (a shot's group
 * after another's), between the samplings and the match, between the mosaic's iterations, before
 * each obstacle grid and before the route's search. */
static fm_status build(fm_flock_model *m, fm_flock_keep *keep, const build_ctx *b, fm_error *err)
{
    const fm_scene_def *def = &m->def;
    fm_mesh source = {0};
    fm_status st = stage(b, NULL, 0, err);
    if (st == FM_OK) st = fm_flock_target_build(&m->target, def, err);
    if (st == FM_OK) st = load_source(def, &source, err);
    if (st == FM_OK) st = alloc_agent_arrays(m, err);
    if (st == FM_OK) st = place_agents(m, &source, keep, b, err);
    if (st == FM_OK) st = stage(b, NULL, 0, err);
    if (st == FM_OK) st = build_obstacles(m, &source, keep, err); /* before the path, routed round them */
    if (st == FM_OK) set_route_margin(m);
    if (st == FM_OK) st = stage(b, NULL, 0, err);
    if (st == FM_OK) st = build_path(m, keep, err);
    if (st == FM_OK) set_ease(m), fm_flock_target_set_start(&m->target, &def->flock, fm_flock_leaders_end(m));
    if (st == FM_OK) st = init_fuzzy(m, err);
    if (st == FM_OK) {
        const fm_mesh *start = m->from ? &m->from->target.mesh : &source;
        draw_parameters(m, 0.5 * (fm_mesh_area(start) + fm_mesh_area(&m->target.mesh)));
        scene_bounds(m, &source);
        set_info(m);
        st = stage(b, NULL, 0, err);
    }
    if (st == FM_OK) st = plan_fields(m, err);
    fm_mesh_free(&source);
    if (st == FM_OK) st = stage(b, "ready", 1.0, err);
    return st;
}

static fm_flock_model *build_model(const fm_scene_def *def, const fm_flock_model *from, fm_flock_keep *keep,
                                   fm_progress_fn progress, void *user, fm_error *err)
{
    if (fm_scene_validate(def, err) != FM_OK) return NULL;
    if (def->mode != FM_MODE_SHAPE_FLOCK) {
        fm_fail(err, FM_ERR_USAGE, "fm_flock_model_build: the scene's mode is not \"shape_flock\"");
        return NULL;
    }
    if (fm_flock_memory_check(def, def->n, err) != FM_OK) return NULL; /* before the per-agent arrays */
    fm_flock_model *m = calloc(1, sizeof *m);
    if (!m) {
        fm_fail(err, FM_ERR_MEMORY, "out of memory");
        return NULL;
    }
    m->def = *def;
    m->n = from ? from->n : def->n;
    m->from = from;
    if (keep) keep->reused = keep->grid_reused = keep->route_reused = 0;
    const build_ctx b = {progress, user, keep ? keep->cancel : NULL};
    fm_status st = build(m, keep, &b, err);
    if (keep && st != FM_OK) keep->reused = keep->grid_reused = keep->route_reused = 0;
    m->from = NULL;
    if (st != FM_OK) {
        fm_flock_model_destroy(m);
        return NULL;
    }
    return m;
}

fm_flock_model *fm_flock_model_build(const fm_scene_def *def, fm_progress_fn progress, void *user, fm_error *err)
{
    if (def->group_count > 0 && def->group_index < 0) {
        fm_fail(err, FM_ERR_USAGE, "%s: the scene is a shot of %d groups: build each group (fm_scene_load_group) "
                "and run them together (fm_flock_shot_build), as flockmorph run does", def->scene_path, def->group_count);
        return NULL;
    }
    return build_model(def, NULL, NULL, progress, user, err);
}

fm_flock_model *fm_flock_model_build_keeping(const fm_scene_def *def, fm_flock_keep *keep, fm_progress_fn progress,
                                             void *user, fm_error *err)
{
    if (def->group_count > 0 && def->group_index < 0) return fm_flock_model_build(def, progress, user, err); /* its error */
    return build_model(def, NULL, keep, progress, user, err);
}

fm_flock_model *fm_flock_model_build_from_shape(const fm_scene_def *def, const fm_flock_model *from,
                                                fm_progress_fn progress, void *user, fm_error *err)
{
    return build_model(def, from, NULL, progress, user, err);
}

fm_flock_model *fm_flock_model_build_from_shape_keeping(const fm_scene_def *def, const fm_flock_model *from,
                                                        fm_flock_keep *keep, fm_progress_fn progress, void *user,
                                                        fm_error *err)
{
    return build_model(def, from, keep, progress, user, err);
}

/* ---------------------------------------------------------------- one model a machine */

/* The model's arrays of n (100 bytes an agent), by address and size: what a machine's ranks share. */
enum { MODEL_ARRAYS = 21 }; /* <= FM_DIST_MAX_ARRAYS */
static int model_arrays(void *model, void **p[], size_t bytes[])
{
    fm_flock_model *m = model;
    const size_t f = sizeof(float) * (size_t)m->n;
    int c = 0;
    p[c] = (void **)&m->max_speed, bytes[c++] = f;
    p[c] = (void **)&m->max_force, bytes[c++] = f;
    p[c] = (void **)&m->max_accel, bytes[c++] = f;
    for (int k = 0; k < 3; k++) {
        p[c] = (void **)&m->start[k], bytes[c++] = f;
        p[c] = (void **)&m->dest0[k], bytes[c++] = f;
        p[c] = (void **)&m->radius[k], bytes[c++] = f;
        p[c] = (void **)&m->cos_half[k], bytes[c++] = f;
        p[c] = (void **)&m->weight[k], bytes[c++] = f;
    }
    p[c] = (void **)&m->target.dest.p, bytes[c++] = 3 * f;
    p[c] = (void **)&m->target.dest.bary, bytes[c++] = 3 * f;
    p[c] = (void **)&m->target.dest.tri, bytes[c++] = sizeof(int32_t) * (size_t)m->n;
    return c;
}

/* A machine's other ranks: the first rank's model as broadcast, with this rank's own scene and
 * none of the first rank's objects (its arrays come from fm_dist_share_arrays). */
static void take_scalars(void *model, const fm_scene_def *def)
{
    fm_flock_model *m = model;
    m->def = *def;
    const fm_samples dest = m->target.dest;
    memset(&m->target, 0, sizeof m->target), memset(&m->path, 0, sizeof m->path);
    m->target.dest = dest;
    m->obstacles = NULL, m->from = NULL, m->shared = NULL;
}

/* The parts every rank builds for itself, from the scene as the first rank did: the target's mesh
 * and deformation (not the destinations on it, which are shared), the path and the obstacles' grid. */
static fm_status build_replicated(void *model, fm_error *err)
{
    fm_flock_model *m = model;
    const fm_samples dest = m->target.dest;
    fm_status st = fm_flock_target_build(&m->target, &m->def, err);
    m->target.dest = dest;
    fm_mesh source = {0};
    if (st == FM_OK && m->def.obstacle_count > 0) st = load_source(&m->def, &source, err);
    if (st == FM_OK) st = build_obstacles(m, &source, NULL, err); /* route_margin came with the scalars */
    fm_mesh_free(&source);
    if (st == FM_OK) st = build_path(m, NULL, err);
    if (st == FM_OK) fm_flock_target_set_start(&m->target, &m->def.flock, fm_flock_leaders_end(m));
    return st;
}

/* context: a shot's group's source group, whose formed shape it starts from; NULL otherwise */
static void *build_one(const fm_scene_def *def, const void *context, fm_progress_fn progress, void *user, fm_error *err)
{
    return context ? fm_flock_model_build_from_shape(def, context, progress, user, err)
                   : fm_flock_model_build(def, progress, user, err);
}

static void destroy_one(void *m) { fm_flock_model_destroy(m); }

static const fm_dist_model_ops SHARED_OPS = {sizeof(fm_flock_model), offsetof(fm_flock_model, shared), build_one,
                                             take_scalars, model_arrays, build_replicated, destroy_one};

fm_flock_model *fm_flock_model_build_shared(const fm_scene_def *def, const fm_dist *dist, fm_progress_fn progress,
                                            void *user, fm_error *err)
{
    return fm_dist_build_shared(dist, &SHARED_OPS, def, NULL, progress, user, err);
}

fm_flock_model *fm_flock_model_build_from_shape_shared(const fm_scene_def *def, const fm_flock_model *from,
                                                       const fm_dist *dist, fm_progress_fn progress, void *user,
                                                       fm_error *err)
{
    return fm_dist_build_shared(dist, &SHARED_OPS, def, from, progress, user, err);
}

void fm_flock_model_destroy(fm_flock_model *m)
{
    if (!m) return;
    void **p[MODEL_ARRAYS];
    size_t bytes[MODEL_ARRAYS];
    for (int i = 0, count = m->shared ? model_arrays(m, p, bytes) : 0; i < count; i++) *p[i] = NULL; /* the segment's */
    fm_dist_shared_free(m->shared);
    fm_flock_target_free(&m->target);
    fm_bspline_free(&m->path);
    fm_obstacles_destroy(m->obstacles);
    fm_free(m->max_speed), fm_free(m->max_force), fm_free(m->max_accel);
    for (int k = 0; k < 3; k++) {
        fm_free(m->start[k]), fm_free(m->dest0[k]);
        fm_free(m->radius[k]), fm_free(m->cos_half[k]), fm_free(m->weight[k]);
    }
    free(m);
}

fm_flock_model_info fm_flock_model_get_info(const fm_flock_model *m) { return m->info; }

int fm_flock_model_warning_count(const fm_flock_model *m) { return m->fields.warning[0] ? 1 : 0; }

const char *fm_flock_model_warning(const fm_flock_model *m, int i)
{
    return i == 0 && m->fields.warning[0] ? m->warning : "";
}

void fm_flock_model_endpoints(const fm_flock_model *m, float *c1, float *c2)
{
    for (int64_t a = 0; a < m->n; a++)
        for (int k = 0; k < 3; k++) {
            if (c1) c1[3 * a + k] = m->start[k][a];
            if (c2) c2[3 * a + k] = m->dest0[k][a];
        }
}

double fm_flock_eased(double x, double e_in, double e_out) { return eased(x, e_in, e_out); }
