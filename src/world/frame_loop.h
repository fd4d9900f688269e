/* The frame loop of both modes (fm_morph_run, morph_run.c; fm_flock_run, flock_run.c): frame 0 is
 * the state before any step; then each frame takes steps_per_frame steps (fewer for the last one if
 * the simulation finishes inside it) and is written, until the simulation finishes or frame_limit
 * frames are written. The loop measures the time spent stepping and writing. At every frame
 * boundary it reads the control's stop flag (a checkpoint, then FM_STOPPED) and takes the
 * checkpoints that are due: the cache flushed, the mode's checkpoint saved to the control's path,
 * the control's hook called. A resumed run continues after the frames it had written. */
#ifndef FM_FRAME_LOOP_H
#define FM_FRAME_LOOP_H

#include "dist.h"
#include "fm_internal.h"

typedef struct fm_frame_loop {
    void *sim;
    void (*step)(void *sim);
    int (*finished)(const void *sim);                           /* checked before every step */
    fm_status (*frame)(void *sim, int64_t frame, fm_error *err); /* computes and writes frame `frame` */
    fm_status (*save)(void *sim, const char *path, fm_error *err); /* the mode's checkpoint, to path */
    int32_t steps_per_frame;
    int32_t frame_limit;
    const fm_run_control *control; /* stop flag, checkpoints and resume (run.h) */
    fm_run_totals *totals;         /* the run's statistics' totals, kept current: a resumed run's
                                      (frames > 0) or zero for a new run, which writes frame 0 first;
                                      the loop adds frames and seconds, the mode sets the steps */
    fm_cache_writer *cache;        /* may be NULL; flushed before every checkpoint (and on a stop), so
                                      the cache on disk holds the frames the checkpoint counts */
    const fm_dist *dist;           /* on P ranks (NULL: one process): a stop or a checkpoint any rank
                                      wants is taken by all at the same frame (a signal, the wall
                                      clock reach each rank at its own time) */
    fm_status (*sync)(void *sim, fm_error *err); /* may be NULL; on P ranks, after the cache's flush
                                      before a checkpoint: the ranks' own writes to it on disk */
} fm_frame_loop;

fm_status fm_frame_loop_run(const fm_frame_loop *loop, fm_error *err);

/* For the shots (morph_shot.c, flock_shot.c): the progress of frame k, the phase counts summed over
 * the groups that write rows (writes[g]; counts[g] their fm_phase counts). */
/* The step at which a shot's group may start: `start` seconds (rounded up to whole steps of dt)
 * after step 0, or after the step its `after` group was done (done_step[after]; -1 while it is
 * not, and then so is the result). */
int64_t fm_frame_loop_group_start(const fm_group_def *group, const int64_t *done_step, double dt);
void fm_frame_loop_shot_progress(const fm_run_control *c, int64_t k, int64_t step, double dt,
                                 const int64_t *const *counts, const int *writes, int groups);

/* Agents farther than this many scene sizes from the scene's box have run away: no scene the
 * engine is meant for flies there, and float positions lose their precision on the way. */
#define FM_RUNAWAY_SCENES 1000.0

/* A frame must show a sane state (issue 15): every position value (per_agent floats per agent,
 * agents in id order) finite and within FM_RUNAWAY_SCENES scene sizes of the box [lo, hi] (the
 * mode's scene bounds). Otherwise FM_ERR_INPUT naming the frame, the agent and its value, and
 * `hint`: the parameters that set the mode's speeds and forces. Nothing is written then. */
fm_status fm_frame_check_runaway(const float *pos, int per_agent, int64_t n, const double lo[3], const double hi[3],
                                 int64_t frame, const char *hint, fm_error *err);
/* The same for the agents first … first + n − 1 of a frame, pos pointing at agent first's values
 * (a rank's share of the frame on P ranks): the message names the agent's id. */
fm_status fm_frame_check_runaway_from(const float *pos, int per_agent, int64_t first, int64_t n, const double lo[3],
                                      const double hi[3], int64_t frame, const char *hint, fm_error *err);

/* Per-frame statistics (a mode's run stats): makes room in *rows (malloc'ed, or NULL) for `count`
 * rows of `width` doubles, growing by doubling from 1024 rows; *capacity is its rows so far (0 for
 * an array that holds exactly what a checkpoint restored). */
fm_status fm_frame_rows_room(double **rows, int64_t count, int width, int64_t *capacity, fm_error *err);

#endif
