/* What a run of n agents needs in memory, estimated from the layouts of fm_model, fm_state, the
 * frame buffers and the neighbour grid (docs/limits.md), so that a run too large for the machine
 * is refused before anything big is allocated. */
#define _POSIX_C_SOURCE 200809L
#include "cache_format.h"
#include "sim.h"

#include <stdio.h>
#include <unistd.h>

/* Bytes per agent of each array, as allocated by model.c, state.c, run.c, cache.c and grid.c. */
static const double MODEL_PER_AGENT =
    sizeof(float) * (12 + 3 + 12 + 3 + 1) /* src_rel, src_c, tgt_f, tgt_c, src_radius */
    + sizeof(double) * 12;                 /* tgt */
static const double STATE_PER_AGENT =
    sizeof(float) * (3 + 3 + 3 + 2 + FM_MORPH_FLOATS + 3) /* p, v, p2, t2 and tf, morph, vla */
    + 6                                                 /* phase, perm, morph_safe, entered, member, mde_needed */
    + sizeof(int64_t)                                   /* target */
    + sizeof(int32_t) + 16 + 2 * sizeof(uint32_t) + 2 * sizeof(int32_t) /* id; re-sort scratch, keys, slots */
    + sizeof(float) * (12 + 1)                          /* rest_rel, rest_radius: the model's, in store order */
    + (double)sizeof(block_counts) / FM_BLOCK;
/* Frames of tet vertices (48 B) and phases (1 B): run.c's buffers. The cache writer's frame also
 * holds the ids (4 B, tools/cli_run.c's attribute list): its two hand-over slots, the previous
 * frame when delta is on (cache_writer.c), its quantise and filter buffers (the largest attribute),
 * the chunk (zstd's output bound: 1/256 more than its input) and the ids it hands over itself. */
static double frames_per_agent(const fm_scene_def *def)
{
    const double run_frame = 12 * sizeof(float) + 1, largest = 12 * sizeof(float);
    const double cached = run_frame + sizeof(uint32_t);
    return run_frame + cached * (CACHE_WRITER_SLOTS + (def->cache_delta ? 1 : 0)) + 2 * largest + cached * (1 + 1.0 / 256) +
           sizeof(uint32_t);
}
/* Preprocessing holds both tet sets in double (subdivided to n), the two orders and the model. */
static const double PREP_PER_AGENT = 2 * 12 * sizeof(double) + 2 * sizeof(int64_t);
/* Not proportional to n: the libraries (TetGen, OpenVDB, Embree, zstd's two workers), measured on
 * a 200-agent run (docs/limits.md). */
static const double FIXED_BYTES = 64.0 * (1 << 20);

/* The MDE neighbour grid (grid.c): quads, slots and the sort scratch per agent, plus a table of
 * the next power of two >= 2n slots. */
static double grid_bytes(int64_t n)
{
    int64_t table = 64;
    while (table < 2 * n) table *= 2;
    return (double)n * (sizeof(fm_grid_quad) / 4.0 + sizeof(uint32_t) + sizeof(fm_grid_rec) + sizeof(uint32_t)) +
           (double)sizeof(int32_t) * (double)(table + 1);
}

/* A baked style-field grid holds 4 floats per cell (fields.c), when some field has a noise part. */
static double field_grid_bytes(const fm_scene_def *def)
{
    int noisy = 0;
    for (int i = 0; i < def->field_count; i++)
        noisy |= def->fields[i].kind == FM_FIELD_CURL_NOISE || def->fields[i].kind == FM_FIELD_WIND;
    const int32_t *g = def->field_grid;
    if (!noisy || g[0] <= 0 || g[1] <= 0 || g[2] <= 0) return 0;
    return 4.0 * sizeof(float) * (double)g[0] * (double)g[1] * (double)g[2];
}

/* Dense signed-distance grids (model.c): the obstacles' with the automatic voxel spans about 160
 * voxels plus the band per axis; a voxel the scene sets is bounded only by the refusal beyond
 * FM_OBSTACLE_MAX_VOXELS. The distance phase switch adds one more automatic grid. */
static double distance_grid_bytes(const fm_scene_def *def)
{
    const double automatic = sizeof(float) * 170.0 * 170.0 * 170.0;
    double bytes = 0;
    if (def->obstacle_count > 0)
        bytes += def->obstacle_voxel > 0 ? (double)FM_OBSTACLE_MAX_VOXELS * sizeof(float) : automatic;
    if (def->phase_switch == FM_SWITCH_DISTANCE) bytes += automatic;
    return bytes;
}

fm_memory_estimate fm_memory_estimate_run(const fm_scene_def *def, int64_t n)
{
    fm_memory_estimate e = {0};
    double agents = (double)n;
    e.model = MODEL_PER_AGENT;
    e.state = STATE_PER_AGENT;
    e.frames = frames_per_agent(def);
    e.grid = def->d_min > 0 && n > 0 ? grid_bytes(n) / agents : 0;
    e.per_agent = e.model + e.state + e.frames + e.grid;
    e.fixed = FIXED_BYTES + field_grid_bytes(def) + distance_grid_bytes(def);
    e.run = e.per_agent * agents + e.fixed;
    e.preprocess = (PREP_PER_AGENT + MODEL_PER_AGENT) * agents + e.fixed;
    e.total = e.run > e.preprocess ? e.run : e.preprocess;
    return e;
}

double fm_physical_memory(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    return pages > 0 && page > 0 ? (double)pages * (double)page : 0;
}

fm_status fm_memory_check(const fm_scene_def *def, int64_t n, fm_error *err)
{
    fm_memory_estimate e = fm_memory_estimate_run(def, n);
    double physical = fm_physical_memory(), gib = 1024.0 * 1024.0 * 1024.0;
    if (physical <= 0 || e.total <= physical) return FM_OK;
    double fits = (physical - e.fixed) / (e.total == e.run ? e.per_agent : PREP_PER_AGENT + MODEL_PER_AGENT);
    char where[FM_PATH_MAX + 64];
    fm_scene_key_location(def, "n", where, sizeof where);
    return fm_fail(err, FM_ERR_INPUT,
                   "%s: %lld agents need about %.1f GiB (%.0f bytes per agent: model %.0f, agent store %.0f, frame "
                   "buffers %.0f, neighbour grid %.0f; plus %.0f MiB that do not grow with n), more than this "
                   "machine's %.1f GiB of physical memory; at most about %.3g agents fit (docs/limits.md)",
                   where, (long long)n, e.total / gib, e.per_agent, e.model, e.state, e.frames, e.grid,
                   e.fixed / (1024.0 * 1024.0), physical / gib, fits > 0 ? fits : 0.0);
}
