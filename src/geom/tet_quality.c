/* The radius-edge distribution of a tet set: what TetGen's -q bounds, measured on what TetGen
 * made and on the tets the agents are after subdivision to n. */
#include "geom.h"
#include "fm_math.h"

#include <math.h>
#include <stdlib.h>

/* The k-th smallest of a[0..n) (0-based), reordering a: Hoare's selection, middle pivot. */
static double select_kth(double *a, int64_t n, int64_t k)
{
    int64_t lo = 0, hi = n - 1;
    while (lo < hi) {
        double pivot = a[lo + (hi - lo) / 2];
        int64_t i = lo, j = hi;
        while (i <= j) {
            while (a[i] < pivot) i++;
            while (a[j] > pivot) j--;
            if (i <= j) {
                double t = a[i];
                a[i++] = a[j], a[j--] = t;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else return a[k];
    }
    return a[k];
}

fm_tet_quality fm_tets_quality(const fm_tets *tets, double bound)
{
    fm_tet_quality q = {bound, 0.0, 0, 0, NAN, tets->n};
    double *ratios = malloc(sizeof(double) * (size_t)(tets->n > 0 ? tets->n : 1));
    for (int64_t i = 0; i < tets->n; i++) {
        double r = fm_tet_radius_edge(tets->v + 12 * i);
        if (r > q.max_ratio) q.max_ratio = r;
        q.above += r > bound;
        q.above_4 += r > 4.0;
        if (ratios) ratios[i] = r;
    }
    if (ratios && tets->n > 0) { /* the lower median for an even count */
        int64_t k = (tets->n - 1) / 2;
        q.median_ratio = select_kth(ratios, tets->n, k);
    }
    free(ratios);
    return q;
}
