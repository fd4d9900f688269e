/* Area-weighted random sampling of a surface and the Hilbert-curve sort of points: the pieces the
 * front (sample.c) and the mosaic and stratified methods build on, so those call down into this
 * file and never into each other or back into sample.c. */
#include "sample.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>

enum { STREAM_RANDOM_TRI = 1, STREAM_RANDOM_U = 2, STREAM_RANDOM_V = 3 };

/* The first triangle whose running area sum exceeds a (a < total), so zero-area triangles are
   never chosen. */
static int32_t triangle_at(const double *cdf, int64_t nt, double a)
{
    int64_t lo = 0, hi = nt - 1;
    while (lo < hi) {
        int64_t mid = lo + (hi - lo) / 2;
        if (cdf[mid] > a) hi = mid;
        else lo = mid + 1;
    }
    return (int32_t)lo;
}

void fm_sample_random_into(const fm_sample_ctx *c, double *x, int32_t *tri)
{
    const fm_mesh *m = c->mesh;
    const uint64_t seed = c->opts.seed;
#pragma omp parallel for num_threads(c->threads) schedule(static)
    for (int64_t i = 0; i < c->n; i++) {
        int32_t t = triangle_at(c->cdf, m->nt, fm_random_unit(seed, STREAM_RANDOM_TRI, (uint64_t)i) * c->area);
        /* uniform on the triangle: b = (1 - sqrt(u), sqrt(u) (1 - v), sqrt(u) v) */
        double r = sqrt(fm_random_unit(seed, STREAM_RANDOM_U, (uint64_t)i));
        double v = fm_random_unit(seed, STREAM_RANDOM_V, (uint64_t)i);
        double b[3] = {1 - r, r * (1 - v), r * v};
        const int32_t *f = m->tri + 3 * (int64_t)t;
        for (int k = 0; k < 3; k++)
            x[3 * i + k] = b[0] * m->v[3 * (int64_t)f[0] + k] + b[1] * m->v[3 * (int64_t)f[1] + k] +
                           b[2] * m->v[3 * (int64_t)f[2] + k];
        tri[i] = t;
    }
}

/* ------------------------------------------------------------------ spatial order */

uint64_t fm_hilbert_key(const double p[3], const double lo[3], double scale)
{
    const double top = (double)((1u << FM_HILBERT_BITS) - 1);
    uint32_t x[3];
    for (int k = 0; k < 3; k++) {
        double q = floor((p[k] - lo[k]) * scale + 0.5);
        x[k] = (uint32_t)(q > 0 ? (q < top ? q : top) : 0); /* NaN goes to 0 */
    }
    const uint32_t m = 1u << (FM_HILBERT_BITS - 1);
    for (uint32_t q = m; q > 1; q >>= 1) { /* inverse undo */
        uint32_t low = q - 1;
        for (int i = 0; i < 3; i++) {
            if (x[i] & q) {
                x[0] ^= low;
            } else {
                uint32_t t = (x[0] ^ x[i]) & low;
                x[0] ^= t, x[i] ^= t;
            }
        }
    }
    for (int i = 1; i < 3; i++) x[i] ^= x[i - 1]; /* Gray encode */
    uint32_t t = 0;
    for (uint32_t q = m; q > 1; q >>= 1)
        if (x[2] & q) t ^= q - 1;
    for (int i = 0; i < 3; i++) x[i] ^= t;
    uint64_t h = 0;
    for (int b = FM_HILBERT_BITS - 1; b >= 0; b--)
        for (int i = 0; i < 3; i++) h = h << 1 | (x[i] >> b & 1u);
    return h;
}

static int keyed_cmp(const void *a, const void *b)
{
    const fm_keyed *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->i > y->i) - (x->i < y->i);
}

void fm_keyed_sort(fm_keyed *k, int64_t n) { qsort(k, (size_t)n, sizeof *k, keyed_cmp); }
