/* What a run of n agents needs in memory, estimated from the layouts of the model, the agent
 * store, the frame buffers and the neighbour grid of either mode (the tetra morph's fm_model and
 * fm_state, the shape flock's fm_flock_model and fm_flock_state; docs/limits.md), so that a run
 * too large for the machine is refused before anything big is allocated. */
#define _POSIX_C_SOURCE 200809L
#include "cache_format.h"
#include "flock.h"
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
/* A frame of `frame` bytes per agent whose largest attribute takes `largest`: the run's own buffers
 * (run.c, flock_run.c). The cache writer's frame also holds the ids (4 B, which the writer hands over
 * itself): its two hand-over slots, the previous frame when delta is on (cache_writer.c), its
 * quantise and filter buffers (the largest attribute) and the chunk (zstd's output bound: 1/256 more
 * than its input). */
static double frames_per_agent(const fm_scene_def *def, double frame, double largest)
{
    const double cached = frame + sizeof(uint32_t);
    return frame + cached * (CACHE_WRITER_SLOTS + (def->cache_delta ? 1 : 0)) + 2 * largest + cached * (1 + 1.0 / 256) +
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
    e.frames = frames_per_agent(def, 12 * sizeof(float) + 1, 12 * sizeof(float)); /* tet vertices, phase */
    e.grid = def->d_min > 0 && n > 0 ? grid_bytes(n) / agents : 0;
    e.per_agent = e.model + e.state + e.frames + e.grid;
    e.fixed = FIXED_BYTES + field_grid_bytes(def) + distance_grid_bytes(def);
    e.run = e.per_agent * agents + e.fixed;
    e.preprocess_per_agent = PREP_PER_AGENT + MODEL_PER_AGENT;
    e.preprocess = e.preprocess_per_agent * agents + e.fixed;
    e.total = e.run > e.preprocess ? e.run : e.preprocess;
    return e;
}

/* The shape flock (flock_model.c, flock_state.c, flock_run.c). The model: start and destination at
 * time 0 (6 floats), the boids parameters (3 rules x radius, angle, weight; max speed and force)
 * and the destination's sample (a point, barycentrics, a triangle). */
static const double FLOCK_MODEL_PER_AGENT = sizeof(float) * (6 + 3 * FM_BOIDS_RULES + 2) + sizeof(float) * 6 + sizeof(int32_t);
/* The store: p, v, dest, dest_v, leader, leader_v, acc, ext (3 floats each), the orientation, the
 * bind time and homing weight, phase and grid membership, the per-block counts. */
static const double FLOCK_STATE_PER_AGENT = sizeof(float) * (8 * 3 + 4 + 2) + 2 + (double)sizeof(flock_block) / FM_BLOCK;
/* A deforming target's destinations, evaluated each step (3 floats). */
static const double FLOCK_DEFORM_PER_AGENT = sizeof(float) * 3;
/* The frame: position, velocity (3 floats), orientation (4) and phase (1 byte). */
static const double FLOCK_FRAME = sizeof(float) * (3 + 3 + 4) + 1, FLOCK_LARGEST_ATTR = sizeof(float) * 4;

/* The peak of preprocessing, while the target is sampled: the model, the agent-sample match
 * (int64) and the source's samples (point, barycentrics, triangle), plus the sampler's own arrays
 * per sample (sample.c, sample_mosaic.c, sample_stratified.c): the double points and triangles;
 * for mosaic also a float copy, the neighbour grid, the moved points and the Hilbert sort's keys
 * and copies; for stratified the candidates (point in double, triangle) and their elimination's
 * float copy, flags, neighbours, keys, heap and grid, 1.1 x oversample candidates per sample. */
static double flock_preprocess_per_agent(const fm_scene_def *def, int64_t n)
{
    const double samples = sizeof(float) * 6 + sizeof(int32_t), points = sizeof(double) * 3 + sizeof(int32_t);
    const double grid = n > 0 ? grid_bytes(n) / (double)n : 0;
    double sampler = points;
    if (def->flock.sampling == FM_FLOCK_SAMPLE_MOSAIC)
        sampler += sizeof(float) * 3 + grid + points + sizeof(fm_keyed) + points;
    else if (def->flock.sampling == FM_FLOCK_SAMPLE_STRATIFIED) {
        const double candidate = points + 4 /* padding */ + sizeof(float) * 3 + 1 + sizeof(int64_t) + sizeof(double) +
                                 sizeof(double) + sizeof(int64_t) + grid;
        sampler += 1.1 * FM_SAMPLE_OVERSAMPLE * candidate;
    }
    return FLOCK_MODEL_PER_AGENT + sizeof(int64_t) + samples + sampler;
}

fm_memory_estimate fm_flock_memory_estimate(const fm_scene_def *def, int64_t n)
{
    fm_memory_estimate e = {0};
    double agents = (double)n;
    e.model = FLOCK_MODEL_PER_AGENT;
    e.state = FLOCK_STATE_PER_AGENT + (def->flock.deform != FM_DEFORM_NONE ? FLOCK_DEFORM_PER_AGENT : 0);
    e.frames = frames_per_agent(def, FLOCK_FRAME, FLOCK_LARGEST_ATTR);
    e.grid = n > 0 ? grid_bytes(n) / agents : 0; /* the boids' neighbour grid, always */
    e.per_agent = e.model + e.state + e.frames + e.grid;
    e.fixed = FIXED_BYTES + field_grid_bytes(def) + distance_grid_bytes(def);
    e.run = e.per_agent * agents + e.fixed;
    e.preprocess_per_agent = flock_preprocess_per_agent(def, n);
    e.preprocess = e.preprocess_per_agent * agents + e.fixed;
    e.total = e.run > e.preprocess ? e.run : e.preprocess;
    return e;
}

double fm_physical_memory(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    return pages > 0 && page > 0 ? (double)pages * (double)page : 0;
}

fm_memory_estimate fm_memory_estimate_for(const fm_scene_def *def, int64_t n)
{
    return def->mode == FM_MODE_SHAPE_FLOCK ? fm_flock_memory_estimate(def, n) : fm_memory_estimate_run(def, n);
}

/* The neighbour grid (the shape flock's boids, the tetra morph's MDE) lists at most
 * FM_GRID_MAX_CAPACITY agents. */
static fm_status grid_capacity_check(const fm_scene_def *def, int64_t n, const char *where, fm_error *err)
{
    int flock = def->mode == FM_MODE_SHAPE_FLOCK;
    if (!(flock || def->d_min > 0) || n <= FM_GRID_MAX_CAPACITY) return FM_OK;
    return fm_fail(err, FM_ERR_INPUT, "%s: %lld agents is more than the %s neighbour grid holds (%lld); lower n%s", where,
                   (long long)n, flock ? "boids'" : "MDE", (long long)FM_GRID_MAX_CAPACITY,
                   flock ? "" : " or turn MDE off (mde.d_min 0)");
}

fm_status fm_memory_check(const fm_scene_def *def, int64_t n, fm_error *err)
{
    char where[FM_PATH_MAX + 64];
    fm_scene_key_location(def, "n", where, sizeof where);
    fm_status st = grid_capacity_check(def, n, where, err);
    if (st != FM_OK) return st;
    fm_memory_estimate e = fm_memory_estimate_for(def, n);
    double physical = fm_physical_memory(), gib = 1024.0 * 1024.0 * 1024.0;
    if (physical <= 0 || e.total <= physical) return FM_OK;
    double fits = (physical - e.fixed) / (e.total == e.run ? e.per_agent : e.preprocess_per_agent);
    return fm_fail(err, FM_ERR_INPUT,
                   "%s: %lld agents need about %.1f GiB (%.0f bytes per agent: model %.0f, agent store %.0f, frame "
                   "buffers %.0f, neighbour grid %.0f; plus %.0f MiB that do not grow with n), more than this "
                   "machine's %.1f GiB of physical memory; at most about %.3g agents fit (docs/limits.md)",
                   where, (long long)n, e.total / gib, e.per_agent, e.model, e.state, e.frames, e.grid,
                   e.fixed / (1024.0 * 1024.0), physical / gib, fits > 0 ? fits : 0.0);
}
