/* The radius-edge distribution of a tet set: what TetGen's -q bounds, measured on what TetGen
 * made and on what the agents become after subdivision (which can only worsen it). */
#include "geom.h"
#include "fm_math.h"

fm_tet_quality fm_tets_quality(const fm_tets *tets, double bound)
{
    fm_tet_quality q = {bound, 0.0, 0, tets->n};
    for (int64_t i = 0; i < tets->n; i++) {
        double r = fm_tet_radius_edge(tets->v + 12 * i);
        if (r > q.max_ratio) q.max_ratio = r;
        q.above += r > bound;
    }
    return q;
}
