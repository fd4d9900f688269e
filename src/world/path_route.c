/* The global detour (issue 38, beyond FM §5.3): eq 7 slides a tet along an obstacle but has no way
 * out of a concave pocket or a wall square to the flight. Two things, both made once at model
 * preparation, deterministically, on one coarse grid over the scene:
 *
 *   route  where the path (the straight line, or the user's curve) passes closer than the largest
 *          tet radius (the shape flock's R: k_a and a margin, flock_model.c) to an obstacle, that
 *          stretch is replaced by a shortest path (A*) around the obstacles inflated by that radius,
 *          which prefers a further k_a of clearance, pulled taut and corner-cut (Chaikin) while it
 *          stays clear; the rest of the path is the user's, bit for bit, and a path that nowhere
 *          comes that close is not touched at all;
 *   nav    a navigation function over the grid: u(x) = the shortest cost from x to C_T (Dijkstra
 *          from C_T alone; near and inside obstacles at a higher cost per length, along the clear
 *          stretches of the key-point polyline, the road, at half), and g(x), the cost onto the
 *          road. -grad u leads from anywhere round the obstacles onto the path and along it; it
 *          has no minimum but C_T (each node has a lower neighbour: its Dijkstra predecessor),
 *          also where the path itself runs into an obstacle (obstacles.route off, or no way round).
 *          The step sends a tet that made no progress in u for a while down -grad u until it is
 *          back on the path where the path leads on (kernel_detour.c). */
#include "fm_math.h"
#include "path_route.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Cost per unit length, by the obstacle distance d of a node: 1 in the clear, up to 1 + SOFT_COST
 * over the preferred clearance (r_infl .. r_infl + r_soft), NEAR_COST closer than r_infl (a tet that
 * close touches), INSIDE_COST inside. The route refuses inside and pays ROUTE_NEAR_COST near, so it
 * goes through a gap narrower than the tets only when there is no other way. */
#define SOFT_COST 3.0
#define NEAR_COST 20.0
#define INSIDE_COST 100.0
#define ROUTE_NEAR_COST 1000.0
/* The grid: at most NAV_CELLS_PER_AXIS cells along the longest side of the padded scene. */
#define NAV_CELLS_PER_AXIS 128
/* The road: the clear nodes of the key-point polyline cost this much of the rest, so the navigation
 * function leads onto the path and along it where the path is clear. */
#define ROAD_COST 0.5
/* Chaikin corner-cutting passes on the taut route. */
#define CHAIKIN_PASSES 3

/* ---------------------------------------------------------------- the grid */

typedef struct nav_grid {
    int32_t n[3];
    double origin[3], h;
    float *d;  /* obstacle distance at each node (the obstacles' grid, exact at its own nodes) */
} nav_grid;

static int64_t nodes_of(const nav_grid *g) { return (int64_t)g->n[0] * g->n[1] * g->n[2]; }

static void node_point(const nav_grid *g, int64_t i, double p[3])
{
    const int64_t x = i % g->n[0], y = i / g->n[0] % g->n[1], z = i / ((int64_t)g->n[0] * g->n[1]);
    p[0] = g->origin[0] + g->h * (double)x, p[1] = g->origin[1] + g->h * (double)y, p[2] = g->origin[2] + g->h * (double)z;
}

/* The node nearest p, clamped into the grid. */
static int64_t node_at(const nav_grid *g, const double p[3])
{
    int64_t c[3];
    for (int k = 0; k < 3; k++) {
        const double u = floor((p[k] - g->origin[k]) / g->h + 0.5);
        c[k] = u < 0 ? 0 : u > g->n[k] - 1 ? g->n[k] - 1 : (int64_t)u;
    }
    return c[0] + g->n[0] * (c[1] + g->n[1] * c[2]);
}

static double obstacle_distance(const fm_obstacles *o, const double p[3])
{
    fm_sdf_view v = fm_obstacles_sdf(o);
    return (double)fm_sdf_sample(&v, (float)p[0], (float)p[1], (float)p[2], NULL);
}

/* The padded box of lo..hi, NAV_CELLS_PER_AXIS cells along its longest side; d at every node. */
static fm_status grid_build(const double lo[3], const double hi[3], double pad, const fm_obstacles *o, nav_grid *g,
                            fm_error *err)
{
    double span = 0;
    for (int k = 0; k < 3; k++) span = fmax(span, hi[k] - lo[k] + 2 * pad);
    g->h = span / NAV_CELLS_PER_AXIS;
    for (int k = 0; k < 3; k++) {
        g->n[k] = (int32_t)ceil((hi[k] - lo[k] + 2 * pad) / g->h) + 1;
        g->origin[k] = lo[k] - pad;
    }
    g->d = fm_alloc(sizeof(float) * (size_t)nodes_of(g));
    if (!g->d) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the detour grid");
    for (int64_t i = 0; i < nodes_of(g); i++) {
        double p[3];
        node_point(g, i, p);
        g->d[i] = (float)obstacle_distance(o, p);
    }
    return FM_OK;
}

/* ---------------------------------------------------------------- Dijkstra / A* */

typedef struct heap_item {
    double key;
    int64_t node;
} heap_item;

typedef struct heap {
    heap_item *a;
    int64_t count, capacity;
} heap;

static int before(const heap_item *x, const heap_item *y) /* ties by node: deterministic */
{
    return x->key < y->key || (x->key == y->key && x->node < y->node);
}

static int heap_push(heap *h, double key, int64_t node)
{
    if (h->count == h->capacity) {
        int64_t cap = h->capacity ? 2 * h->capacity : 4096;
        heap_item *a = realloc(h->a, sizeof *a * (size_t)cap);
        if (!a) return -1;
        h->a = a, h->capacity = cap;
    }
    int64_t i = h->count++;
    h->a[i] = (heap_item){key, node};
    while (i > 0 && before(&h->a[i], &h->a[(i - 1) / 2])) {
        heap_item t = h->a[i];
        h->a[i] = h->a[(i - 1) / 2], h->a[(i - 1) / 2] = t, i = (i - 1) / 2;
    }
    return 0;
}

static heap_item heap_pop(heap *h)
{
    heap_item top = h->a[0];
    h->a[0] = h->a[--h->count];
    for (int64_t i = 0;;) {
        int64_t l = 2 * i + 1, r = l + 1, m = i;
        if (l < h->count && before(&h->a[l], &h->a[m])) m = l;
        if (r < h->count && before(&h->a[r], &h->a[m])) m = r;
        if (m == i) break;
        heap_item t = h->a[i];
        h->a[i] = h->a[m], h->a[m] = t, i = m;
    }
    return top;
}

typedef struct search {
    const nav_grid *g;
    const float *cost;  /* per node, per unit length; INFINITY: never entered */
    double *dist;       /* out: shortest cost from the sources */
    int64_t *from;      /* out (may be NULL): predecessor, -1 at a source */
    int64_t goal;       /* A*: stop there, heuristic the straight length to it; -1: every node */
} search;

/* Shortest costs over the 26-neighbour grid, an edge costing its length times the mean of its
 * ends' costs. Sources are already in dist (others INFINITY) and in the heap. */
static fm_status run_search(const search *s, heap *open, fm_error *err)
{
    const nav_grid *g = s->g;
    const int64_t sx = 1, sy = g->n[0], sz = (int64_t)g->n[0] * g->n[1];
    double goal_p[3] = {0, 0, 0};
    if (s->goal >= 0) node_point(g, s->goal, goal_p);
    while (open->count > 0) {
        const heap_item top = heap_pop(open);
        const int64_t i = top.node;
        double p[3];
        node_point(g, i, p);
        const double h_i = s->goal >= 0 ? sqrt((p[0] - goal_p[0]) * (p[0] - goal_p[0]) + (p[1] - goal_p[1]) * (p[1] - goal_p[1]) +
                                               (p[2] - goal_p[2]) * (p[2] - goal_p[2]))
                                        : 0;
        if (top.key > s->dist[i] + h_i) continue; /* a stale entry */
        if (i == s->goal) return FM_OK;
        const int64_t x = i % g->n[0], y = i / g->n[0] % g->n[1], z = i / sz;
        for (int dz = -1; dz <= 1; dz++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    if (!(dx | dy | dz) || x + dx < 0 || x + dx >= g->n[0] || y + dy < 0 || y + dy >= g->n[1] ||
                        z + dz < 0 || z + dz >= g->n[2])
                        continue;
                    const int64_t j = i + dx * sx + dy * sy + dz * sz;
                    if (!isfinite(s->cost[j])) continue;
                    const double len = g->h * sqrt((double)(dx * dx + dy * dy + dz * dz));
                    const double nd = s->dist[i] + len * 0.5 * ((double)s->cost[i] + (double)s->cost[j]);
                    if (!(nd < s->dist[j])) continue;
                    s->dist[j] = nd;
                    if (s->from) s->from[j] = i;
                    double q[3], hj = 0;
                    if (s->goal >= 0) {
                        node_point(g, j, q);
                        hj = sqrt((q[0] - goal_p[0]) * (q[0] - goal_p[0]) + (q[1] - goal_p[1]) * (q[1] - goal_p[1]) +
                                  (q[2] - goal_p[2]) * (q[2] - goal_p[2]));
                    }
                    if (heap_push(open, nd + hj, j) != 0) return fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
                }
    }
    return s->goal >= 0 ? FM_ERR_INPUT : FM_OK; /* the goal not reached: no way round */
}

/* ---------------------------------------------------------------- polylines */

typedef struct polyline {
    double *p;
    int64_t count, capacity;
} polyline;

static int poly_add(polyline *l, const double p[3])
{
    if (l->count == l->capacity) {
        int64_t cap = l->capacity ? 2 * l->capacity : 256;
        double *a = realloc(l->p, sizeof(double) * 3 * (size_t)cap);
        if (!a) return -1;
        l->p = a, l->capacity = cap;
    }
    memcpy(l->p + 3 * l->count++, p, 3 * sizeof(double));
    return 0;
}

static double dist3(const double *a, const double *b)
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* The point at arc length s along pts (n points, cumulative lengths at[]). */
static void point_at(const double *pts, const double *at, int64_t n, double s, double out[3])
{
    int64_t i = 0;
    while (i + 2 < n && at[i + 1] < s) i++;
    const double len = at[i + 1] - at[i], t = len > 0 ? fmin(fmax((s - at[i]) / len, 0), 1) : 0;
    for (int k = 0; k < 3; k++) out[k] = pts[3 * i + k] + t * (pts[3 * (i + 1) + k] - pts[3 * i + k]);
}

/* The smallest obstacle distance along segment a-b, sampled every `step`. */
static double segment_clearance(const fm_obstacles *o, const double a[3], const double b[3], double step)
{
    const double len = dist3(a, b);
    const int64_t samples = (int64_t)ceil(len / step) + 1;
    double least = INFINITY;
    for (int64_t i = 0; i <= samples; i++) {
        const double t = (double)i / (double)samples, p[3] = {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]),
                                                               a[2] + t * (b[2] - a[2])};
        least = fmin(least, obstacle_distance(o, p));
    }
    return least;
}

/* ---------------------------------------------------------------- the route */

static float route_cost(double d, const fm_path_route *r)
{
    if (d <= 0) return INFINITY;
    if (d < r->r_infl) return (float)ROUTE_NEAR_COST;
    const double u = (r->r_infl + r->r_soft - d) / r->r_soft;
    return (float)(u > 0 ? 1 + SOFT_COST * u * u : 1);
}

/* A* from a to b; the node path, taut and corner-cut, into out (a and b included). */
static fm_status route_between(const nav_grid *g, const fm_path_route *r, float *cost, const double a[3],
                               const double b[3], polyline *out, fm_error *err)
{
    const int64_t nodes = nodes_of(g), start = node_at(g, a), goal = node_at(g, b);
    double *dist = malloc(sizeof(double) * (size_t)nodes);
    int64_t *from = malloc(sizeof(int64_t) * (size_t)nodes);
    heap open = {0};
    polyline raw = {0};
    fm_status st = dist && from ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    if (st == FM_OK) {
        for (int64_t i = 0; i < nodes; i++) dist[i] = INFINITY, from[i] = -1;
        dist[start] = 0;
        st = heap_push(&open, 0, start) ? fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path") : FM_OK;
    }
    float *c = cost; /* the ends may lie where the route would not go */
    const float start_cost = cost[start], goal_cost = cost[goal];
    if (st == FM_OK) {
        c[start] = fminf(c[start], (float)ROUTE_NEAR_COST), c[goal] = fminf(c[goal], (float)ROUTE_NEAR_COST);
        st = run_search(&(search){g, cost, dist, from, goal}, &open, err);
        c[start] = start_cost, c[goal] = goal_cost;
    }
    /* the node path, goal to start, reversed; a and b themselves at the ends */
    if (st == FM_OK && poly_add(&raw, b)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    for (int64_t i = from[goal]; st == FM_OK && i >= 0 && i != start; i = from[i]) {
        double p[3];
        node_point(g, i, p);
        if (poly_add(&raw, p)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    }
    if (st == FM_OK && poly_add(&raw, a)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    for (int64_t i = 0; st == FM_OK && i < raw.count / 2; i++)
        for (int k = 0; k < 3; k++) {
            double t = raw.p[3 * i + k];
            raw.p[3 * i + k] = raw.p[3 * (raw.count - 1 - i) + k], raw.p[3 * (raw.count - 1 - i) + k] = t;
        }
    /* Taut: from each kept point, the farthest later point in straight sight, a sight line being
       one that comes no nearer the obstacles than the node path did between them (or than the
       preferred clearance), so pulling keeps the clearance A* chose. */
    const double step = 0.25 * g->h, want = r->r_infl + r->r_soft;
    polyline taut = {0};
    if (st == FM_OK && poly_add(&taut, raw.p)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    for (int64_t k = 0; st == FM_OK && k + 1 < raw.count;) {
        int64_t best = k + 1;
        double least = obstacle_distance(r->obstacles, raw.p + 3 * (k + 1));
        for (int64_t j = k + 2; j < raw.count; j++) {
            least = fmin(least, obstacle_distance(r->obstacles, raw.p + 3 * j));
            if (segment_clearance(r->obstacles, raw.p + 3 * k, raw.p + 3 * j, step) >= fmin(want, least) - 1e-9) best = j;
        }
        if (poly_add(&taut, raw.p + 3 * best)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
        k = best;
    }
    /* Chaikin: each pass replaces every inner corner by two points a quarter along its edges; a
       pass is kept only while every new edge stays clear of the inflated obstacles. */
    for (int pass = 0; st == FM_OK && pass < CHAIKIN_PASSES && taut.count > 2; pass++) {
        polyline cut = {0};
        int ok = !poly_add(&cut, taut.p);
        for (int64_t i = 0; ok && i + 1 < taut.count; i++) {
            const double *p = taut.p + 3 * i, *q = taut.p + 3 * (i + 1);
            double x[3], y[3];
            for (int k = 0; k < 3; k++) x[k] = 0.75 * p[k] + 0.25 * q[k], y[k] = 0.25 * p[k] + 0.75 * q[k];
            if (i > 0) ok = ok && !poly_add(&cut, x);
            if (i + 2 < taut.count) ok = ok && !poly_add(&cut, y);
        }
        ok = ok && !poly_add(&cut, taut.p + 3 * (taut.count - 1));
        if (!ok) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
        int clear = ok;
        for (int64_t i = 1; clear && i + 2 < cut.count; i++) /* the end edges join the user's path */
            clear = segment_clearance(r->obstacles, cut.p + 3 * i, cut.p + 3 * (i + 1), step) >= r->r_infl;
        if (clear) free(taut.p), taut = cut;
        else free(cut.p);
        if (!clear) break;
    }
    for (int64_t i = 0; st == FM_OK && i < taut.count; i++)
        if (poly_add(out, taut.p + 3 * i)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    free(taut.p), free(raw.p), free(open.a), free(dist), free(from);
    return st;
}

/* The obstacle meshes whose boxes, grown by the clearance, overlap (directly or through others)
 * form one obstacle to go round: the box of each mesh's group, into lo[i], hi[i]. */
static void grouped_boxes(const fm_path_route *r, double lo[][3], double hi[][3])
{
    const double grow = r->r_infl + r->r_soft;
    for (int i = 0; i < r->meshes; i++)
        for (int k = 0; k < 3; k++) lo[i][k] = r->mesh_lo[i][k] - grow, hi[i][k] = r->mesh_hi[i][k] + grow;
    for (int merged = 1; merged;) { /* grow each box by every box it overlaps until none changes */
        merged = 0;
        for (int i = 0; i < r->meshes; i++)
            for (int j = 0; j < r->meshes; j++) {
                int overlap = 1, inside = 1;
                for (int k = 0; k < 3; k++) {
                    overlap = overlap && lo[i][k] <= hi[j][k] && lo[j][k] <= hi[i][k];
                    inside = inside && lo[i][k] <= lo[j][k] && hi[j][k] <= hi[i][k];
                }
                if (!overlap || inside) continue;
                for (int k = 0; k < 3; k++) lo[i][k] = fmin(lo[i][k], lo[j][k]), hi[i][k] = fmax(hi[i][k], hi[j][k]);
                merged = 1;
            }
    }
}

static int in_box(const double p[3], const double lo[3], const double hi[3])
{
    return p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1] && p[2] >= lo[2] && p[2] <= hi[2];
}

/* The stretches of the dense path closer than r_infl to an obstacle, as arc-length intervals, each
 * widened to where the path enters and leaves the box of the obstacle group it meets (so the way
 * round starts before a concave pocket, not inside it), by at least r_soft and two cells, and
 * merged where they then overlap; into from[], to[]. Returns their count (at most `most`). */
static int blocked_stretches(const fm_path_route *r, const double *pts, const double *at, int64_t n, double h,
                             double *from, double *to, int most)
{
    const double total = at[n - 1], step = 0.25 * h;
    const int64_t samples = (int64_t)ceil(total / step);
    double lo[FM_MAX_OBSTACLES][3], hi[FM_MAX_OBSTACLES][3];
    grouped_boxes(r, lo, hi);
    int count = 0;
    int64_t in = -1;
    unsigned hit = 0; /* the groups (by a member mesh) the blocked samples lie in */
    for (int64_t i = 0; i <= samples; i++) {
        double p[3];
        point_at(pts, at, n, total * (double)i / (double)samples, p);
        const int blocked = obstacle_distance(r->obstacles, p) < r->r_infl;
        if (blocked) {
            if (in < 0) in = i, hit = 0;
            for (int j = 0; j < r->meshes; j++) hit |= (unsigned)in_box(p, lo[j], hi[j]) << j;
        }
        if ((blocked && i < samples) || in < 0) continue;
        int64_t a = in, b = i; /* out to the edges of the groups' boxes */
        for (int moved = 1; moved;) {
            moved = 0;
            double q[3];
            for (int j = 0; j < r->meshes; j++) {
                if (!(hit >> j & 1)) continue;
                while (a > 0 && (point_at(pts, at, n, total * (double)(a - 1) / (double)samples, q), in_box(q, lo[j], hi[j])))
                    a--, moved = 1;
                while (b < samples && (point_at(pts, at, n, total * (double)(b + 1) / (double)samples, q), in_box(q, lo[j], hi[j])))
                    b++, moved = 1;
            }
        }
        const double s_in = total * (double)in / (double)samples, s_out = total * (double)i / (double)samples;
        const double back = r->r_soft + 2 * h;
        const double sa = fmax(fmin(total * (double)a / (double)samples, s_in - back), 0);
        const double sb = fmin(fmax(total * (double)b / (double)samples, s_out + back), total);
        if (count > 0 && sa <= to[count - 1]) to[count - 1] = fmax(to[count - 1], sb);
        else if (count < most) from[count] = sa, to[count] = sb, count++;
        in = -1;
    }
    return count;
}

/* Pads the scene box (the dense path and the obstacles) so that a route round an obstacle at its
 * edge fits: by the obstacles' largest side plus the clearance. */
static void scene_box(const fm_path_route *r, const double *pts, int64_t n, double lo[3], double hi[3], double *pad)
{
    for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    fm_grow_bounds(lo, hi, pts, n);
    fm_grow_bounds(lo, hi, r->lo, 1);
    fm_grow_bounds(lo, hi, r->hi, 1);
    double side = 0;
    for (int k = 0; k < 3; k++) side = fmax(side, r->obstacle_hi[k] - r->obstacle_lo[k]);
    fm_grow_bounds(lo, hi, r->obstacle_lo, 1);
    fm_grow_bounds(lo, hi, r->obstacle_hi, 1);
    *pad = 0.5 * side + 2 * (r->r_infl + r->r_soft);
}

fm_status fm_path_route_dense(fm_path_route *r, double **pts, int64_t *n, fm_error *err)
{
    r->routed = 0;
    const int64_t count = *n;
    double *at = malloc(sizeof(double) * (size_t)count);
    if (!at) return fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    at[0] = 0;
    for (int64_t i = 1; i < count; i++) at[i] = at[i - 1] + dist3(*pts + 3 * (i - 1), *pts + 3 * i);
    double lo[3], hi[3], pad;
    scene_box(r, *pts, count, lo, hi, &pad);
    nav_grid g = {0};
    fm_status st = grid_build(lo, hi, pad, r->obstacles, &g, err);
    enum { MOST = 64 };
    double from[MOST], to[MOST];
    const int stretches = st == FM_OK ? blocked_stretches(r, *pts, at, count, g.h, from, to, MOST) : 0;
    float *cost = stretches ? malloc(sizeof(float) * (size_t)nodes_of(&g)) : NULL;
    if (stretches && !cost) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    for (int64_t i = 0; cost && i < nodes_of(&g); i++) cost[i] = route_cost(g.d[i], r);
    polyline out = {0};
    int64_t next = 0; /* the first dense point not yet copied */
    for (int s = 0; st == FM_OK && s < stretches; s++) {
        double a[3], b[3];
        point_at(*pts, at, count, from[s], a);
        point_at(*pts, at, count, to[s], b);
        for (; next < count && at[next] < from[s]; next++)
            if (poly_add(&out, *pts + 3 * next)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
        if (st == FM_OK) st = route_between(&g, r, cost, a, b, &out, err);
        if (st == FM_ERR_INPUT) { /* no way round: keep the user's path there, and say so */
            r->unroutable++;
            for (int64_t j = next; j < count && at[j] <= to[s]; j++, next++)
                if (poly_add(&out, *pts + 3 * j)) return fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
            st = FM_OK;
            continue;
        }
        r->routed++;
        while (next < count && at[next] <= to[s]) next++;
    }
    for (; st == FM_OK && stretches && next < count; next++)
        if (poly_add(&out, *pts + 3 * next)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory routing the path");
    if (st == FM_OK && r->routed) {
        free(*pts);
        *pts = out.p, *n = out.count;
        out.p = NULL;
    }
    free(out.p), free(cost), free(at), fm_free(g.d);
    return st;
}

/* ---------------------------------------------------------------- the navigation function */

static float nav_cost(double d, double r_infl, double r_soft)
{
    if (d <= 0) return (float)INSIDE_COST;
    if (d < r_infl) return (float)NEAR_COST;
    const double u = (r_infl + r_soft - d) / r_soft;
    return (float)(u > 0 ? 1 + SOFT_COST * u * u : 1);
}

fm_status fm_nav_build(const fm_path_route *r, const double *q, int32_t keys, fm_nav *nav, fm_error *err)
{
    memset(nav, 0, sizeof *nav);
    double lo[3], hi[3], pad;
    scene_box(r, q, keys, lo, hi, &pad);
    nav_grid g = {0};
    fm_status st = grid_build(lo, hi, pad, r->obstacles, &g, err);
    if (st != FM_OK) return st;
    const int64_t nodes = nodes_of(&g);
    float *cost = malloc(sizeof(float) * (size_t)nodes), *road = malloc(sizeof(float) * (size_t)nodes);
    double *dist = malloc(sizeof(double) * (size_t)nodes);
    nav->u = fm_alloc(sizeof(float) * (size_t)nodes), nav->g = fm_alloc(sizeof(float) * (size_t)nodes);
    heap open = {0};
    if (!cost || !road || !dist || !nav->u || !nav->g) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for the detour grid");
    for (int64_t i = 0; st == FM_OK && i < nodes; i++) cost[i] = road[i] = nav_cost(g.d[i], r->r_infl, r->r_soft);
    /* the road: the nodes of the key-point polyline (every half cell) that are clear of the
       inflated obstacles, at ROAD_COST of the cost; where the path crosses an obstacle it has none */
    for (int32_t i = 0; st == FM_OK && i + 1 < keys; i++) {
        const int64_t samples = (int64_t)ceil(dist3(q + 3 * i, q + 3 * (i + 1)) / (0.5 * g.h)) + 1;
        for (int64_t k = 0; k <= samples; k++) {
            const double t = (double)k / (double)samples, p[3] = {q[3 * i] + t * (q[3 * i + 3] - q[3 * i]),
                                                                   q[3 * i + 1] + t * (q[3 * i + 4] - q[3 * i + 1]),
                                                                   q[3 * i + 2] + t * (q[3 * i + 5] - q[3 * i + 2])};
            const int64_t j = node_at(&g, p);
            if (g.d[j] >= r->r_infl) road[j] = (float)ROAD_COST * cost[j];
        }
    }
    /* u: from C_T alone, so every node but C_T's has a lower neighbour */
    for (int64_t i = 0; st == FM_OK && i < nodes; i++) dist[i] = INFINITY;
    const int64_t goal = node_at(&g, q + 3 * (keys - 1));
    if (st == FM_OK) {
        dist[goal] = 0;
        if (heap_push(&open, 0, goal)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for the detour grid");
    }
    if (st == FM_OK) st = run_search(&(search){&g, road, dist, NULL, -1}, &open, err);
    for (int64_t i = 0; st == FM_OK && i < nodes; i++) nav->u[i] = (float)dist[i];
    /* g: the way onto the road */
    for (int64_t i = 0; st == FM_OK && i < nodes; i++) {
        dist[i] = road[i] < cost[i] ? 0 : INFINITY;
        if (dist[i] == 0 && heap_push(&open, 0, i)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for the detour grid");
    }
    if (st == FM_OK) st = run_search(&(search){&g, cost, dist, NULL, -1}, &open, err);
    for (int64_t i = 0; st == FM_OK && i < nodes; i++) nav->g[i] = (float)fmin(dist[i], 1e30);
    if (st == FM_OK) {
        for (int k = 0; k < 3; k++) nav->n[k] = g.n[k], nav->origin[k] = (float)g.origin[k];
        nav->h = (float)g.h;
    } else {
        fm_free(nav->u), fm_free(nav->g), nav->u = nav->g = NULL;
    }
    free(cost), free(road), free(dist), free(open.a), fm_free(g.d);
    return st;
}

/* What the routed path is made from (fm_route_key), zeroed first so that it compares byte for byte. */
void fm_route_key_of(const fm_scene_def *def, const double cs[3], const double ct[3], const fm_path_route *r,
                     fm_route_key *key)
{
    memset(key, 0, sizeof *key);
    memcpy(key->cs, cs, sizeof key->cs), memcpy(key->ct, ct, sizeof key->ct);
    memcpy(&key->route, r, sizeof key->route);
    key->route.obstacles = NULL, key->route.routed = key->route.unroutable = 0;
    key->curve = (int32_t)def->path_curve, key->key_points = def->path_key_points;
    key->point_count = def->path_point_count;
    memcpy(key->points, def->path_points, sizeof(double) * 3 * (size_t)def->path_point_count);
}
