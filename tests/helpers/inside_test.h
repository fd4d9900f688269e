/* An inside test for closed triangle meshes that shares nothing with the engine's distance field or
 * its Embree queries: ray parity along +x, +y and +z (a point is inside when at least two of the
 * three rays cross the surface an odd number of times), each ray tested only against the triangles
 * whose projection covers its cell of a bucket grid, and, for a point found inside, its depth: the
 * distance to the nearest triangle (Ericson, Real-Time Collision Detection 5.1.5). */
#ifndef FM_INSIDE_TEST_H
#define FM_INSIDE_TEST_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

enum { INSIDE_CELLS = 64 };

typedef struct inside_mesh {
    const double *v;     /* 3 per vertex */
    const int32_t *tri;  /* 3 per triangle */
    int64_t nt;
    double lo[3], hi[3];
    int32_t *start[3];   /* per ray axis: INSIDE_CELLS^2 + 1 offsets into list */
    int32_t *list[3];
} inside_mesh;

/* The two axes of the plane a ray along `axis` is projected onto. */
static inline void inside_plane(int axis, int *a, int *b)
{
    *a = (axis + 1) % 3, *b = (axis + 2) % 3;
}

static inline int inside_cell(const inside_mesh *m, int k, double x)
{
    double t = (x - m->lo[k]) / (m->hi[k] - m->lo[k]) * INSIDE_CELLS;
    int c = (int)floor(t);
    return c < 0 ? 0 : c >= INSIDE_CELLS ? INSIDE_CELLS - 1 : c;
}

static inline void inside_tri_range(const inside_mesh *m, int64_t t, int a, int b, int r[4])
{
    double mn[2] = {INFINITY, INFINITY}, mx[2] = {-INFINITY, -INFINITY};
    for (int i = 0; i < 3; i++) {
        const double *p = m->v + 3 * m->tri[3 * t + i];
        mn[0] = fmin(mn[0], p[a]), mx[0] = fmax(mx[0], p[a]), mn[1] = fmin(mn[1], p[b]), mx[1] = fmax(mx[1], p[b]);
    }
    r[0] = inside_cell(m, a, mn[0]), r[1] = inside_cell(m, a, mx[0]), r[2] = inside_cell(m, b, mn[1]),
    r[3] = inside_cell(m, b, mx[1]);
}

/* Buckets every triangle by its projection for each ray axis (counting sort). 0 on success. */
static inline int inside_build(inside_mesh *m, const double *v, int64_t nv, const int32_t *tri, int64_t nt)
{
    m->v = v, m->tri = tri, m->nt = nt;
    for (int k = 0; k < 3; k++) m->lo[k] = INFINITY, m->hi[k] = -INFINITY;
    for (int64_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++) m->lo[k] = fmin(m->lo[k], v[3 * i + k]), m->hi[k] = fmax(m->hi[k], v[3 * i + k]);
    for (int axis = 0; axis < 3; axis++) {
        int a, b, r[4];
        inside_plane(axis, &a, &b);
        int32_t *start = calloc(INSIDE_CELLS * INSIDE_CELLS + 1, sizeof *start);
        if (!start) return -1;
        for (int64_t t = 0; t < nt; t++) {
            inside_tri_range(m, t, a, b, r);
            for (int i = r[0]; i <= r[1]; i++)
                for (int j = r[2]; j <= r[3]; j++) start[i * INSIDE_CELLS + j + 1]++;
        }
        for (int c = 0; c < INSIDE_CELLS * INSIDE_CELLS; c++) start[c + 1] += start[c];
        int32_t *list = malloc(sizeof *list * (size_t)(start[INSIDE_CELLS * INSIDE_CELLS] + 1));
        int32_t *fill = malloc(sizeof *fill * INSIDE_CELLS * INSIDE_CELLS);
        if (!list || !fill) return free(start), free(list), free(fill), -1;
        for (int c = 0; c < INSIDE_CELLS * INSIDE_CELLS; c++) fill[c] = start[c];
        for (int64_t t = 0; t < nt; t++) {
            inside_tri_range(m, t, a, b, r);
            for (int i = r[0]; i <= r[1]; i++)
                for (int j = r[2]; j <= r[3]; j++) list[fill[i * INSIDE_CELLS + j]++] = (int32_t)t;
        }
        free(fill);
        m->start[axis] = start, m->list[axis] = list;
    }
    return 0;
}

static inline void inside_free(inside_mesh *m)
{
    for (int k = 0; k < 3; k++) free(m->start[k]), free(m->list[k]);
}

/* Crossings of the ray from p along +axis with the surface. */
static inline int inside_crossings(const inside_mesh *m, int axis, const double p[3])
{
    int a, b, crossings = 0;
    inside_plane(axis, &a, &b);
    int c = inside_cell(m, a, p[a]) * INSIDE_CELLS + inside_cell(m, b, p[b]);
    for (int32_t s = m->start[axis][c]; s < m->start[axis][c + 1]; s++) {
        const int32_t *t = m->tri + 3 * m->list[axis][s];
        const double *q0 = m->v + 3 * t[0], *q1 = m->v + 3 * t[1], *q2 = m->v + 3 * t[2];
        /* edge functions of p's projection against the projected triangle: all one sign inside */
        double e0 = (q1[a] - q0[a]) * (p[b] - q0[b]) - (q1[b] - q0[b]) * (p[a] - q0[a]);
        double e1 = (q2[a] - q1[a]) * (p[b] - q1[b]) - (q2[b] - q1[b]) * (p[a] - q1[a]);
        double e2 = (q0[a] - q2[a]) * (p[b] - q2[b]) - (q0[b] - q2[b]) * (p[a] - q2[a]);
        int pos = e0 > 0 && e1 > 0 && e2 > 0, neg = e0 < 0 && e1 < 0 && e2 < 0;
        double sum = e0 + e1 + e2;
        if (!(pos || neg) || sum == 0) continue;
        double hit = (e1 * q0[axis] + e2 * q1[axis] + e0 * q2[axis]) / sum; /* barycentric height */
        crossings += hit > p[axis];
    }
    return crossings;
}

static inline int inside_point(const inside_mesh *m, const double p[3])
{
    for (int k = 0; k < 3; k++)
        if (!(p[k] >= m->lo[k] && p[k] <= m->hi[k])) return 0;
    int votes = 0;
    for (int axis = 0; axis < 3; axis++) votes += inside_crossings(m, axis, p) & 1;
    return votes >= 2;
}

static inline double inside_dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Squared distance from p to triangle abc (Ericson 5.1.5, closest point by Voronoi region). */
static inline double inside_tri_dist2(const double p[3], const double *a, const double *b, const double *c)
{
    double ab[3], ac[3], ap[3], q[3];
    for (int k = 0; k < 3; k++) ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
    double d1 = inside_dot(ab, ap), d2 = inside_dot(ac, ap);
    double bp[3], cp[3];
    for (int k = 0; k < 3; k++) bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
    double d3 = inside_dot(ab, bp), d4 = inside_dot(ac, bp), d5 = inside_dot(ab, cp), d6 = inside_dot(ac, cp);
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    if (d1 <= 0 && d2 <= 0) for (int k = 0; k < 3; k++) q[k] = a[k];
    else if (d3 >= 0 && d4 <= d3) for (int k = 0; k < 3; k++) q[k] = b[k];
    else if (d6 >= 0 && d5 <= d6) for (int k = 0; k < 3; k++) q[k] = c[k];
    else if (vc <= 0 && d1 >= 0 && d3 <= 0) for (int k = 0; k < 3; k++) q[k] = a[k] + d1 / (d1 - d3) * ab[k];
    else if (vb <= 0 && d2 >= 0 && d6 <= 0) for (int k = 0; k < 3; k++) q[k] = a[k] + d2 / (d2 - d6) * ac[k];
    else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) q[k] = b[k] + w * (c[k] - b[k]);
    } else {
        double den = 1 / (va + vb + vc), v = vb * den, w = vc * den;
        for (int k = 0; k < 3; k++) q[k] = a[k] + ab[k] * v + ac[k] * w;
    }
    double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
    return inside_dot(d, d);
}

/* The distance from p to the surface (brute force: for the few points found inside). */
static inline double inside_depth(const inside_mesh *m, const double p[3])
{
    double best = INFINITY;
    for (int64_t t = 0; t < m->nt; t++) {
        const int32_t *i = m->tri + 3 * t;
        best = fmin(best, inside_tri_dist2(p, m->v + 3 * i[0], m->v + 3 * i[1], m->v + 3 * i[2]));
    }
    return sqrt(best);
}

#endif
