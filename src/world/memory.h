/* What a run of n agents needs in memory (memory.c, docs/limits.md). Each mode estimates its own
 * model, store and preparation (morph_memory.c, flock_memory.c) from the shared parts here, and
 * hands fm_memory_check the estimate, so that a run too large for the machine is refused before
 * anything big is allocated. */
#ifndef FM_MEMORY_H
#define FM_MEMORY_H

#include "fm_internal.h"

#include <stdint.h>

typedef struct fm_memory_estimate {
    double model, state, frames, grid; /* bytes per agent while stepping: model, agent store, frame
                                          buffers (run, cache writer, zstd output), neighbour grid */
    double per_agent;                  /* their sum: one process's (one rank's) */
    double shared;                     /* bytes per agent a machine holds once, whatever its ranks: the
                                          model on P ranks (fm_morph_model_build_shared); 0 otherwise */
    double fixed;                      /* bytes that do not grow with n: libraries, field and distance grids */
    double run;                        /* per_agent * n + fixed: one rank's */
    double preprocess_per_agent;       /* bytes per agent at the preparation's peak */
    double preprocess;                 /* preprocess_per_agent * n + fixed */
    int ranks_here;                    /* processes of the run on this machine (fm_memory_set_ranks) */
    int preparations_here;             /* of them, those that prepare the model: 1 when it is shared */
    double total;                      /* what this machine needs: the larger of its ranks' runs with the
                                          shared model (shared * n + ranks_here * run) and its preparations
                                          with the other ranks idle */
} fm_memory_estimate;

/* A mode's estimate and its neighbour grid, for fm_memory_check. */
typedef struct fm_memory_need {
    fm_memory_estimate estimate;
    const char *grid;      /* the grid's user for the refusal ("boids'", "MDE"); NULL: no grid */
    const char *grid_hint; /* appended to the grid's refusal (" or turn MDE off ..."); may be NULL */
} fm_memory_need;

/* Per agent: a frame of `frame` bytes in the run's buffers, the cache writer's and zstd's output. */
double fm_memory_frames_per_agent(const fm_scene_def *def, double frame);
/* The cache encoder's scratch, which does not grow with n past a piece: a block of the largest
 * attribute (`largest` bytes an agent) for each of its threads. */
double fm_memory_encoder_scratch_bytes(const fm_scene_def *def, int64_t n, double largest);
/* The neighbour grid (grid.c) for n agents, in bytes. */
double fm_memory_grid_bytes(int64_t n);
/* Bytes that do not grow with n: the libraries, a baked field grid, the distance grids. */
double fm_memory_fixed_bytes(const fm_scene_def *def);
/* The run's MPI ranks, and those on this machine (set once, before the model is built, by a run on
 * P ranks): an estimate is then one rank's (a mode counts its share of n), and the ranks on a
 * machine share its memory. 1 and 1 by default. */
void fm_memory_set_ranks(int ranks, int ranks_here);
int fm_memory_ranks(void);
/* Fills per_agent, run, preprocess, ranks_here, preparations_here and total from the parts. */
void fm_memory_total(fm_memory_estimate *e, int64_t n);
double fm_physical_memory(void); /* bytes (sysconf), or the address-space limit (RLIMIT_AS) if lower; 0 if unknown */
/* Whether the machine's total fits its physical memory (or that is unknown), and how many agents
 * would. */
int fm_memory_fits(const fm_memory_estimate *e);
double fm_memory_agents_that_fit(const fm_memory_estimate *e);

/* FM_ERR_INPUT naming the scene's n, the estimate and the machine's memory if it does not fit, or
 * the neighbour grid's capacity if n exceeds it. */
fm_status fm_memory_check(const fm_scene_def *def, int64_t n, const fm_memory_need *need, fm_error *err);

/* A shot's groups together (morph_shot.c, flock_shot.c): built one after another, then stepped side
 * by side, so the run holds every group's model, store and grid, one frame of the shot's rows (the
 * groups from a mesh) and every group's grids (the libraries once), and the preparation of group g
 * the models before it. agents[g]: group g's agents, 0 while not known (a tetra group with n 0
 * before TetGen: left out); estimate: the mode's (fm_morph_memory_estimate, fm_flock_memory_estimate).
 * FM_ERR_INPUT naming the groups and the machine's memory if they do not fit together. */
typedef fm_memory_estimate (*fm_memory_estimate_fn)(const fm_scene_def *def, int64_t n);
fm_status fm_memory_check_shot(const fm_scene_def *defs, const int64_t *agents, int count, fm_memory_estimate_fn estimate,
                               fm_error *err);

#endif
