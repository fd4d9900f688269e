/* Stratified point sampling (SCF §3, after Nehab & Shilane, "Stratified point sampling of 3D
 * models", SPBG 2004).
 *
 * 1. Voxelize the surface with an octree: a root cube around the mesh is split into 8 children
 *    down to leaves of edge h, keeping only children that a triangle overlaps (exact
 *    triangle-box test, Akenine-Moller 2001); each occupied leaf knows its triangles.
 * 2. One sample per occupied leaf. Each of its triangles is subdivided (1 to 4, at the edge
 *    midpoints) until the density lambda e^(-lambda d) can be considered constant on a piece:
 *    pieces are cut until their longest edge is at most h / max(2, 2 lambda), so the density
 *    varies by at most a factor e^(1/2) across one. Pieces wholly outside the voxel's box are
 *    dropped. (The pieces of one level are the cells of a regular grid in barycentric
 *    coordinates, so the terminal ones near the voxel are read off that grid directly; only
 *    slivers, whose barycentric coordinates bound the voxel poorly, are split level by level.) A terminal piece whose centroid lies in the voxel has the priority
 *    f(d) x area, d = |centroid - voxel centre| in voxel edges; one piece is drawn with
 *    probability proportional to its priority, then a uniform point on it. (If no centroid falls
 *    in the voxel, a sliver of a triangle grazing it, the piece whose centroid is nearest the
 *    centre is used, so every occupied leaf gives exactly one candidate.)
 * 3. Minimum-distance elimination (the paper: "we eliminate those sample points that are too
 *    close to each other"): while more than N candidates are left, the closest pair is found and
 *    the one of the two that is more crowded (nearer its next neighbour) is removed. That always
 *    stops at exactly N, and removes the tightest spots first.
 *
 * How N is reached: the number of occupied leaves falls as h grows (about as 1/h^2), so h is
 * searched (a few counting passes of the octree, no sampling) until the leaves number between
 * oversample x N and 1.1 x that; step 3 then brings them to exactly N. The root cube is h 2^L for
 * the smallest depth L that covers the mesh with a voxel to spare, offset by an irrational
 * fraction of h so that axis-aligned faces do not lie on voxel planes.
 *
 * Determinism: the octree is expanded breadth-first on one thread until there are enough nodes,
 * the subtrees are then processed on threads and their candidates concatenated in node order;
 * each leaf draws its random numbers from its own coordinates. Step 3 runs on one thread. */
#include "sample.h"

#include "grid.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { STREAM_PICK = 11, STREAM_U = 12, STREAM_V = 13 };
enum { MAX_DEPTH = 21, MAX_PIECE_LEVELS = 40, TASK_NODES = 64 };

typedef struct strat {
    const fm_sample_ctx *c;
    double origin[3];  /* root cube's lower corner */
    double h;          /* leaf edge */
    int depth;         /* L: leaves are at this level */
    double piece_edge; /* terminal pieces' longest edge */
} strat;

/* Candidates: a point and its triangle; growable (one task's output, or all of them). */
typedef struct cand {
    double x[3];
    int32_t tri;
} cand;

typedef struct cands {
    cand *a;
    int64_t n, cap;
} cands;

/* A piece of a triangle: its 3 corners, in space and as barycentric (u, v) (b = (1 - u - v, u, v)). */
typedef struct piece {
    double p[3][3];
    double uv[3][2];
    int level;
} piece;

typedef struct choice {
    double priority;
    int32_t tri;
    double uv[3][2];
} choice;

/* Per-task scratch. */
typedef struct task {
    int32_t *lists[MAX_DEPTH + 2]; /* triangle list per level below the task's root */
    int64_t list_cap;
    piece *stack;
    int64_t stack_cap;
    choice *ch;
    int64_t ch_n, ch_cap;
    cands out;
    int64_t count;                 /* leaves seen (counting pass) */
    int failed;                    /* out of memory */
} task;

static int grow(void **p, int64_t *cap, int64_t need, size_t size)
{
    if (need <= *cap) return 1;
    int64_t c = *cap ? *cap : 64;
    while (c < need) c *= 2;
    void *q = realloc(*p, size * (size_t)c);
    if (!q) return 0;
    *p = q, *cap = c;
    return 1;
}

/* ------------------------------------------------------------------ triangle-box overlap */

/* (libm's fmin and fmax are calls; these are not, and no NaN reaches them) */
static inline double min3(double a, double b, double c)
{
    double m = a < b ? a : b;
    return m < c ? m : c;
}
static inline double max3(double a, double b, double c)
{
    double m = a > b ? a : b;
    return m > c ? m : c;
}

/* Does the triangle a, b, c (relative to the box centre) overlap the cube of half-edge r? The
   separating axis test of Akenine-Moller ("Fast 3D triangle-box overlap testing", 2001): the 3
   box axes, the triangle's normal, and the 9 cross products of box axes and triangle edges.
   Touching counts as overlapping. */
static int tri_box_overlap(const double v[3][3], double r)
{
    for (int k = 0; k < 3; k++) {
        double lo = min3(v[0][k], v[1][k], v[2][k]), hi = max3(v[0][k], v[1][k], v[2][k]);
        if (lo > r || hi < -r) return 0;
    }
    double e[3][3];
    for (int k = 0; k < 3; k++) e[0][k] = v[1][k] - v[0][k], e[1][k] = v[2][k] - v[1][k], e[2][k] = v[0][k] - v[2][k];
    double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                   e[0][0] * e[1][1] - e[0][1] * e[1][0]};
    double d = n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2];
    if (fabs(d) > r * (fabs(n[0]) + fabs(n[1]) + fabs(n[2]))) return 0;
    for (int j = 0; j < 3; j++)
        for (int k = 0; k < 3; k++) { /* axis = unit_k x e_j */
            double ax[3] = {0, 0, 0};
            int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
            ax[k1] = -e[j][k2], ax[k2] = e[j][k1];
            double p0 = ax[0] * v[0][0] + ax[1] * v[0][1] + ax[2] * v[0][2];
            double p1 = ax[0] * v[1][0] + ax[1] * v[1][1] + ax[2] * v[1][2];
            double p2 = ax[0] * v[2][0] + ax[1] * v[2][1] + ax[2] * v[2][2];
            double rad = r * (fabs(ax[0]) + fabs(ax[1]) + fabs(ax[2]));
            if (min3(p0, p1, p2) > rad || max3(p0, p1, p2) < -rad) return 0;
        }
    return 1;
}

static int triangle_overlaps(const fm_mesh *m, int32_t t, const double centre[3], double r)
{
    double v[3][3];
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < 3; k++) v[c][k] = m->v[3 * (int64_t)m->tri[3 * (int64_t)t + c] + k] - centre[k];
    return tri_box_overlap(v, r);
}

/* ------------------------------------------------------------------ one leaf's sample */

static void piece_point(const fm_mesh *m, int32_t t, const double uv[2], double x[3])
{
    const int32_t *f = m->tri + 3 * (int64_t)t;
    double b[3] = {1 - uv[0] - uv[1], uv[0], uv[1]};
    for (int k = 0; k < 3; k++)
        x[k] = b[0] * m->v[3 * (int64_t)f[0] + k] + b[1] * m->v[3 * (int64_t)f[1] + k] + b[2] * m->v[3 * (int64_t)f[2] + k];
}

static double piece_area(const double p[3][3])
{
    double u[3], w[3];
    for (int k = 0; k < 3; k++) u[k] = p[1][k] - p[0][k], w[k] = p[2][k] - p[0][k];
    double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    return 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

static double longest_edge2(const double p[3][3])
{
    double best = 0;
    for (int e = 0; e < 3; e++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (p[(e + 1) % 3][k] - p[e][k]) * (p[(e + 1) % 3][k] - p[e][k]);
        best = d2 > best ? d2 : best;
    }
    return best;
}

/* The 4 children of a piece (corners a, b, c; midpoints ab, bc, ca), in space and in (u, v). */
static void split_piece(const piece *pc, piece out[4])
{
    double mid[3][3], muv[3][2];
    for (int e = 0; e < 3; e++) {
        for (int k = 0; k < 3; k++) mid[e][k] = 0.5 * (pc->p[e][k] + pc->p[(e + 1) % 3][k]);
        for (int k = 0; k < 2; k++) muv[e][k] = 0.5 * (pc->uv[e][k] + pc->uv[(e + 1) % 3][k]);
    }
    /* corners of each child: 0..2 the parent's corners, 3..5 the midpoints ab, bc, ca */
    static const int corner[4][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}, {3, 4, 5}};
    for (int q = 0; q < 4; q++) {
        for (int c = 0; c < 3; c++) {
            int j = corner[q][c];
            const double *x = j < 3 ? pc->p[j] : mid[j - 3], *uv = j < 3 ? pc->uv[j] : muv[j - 3];
            for (int k = 0; k < 3; k++) out[q].p[c][k] = x[k];
            out[q].uv[c][0] = uv[0], out[q].uv[c][1] = uv[1];
        }
        out[q].level = pc->level + 1;
    }
}

static int inside_box(const double x[3], const double lo[3], double h)
{
    return x[0] >= lo[0] && x[0] < lo[0] + h && x[1] >= lo[1] && x[1] < lo[1] + h && x[2] >= lo[2] && x[2] < lo[2] + h;
}

static int piece_outside(const piece *pc, const double lo[3], double h)
{
    int outside = 0;
    for (int k = 0; k < 3; k++)
        outside |= max3(pc->p[0][k], pc->p[1][k], pc->p[2][k]) < lo[k] || min3(pc->p[0][k], pc->p[1][k], pc->p[2][k]) > lo[k] + h;
    return outside;
}

/* Adds a terminal piece of triangle t meeting the voxel [lo, lo + h) to the leaf's choices: its
   priority f(d) x area, or, when its centroid is outside the voxel, minus its distance (so the
   nearest can stand in if no centroid is inside). 0 on out of memory. */
static int add_choice(const strat *s, task *tk, int32_t t, const piece *pc, const double lo[3])
{
    const double h = s->h, lambda = s->c->opts.lambda;
    double g[3], d2 = 0;
    for (int k = 0; k < 3; k++) {
        g[k] = (pc->p[0][k] + pc->p[1][k] + pc->p[2][k]) / 3.0;
        d2 += (g[k] - lo[k] - 0.5 * h) * (g[k] - lo[k] - 0.5 * h);
    }
    if (!grow((void **)&tk->ch, &tk->ch_cap, tk->ch_n + 1, sizeof(choice))) return 0;
    choice *ch = &tk->ch[tk->ch_n++];
    double d = sqrt(d2) / h; /* in voxel edges */
    ch->priority = inside_box(g, lo, h) ? lambda * exp(-lambda * d) * piece_area(pc->p) : -d;
    ch->tri = t;
    memcpy(ch->uv, pc->uv, sizeof ch->uv);
    return 1;
}

/* The general way: split from the whole triangle down, dropping pieces outside the voxel. */
static void collect_by_splitting(const strat *s, task *tk, int32_t t, const double lo[3])
{
    const double edge2 = s->piece_edge * s->piece_edge;
    int64_t top = 0;
    piece *root = &tk->stack[top++];
    *root = (piece){.uv = {{0, 0}, {1, 0}, {0, 1}}, .level = 0};
    for (int c = 0; c < 3; c++) piece_point(s->c->mesh, t, root->uv[c], root->p[c]);
    while (top > 0) {
        piece pc = tk->stack[--top];
        if (piece_outside(&pc, lo, s->h)) continue;
        if (longest_edge2(pc.p) > edge2 && pc.level < MAX_PIECE_LEVELS) {
            if (!grow((void **)&tk->stack, &tk->stack_cap, top + 4, sizeof(piece))) {
                tk->failed = 1;
                return;
            }
            split_piece(&pc, tk->stack + top);
            top += 4;
        } else if (!add_choice(s, tk, t, &pc, lo)) {
            tk->failed = 1;
            return;
        }
    }
}

/* The pieces at level L are the cells of a regular grid in (u, v) with spacing 2^-L (up
   triangles (i, j), (i+1, j), (i, j+1) and down triangles (i+1, j), (i+1, j+1), (i, j+1)), and all
   have the same shape. The shortcut: find the terminal level, bound (u, v) over the voxel (an affine
   function of position, so its extremes over the box are at the box's corners), and visit only
   those cells. Same pieces as splitting, without the descent. 0 if the triangle is too thin for
   the bound to help (then split). */
static int collect_from_grid(const strat *s, task *tk, int32_t t, const double lo[3])
{
    piece whole = {.uv = {{0, 0}, {1, 0}, {0, 1}}, .level = 0};
    for (int c = 0; c < 3; c++) piece_point(s->c->mesh, t, whole.uv[c], whole.p[c]);
    double e1[3], e2[3], d00 = 0, d01 = 0, d11 = 0;
    for (int k = 0; k < 3; k++) {
        e1[k] = whole.p[1][k] - whole.p[0][k], e2[k] = whole.p[2][k] - whole.p[0][k];
        d00 += e1[k] * e1[k], d01 += e1[k] * e2[k], d11 += e2[k] * e2[k];
    }
    const double det = d00 * d11 - d01 * d01;
    if (!(det > 1e-6 * d00 * d11)) return 0;
    double umin = INFINITY, umax = -INFINITY, vmin = INFINITY, vmax = -INFINITY;
    for (int c = 0; c < 8; c++) {
        double a = 0, b = 0;
        for (int k = 0; k < 3; k++) {
            double r = lo[k] + (c >> k & 1 ? s->h : 0.0) - whole.p[0][k];
            a += e1[k] * r, b += e2[k] * r;
        }
        double u = (d11 * a - d01 * b) / det, v = (d00 * b - d01 * a) / det;
        umin = u < umin ? u : umin, umax = u > umax ? u : umax, vmin = v < vmin ? v : vmin, vmax = v > vmax ? v : vmax;
    }
    int level = 0;
    for (double e = sqrt(longest_edge2(whole.p)); e > s->piece_edge && level < MAX_PIECE_LEVELS; e *= 0.5) level++;
    const int64_t n = INT64_C(1) << level;
    const double fn = (double)n;
    int64_t i0 = (int64_t)floor(fmax(umin, 0.0) * fn), i1 = (int64_t)floor(fmin(umax, 1.0) * fn);
    int64_t j0 = (int64_t)floor(fmax(vmin, 0.0) * fn), j1 = (int64_t)floor(fmin(vmax, 1.0) * fn);
    i1 = i1 < n - 1 ? i1 : n - 1, j1 = j1 < n - 1 ? j1 : n - 1;
    if (i1 < i0 || j1 < j0) return 1; /* the voxel's (u, v) misses the triangle */
    if ((i1 - i0 + 1) * (j1 - j0 + 1) > 4096) return 0;
    piece pc;
    pc.level = level;
    for (int64_t i = i0; i <= i1; i++)
        for (int64_t j = j0; j <= j1 && i + j <= n - 1; j++)
            for (int down = 0; down < 2 && i + j + down <= n - 1; down++) {
                /* grid nodes of the piece: up (i, j), (i+1, j), (i, j+1); down (i+1, j), (i+1, j+1), (i, j+1) */
                const int64_t ni[3] = {i + down, i + 1, i}, nj[3] = {j, j + down, j + 1};
                for (int c = 0; c < 3; c++) {
                    const double u = (double)ni[c] / fn, v = (double)nj[c] / fn;
                    pc.uv[c][0] = u, pc.uv[c][1] = v;
                    for (int k = 0; k < 3; k++) pc.p[c][k] = whole.p[0][k] + u * e1[k] + v * e2[k];
                }
                if (piece_outside(&pc, lo, s->h)) continue;
                if (!add_choice(s, tk, t, &pc, lo)) {
                    tk->failed = 1;
                    return 1;
                }
            }
    return 1;
}

/* Appends triangle t's terminal pieces that meet the voxel [lo, lo + h) to tk->ch. */
static void collect_pieces(const strat *s, task *tk, int32_t t, const double lo[3])
{
    if (!collect_from_grid(s, tk, t, lo)) collect_by_splitting(s, tk, t, lo);
}

/* The leaf's candidate: a piece drawn by priority, then a uniform point on it. */
static void leaf_sample(const strat *s, task *tk, const int64_t ijk[3], const int32_t *list, int64_t count)
{
    const double lo[3] = {s->origin[0] + s->h * (double)ijk[0], s->origin[1] + s->h * (double)ijk[1],
                          s->origin[2] + s->h * (double)ijk[2]};
    tk->ch_n = 0;
    for (int64_t i = 0; i < count && !tk->failed; i++) collect_pieces(s, tk, list[i], lo);
    if (tk->failed) return;
    if (tk->ch_n == 0) { /* rounding between the exact box test and the pieces' boxes: the whole first triangle */
        if (!grow((void **)&tk->ch, &tk->ch_cap, 1, sizeof(choice))) {
            tk->failed = 1;
            return;
        }
        tk->ch[tk->ch_n++] = (choice){-1.0, list[0], {{0, 0}, {1, 0}, {0, 1}}};
    }
    const uint64_t key = (uint64_t)ijk[0] | (uint64_t)ijk[1] << 21 | (uint64_t)ijk[2] << 42, seed = s->c->opts.seed;
    double total = 0;
    int64_t nearest = 0;
    for (int64_t i = 0; i < tk->ch_n; i++) {
        if (tk->ch[i].priority > 0) total += tk->ch[i].priority;
        else if (tk->ch[nearest].priority <= 0 && -tk->ch[i].priority < -tk->ch[nearest].priority) nearest = i;
    }
    int64_t pick = nearest;
    if (total > 0) {
        double target = fm_random_unit(seed, STREAM_PICK, key) * total, run = 0;
        pick = -1;
        for (int64_t i = 0; i < tk->ch_n; i++) {
            if (!(tk->ch[i].priority > 0)) continue;
            run += tk->ch[i].priority, pick = i;
            if (run > target) break;
        }
    }
    const choice *ch = &tk->ch[pick];
    double r = sqrt(fm_random_unit(seed, STREAM_U, key)), v = fm_random_unit(seed, STREAM_V, key);
    double w[3] = {1 - r, r * (1 - v), r * v}, uv[2];
    for (int k = 0; k < 2; k++) uv[k] = w[0] * ch->uv[0][k] + w[1] * ch->uv[1][k] + w[2] * ch->uv[2][k];
    cands *o = &tk->out;
    if (!grow((void **)&o->a, &o->cap, o->n + 1, sizeof(cand))) {
        tk->failed = 1;
        return;
    }
    piece_point(s->c->mesh, ch->tri, uv, o->a[o->n].x);
    o->a[o->n++].tri = ch->tri;
}

/* ------------------------------------------------------------------ the octree */

static double node_edge(const strat *s, int level) { return s->h * (double)(INT64_C(1) << (s->depth - level)); }

/* The triangles of list overlapping child (2i + d) of a node at level - 1, into out; returns how many. */
static int64_t child_triangles(const strat *s, int level, const int64_t ijk[3], const int32_t *list, int64_t count,
                               int32_t *out)
{
    const double e = node_edge(s, level);
    double centre[3];
    for (int k = 0; k < 3; k++) centre[k] = s->origin[k] + e * ((double)ijk[k] + 0.5);
    int64_t m = 0;
    for (int64_t i = 0; i < count; i++)
        if (triangle_overlaps(s->c->mesh, list[i], centre, 0.5 * e)) out[m++] = list[i];
    return m;
}

/* Depth first below a node: counts the leaves, or samples them when sample is set. */
static void descend(const strat *s, task *tk, int level, const int64_t ijk[3], const int32_t *list, int64_t count,
                    int sample)
{
    if (level == s->depth) {
        tk->count++;
        if (sample) leaf_sample(s, tk, ijk, list, count);
        return;
    }
    int32_t *child = tk->lists[level + 1];
    for (int c = 0; c < 8 && !tk->failed; c++) {
        int64_t cijk[3] = {2 * ijk[0] + (c & 1), 2 * ijk[1] + (c >> 1 & 1), 2 * ijk[2] + (c >> 2 & 1)};
        int64_t m = child_triangles(s, level + 1, cijk, list, count, child);
        if (m > 0) descend(s, tk, level + 1, cijk, child, m, sample);
    }
}

/* Nodes of one level with their triangle lists, concatenated. */
typedef struct level_nodes {
    int64_t n;
    int64_t (*ijk)[3];
    int64_t *first;    /* n + 1: node k's triangles are tris[first[k] .. first[k + 1]) */
    int32_t *tris;
} level_nodes;

static void level_free(level_nodes *l)
{
    free(l->ijk), free(l->first), free(l->tris);
    *l = (level_nodes){0};
}

/* The next level of nodes (sequential; children in octant order). 0 on out of memory. */
static int expand(const strat *s, int level, const level_nodes *in, level_nodes *out)
{
    int64_t cap_nodes = 8 * in->n, cap_tris = 8 * in->first[in->n];
    *out = (level_nodes){0, malloc(sizeof *out->ijk * (size_t)cap_nodes), malloc(sizeof(int64_t) * (size_t)(cap_nodes + 1)),
                         malloc(sizeof(int32_t) * (size_t)(cap_tris ? cap_tris : 1))};
    if (!out->ijk || !out->first || !out->tris) return 0;
    int64_t used = 0;
    out->first[0] = 0;
    for (int64_t k = 0; k < in->n; k++)
        for (int c = 0; c < 8; c++) {
            int64_t cijk[3] = {2 * in->ijk[k][0] + (c & 1), 2 * in->ijk[k][1] + (c >> 1 & 1), 2 * in->ijk[k][2] + (c >> 2 & 1)};
            int64_t m = child_triangles(s, level + 1, cijk, in->tris + in->first[k], in->first[k + 1] - in->first[k],
                                        out->tris + used);
            if (m == 0) continue;
            memcpy(out->ijk[out->n], cijk, sizeof cijk);
            used += m;
            out->first[++out->n] = used;
        }
    return 1;
}

static void task_free(task *tk)
{
    for (int l = 0; l <= MAX_DEPTH + 1; l++) free(tk->lists[l]);
    free(tk->stack), free(tk->ch), free(tk->out.a);
    *tk = (task){0};
}

static int task_init(task *tk, int64_t list_cap)
{
    *tk = (task){0};
    tk->list_cap = list_cap > 0 ? list_cap : 1;
    for (int l = 0; l <= MAX_DEPTH + 1; l++)
        if (!(tk->lists[l] = malloc(sizeof(int32_t) * (size_t)tk->list_cap))) return 0;
    return grow((void **)&tk->stack, &tk->stack_cap, 4 * MAX_PIECE_LEVELS + 4, sizeof(piece));
}

/* Runs the octree: counts the occupied leaves (*leaves) and, with sample, writes one candidate
   per leaf to *out (malloc'd; in octree order). 0 on out of memory. */
static int run_octree(const strat *s, int sample, int64_t *leaves, cands *out)
{
    const fm_mesh *m = s->c->mesh;
    level_nodes cur = {1, malloc(sizeof *cur.ijk), malloc(2 * sizeof(int64_t)), malloc(sizeof(int32_t) * (size_t)m->nt)};
    if (!cur.ijk || !cur.first || !cur.tris) return level_free(&cur), 0;
    cur.ijk[0][0] = cur.ijk[0][1] = cur.ijk[0][2] = 0;
    cur.first[0] = 0, cur.first[1] = m->nt;
    for (int64_t t = 0; t < m->nt; t++) cur.tris[t] = (int32_t)t;
    int level = 0;
    while (level < s->depth && cur.n < TASK_NODES) { /* sequential breadth first */
        level_nodes next;
        int ok = expand(s, level, &cur, &next);
        level_free(&cur);
        cur = next;
        if (!ok) return level_free(&cur), 0;
        level++;
    }
    task *tasks = calloc((size_t)(cur.n ? cur.n : 1), sizeof(task));
    int ok = tasks != NULL;
#pragma omp parallel for num_threads(s->c->threads) schedule(dynamic, 1) reduction(&& : ok)
    for (int64_t k = 0; k < cur.n; k++) {
        task *tk = &tasks[k];
        int64_t count = cur.first[k + 1] - cur.first[k];
        if (!ok || !task_init(tk, count)) {
            ok = 0;
            continue;
        }
        descend(s, tk, level, cur.ijk[k], cur.tris + cur.first[k], count, sample);
        if (tk->failed) ok = 0;
        free(tk->stack), free(tk->ch);
        tk->stack = NULL, tk->ch = NULL;
        for (int l = 0; l <= MAX_DEPTH + 1; l++) free(tk->lists[l]), tk->lists[l] = NULL;
    }
    int64_t total = 0, produced = 0;
    for (int64_t k = 0; ok && k < cur.n; k++) total += tasks[k].count, produced += tasks[k].out.n;
    *leaves = total;
    if (ok && sample) {
        *out = (cands){malloc(sizeof(cand) * (size_t)(produced ? produced : 1)), 0, produced};
        ok = out->a != NULL;
        for (int64_t k = 0; ok && k < cur.n; k++) {
            memcpy(out->a + out->n, tasks[k].out.a, sizeof(cand) * (size_t)tasks[k].out.n);
            out->n += tasks[k].out.n;
        }
    }
    for (int64_t k = 0; tasks && k < cur.n; k++) task_free(&tasks[k]);
    free(tasks);
    level_free(&cur);
    return ok;
}

/* The octree for leaves of edge h: depth and root placement. 0 if deeper than MAX_DEPTH. */
static int place_octree(strat *s, double h)
{
    const fm_mesh *m = s->c->mesh;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, extent = 0;
    for (int64_t i = 0; i < m->nv; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], m->v[3 * i + k]), hi[k] = fmax(hi[k], m->v[3 * i + k]);
    for (int k = 0; k < 3; k++) extent = fmax(extent, hi[k] - lo[k]);
    s->h = h;
    s->depth = 0;
    while (s->depth <= MAX_DEPTH && h * (double)(INT64_C(1) << s->depth) < extent + h) s->depth++;
    /* the mesh starts a fraction of a voxel (1/(2 pi)) inside the root's lower corner */
    for (int k = 0; k < 3; k++) s->origin[k] = lo[k] - h * 0.15915494309189535;
    s->piece_edge = h / fmax(2.0, 2.0 * s->c->opts.lambda);
    return s->depth <= MAX_DEPTH;
}

/* Searches h so that the occupied leaves number target .. 1.1 target (at least n). */
static fm_status choose_leaf_edge(strat *s, fm_error *err)
{
    const fm_sample_ctx *c = s->c;
    const double target = ceil(c->opts.oversample * (double)c->n);
    /* a surface of area M crosses about 1.5 M / h^2 cubes of edge h */
    double h = sqrt(1.5 * c->area / target), best_h = 0;
    int64_t best = INT64_MAX, leaves = 0;
    for (int it = 0; it < 12; it++) {
        if (!place_octree(s, h))
            return fm_fail(err, FM_ERR_INPUT, "stratified sampling: %lld samples need an octree deeper than %d levels",
                           (long long)c->n, MAX_DEPTH);
        if (!run_octree(s, 0, &leaves, NULL)) return fm_fail(err, FM_ERR_MEMORY, "out of memory in the octree");
        if (leaves >= (int64_t)target && leaves < best) best = leaves, best_h = h;
        if ((double)leaves >= target && (double)leaves <= 1.1 * target) break;
        h *= leaves > 0 ? sqrt((double)leaves / target) : 0.5;
    }
    for (h = best_h > 0 ? best_h : h; best_h == 0; h *= 0.8) { /* never settled: shrink until enough */
        if (!place_octree(s, h))
            return fm_fail(err, FM_ERR_INPUT, "stratified sampling: %lld samples need an octree deeper than %d levels",
                           (long long)c->n, MAX_DEPTH);
        if (!run_octree(s, 0, &leaves, NULL)) return fm_fail(err, FM_ERR_MEMORY, "out of memory in the octree");
        if (leaves >= c->n) best_h = h;
    }
    place_octree(s, best_h);
    return FM_OK;
}

/* ------------------------------------------------------------------ elimination */

typedef struct heap_entry {
    double key;
    int64_t i;
} heap_entry;

typedef struct heap {
    heap_entry *e;
    int64_t n, cap;
} heap;

static int entry_less(heap_entry a, heap_entry b) { return a.key < b.key || (a.key == b.key && a.i < b.i); }

static void heap_down(heap *hp, int64_t k)
{
    for (;;) {
        int64_t l = 2 * k + 1, r = l + 1, m = k;
        if (l < hp->n && entry_less(hp->e[l], hp->e[m])) m = l;
        if (r < hp->n && entry_less(hp->e[r], hp->e[m])) m = r;
        if (m == k) return;
        heap_entry t = hp->e[k];
        hp->e[k] = hp->e[m], hp->e[m] = t, k = m;
    }
}

static int heap_push(heap *hp, heap_entry x)
{
    if (!grow((void **)&hp->e, &hp->cap, hp->n + 1, sizeof(heap_entry))) return 0;
    int64_t k = hp->n++;
    while (k > 0 && entry_less(x, hp->e[(k - 1) / 2])) hp->e[k] = hp->e[(k - 1) / 2], k = (k - 1) / 2;
    hp->e[k] = x;
    return 1;
}

static heap_entry heap_pop(heap *hp)
{
    heap_entry top = hp->e[0];
    hp->e[0] = hp->e[--hp->n];
    heap_down(hp, 0);
    return top;
}

typedef struct elim {
    fm_grid g;
    float *xyz[3];
    uint8_t *alive;
    int64_t *nn;
    double *key;    /* squared distance to nn, INFINITY if none within a cell */
    heap hp;
} elim;

static void point_of(const elim *e, int64_t i, float q[3]) { q[0] = e->xyz[0][i], q[1] = e->xyz[1][i], q[2] = e->xyz[2][i]; }

static void refresh(elim *e, int64_t i)
{
    float q[3];
    point_of(e, i, q);
    e->nn[i] = fm_grid_nearest(&e->g, q, e->alive, i, -1, &e->key[i]);
}

/* The squared distance from i to its nearest alive point other than skip. */
static double next_d2(const elim *e, int64_t i, int64_t skip)
{
    float q[3];
    double d2;
    point_of(e, i, q);
    fm_grid_nearest(&e->g, q, e->alive, i, skip, &d2);
    return d2;
}

/* Removes one point: of the closest pair (i, nn[i]) the one nearer its next neighbour; returns it. */
static int64_t remove_one(elim *e, int64_t i)
{
    int64_t j = e->nn[i], victim = i;
    if (j >= 0) {
        double di = next_d2(e, i, j), dj = next_d2(e, j, i);
        victim = dj < di || (dj == di && j > i) ? j : i;
    }
    e->alive[victim] = 0;
    return victim;
}

/* Points whose nearest neighbour was v look again (they are all in v's 27 cells). */
static int requeue_orphans(elim *e, int64_t v)
{
    int32_t rk[2 * FM_GRID_MAX_RANGES];
    float q[3];
    point_of(e, v, q);
    const int nr = fm_grid_ranges(&e->g, q[0], q[1], q[2], rk);
    for (int r = 0; r < nr; r++)
        for (int32_t k = rk[2 * r]; k < rk[2 * r + 1]; k++) {
            int64_t j = e->g.quad[k >> 2].i[k & 3];
            if (!e->alive[j] || e->nn[j] != v) continue;
            refresh(e, j);
            if (!heap_push(&e->hp, (heap_entry){e->key[j], j})) return 0;
        }
    return 1;
}

static void elim_free(elim *e)
{
    fm_grid_free(&e->g);
    for (int k = 0; k < 3; k++) fm_free(e->xyz[k]);
    fm_free(e->alive), fm_free(e->nn), fm_free(e->key);
    free(e->hp.e);
}

/* Keeps exactly n of the candidates (in their order) in x and tri. */
static fm_status eliminate(const fm_sample_ctx *c, const cands *cd, double *x, int32_t *tri, fm_error *err)
{
    const int64_t m = cd->n;
    elim e = {0};
    for (int k = 0; k < 3; k++) e.xyz[k] = fm_alloc(sizeof(float) * (size_t)m);
    e.alive = fm_alloc((size_t)m);
    e.nn = fm_alloc(sizeof(int64_t) * (size_t)m);
    e.key = fm_alloc(sizeof(double) * (size_t)m);
    e.hp.e = malloc(sizeof(heap_entry) * (size_t)m);
    e.hp.cap = m;
    fm_status st = !e.xyz[0] || !e.xyz[1] || !e.xyz[2] || !e.alive || !e.nn || !e.key || !e.hp.e
                       ? fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld candidates", (long long)m)
                       : fm_grid_init(&e.g, m, err);
    if (st == FM_OK) {
        for (int64_t i = 0; i < m; i++) {
            e.alive[i] = 1;
            for (int k = 0; k < 3; k++) e.xyz[k][i] = (float)cd->a[i].x[k];
        }
        /* cells of 1.5 x sqrt(M/N): while more than N points are left their closest pair is nearer (N
           points on area M cannot all be farther apart than a hexagonal packing, 1.075 sqrt(M/N)) */
        fm_grid_build(&e.g, (const float *const *)e.xyz, NULL, m, (float)(1.5 * sqrt(c->area / (double)c->n)), c->threads);
#pragma omp parallel for num_threads(c->threads) schedule(static)
        for (int64_t i = 0; i < m; i++) refresh(&e, i);
        for (int64_t i = 0; i < m; i++) e.hp.e[i] = (heap_entry){e.key[i], i};
        e.hp.n = m;
        for (int64_t k = m / 2; k-- > 0;) heap_down(&e.hp, k);
        for (int64_t left = m; left > c->n && st == FM_OK;) {
            heap_entry top = heap_pop(&e.hp);
            if (!e.alive[top.i] || top.key != e.key[top.i]) continue; /* stale */
            int64_t v = remove_one(&e, top.i);
            left--;
            if (!requeue_orphans(&e, v)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory eliminating candidates");
        }
    }
    for (int64_t i = 0, k = 0; st == FM_OK && i < m; i++) {
        if (!e.alive[i]) continue;
        memcpy(x + 3 * k, cd->a[i].x, 3 * sizeof(double));
        tri[k++] = cd->a[i].tri;
    }
    elim_free(&e);
    return st;
}

fm_status fm_sample_stratified(const fm_sample_ctx *c, double *x, int32_t *tri, fm_error *err)
{
    strat s = {.c = c};
    fm_status st = choose_leaf_edge(&s, err);
    if (st != FM_OK) return st;
    int64_t leaves = 0;
    cands cd = {0};
    if (!run_octree(&s, 1, &leaves, &cd)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory sampling the octree");
    else if (cd.n < c->n)
        st = fm_fail(err, FM_ERR_INTERNAL, "stratified sampling: %lld candidates for %lld samples", (long long)cd.n,
                     (long long)c->n);
    if (st == FM_OK) st = eliminate(c, &cd, x, tri, err);
    free(cd.a);
    return st;
}
