/* The tets of the agents in phase 1 (FM §6: the source tet, shrunk while it flies), written into a
 * frame in id order: the scalar reference and the SIMD variants (kernel_synth_simd.c: FM_WD agents
 * at once in double, the same operations, so the same bits). */
#ifndef FM_KERNEL_SYNTH_H
#define FM_KERNEL_SYNTH_H

#include "simd.h"

#include <stdint.h>

/* The linear scale of a tet tau seconds after its launch: 1 before, then down to `shrink` over
 * shrink_time (at once if shrink_time <= 0). */
static inline double fm_shrink_at(double tau, double shrink, double shrink_time)
{
    if (tau <= 0) return 1.0;
    double s = shrink_time > 0 ? tau / shrink_time : 1.0;
    if (s > 1) s = 1;
    return 1.0 - (1.0 - shrink) * s;
}

typedef struct fm_synth_view {
    const float *p[3];     /* centroids */
    const float *rest[12]; /* rest vertices relative to the centroid, SoA */
    const int32_t *id;     /* agent id: launched at id / launch_rate, written at out + 12 id */
    double time, launch_rate, shrink, shrink_time;
    int by_slot;           /* 1: written at out + 12 a instead (a rank's own agents, P ranks) */
} fm_synth_view;

/* Where agent a's tet goes in out: 12 floats at its id, or at its slot. */
static inline size_t fm_synth_place(const fm_synth_view *s, int64_t a)
{
    return 12 * (size_t)(s->by_slot ? a : s->id[a]);
}

/* For agents a in [begin, end) with phase[a] == flying (at 12 a instead of 12 id[a] with by_slot):
 *     out[12 id[a] + 3 v + k] = (float)(p[k][a] + scale * rest[3 v + k][a]),
 * scale = fm_shrink_at(time - id[a] / launch_rate, ...), in double. Other agents' tets untouched. */
void fm_kernel_flying_tets(const fm_synth_view *s, const uint8_t *phase, uint8_t flying, int64_t begin,
                           int64_t end, float *out);
void fm_kernel_flying_tets_ref(const fm_synth_view *s, const uint8_t *phase, uint8_t flying, int64_t begin,
                               int64_t end, float *out);

/* One agent, the reference's way (the variants use it where a vector is not all in phase 1). */
static inline void flying_tet(const fm_synth_view *s, int64_t a, float *out)
{
    const int32_t i = s->id[a];
    const double scale = fm_shrink_at(s->time - (double)i / s->launch_rate, s->shrink, s->shrink_time);
    float *o = out + fm_synth_place(s, a);
    for (int j = 0; j < 12; j++) o[j] = (float)((double)s->p[j % 3][a] + scale * (double)s->rest[j][a]);
}

typedef void fm_flying_tets_fn(const fm_synth_view *s, const uint8_t *phase, uint8_t flying, int64_t begin,
                               int64_t end, float *out);
FM_SIMD_DECLARE(fm_flying_tets_fn, fm_kernel_flying_tets);

#endif
