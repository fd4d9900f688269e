/* flockmorph runs, in either mode: one control for progress, checkpoints, a stop flag and resume
 * (fm_morph_run_controlled, fm_flock_run_controlled; docs/resume.md). */
#ifndef FLOCKMORPH_RUN_H
#define FLOCKMORPH_RUN_H

#include "flockmorph/scene.h"
#include <signal.h>

#ifdef __cplusplus
extern "C" {
#endif

/* What every mode reports about its state: the clock and the agents per phase. */
typedef struct fm_run_info {
    int64_t step;
    double time;               /* seconds of animation time */
    int64_t count[4];          /* agents per fm_phase */
} fm_run_info;

/* What every run measures (the first member of each mode's run statistics): the totals of a
 * resumed run include its earlier sessions. */
typedef struct fm_run_totals {
    int64_t frames;            /* frames written, frame 0 (the rest state) included */
    int64_t steps;
    double simulate_seconds;   /* time spent stepping */
    double output_seconds;     /* time spent computing and writing frames */
} fm_run_totals;

/* Called after every frame (frame >= 1); may be NULL. */
typedef void (*fm_run_progress_fn)(const fm_run_info *info, int64_t frame, void *user);

/* Called at a checkpoint: at a frame boundary once the cache is flushed (its first `frames` frames
 * are on disk) and, when checkpoint_path is set, after the run's checkpoint is saved there. A
 * failure ends the run. */
typedef fm_status (*fm_run_checkpoint_fn)(int64_t frames, void *user, fm_error *err);

typedef struct fm_run_control {
    fm_run_progress_fn progress;     /* after every frame; may be NULL */
    void *progress_user;
    int resume;                      /* 0: a new run (frame 0 is written first, stats start at zero);
                                        1: state and stats were restored by the mode's checkpoint load
                                        and the run continues after frame stats->frames - 1 */
    const char *checkpoint_path;     /* NULL: the run saves no checkpoint; else it saves its mode's
                                        checkpoint (fm_morph_checkpoint_save, fm_flock_checkpoint_save)
                                        here whenever one is due */
    fm_run_checkpoint_fn checkpoint; /* NULL: no hook; called at every checkpoint */
    void *checkpoint_user;
    int64_t checkpoint_every;        /* checkpoint every this many frames; 0: not by frame count */
    double checkpoint_seconds;       /* ... or when this much wall time passed since the last one
                                        (or the start); 0: not by time. Checkpoints are taken only
                                        when checkpoint_path or checkpoint is set */
    volatile sig_atomic_t *stop;     /* may be NULL; read at every frame boundary: when non-zero, the
                                        run checkpoints there (if it takes checkpoints) and returns
                                        FM_STOPPED (unless that frame already ends the run), every
                                        frame so far handed to the cache and the stats filled in */
    int64_t stop_frames;             /* 0, or a planned stop: once this many frames are written (frame
                                        0 included) the run stops as for the stop flag, unless it
                                        ended first (a farm's job split into segments) */
} fm_run_control;

/* No checkpoints, no stop flag, a new run. */
fm_run_control fm_default_run_control(void);

/* Checks a checkpoint file of either mode against a scene before the (long) model build: readable, undamaged
 * (checksum), this version's layout, written for the same scene parameters. FM_ERR_INPUT with a
 * message saying which, FM_ERR_IO if it cannot be read. */
fm_status fm_checkpoint_check(const char *path, const fm_scene_def *def, fm_error *err);

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_RUN_H */
