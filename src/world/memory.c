/* The memory check (memory.h): the parts of an estimate that every mode shares (frame buffers,
 * the neighbour grid, the field and distance grids, the libraries) and the refusal of a run too
 * large for the machine, before anything big is allocated. Each mode adds its own model and store
 * (morph_memory.c, flock_memory.c; docs/limits.md). */
#define _POSIX_C_SOURCE 200809L
#include "cache_format.h"
#include "grid.h"
#include "memory.h"
#include "obstacles.h"
#include "scene_internal.h"

#include <math.h>
#include <stdio.h>
#include <sys/resource.h>
#include <unistd.h>

/* A frame of `frame` bytes per agent: the run's own buffers (morph_run.c, flock_run.c). The cache
 * writer's frame also holds the ids (4 B, which the writer hands over itself): its two hand-over
 * slots, the previous frame's words when delta is on and the frame's stored words (cache_encode.c),
 * the chunk (zstd's output bound: 1/256 more than its input) and the ids. */
double fm_memory_frames_per_agent(const fm_scene_def *def, double frame)
{
    const double cached = frame + sizeof(uint32_t);
    return frame + cached * (CACHE_WRITER_SLOTS + (def->cache_delta ? 1 : 0) + 1) + cached * (1 + 1.0 / 256) +
           sizeof(uint32_t);
}

double fm_memory_encoder_scratch_bytes(const fm_scene_def *def, int64_t n, double largest)
{
    const int64_t piece = def->cache_piece_agents > 0 ? def->cache_piece_agents : n;
    return CACHE_ENCODER_THREADS * (double)(n < piece ? n : piece) * largest;
}

/* Not proportional to n: the libraries (TetGen, OpenVDB, Embree, zstd's two workers), measured on
 * a 200-agent run (docs/limits.md). */
static const double FIXED_BYTES = 64.0 * (1 << 20);

/* The MDE neighbour grid (grid.c): quads, slots and the sort scratch per agent, plus a table of
 * the next power of two >= 2n slots. */
double fm_memory_grid_bytes(int64_t n)
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

/* Dense signed-distance grids (scene_obstacles.c, morph_model.c): the obstacles' with the automatic voxel spans about 160
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

double fm_memory_fixed_bytes(const fm_scene_def *def)
{
    return FIXED_BYTES + field_grid_bytes(def) + distance_grid_bytes(def);
}

static int run_ranks = 1, run_ranks_here = 1;

void fm_memory_set_ranks(int ranks, int ranks_here)
{
    run_ranks = ranks > 1 ? ranks : 1, run_ranks_here = ranks_here > 1 ? ranks_here : 1;
}

int fm_memory_ranks(void) { return run_ranks; }

void fm_memory_total(fm_memory_estimate *e, int64_t n)
{
    const double ranks = e->ranks_here = run_ranks_here;
    const double preparations = e->preparations_here = e->shared > 0 ? 1 : run_ranks_here;
    e->per_agent = e->model + e->state + e->frames + e->grid;
    e->run = e->per_agent * (double)n + e->fixed;
    e->preprocess = e->preprocess_per_agent * (double)n + e->fixed;
    const double running = e->shared * (double)n + ranks * e->run;
    const double preparing = preparations * e->preprocess + (ranks - preparations) * e->fixed; /* the others wait */
    e->total = running > preparing ? running : preparing;
}

double fm_physical_memory(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    double bytes = pages > 0 && page > 0 ? (double)pages * (double)page : 0;
    /* a process limited to less address space (ulimit -v, a farm's cap) has only that: refused here,
     * a run fails at once instead of after TetGen has spent minutes filling the limit */
    struct rlimit limit;
    if (getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY && (bytes <= 0 || (double)limit.rlim_cur < bytes))
        bytes = (double)limit.rlim_cur;
    return bytes;
}

int fm_memory_fits(const fm_memory_estimate *e)
{
    double physical = fm_physical_memory();
    return physical <= 0 || e->total <= physical;
}

double fm_memory_agents_that_fit(const fm_memory_estimate *e)
{
    const double ranks = FM_MAX(e->ranks_here, 1), preparations = FM_MAX(e->preparations_here, 1);
    const double room = fm_physical_memory() - ranks * e->fixed;
    double fits = fmin(room / (e->shared + ranks * e->per_agent), room / (preparations * e->preprocess_per_agent));
    return fits > 0 ? fits : 0;
}

/* The neighbour grid (the shape flock's boids, the tetra morph's MDE) lists at most
 * FM_GRID_MAX_CAPACITY agents. */
static fm_status grid_capacity_check(const fm_memory_need *need, int64_t n, const char *where, fm_error *err)
{
    if (!need->grid || n <= FM_GRID_MAX_CAPACITY) return FM_OK;
    return fm_fail(err, FM_ERR_INPUT, "%s: %lld agents is more than the %s neighbour grid holds (%lld); lower n%s", where,
                   (long long)n, need->grid, (long long)FM_GRID_MAX_CAPACITY, need->grid_hint ? need->grid_hint : "");
}

fm_status fm_memory_check(const fm_scene_def *def, int64_t n, const fm_memory_need *need, fm_error *err)
{
    char where[FM_PATH_MAX + 64];
    fm_scene_key_location(def, "n", where, sizeof where);
    fm_status st = grid_capacity_check(need, n, where, err);
    if (st != FM_OK) return st;
    const fm_memory_estimate e = need->estimate;
    double physical = fm_physical_memory(), gib = 1024.0 * 1024.0 * 1024.0;
    if (fm_memory_fits(&e)) return FM_OK;
    double fits = fm_memory_agents_that_fit(&e);
    if (e.shared > 0)
        return fm_fail(err, FM_ERR_INPUT,
                       "%s: %lld agents need about %.1f GiB on this machine's %d ranks (bytes per agent: the model %.0f, "
                       "once; and on each rank agent store %.0f, frame buffers %.0f, neighbour grid %.0f, plus %.0f MiB "
                       "that do not grow with n), more than its %.1f GiB of physical memory (or ulimit -v); at most about %.3g agents "
                       "fit (docs/limits.md)", where, (long long)n, e.total / gib, e.ranks_here, e.shared, e.state, e.frames,
                       e.grid, e.fixed / (1024.0 * 1024.0), physical / gib, fits);
    char ranks[96] = "";
    if (e.ranks_here > 1) snprintf(ranks, sizeof ranks, " on this machine's %d ranks, each", e.ranks_here);
    return fm_fail(err, FM_ERR_INPUT,
                   "%s: %lld agents need about %.1f GiB%s (%.0f bytes per agent: model %.0f, agent store %.0f, frame "
                   "buffers %.0f, neighbour grid %.0f; plus %.0f MiB that do not grow with n), more than this "
                   "machine's %.1f GiB of physical memory (or ulimit -v); at most about %.3g agents fit (docs/limits.md)",
                   where, (long long)n, e.total / gib, ranks, e.per_agent, e.model, e.state, e.frames, e.grid,
                   e.fixed / (1024.0 * 1024.0), physical / gib, fits);
}

/* The shot's groups and their agents, for the refusal: "king 1.5e+07, rook 1.5e+07". */
static void list_groups(const fm_scene_def *defs, const int64_t *agents, int count, char *out, size_t size)
{
    size_t used = 0;
    out[0] = 0;
    for (int g = 0; g < count && used < size; g++)
        used += (size_t)snprintf(out + used, size - used, "%s%s %.3g", g ? ", " : "", defs[g].group.name, (double)agents[g]);
}

fm_status fm_memory_check_shot(const fm_scene_def *defs, const int64_t *agents, int count, fm_memory_estimate_fn estimate,
                               fm_error *err)
{
    double models = 0, shared = 0, stores = 0, frame = 0, fixed = FIXED_BYTES, preparation = 0, rows = 0;
    int here = 1;
    for (int g = 0; g < count; g++) {
        if (agents[g] <= 0) continue;
        const fm_memory_estimate e = estimate(&defs[g], agents[g]);
        const double n = (double)agents[g];
        preparation = fmax(preparation, models + shared + e.preprocess_per_agent * n); /* beside the groups before */
        models += e.model * n, shared += e.shared * n, stores += (e.state + e.grid) * n;
        frame = fmax(frame, e.frames), fixed += e.fixed - FIXED_BYTES, here = e.ranks_here;
        if (defs[g].group.source_group < 0) rows += n;
    }
    /* a machine: one copy of the shared models, each rank's own part; one rank prepares when shared */
    const int preparations = shared > 0 ? 1 : here;
    const double run = models + stores + frame * rows, running = shared + here * (run + fixed);
    const double preparing = preparations * (preparation + fixed) + (here - preparations) * (fixed + models);
    const double total = fmax(running, preparing), physical = fm_physical_memory(), gib = 1024.0 * 1024.0 * 1024.0;
    if (physical <= 0 || total <= physical) return FM_OK;
    char groups[512], ranks[96] = "";
    list_groups(defs, agents, count, groups, sizeof groups);
    if (here > 1) snprintf(ranks, sizeof ranks, " on this machine's %d ranks", here);
    return fm_fail(err, FM_ERR_INPUT,
                   "%s: the shot's %d groups (%s agents) need about %.1f GiB together%s (models %.1f GiB%s, agent "
                   "stores and grids %.1f GiB, a frame of %.3g rows %.1f GiB, preparation peak %.1f GiB; plus %.0f MiB "
                   "that do not grow with n), more than this machine's %.1f GiB of physical memory (or ulimit -v): lower the groups' "
                   "n (docs/limits.md)", defs[0].scene_path, count, groups, total / gib, ranks, (models + shared) / gib,
                   shared > 0 ? " once" : here > 1 ? " on each rank" : "", stores / gib, rows, frame * rows / gib,
                   preparation / gib, fixed / (1024.0 * 1024.0), physical / gib);
}
