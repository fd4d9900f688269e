/* Fuzzy weight curves (SCF Figure 6); see fuzzy.h. */
#include "fuzzy.h"

#include <math.h>

fm_status fm_fuzzy_init(fm_fuzzy *c, const fm_fuzzy_def *def, const char *key, fm_error *err)
{
    if (def->count < 1 || def->count > FM_FUZZY_MAX_POINTS)
        return fm_fail(err, FM_ERR_INPUT, "%s: a weight curve needs 1 to %d points, got %d", key, FM_FUZZY_MAX_POINTS,
                       def->count);
    c->count = def->count;
    for (int32_t i = 0; i < def->count; i++) {
        if (!isfinite(def->d[i]) || !isfinite(def->w[i]) || def->d[i] < 0 || def->w[i] < 0)
            return fm_fail(err, FM_ERR_INPUT, "%s[%d]: distance and weight must be finite and >= 0", key, i);
        if (i > 0 && !((float)def->d[i] > (float)def->d[i - 1]))
            return fm_fail(err, FM_ERR_INPUT, "%s[%d]: the distances must increase (%g after %g)", key, i, def->d[i],
                           def->d[i - 1]);
        c->d[i] = (float)def->d[i];
        c->w[i] = (float)def->w[i];
    }
    for (int32_t i = 0; i + 1 < c->count; i++) c->slope[i] = (c->w[i + 1] - c->w[i]) / (c->d[i + 1] - c->d[i]);
    c->slope[c->count - 1] = 0;
    return FM_OK;
}
