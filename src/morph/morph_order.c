/* Launch and arrival orders (FM eq 4), computed once from the tets' rest centroids.
 *   D1(X)  =  (Q_0 - Q_1) . (x - Q_1)          ascending: the front of the source launches first
 *   D2(X') = -(Q_{m+1} - Q_m) . (x' - Q_m)     ascending: the target fills from its far side */
#include "morph.h"

#include <stdlib.h>

typedef struct order_key {
    double key;
    int64_t index;
} order_key;

static int by_key(const void *a, const void *b)
{
    const order_key *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

/* order[k] = index of the tet with the k-th smallest sign * dir . (centroid - origin). */
static fm_status order_by_projection(const fm_tets *tets, const double *dir, const double *origin,
                                     double sign, int64_t *order, fm_error *err)
{
    order_key *keys = malloc(sizeof *keys * (size_t)(tets->n ? tets->n : 1));
    if (!keys) return fm_fail(err, FM_ERR_MEMORY, "out of memory ordering %lld tets", (long long)tets->n);
    for (int64_t i = 0; i < tets->n; i++) {
        double c[3];
        fm_tet_centroid(tets->v + 12 * i, c);
        double key = 0;
        for (int k = 0; k < 3; k++) key += dir[k] * (c[k] - origin[k]);
        keys[i] = (order_key){sign * key, i};
    }
    qsort(keys, (size_t)tets->n, sizeof *keys, by_key);
    for (int64_t i = 0; i < tets->n; i++) order[i] = keys[i].index;
    free(keys);
    return FM_OK;
}

fm_status fm_order_d1(const fm_tets *src, const fm_path *path, int64_t *order, fm_error *err)
{
    const double *q0 = path->q, *q1 = path->q + 3;
    double dir[3] = {q0[0] - q1[0], q0[1] - q1[1], q0[2] - q1[2]};
    return order_by_projection(src, dir, q1, 1.0, order, err);
}

fm_status fm_order_d2(const fm_tets *dst, const fm_path *path, int64_t *order, fm_error *err)
{
    const double *qm = path->q + 3 * (path->count - 2), *qe = path->q + 3 * (path->count - 1);
    double dir[3] = {qe[0] - qm[0], qe[1] - qm[1], qe[2] - qm[2]};
    return order_by_projection(dst, dir, qm, -1.0, order, err);
}
