/* examples/flock_bird, the shape flock on a flapping bird (an OBJ sequence from
 * tools/make-bird-sequence.py), measured independently of the engine: the example is run through the
 * CLI, its cache read through the public reader, and the deforming surface rebuilt from the OBJ files
 * themselves (read here, placed as scene.json says, interpolated linearly between meshes and looped,
 * docs/scene.md). Each agent's distance to the surface is the distance to its closest point on the
 * triangles (Ericson, tests/helpers/inside_test.h), exact through a bucket grid with a brute-force
 * fallback.
 *   - Over the frames stats.json's tracking_lag covers (t > leaders_end, the last leader's arrival), the mean closest-point
 *     distance is at most tracking_lag: an agent's destination is one point of the surface, so its
 *     distance to the destination is at least its distance to the surface.
 *   - Once the flock has settled (one wingbeat after leaders_end), the mean distance is below half the
 *     agents' spacing on the surface, sqrt(area / n): the flock is a sheet thinner than its spacing,
 *     so it reads as the surface.
 *   - It tracks the wings: at the settled frames where the wings are far from the rest shape (the
 *     surface's largest vertex displacement from mesh 0 at least 3/4 of its largest over the loop),
 *     the mean distance to the rest shape (mesh 0, not deforming) is at least 10 times the mean
 *     distance to the deformed surface. */
#include "flockmorph/flockmorph.h"
#include "inside_test.h"
#include "test_macros.h"

#include <jansson.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#define SCENE FM_SOURCE_DIR "/examples/flock_bird/scene.json"
#define OUT FM_TEST_TMP "/flock_bird"
#define GRID_CELL 0.5 /* units: the bucket grid's cell, and how far from a triangle it lists it */
#define FAR_FROM_REST 0.75
#define REST_RATIO 10.0

typedef struct obj_mesh {
    int64_t nv, nt;
    double *v;
    int32_t *tri;
} obj_mesh;

/* What the test takes from scene.json: the target's placement and the sequence. */
typedef struct bird_scene {
    double translate[3], scale;
    char pattern[FM_PATH_MAX];
    int frames;
    double mesh_rate;
} bird_scene;

static int read_scene(bird_scene *s)
{
    json_error_t jerr;
    json_t *root = json_load_file(SCENE, 0, &jerr);
    ENSURE_MSG(root != NULL, "%s: %s", SCENE, jerr.text);
    if (!root) return 0;
    json_t *target = json_object_get(root, "target"), *deform = json_object_get(json_object_get(root, "shape_flock"), "deform");
    json_t *t = json_object_get(target, "translate"), *scale = json_object_get(target, "scale");
    for (int k = 0; k < 3; k++) s->translate[k] = t ? json_number_value(json_array_get(t, k)) : 0;
    s->scale = scale ? json_number_value(scale) : 1;
    ENSURE_MSG(!json_object_get(target, "rotate_deg"), "the test places the bird by scale and translate only");
    ENSURE(strcmp(json_string_value(json_object_get(deform, "type")), "sequence") == 0);
    snprintf(s->pattern, sizeof s->pattern, "%s/examples/flock_bird/%s", FM_SOURCE_DIR,
             json_string_value(json_object_get(deform, "sequence")));
    s->frames = (int)json_integer_value(json_object_get(deform, "frames"));
    s->mesh_rate = json_number_value(json_object_get(deform, "frame_rate"));
    json_decref(root);
    return s->frames > 0 && s->mesh_rate > 0;
}

/* An OBJ of "v x y z" and "f a b c" lines (1-based), placed: scale, then translate. */
static int read_obj(const char *path, const bird_scene *s, obj_mesh *m)
{
    FILE *f = fopen(path, "r");
    ENSURE_MSG(f != NULL, "cannot open %s", path);
    if (!f) return 0;
    char line[256];
    int64_t cap_v = 1024, cap_t = 2048;
    m->nv = m->nt = 0, m->v = malloc(sizeof(double) * 3 * cap_v), m->tri = malloc(sizeof(int32_t) * 3 * cap_t);
    while (fgets(line, sizeof line, f)) {
        double x, y, z;
        int a, b, c;
        if (sscanf(line, "v %lf %lf %lf", &x, &y, &z) == 3) {
            if (m->nv == cap_v) m->v = realloc(m->v, sizeof(double) * 3 * (cap_v *= 2));
            double p[3] = {x, y, z};
            for (int k = 0; k < 3; k++) m->v[3 * m->nv + k] = s->scale * p[k] + s->translate[k];
            m->nv++;
        } else if (sscanf(line, "f %d %d %d", &a, &b, &c) == 3) {
            if (m->nt == cap_t) m->tri = realloc(m->tri, sizeof(int32_t) * 3 * (cap_t *= 2));
            int32_t *t = m->tri + 3 * m->nt++;
            t[0] = a - 1, t[1] = b - 1, t[2] = c - 1;
        }
    }
    fclose(f);
    return m->nv > 0 && m->nt > 0;
}

static void free_obj(obj_mesh *m) { free(m->v), free(m->tri); }

static void free_sequence(obj_mesh *seq, const bird_scene *s)
{
    for (int i = 0; seq && i < s->frames; i++) free_obj(&seq[i]);
    free(seq);
}

/* The sequence's vertices at time t (s): linear between meshes, looping. */
static void surface_at(const obj_mesh *seq, const bird_scene *s, double t, double *out)
{
    double f = t * s->mesh_rate, whole = floor(f), w = f - whole;
    int i0 = (int)fmod(whole, s->frames), i1 = (i0 + 1) % s->frames;
    for (int64_t j = 0; j < 3 * seq[0].nv; j++) out[j] = seq[i0].v[j] + w * (seq[i1].v[j] - seq[i0].v[j]);
}

/* Triangles bucketed by cells of GRID_CELL: a cell lists every triangle whose bounding box, grown by
 * GRID_CELL, overlaps it, so a closest point found within GRID_CELL among them is the closest. */
typedef struct tri_grid {
    const double *v;
    const int32_t *tri;
    int64_t nt;
    double lo[3];
    int dim[3];
    int32_t *start, *list;
} tri_grid;

static int grid_index(const tri_grid *g, int k, double x)
{
    int i = (int)floor((x - g->lo[k]) / GRID_CELL);
    return i < 0 ? 0 : i >= g->dim[k] ? g->dim[k] - 1 : i;
}

/* The cell range of triangle t's grown bounding box. */
static void tri_cells(const tri_grid *g, int64_t t, int r0[3], int r1[3])
{
    for (int k = 0; k < 3; k++) {
        double lo = INFINITY, hi = -INFINITY;
        for (int c = 0; c < 3; c++) lo = fmin(lo, g->v[3 * g->tri[3 * t + c] + k]), hi = fmax(hi, g->v[3 * g->tri[3 * t + c] + k]);
        r0[k] = grid_index(g, k, lo - GRID_CELL), r1[k] = grid_index(g, k, hi + GRID_CELL);
    }
}

/* Counts (fill 0) or lists (fill 1) triangle t in its cells. */
static void grid_put(tri_grid *g, int64_t t, int fill, int32_t *at)
{
    int r0[3], r1[3];
    tri_cells(g, t, r0, r1);
    for (int x = r0[0]; x <= r1[0]; x++)
        for (int y = r0[1]; y <= r1[1]; y++)
            for (int z = r0[2]; z <= r1[2]; z++) {
                int cell = (x * g->dim[1] + y) * g->dim[2] + z;
                if (fill) g->list[at[cell]++] = (int32_t)t;
                else g->start[cell + 1]++;
            }
}

static void grid_build(tri_grid *g, const double *v, int64_t nv, const int32_t *tri, int64_t nt)
{
    *g = (tri_grid){.v = v, .tri = tri, .nt = nt};
    for (int k = 0; k < 3; k++) {
        double lo = INFINITY, hi = -INFINITY;
        for (int64_t i = 0; i < nv; i++) lo = fmin(lo, v[3 * i + k]), hi = fmax(hi, v[3 * i + k]);
        g->lo[k] = lo - GRID_CELL, g->dim[k] = (int)ceil((hi - lo) / GRID_CELL) + 2;
    }
    size_t cells = (size_t)g->dim[0] * g->dim[1] * g->dim[2];
    g->start = calloc(cells + 1, sizeof(int32_t));
    for (int64_t t = 0; t < nt; t++) grid_put(g, t, 0, NULL);
    for (size_t c = 0; c < cells; c++) g->start[c + 1] += g->start[c];
    int32_t *at = malloc(sizeof(int32_t) * cells);
    memcpy(at, g->start, sizeof(int32_t) * cells);
    g->list = malloc(sizeof(int32_t) * (size_t)(g->start[cells] ? g->start[cells] : 1));
    for (int64_t t = 0; t < nt; t++) grid_put(g, t, 1, at);
    free(at);
}

static void grid_free(tri_grid *g) { free(g->start), free(g->list); }

static double tri_d2(const tri_grid *g, int64_t t, const double p[3])
{
    const int32_t *i = g->tri + 3 * t;
    return inside_tri_dist2(p, g->v + 3 * i[0], g->v + 3 * i[1], g->v + 3 * i[2]);
}

/* The distance from p to the nearest triangle. */
static double grid_distance(const tri_grid *g, const double p[3])
{
    double best = INFINITY;
    int inside = 1;
    for (int k = 0; k < 3; k++) inside &= p[k] >= g->lo[k] && p[k] < g->lo[k] + g->dim[k] * GRID_CELL;
    if (inside) {
        int cell = (grid_index(g, 0, p[0]) * g->dim[1] + grid_index(g, 1, p[1])) * g->dim[2] + grid_index(g, 2, p[2]);
        for (int32_t j = g->start[cell]; j < g->start[cell + 1]; j++) best = fmin(best, tri_d2(g, g->list[j], p));
        if (best <= GRID_CELL * GRID_CELL) return sqrt(best);
    }
    for (int64_t t = 0; t < g->nt; t++) best = fmin(best, tri_d2(g, t, p));
    return sqrt(best);
}

/* The mean distance of the agents (float positions) to the grid's surface. */
static double mean_distance(const tri_grid *g, const float *pos, size_t n)
{
    double sum = 0;
    for (size_t a = 0; a < n; a++) {
        double p[3] = {pos[3 * a], pos[3 * a + 1], pos[3 * a + 2]};
        sum += grid_distance(g, p);
    }
    return sum / (double)n;
}

static double mesh_area(const obj_mesh *m)
{
    double area = 0;
    for (int64_t t = 0; t < m->nt; t++) {
        const double *a = m->v + 3 * m->tri[3 * t], *b = m->v + 3 * m->tri[3 * t + 1], *c = m->v + 3 * m->tri[3 * t + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double x[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        area += 0.5 * sqrt(inside_dot(x, x));
    }
    return area;
}

/* The largest displacement of a vertex of `v` from the rest shape's. */
static double max_displacement(const obj_mesh *rest, const double *v)
{
    double most = 0;
    for (int64_t i = 0; i < rest->nv; i++) {
        const double *p = rest->v + 3 * i, *q = v + 3 * i;
        double d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
        most = fmax(most, sqrt(inside_dot(d, d)));
    }
    return most;
}

/* Reads mesh 0 .. frames-1 of the sequence; all must have mesh 0's vertex count and triangles. */
static obj_mesh *read_sequence(const bird_scene *s)
{
    obj_mesh *seq = calloc((size_t)s->frames, sizeof *seq);
    int ok = 1;
    for (int i = 0; i < s->frames && ok; i++) {
        char path[FM_PATH_MAX + 32];
        snprintf(path, sizeof path, s->pattern, i);
        ok = read_obj(path, s, &seq[i]);
        ok = ok && seq[i].nv == seq[0].nv && seq[i].nt == seq[0].nt &&
             !memcmp(seq[i].tri, seq[0].tri, sizeof(int32_t) * 3 * (size_t)seq[0].nt);
        ENSURE_MSG(ok, "%s: unreadable, or not mesh 0's connectivity", path);
    }
    if (ok) return seq;
    free_sequence(seq, s);
    return NULL;
}

static json_t *run_example(void)
{
    char cmd[4 * FM_PATH_MAX];
    snprintf(cmd, sizeof cmd, "'%s' run '%s' -o '%s' --threads 2 --quiet > '%s.log' 2>&1", FM_CLI, SCENE, OUT, OUT);
    int rc = system(cmd);
    ENSURE_MSG(WIFEXITED(rc) && WEXITSTATUS(rc) == 0, "exit status %d (see %s.log)", WEXITSTATUS(rc), OUT);
    json_error_t jerr;
    json_t *stats = json_load_file(OUT "/stats.json", 0, &jerr);
    ENSURE_MSG(stats != NULL, "%s", jerr.text);
    return stats;
}

/* What the frames give: means over the tracking frames (t > leaders_end, the last leader's arrival) and the settled ones. */
typedef struct tracking {
    double lag_sum, settled_sum, far_sum, far_rest_sum;
    int lag_frames, settled_frames, far_frames;
} tracking;

/* One frame at time t: its mean distance to the surface, and to the rest shape if the wings are far. */
static void measure_frame(const obj_mesh *seq, const bird_scene *s, const float *pos, size_t n, double t,
                          double most, const tri_grid *rest, int settled, tracking *out, double *v)
{
    surface_at(seq, s, t, v);
    tri_grid g;
    grid_build(&g, v, seq[0].nv, seq[0].tri, seq[0].nt);
    double d = mean_distance(&g, pos, n);
    grid_free(&g);
    out->lag_sum += d, out->lag_frames++;
    if (!settled) return;
    out->settled_sum += d, out->settled_frames++;
    if (max_displacement(&seq[0], v) < FAR_FROM_REST * most) return;
    out->far_sum += d, out->far_rest_sum += mean_distance(rest, pos, n), out->far_frames++;
}

/* The largest vertex displacement from mesh 0 over the loop (meshes and the midpoints between them). */
static double loop_displacement(const obj_mesh *seq, const bird_scene *s, double *v)
{
    double most = 0;
    for (int i = 0; i < 2 * s->frames; i++) {
        surface_at(seq, s, 0.5 * i / s->mesh_rate, v);
        most = fmax(most, max_displacement(&seq[0], v));
    }
    return most;
}

static void measure(const obj_mesh *seq, const bird_scene *s, fm_cache_reader *r, double path_time, double settle,
                    tracking *out)
{
    const size_t n = fm_cache_agents(r);
    float *pos = malloc(sizeof(float) * 3 * n);
    double *v = malloc(sizeof(double) * 3 * (size_t)seq[0].nv);
    double most = loop_displacement(seq, s, v);
    tri_grid rest;
    grid_build(&rest, seq[0].v, seq[0].nv, seq[0].tri, seq[0].nt);
    fm_error err = {0};
    for (uint32_t f = 0; f < fm_cache_frames(r); f++) {
        double t = f / fm_cache_frame_rate(r);
        if (t <= path_time) continue;
        ENSURE_MSG(fm_cache_read_attr(r, f, FM_ATTR_POSITION, pos, &err) == FM_OK, "%s", err.message);
        measure_frame(seq, s, pos, n, t, most, &rest, t >= path_time + settle, out, v);
    }
    printf("  wings: largest vertex displacement from the rest shape over the loop %.3f units\n", most);
    grid_free(&rest);
    free(pos), free(v);
}

static void check(const tracking *m, json_t *stats, double spacing)
{
    double lag = json_number_value(json_object_get(stats, "tracking_lag"));
    double surface = m->lag_sum / m->lag_frames, settled = m->settled_sum / m->settled_frames;
    double far = m->far_sum / m->far_frames, far_rest = m->far_rest_sum / m->far_frames;
    printf("  tracking frames %d: mean distance to the surface %.4f, stats.json tracking_lag %.4f\n", m->lag_frames, surface, lag);
    printf("  settled frames %d: mean distance %.4f (bound: half the spacing sqrt(area/n) = %.4f)\n", m->settled_frames,
           settled, 0.5 * spacing);
    printf("  wings far from rest, %d frames: %.4f to the deformed surface, %.4f to the rest shape (%.1f x)\n",
           m->far_frames, far, far_rest, far_rest / far);
    ENSURE_MSG(m->lag_frames == json_integer_value(json_object_get(stats, "tracking_frames")),
               "%d frames after path_time, stats.json says %lld", m->lag_frames,
               (long long)json_integer_value(json_object_get(stats, "tracking_frames")));
    ENSURE_MSG(surface <= lag + 1e-5, "mean distance to the surface %g above the tracking lag %g", surface, lag);
    ENSURE_MSG(m->settled_frames > 0 && settled < 0.5 * spacing, "settled mean distance %g", settled);
    ENSURE_MSG(m->far_frames > 0 && far_rest >= REST_RATIO * far, "rest %g against deformed %g", far_rest, far);
}

static void test_the_flock_tracks_the_flapping_bird(void)
{
    bird_scene s;
    if (!read_scene(&s)) return;
    obj_mesh *seq = read_sequence(&s);
    json_t *stats = seq ? run_example() : NULL;
    if (!stats) {
        free_sequence(seq, &s);
        return;
    }
    double path_time = json_number_value(json_object_get(json_object_get(stats, "shape_flock"), "leaders_end"));
    double spacing = sqrt(mesh_area(&seq[0]) / (double)json_integer_value(json_object_get(stats, "agents")));
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(OUT "/frames.fmc", &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (r) {
        tracking m = {0};
        measure(seq, &s, r, path_time, s.frames / s.mesh_rate, &m);
        check(&m, stats, spacing);
        fm_cache_close(r);
    }
    json_decref(stats);
    free_sequence(seq, &s);
}

int main(void)
{
    RUN_TEST(test_the_flock_tracks_the_flapping_bird);
    return test_result();
}
