/* The shape flock's target surface over time: static, a procedural wave or pulse, or a sequence of
 * meshes with the target's connectivity (SCF "Shape Constraints": samples are drawn on the first
 * shape and follow its vertices); and any of them carried along a route (SCF Figure 1's horse runs
 * along one), a pure function of time, so every rank and thread evaluates the same target. */
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

/* ---------------------------------------------------------------- the route */

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* x minus its component along unit t, normalised (left as is if nothing is left). */
static void perpendicular_unit(double x[3], const double t[3])
{
    const double along = dot3(x, t);
    double y[3] = {x[0] - along * t[0], x[1] - along * t[1], x[2] - along * t[2]}, len = sqrt(dot3(y, y));
    if (len > 0)
        for (int k = 0; k < 3; k++) x[k] = y[k] / len;
}

/* The unit tangent at route.arc's sample j (dR/ds there; the previous one where it vanishes). */
static void tangent_at(const fm_bspline *b, int32_t j, double out[3])
{
    const double *d = b->arc + 6 * j + 3, len = sqrt(dot3(d, d));
    if (len > 0)
        for (int k = 0; k < 3; k++) out[k] = d[k] / len;
}

/* The route's rotation-minimising frame by double reflection (Wang, Juettler, Zheng and Liu 2008,
 * "Computation of rotation minimizing frames"): the normal carried from each of route.arc's samples
 * to the next, from the unit perpendicular to the first tangent nearest the axis the tangent is
 * least along. The frame turns with the tangent and never twists about it, so the shape turns as the
 * route does (on a level route about the vertical alone) and a U-turn does not flip it. */
static fm_status route_frames(fm_flock_target *t, fm_error *err)
{
    const fm_bspline *b = &t->route;
    t->route_normal = malloc(sizeof(double) * 3 * (FM_BSPLINE_ARC_SAMPLES + 1));
    if (!t->route_normal) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the target's route");
    double tan[3] = {1, 0, 0}, r[3] = {0, 0, 0};
    tangent_at(b, 0, tan);
    int axis = 0;
    for (int k = 1; k < 3; k++) axis = fabs(tan[k]) < fabs(tan[axis]) ? k : axis;
    r[axis] = 1;
    perpendicular_unit(r, tan);
    memcpy(t->route_normal, r, sizeof r);
    for (int32_t j = 0; j < FM_BSPLINE_ARC_SAMPLES; j++) {
        const double *x0 = b->arc + 6 * j, *x1 = x0 + 6;
        double next[3] = {tan[0], tan[1], tan[2]}, v1[3], v2[3], rl[3], tl[3];
        tangent_at(b, j + 1, next);
        for (int k = 0; k < 3; k++) v1[k] = x1[k] - x0[k];
        const double c1 = dot3(v1, v1), fr = c1 > 0 ? 2 * dot3(v1, r) / c1 : 0, ft = c1 > 0 ? 2 * dot3(v1, tan) / c1 : 0;
        for (int k = 0; k < 3; k++) rl[k] = r[k] - fr * v1[k], tl[k] = tan[k] - ft * v1[k], v2[k] = next[k] - tl[k];
        const double c2 = dot3(v2, v2), f2 = c2 > 0 ? 2 * dot3(v2, rl) / c2 : 0;
        for (int k = 0; k < 3; k++) r[k] = rl[k] - f2 * v2[k];
        memcpy(tan, next, sizeof tan);
        perpendicular_unit(r, tan); /* no drift off the tangent's plane */
        memcpy(t->route_normal + 3 * (j + 1), r, sizeof r);
    }
    return FM_OK;
}

/* The route B through target.path.points by arc length, its frames, and its timing: a cruise at
 * target.path.speed between raised-cosine speed ramps of target.path.ease seconds each (as the
 * leaders', fm_flock_eased), which add half their length to the time; ramps longer than the route
 * allows share it and never reach the cruise. */
static fm_status build_route(fm_flock_target *t, const fm_scene_def *def, fm_error *err)
{
    const fm_flock_def *f = &def->flock;
    if (f->travel_point_count == 0) return FM_OK;
    fm_status st = fm_bspline_build(&f->travel_points[0][0], f->travel_point_count, &t->route, err);
    if (st == FM_OK) st = route_frames(t, err);
    const double speed = f->travel_speed > 0 ? f->travel_speed : def->speed0;
    t->route_time = fmax(t->route.length / speed + f->travel_ease, 2 * f->travel_ease);
    t->route_ease = f->travel_ease / t->route_time;
    return fm_scene_name_key(def, st, "target.path.points", err);
}

void fm_flock_target_set_start(fm_flock_target *t, const fm_flock_def *def, double leaders_end)
{
    t->route_start = def->travel_start >= 0 ? def->travel_start : leaders_end;
}

double fm_flock_target_travel_end(const fm_flock_target *t)
{
    return t->route.count > 0 ? t->route_start + t->route_time : 0;
}

/* M = F(u) F(0)^T, row-major: the turn from the route's frame at its start to its frame at u, with
 * the tangent exact (d = dR/ds at u) and the normal interpolated between the samples around u. */
static void route_turn(const fm_flock_target *t, double u, const double d[3], double m[9])
{
    const double x = u * FM_BSPLINE_ARC_SAMPLES;
    int32_t j = (int32_t)x;
    if (j >= FM_BSPLINE_ARC_SAMPLES) j = FM_BSPLINE_ARC_SAMPLES - 1;
    const double w = x - j, *n0 = t->route_normal + 3 * j, *n1 = n0 + 3;
    double f[3][3], f0[3][3]; /* rows: tangent, normal, binormal */
    const double len = sqrt(dot3(d, d));
    for (int k = 0; k < 3; k++) f[0][k] = d[k] / len, f[1][k] = (1 - w) * n0[k] + w * n1[k];
    perpendicular_unit(f[1], f[0]);
    tangent_at(&t->route, 0, f0[0]);
    memcpy(f0[1], t->route_normal, sizeof f0[1]);
    for (int k = 0; k < 3; k++) {
        f[2][k] = f[0][(k + 1) % 3] * f[1][(k + 2) % 3] - f[0][(k + 2) % 3] * f[1][(k + 1) % 3];
        f0[2][k] = f0[0][(k + 1) % 3] * f0[1][(k + 2) % 3] - f0[0][(k + 2) % 3] * f0[1][(k + 1) % 3];
    }
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) m[3 * r + c] = f[0][r] * f0[0][c] + f[1][r] * f0[1][c] + f[2][r] * f0[2][c];
}

/* The shape at time `time` carried along the route: x -> B(u) + M (x - B(0)). Before it sets off the
 * vertices are left as they are, bit for bit. */
static void travel(const fm_flock_target *t, int orient, double time, double *out)
{
    const double u = fm_flock_eased((time - t->route_start) / t->route_time, t->route_ease, t->route_ease);
    if (!(u > 0)) return;
    double b[3], d[3], m[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    fm_bspline_eval_arc(&t->route, u, b, d);
    if (orient && dot3(d, d) > 0) route_turn(t, u, d, m);
    const double *b0 = t->route.arc; /* B(0) */
    for (int64_t i = 0; i < t->mesh.nv; i++) {
        double *v = out + 3 * i, x[3] = {v[0] - b0[0], v[1] - b0[1], v[2] - b0[2]};
        for (int k = 0; k < 3; k++) v[k] = b[k] + m[3 * k] * x[0] + m[3 * k + 1] * x[1] + m[3 * k + 2] * x[2];
    }
}

void fm_flock_target_grow_bounds(const fm_flock_target *t, double lo[3], double hi[3])
{
    if (t->route.count == 0) return;
    const double *b0 = t->route.arc;
    double reach = 0; /* the farthest vertex from the point the shape turns about */
    for (int64_t i = 0; i < t->mesh.nv; i++) {
        const double *v = t->mesh.v + 3 * i, x[3] = {v[0] - b0[0], v[1] - b0[1], v[2] - b0[2]};
        reach = fmax(reach, sqrt(dot3(x, x)));
    }
    for (int32_t j = 0; j <= FM_BSPLINE_ARC_SAMPLES; j++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], t->route.arc[6 * j + k] - reach);
            hi[k] = fmax(hi[k], t->route.arc[6 * j + k] + reach);
        }
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
    if ((st = build_route(t, def, err)) != FM_OK) return st;
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
    fm_bspline_free(&t->route);
    free(t->route_normal);
    t->normals = t->frames = t->route_normal = NULL;
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
    if (t->route.count > 0) travel(t, def->travel_orient, time, out);
}
