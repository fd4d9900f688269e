/* Subdivision of a tet set to exactly n tets (FM §4, eqs 1-2), and the engine's default since issue
 * 38: longest-edge bisection of the largest tets (fm_bisect_to).
 *
 * As DESIGN.md reads Figure 3: 1-to-4 puts a new vertex at the centroid, 1-to-3 at the centroid of
 * the largest face, 1-to-2 at the midpoint of the longest edge. Each child replaces one vertex of
 * the parent by the new point, so children keep the parent's orientation and their volumes sum to
 * the parent's exactly (up to round-off). */
#include "geom.h"

#include <stdlib.h>
#include <string.h>

double fm_tet_signed_volume(const double *t)
{
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; k++) a[k] = t[3 + k] - t[k], b[k] = t[6 + k] - t[k], c[k] = t[9 + k] - t[k];
    return (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
            a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0;
}

void fm_tet_centroid(const double *t, double c[3])
{
    for (int k = 0; k < 3; k++) c[k] = 0.25 * (t[k] + t[3 + k] + t[6 + k] + t[9 + k]);
}

/* Writes the child of `tet` whose vertex `slot` is replaced by `p`. */
static void child_replacing(const double *tet, int slot, const double p[3], double *out)
{
    memcpy(out, tet, 12 * sizeof(double));
    memcpy(out + 3 * slot, p, 3 * sizeof(double));
}

void fm_split_1to4(const double *tet, double *out)
{
    double c[3];
    fm_tet_centroid(tet, c);
    for (int s = 0; s < 4; s++) child_replacing(tet, s, c, out + 12 * s);
}

static double face_area2(const double *tet, int opposite)
{
    const double *p[3];
    for (int k = 0, j = 0; k < 4; k++)
        if (k != opposite) p[j++] = tet + 3 * k;
    double u[3], v[3];
    for (int k = 0; k < 3; k++) u[k] = p[1][k] - p[0][k], v[k] = p[2][k] - p[0][k];
    double x = u[1] * v[2] - u[2] * v[1], y = u[2] * v[0] - u[0] * v[2], z = u[0] * v[1] - u[1] * v[0];
    return x * x + y * y + z * z;
}

void fm_split_1to3(const double *tet, double *out)
{
    int opposite = 0; /* the largest face is the one opposite this vertex */
    for (int k = 1; k < 4; k++)
        if (face_area2(tet, k) > face_area2(tet, opposite)) opposite = k;
    double f[3] = {0, 0, 0};
    for (int k = 0; k < 4; k++)
        if (k != opposite)
            for (int i = 0; i < 3; i++) f[i] += tet[3 * k + i] / 3.0;
    int j = 0;
    for (int k = 0; k < 4; k++)
        if (k != opposite) child_replacing(tet, k, f, out + 12 * j++);
}

void fm_split_1to2(const double *tet, double *out)
{
    int ea = 0, eb = 1;
    double best = -1;
    for (int a = 0; a < 4; a++) {
        for (int b = a + 1; b < 4; b++) {
            double d2 = 0;
            for (int i = 0; i < 3; i++) d2 += (tet[3 * a + i] - tet[3 * b + i]) * (tet[3 * a + i] - tet[3 * b + i]);
            if (d2 > best) best = d2, ea = a, eb = b;
        }
    }
    double m[3];
    for (int i = 0; i < 3; i++) m[i] = 0.5 * (tet[3 * ea + i] + tet[3 * eb + i]);
    child_replacing(tet, ea, m, out);
    child_replacing(tet, eb, m, out + 12);
}

typedef struct volume_key {
    double volume;
    int64_t index;
} volume_key;

static int by_volume_descending(const void *a, const void *b)
{
    const volume_key *x = a, *y = b;
    if (x->volume != y->volume) return x->volume < y->volume ? 1 : -1;
    return (x->index > y->index) - (x->index < y->index);
}

/* One uniform 1-to-4 level: n tets become 4n. */
static fm_status split_all(fm_tets *tets, fm_error *err)
{
    double *out = malloc(sizeof(double) * 48 * (size_t)tets->n);
    if (!out) return fm_fail(err, FM_ERR_MEMORY, "out of memory subdividing %lld tets", (long long)tets->n);
    for (int64_t i = 0; i < tets->n; i++) fm_split_1to4(tets->v + 12 * i, out + 48 * i);
    free(tets->v);
    tets->v = out;
    tets->n *= 4;
    return FM_OK;
}

fm_status fm_subdivide_to(fm_tets *tets, int64_t n, fm_error *err)
{
    if (n < tets->n)
        return fm_fail(err, FM_ERR_INPUT, "n = %lld is smaller than the %lld tets TetGen made",
                       (long long)n, (long long)tets->n);
    while (4 * tets->n <= n) { /* eq 1: k levels of 1-to-4 */
        fm_status st = split_all(tets, err);
        if (st != FM_OK) return st;
    }
    int64_t m = tets->n, d = (n - m) / 3, r = n - m - 3 * d; /* eq 2 */
    if (d == 0 && r == 0) return FM_OK;
    volume_key *keys = malloc(sizeof *keys * (size_t)m);
    double *out = malloc(sizeof(double) * 12 * (size_t)n);
    if (!keys || !out) {
        free(keys), free(out);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory subdividing to %lld tets", (long long)n);
    }
    for (int64_t i = 0; i < m; i++) keys[i] = (volume_key){fm_tet_signed_volume(tets->v + 12 * i), i};
    qsort(keys, (size_t)m, sizeof *keys, by_volume_descending);
    double *w = out;
    for (int64_t k = 0; k < m; k++) {
        const double *tet = tets->v + 12 * keys[k].index;
        if (k < d) fm_split_1to4(tet, w), w += 48;
        else if (k == d && r == 2) fm_split_1to3(tet, w), w += 36;
        else if (k == d && r == 1) fm_split_1to2(tet, w), w += 24;
        else memcpy(w, tet, 12 * sizeof(double)), w += 12;
    }
    free(keys);
    free(tets->v);
    tets->v = out;
    tets->n = n;
    return FM_OK;
}

/* ---------------------------------------------------------------- longest-edge bisection */

/* A max-heap of tets by volume, ties to the lower index: the order of splits, and so the tets,
 * depend on nothing but the input. */
static int heap_before(const volume_key *x, const volume_key *y)
{
    return x->volume > y->volume || (x->volume == y->volume && x->index < y->index);
}

static void heap_push(volume_key *h, int64_t *size, volume_key k)
{
    int64_t i = (*size)++;
    while (i > 0 && heap_before(&k, &h[(i - 1) / 2])) h[i] = h[(i - 1) / 2], i = (i - 1) / 2;
    h[i] = k;
}

static volume_key heap_pop(volume_key *h, int64_t *size)
{
    volume_key top = h[0], last = h[--*size];
    int64_t i = 0;
    for (;;) {
        int64_t c = 2 * i + 1;
        if (c >= *size) break;
        if (c + 1 < *size && heap_before(&h[c + 1], &h[c])) c++;
        if (!heap_before(&h[c], &last)) break;
        h[i] = h[c], i = c;
    }
    if (*size > 0) h[i] = last;
    return top;
}

/* Tets are agents, so the split need not conform: a tet cut at the midpoint of its longest edge
 * (fm_split_1to2) is two tets of half its volume that keep its orientation and, unlike the 1-to-4
 * centroid split, its shape class (the children of a good tet stay near it; the centroid split
 * makes four caps). The largest tet is split first, a child again when it is still the largest. */
fm_status fm_bisect_to(fm_tets *tets, int64_t n, fm_error *err)
{
    if (n < tets->n)
        return fm_fail(err, FM_ERR_INPUT, "n = %lld is smaller than the %lld tets TetGen made",
                       (long long)n, (long long)tets->n);
    if (n == tets->n) return FM_OK;
    if (tets->n == 0) return fm_fail(err, FM_ERR_INPUT, "no tets to subdivide to %lld", (long long)n);
    volume_key *heap = calloc((size_t)n, sizeof *heap);
    double *v = realloc(tets->v, sizeof(double) * 12 * (size_t)n);
    if (!heap || !v) {
        free(heap);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory subdividing to %lld tets", (long long)n);
    }
    tets->v = v;
    int64_t size = 0, m = tets->n;
    for (int64_t i = 0; i < m; i++) heap_push(heap, &size, (volume_key){fm_tet_signed_volume(v + 12 * i), i});
    while (m < n) {
        volume_key k = heap_pop(heap, &size);
        double two[24];
        fm_split_1to2(v + 12 * k.index, two);
        memcpy(v + 12 * k.index, two, 12 * sizeof(double));
        memcpy(v + 12 * m, two + 12, 12 * sizeof(double));
        heap_push(heap, &size, (volume_key){fm_tet_signed_volume(v + 12 * k.index), k.index});
        heap_push(heap, &size, (volume_key){fm_tet_signed_volume(v + 12 * m), m});
        m++;
    }
    free(heap);
    tets->n = n;
    return FM_OK;
}
