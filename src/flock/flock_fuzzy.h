/* Fuzzy control (SCF "Fuzzy Control Logic", Figure 6): each kind of force (steering, homing,
 * damping, external) is weighted by a curve over the agent's distance to its destination, from the
 * set of the paper's static strategy or of its tracking one, chosen by the target. The
 * paper's curves are "piecewise continuous functions" drawn in Figure 6; ours are piecewise linear
 * through the scene's points and constant beyond the first and the last point, so every curve is
 * continuous and its slope is bounded by the steepest of its pieces. */
#ifndef FM_FUZZY_H
#define FM_FUZZY_H

#include "scene_internal.h"

typedef struct fm_fuzzy {
    int32_t count;                     /* >= 1 */
    float d[FM_FUZZY_MAX_POINTS];      /* strictly increasing */
    float w[FM_FUZZY_MAX_POINTS];
    float slope[FM_FUZZY_MAX_POINTS];  /* (w[i+1] - w[i]) / (d[i+1] - d[i]) */
} fm_fuzzy;

/* Checks def (fm_fuzzy_def_check) and fills c; errors name `key` ("shape_flock.fuzzy.homing"). */
fm_status fm_fuzzy_init(fm_fuzzy *c, const fm_fuzzy_def *def, const char *key, fm_error *err);

/* The weight at distance d (NaN gives the first point's weight). */
static inline float fm_fuzzy_eval(const fm_fuzzy *c, float d)
{
    if (!(d > c->d[0])) return c->w[0];
    int32_t i = 0;
    while (i + 1 < c->count && d > c->d[i + 1]) i++;
    if (i + 1 >= c->count) return c->w[c->count - 1];
    return c->w[i] + c->slope[i] * (d - c->d[i]);
}

#endif
