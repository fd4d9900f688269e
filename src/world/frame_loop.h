/* The frame loop of both modes (fm_morph_run, morph_run.c; fm_flock_run, flock_run.c): frame 0 is the state
 * before any step; then each frame takes steps_per_frame steps (fewer for the last one if the simulation
 * finishes inside it) and is written, until the simulation finishes or frame_limit frames are
 * written. The loop measures the time spent stepping and writing. At every frame boundary it reads
 * a stop flag (a checkpoint, then FM_STOPPED) and takes the checkpoints that are due; a resumed run
 * continues after the frames it had written. */
#ifndef FM_FRAME_LOOP_H
#define FM_FRAME_LOOP_H

#include "fm_internal.h"

#include <signal.h>

typedef struct fm_loop_times {
    int64_t frames;          /* frames written (the resumed run's earlier ones included) */
    double simulate_seconds; /* in step(), this session */
    double output_seconds;   /* in frame(), this session */
} fm_loop_times;

typedef struct fm_frame_loop {
    void *sim;
    void (*step)(void *sim);
    int (*finished)(const void *sim);                           /* checked before every step */
    fm_status (*frame)(void *sim, int64_t frame, fm_error *err); /* computes and writes frame `frame` */
    int32_t steps_per_frame;
    int32_t frame_limit;
    volatile sig_atomic_t *stop;  /* may be NULL; non-zero: checkpoint and FM_STOPPED after the frame being written */
    int64_t resume_frames;        /* 0: a new run, frame 0 first; F > 0: frames 0 .. F-1 were written before */
    fm_status (*checkpoint)(void *sim, const fm_loop_times *times, fm_error *err); /* NULL: none */
    int64_t checkpoint_every;     /* frames between checkpoints; 0: not by count */
    double checkpoint_seconds;    /* wall time between checkpoints; 0: not by time */
    fm_cache_writer *cache;       /* may be NULL; flushed before every checkpoint (and on a stop), so
                                     the cache on disk holds the frames the checkpoint counts */
} fm_frame_loop;

fm_status fm_frame_loop_run(const fm_frame_loop *loop, fm_loop_times *times, fm_error *err);

#endif
