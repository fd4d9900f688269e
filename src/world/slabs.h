/* Slabs: the decomposition of space among P ranks that both modes use on MPI (docs/scale-out.md).
 *
 * Space is cut into P slabs along the scene's longest axis: contiguous ranges of the coordinate,
 * rank r owning cut[r] <= x < cut[r + 1]. An agent within `halo` of another slab is that slab's
 * ghost for the step. Every FM_RESORT_INTERVAL-like interval the mode fills a histogram of its
 * agents along the axis (FM_SLAB_BINS bins over [lo, hi]), each weighted by what it costs, and the
 * cuts move to its quantiles (summed over the ranks): the cuts decide only where an agent is
 * computed, never what, so they may follow measured timings. */
#ifndef FM_SLABS_H
#define FM_SLABS_H

#include "dist.h"
#include "fm_internal.h"

#include <stdint.h>

enum { FM_SLAB_BINS = 4096 }; /* the cut positions' resolution along the axis */

/* What the decomposition cost, for stats.json's scale_out (this rank's until summed). */
typedef struct fm_dist_totals {
    int64_t migrated;             /* agents that changed rank (this rank's sends) */
    int64_t ghost_agent_steps;    /* halo agents received, summed over steps */
    int64_t bytes_sent;           /* by this rank: migration, halos, frames */
    int64_t agent_steps;          /* agents in flight, all ranks, summed over steps */
    int64_t max_rank_agent_steps; /* the busiest rank's agents in flight, summed over steps */
    double busy_seconds;          /* this rank's own work in its steps (no exchange, no waiting); after
                                     cli_sum_totals the sum over the ranks */
    double busiest_seconds;       /* after cli_sum_totals: the largest rank's busy_seconds */
    int64_t peak_rss_bytes;       /* after cli_sum_totals: the largest rank's peak resident memory so far */
} fm_dist_totals;

typedef struct fm_slabs {
    int axis, ranks, rank;
    double lo, hi;   /* the scene along the axis (the balancing histogram's range) */
    double *cut;     /* ranks + 1 */
    float halo;      /* the interaction radius, and a margin for the rounding of a distance */
    int64_t *count;  /* per rank: records to send */
    double cost;     /* since the last cut, the least time per agent a step of this rank took: the next
                        cut's weight. The least, since a step that shared the core (rank 0's cache
                        writer, the machine's other jobs) says nothing about the work */
    double weight;   /* the weight of this rank's agents in the cuts, held between takes (fm_slabs_weight) */
    fm_dist_totals totals;
} fm_slabs;

/* Slabs of dist's ranks along the longest axis of [lo, hi], all cut at lo until the first
 * histogram; halo from the interaction radius. NULL, with err set, without memory. */
fm_slabs *fm_slabs_create(const fm_dist *dist, const double lo[3], const double hi[3], double radius, fm_error *err);
void fm_slabs_free(fm_slabs *d);

/* The rank whose slab holds x (`current` for a NaN: kept where it is). */
int fm_slabs_owner(const fm_slabs *d, float x, int current);
/* x's bin of the balancing histogram. */
int fm_slabs_bin(const fm_slabs *d, float x);
/* The cuts at the weighted quantiles of bins (FM_SLAB_BINS), summed over the ranks first when
 * dist is set (every rank then gets the same cuts). */
void fm_slabs_cut(fm_slabs *d, double *bins, const fm_dist *dist);

/* Whether x is within the halo of rank r's slab. */
static inline int fm_slabs_near(const fm_slabs *d, int r, float x)
{
    return x >= d->cut[r] - d->halo && x < d->cut[r + 1] + d->halo;
}

/* Whether this rank's agent at x is in another slab's halo: only near its own slab's faces (the
 * common case, deep inside, costs two comparisons). */
static inline int fm_slabs_in_halo(const fm_slabs *d, float x)
{
    return x < d->cut[d->rank] + d->halo || x >= d->cut[d->rank + 1] - d->halo;
}

/* The least time per agent of a step, for the next cut's weight (fm_slabs.cost); `agents` may be
 * weighted (the shape flock counts a bound agent as a fraction of one in flight). */
static inline void fm_slabs_add_busy(fm_slabs *d, double seconds, double agents)
{
    d->totals.busy_seconds += seconds;
    if (agents > 0 && seconds / agents < d->cost) d->cost = seconds / agents;
}

/* The weight of an agent at the next cut (the measured cost, or 1 before any), and the cost reset. */
double fm_slabs_take_weight(fm_slabs *d);

/* The weight of this rank's agents in step `step`'s cuts: taken (fm_slabs_take_weight) every
 * FM_WEIGHT_INTERVAL steps and held between. One step's time is noisy (a rank that shares a core, or
 * waits on the cache writer, looks slow), and cuts that followed it would jitter and pile agents onto
 * a rank; the cuts themselves follow the agents every step. */
enum { FM_WEIGHT_INTERVAL = 8 };
double fm_slabs_weight(fm_slabs *d, int64_t step);

/* The offsets at which each rank's records start in a send buffer (ranks + 1: the sum last), from
 * the records per rank: count, or d->count. */
void fm_offsets(const int64_t *count, int ranks, int64_t *at);
void fm_slabs_offsets(const fm_slabs *d, int64_t *at);

/* The ranks agree on `packed` (this rank's status after packing out), then each rank gets the
 * records of `size` bytes the others packed for it (grouped by rank in out, d->count of them) in
 * *in (fm_alloc'd, NULL when empty), *received of them; the bytes sent are counted. */
fm_status fm_slabs_send(fm_slabs *d, const fm_dist *dist, fm_status packed, const void *out, size_t size, void **in,
                        int64_t *received, fm_error *err);

/* This step's load: agents in flight on this rank, summed as the busiest rank's and all ranks'. */
void fm_slabs_record_load(fm_slabs *d, const fm_dist *dist, int64_t mine);

#endif
