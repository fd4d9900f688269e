/* A uniform hash grid over agent centroids for the MDE neighbour search (FM §5.4).
 *
 * Rebuilt every step by a counting sort: no linked lists, no allocation after fm_grid_init. Cells
 * are cubes of edge `cell`; the integer cell coordinates (cx, cy, cz) are hashed into a power-of-two
 * table of at least 2x the capacity. The hash keeps a row of cells together:
 *
 *     slot(cx, cy, cz) = (cx + row(cy, cz)) & mask
 *
 * so the three cells (cx-1 .. cx+1, cy, cz) are three consecutive slots (mod the table size) and
 * their agents one contiguous range of the sorted arrays: a 27-cell neighbourhood is 9 ranges.
 * Distinct cells can share a slot (the table is a hash), so a slot lists every agent of every cell
 * hashed there: callers filter by distance.
 *
 * Agents are listed by slot, and inside a slot in increasing agent index, whatever the thread count:
 * the whole grid (start, quad, slot) is bitwise the same for any `threads`.
 *
 * Limits: capacity <= 2^29 agents; cell coordinates are clamped to +-2^30 (points that far out, or
 * NaN, land in the clamp cells and are merely listed there). */
#ifndef FM_GRID_H
#define FM_GRID_H

#include "fm_internal.h"

#include <stdint.h>

#define FM_GRID_NONE UINT32_MAX      /* slot[a] of an agent the last build did not list */
#define FM_GRID_MAX_CAPACITY (INT64_C(1) << 29)
#define FM_GRID_MAX_BLOCKS 64        /* agent blocks of the parallel build (more threads: idle) */
#define FM_GRID_PAD 12               /* quad holds capacity + FM_GRID_PAD entries (SIMD tails) */
#define FM_GRID_SOA_PAD 16           /* soa[] hold capacity + this many floats (16-lane tails), zeroed */
#define FM_GRID_COORD_LIMIT 1073741824.0 /* 2^30 */

/* The listed agents, 4 to a 64-byte line: entry k is lane k & 3 of quad k >> 2 (a copy of its
 * centroid and its index). A run of a few agents is one or two cache lines, and SIMD loads of 4
 * coordinates are aligned. */
typedef struct fm_grid_quad {
    float x[4], y[4], z[4];
    int32_t i[4];
} fm_grid_quad;

/* Build scratch: one agent. */
typedef struct fm_grid_rec {
    float x, y, z;
    int32_t i;
} fm_grid_rec;

typedef struct fm_grid {
    int64_t capacity;      /* agents the arrays hold */
    int64_t n;             /* agents a < n were considered by the last build */
    int64_t count;         /* agents listed by the last build */
    uint32_t mask;         /* table size - 1 */
    int log2_table;        /* table size = 1 << log2_table, 6 .. 31 */
    int64_t table_agents;  /* > 0: every build's table is the one for this many agents (fm_grid_init_table) */
    int linear_rows;       /* rows by position, not hashed (set after fm_grid_init; see fm_grid_row):
                              FM_GRID_ROWS_THIRDS or FM_GRID_ROWS_FITTED */
    int shift_y, shift_z;  /* linear rows: row(cy, cz) = cy << shift_y + cz << shift_z (mod the table) */
    int runs_apart;        /* the placement keeps a neighbourhood's 9 runs of 3 slots apart (grid.c) */
    float cell;            /* cell edge of the last build (as requested) */
    double inv_cell;       /* 1 / (cell * (1 + 2^-20)): see fm_grid_scaled */
    int32_t *start;        /* table size + 1: slot s lists entries start[s] .. start[s+1]-1 */
    fm_grid_quad *quad;    /* (capacity + FM_GRID_PAD) / 4: entries by slot, then by agent index */
    uint32_t *slot;        /* capacity: each agent's slot, FM_GRID_NONE if it was not listed */
    float *soa[6];         /* NULL, or (fm_grid_init_velocities) the listed agents' positions x, y, z and
                              velocities vx, vy, vz in entry order, one plain array each (capacity +
                              FM_GRID_SOA_PAD floats): a SIMD walk loads FM_W candidates' coordinates at
                              once and reads a neighbour's velocity without gathering it by agent */
    float *tmp_vel;        /* build scratch for the velocities: 3 per agent */

    /* build scratch: a two-level counting sort (coarse buckets of 1 << log2_fine slots, then slots) */
    int log2_fine;
    int32_t coarse;        /* coarse buckets = table size >> log2_fine */
    int32_t *hist;         /* FM_GRID_MAX_BLOCKS * coarse: per-block bucket counts, then offsets */
    fm_grid_rec *tmp;      /* capacity: agents grouped by coarse bucket */
    uint32_t *tmp_slot;    /* capacity: their slots */
} fm_grid;

fm_status fm_grid_init(fm_grid *g, int64_t capacity, fm_error *err); /* all allocation is here */
void fm_grid_free(fm_grid *g);                                       /* g may be zeroed or freed */
/* The same, with every build's table the one for table_agents agents, whatever it lists: a rank
 * listing its share of n agents gets the cells' slots, so the order of a walk over the 27 cells, of
 * one process listing all n (grid.h's walks merge cells that share a slot). */
fm_status fm_grid_init_table(fm_grid *g, int64_t capacity, int64_t table_agents, fm_error *err);
/* Makes the builds keep entry-order copies of the positions and velocities (soa) too: 36 more bytes
 * per agent of capacity. */
fm_status fm_grid_init_velocities(fm_grid *g, fm_error *err);

/* linear_rows: 0 hashes the rows; FM_GRID_ROWS_THIRDS gives cx, cy and cz a third of the table's bits
 * each; FM_GRID_ROWS_FITTED fits the bits to the box of the agents a build lists (each axis the
 * bits its cells span, with a cell of margin on each side), so that no two cells of the box share
 * a slot while the box fits the table: a flock that flies as one keeps its cells' order (and a
 * store sorted by slot stays nearly in the grid's order), and its walks meet no other cell's agents.
 * The box is a min/max over the listed agents: the same for any thread count. */
enum { FM_GRID_ROWS_THIRDS = 1, FM_GRID_ROWS_FITTED = 2 };

/* Lists the agents a < n (n <= capacity) with member[a] != 0 (all of them if member is NULL); the
 * others get slot FM_GRID_NONE.
 * cell > 0. threads: OpenMP threads for the parallel passes; the result does not depend on it. */
void fm_grid_build(fm_grid *g, const float *const p[3], const uint8_t *member, int64_t n, float cell,
                   int threads);
/* The same, copying p and v into soa (g initialised with fm_grid_init_velocities). */
void fm_grid_build_moving(fm_grid *g, const float *const p[3], const float *const v[3], const uint8_t *member,
                          int64_t n, float cell, int threads);

/* The pieces a neighbourhood walk needs, shared with the build so both place a point alike. */

/* Scaled coordinate x / cell, in double with the cell enlarged by 2^-20: two points whose float
 * distance test passes for a d_min <= cell are then at most one cell apart on every axis. */
static inline double fm_grid_scaled(const fm_grid *g, float x) { return (double)x * g->inv_cell; }

/* floor(q) clamped to +-2^30 (NaN goes to -2^30); no libm call. */
static inline int32_t fm_grid_coord(double q)
{
    if (!(q >= -FM_GRID_COORD_LIMIT)) q = -FM_GRID_COORD_LIMIT;
    if (q > FM_GRID_COORD_LIMIT) q = FM_GRID_COORD_LIMIT;
    int32_t t = (int32_t)q;
    return t - ((double)t > q);
}

/* Row hash factors: row(cy, cz) = mix(cy * FM_GRID_HY ^ cz * FM_GRID_HZ) >> (32 - log2_table). */
#define FM_GRID_HY 0x9E3779B1u
#define FM_GRID_HZ 0x85EBCA77u

static inline uint32_t fm_grid_row_mix(const fm_grid *g, uint32_t hy, uint32_t hz)
{
    uint32_t h = hy ^ hz;
    h ^= h >> 15;
    h *= 0x2C1B3C6Du;
    h ^= h >> 12;
    h *= 0x297A2D39u;
    return h >> (32 - g->log2_table);
}

/* The first slot of row (cy, cz), before adding cx. Hashed, or with linear_rows a row-major index
 * wrapped by the table: cells near each other in space then have slots near each other, so a store
 * sorted along a space-filling curve walks the table (and the entries) almost in order instead of
 * at random. Distant cells share slots either way; callers filter by distance. */
static inline uint32_t fm_grid_row(const fm_grid *g, int32_t cy, int32_t cz)
{
    if (g->linear_rows) return ((uint32_t)cy << g->shift_y) + ((uint32_t)cz << g->shift_z);
    return fm_grid_row_mix(g, (uint32_t)cy * FM_GRID_HY, (uint32_t)cz * FM_GRID_HZ);
}

static inline uint32_t fm_grid_slot(const fm_grid *g, int32_t cx, int32_t cy, int32_t cz)
{
    return ((uint32_t)cx + fm_grid_row(g, cy, cz)) & g->mask;
}

/* The slot of the cell holding (x, y, z), as a build places it. */
static inline uint32_t fm_grid_slot_of(const fm_grid *g, float x, float y, float z)
{
    return fm_grid_slot(g, fm_grid_coord(fm_grid_scaled(g, x)), fm_grid_coord(fm_grid_scaled(g, y)),
                        fm_grid_coord(fm_grid_scaled(g, z)));
}

/* A copy of g's placement as a build over `agents` agents with edge `cell` would lay it out (the
 * table's size and rows, the scale), with no arrays: fm_grid_slot_of on it gives the slots that
 * build will give, for a caller that orders its agents by slot beforehand (the morph's re-sort),
 * so that the build lists them in the caller's order. g is unchanged. With FM_GRID_ROWS_FITTED the
 * rows are fitted to the agents a < agents of p with member[a] != 0 (member may be NULL: all), as
 * that build will fit them; p is unused otherwise (may be NULL). */
fm_grid fm_grid_placement(const fm_grid *g, const float *const p[3], const uint8_t *member, int64_t agents, float cell,
                          int threads);

/* The listed entries of the 27 cells around the cell of (x, y, z): up to 27 ranges
 * [rk[2r], rk[2r + 1]) of the sorted entries (g->quad), each slot once even when hashing maps two
 * of the cells to it; runs of consecutive slots are merged. Returns the number of ranges. Distinct
 * cells can share a slot, so callers filter by distance. A walk for any caller; the MDE kernel
 * keeps its own pipelined one. */
#define FM_GRID_MAX_RANGES 27
int fm_grid_ranges(const fm_grid *g, float x, float y, float z, int32_t rk[2 * FM_GRID_MAX_RANGES]);

/* The nearest listed entry to q other than agents self and skip (either may be -1), among those
 * with alive[j] != 0 (alive may be NULL), by the float coordinates the grid holds, the distance
 * in double: returns its agent index and writes the squared distance to *d2, or returns -1 (and
 * *d2 = INFINITY) if none is within the build's cell, beyond which a neighbour may be missed. Ties
 * go to the lower index. */
int64_t fm_grid_nearest(const fm_grid *g, const float q[3], const uint8_t *alive, int64_t self, int64_t skip,
                        double *d2);

#endif
