/* Slabs along one axis (slabs.h, docs/scale-out.md). */
#include "slabs.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int longest_axis(const double lo[3], const double hi[3])
{
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    return axis;
}

fm_slabs *fm_slabs_create(const fm_dist *dist, const double lo[3], const double hi[3], double radius, fm_error *err)
{
    fm_slabs *d = calloc(1, sizeof *d);
    const int ranks = fm_dist_size(dist);
    if (d) d->cut = malloc(sizeof(double) * (size_t)(ranks + 1)), d->count = calloc((size_t)ranks, sizeof(int64_t));
    if (!d || !d->cut || !d->count) return fm_slabs_free(d), fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    d->axis = longest_axis(lo, hi), d->ranks = ranks, d->rank = fm_dist_rank(dist);
    d->lo = lo[d->axis], d->hi = hi[d->axis];
    if (!(d->hi > d->lo)) d->hi = d->lo + 1;
    for (int r = 0; r <= ranks; r++) d->cut[r] = r == 0 ? -INFINITY : r == ranks ? INFINITY : d->lo;
    d->cost = INFINITY, d->weight = 1;
    d->halo = (float)(radius * (1 + 1e-4)) + 1e-6f * (float)fmax(fabs(d->lo), fabs(d->hi));
    return d;
}

void fm_slabs_free(fm_slabs *d)
{
    if (!d) return;
    free(d->cut), free(d->count), free(d);
}

int fm_slabs_owner(const fm_slabs *d, float x, int current)
{
    if (!(x == x)) return current; /* NaN: kept where it is; the frame's runaway check reports it */
    if (x >= d->cut[d->rank] && x < d->cut[d->rank + 1]) return d->rank; /* most agents stay */
    int lo = 0, hi = d->ranks - 1;
    while (lo < hi) { /* the last r with cut[r] <= x */
        int mid = (lo + hi + 1) / 2;
        if (d->cut[mid] <= x) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}

int fm_slabs_bin(const fm_slabs *d, float x)
{
    double q = ((double)x - d->lo) / (d->hi - d->lo) * FM_SLAB_BINS;
    return !(q > 0) ? 0 : q >= FM_SLAB_BINS ? FM_SLAB_BINS - 1 : (int)q;
}

void fm_slabs_cut(fm_slabs *d, double *bins, const fm_dist *dist)
{
    if (dist) fm_dist_sum_f64(dist, bins, FM_SLAB_BINS); /* every rank gets the same histogram: the same cuts */
    double total = 0;
    for (int b = 0; b < FM_SLAB_BINS; b++) total += bins[b];
    if (!(total > 0)) return;
    const double width = (d->hi - d->lo) / FM_SLAB_BINS;
    double seen = 0;
    int b = 0;
    for (int r = 1; r < d->ranks; r++) {
        const double share = total * r / d->ranks;
        while (b < FM_SLAB_BINS && seen + bins[b] < share) seen += bins[b++];
        d->cut[r] = d->lo + width * (b + 1);
    }
}

double fm_slabs_take_weight(fm_slabs *d)
{
    const double w = isfinite(d->cost) && d->cost > 0 ? d->cost : 1;
    d->cost = INFINITY;
    return w;
}

double fm_slabs_weight(fm_slabs *d, int64_t step)
{
    if (step % FM_WEIGHT_INTERVAL == 0) d->weight = fm_slabs_take_weight(d);
    return d->weight;
}

void fm_offsets(const int64_t *count, int ranks, int64_t *at)
{
    at[0] = 0;
    for (int r = 0; r < ranks; r++) at[r + 1] = at[r] + count[r];
}

void fm_slabs_offsets(const fm_slabs *d, int64_t *at) { fm_offsets(d->count, d->ranks, at); }

void fm_slabs_record_load(fm_slabs *d, const fm_dist *dist, int64_t mine)
{
    int64_t most = mine, all = mine;
    fm_dist_max_i64(dist, &most, 1);
    fm_dist_sum_i64(dist, &all, 1);
    d->totals.max_rank_agent_steps += most, d->totals.agent_steps += all;
}

fm_status fm_slabs_send(fm_slabs *d, const fm_dist *dist, fm_status packed, const void *out, size_t size, void **in,
                        int64_t *received, fm_error *err)
{
    *in = NULL, *received = 0;
    fm_status st = fm_dist_agree(dist, packed, err);
    if (st != FM_OK) return st;
    int64_t sending = 0;
    for (int r = 0; r < d->ranks; r++) sending += d->count[r];
    st = fm_dist_exchange(dist, out, d->count, size, in, received, err);
    if (st == FM_OK) d->totals.bytes_sent += sending * (int64_t)size;
    return st;
}
