/* The shape flock's virtual leaders (flock_step.c, stage 2) FM_WD agents at a time in double lanes:
 * fm_flock_leader's delay and eased fraction, the layout's blend, fm_bspline_eval_table and
 * fm_path_map_blend, with their operations in their order lane by lane, so the same bits. A lane
 * on an ease ramp (a sine) is left to the scalar code. */
#ifndef FM_KERNEL_LEADER_H
#define FM_KERNEL_LEADER_H

#include "simd.h"

#include <stdint.h>

typedef struct fm_leader_view {
    double t, inv_dt, path_time;
    double axis[3], lo, inv_range, spread; /* the delay (inv_range 0: none) */
    double e_in, e_out, top;               /* the ramps and the cruise speed, 1 / (1 - (e_in + e_out) / 2) */
    double reform;                         /* shape_flock.reform (not > 0: the blend is u) */
    const double *arc;                     /* the path's table: R and dR/ds, 6 doubles a sample */
    int32_t samples;                       /* its steps (FM_BSPLINE_ARC_SAMPLES) */
    double o1[3], o2[3], oo;               /* the path's ends and |O2 - O1|^2 as fm_path_map_blend sums it */
} fm_leader_view;

/* The leader and its velocity of the agents in whole groups of FM_WD from begin whose phase is not
 * `skip`, except those on a ramp, which are appended to left[] (*left_count of them) for the scalar
 * code; returns the first agent it did not look at (begin where no SIMD variant is picked). */
int64_t fm_kernel_leaders(const fm_leader_view *w, const uint8_t *phase, uint8_t skip, const float *const start[3],
                          const float *const dest[3], float *const leader[3], float *const leader_v[3], int64_t begin,
                          int64_t end, int64_t *left, int64_t *left_count);
typedef int64_t fm_leaders_fn(const fm_leader_view *w, const uint8_t *phase, uint8_t skip, const float *const start[3],
                              const float *const dest[3], float *const leader[3], float *const leader_v[3],
                              int64_t begin, int64_t end, int64_t *left, int64_t *left_count);
FM_SIMD_DECLARE(fm_leaders_fn, fm_kernel_leaders);

#endif
