/* Fuzzy weight curves (SCF Figure 6); see flock_fuzzy.h. */
#include "flock_fuzzy.h"


fm_status fm_fuzzy_init(fm_fuzzy *c, const fm_fuzzy_def *def, const char *key, fm_error *err)
{
    fm_status st = fm_fuzzy_def_check(def, key, err);
    if (st != FM_OK) return st;
    c->count = def->count;
    for (int32_t i = 0; i < def->count; i++) {
        c->d[i] = (float)def->d[i];
        c->w[i] = (float)def->w[i];
    }
    for (int32_t i = 0; i + 1 < c->count; i++) c->slope[i] = (c->w[i + 1] - c->w[i]) / (c->d[i + 1] - c->d[i]);
    c->slope[c->count - 1] = 0;
    return FM_OK;
}
