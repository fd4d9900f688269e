/* The frame loop shared by the tetra morph (fm_run, run.c) and the shape flock (fm_flock_run,
 * flock_run.c): frame 0 is the state before any step; then each frame takes steps_per_frame steps
 * (fewer for the last one if the simulation finishes inside it) and is written, until the
 * simulation finishes or frame_limit frames are written. The loop measures the time spent stepping
 * and writing. A stop flag, read at every frame boundary, ends it there with FM_STOPPED. */
#ifndef FM_FRAME_LOOP_H
#define FM_FRAME_LOOP_H

#include "fm_internal.h"

#include <signal.h>

typedef struct fm_frame_loop {
    void *sim;
    void (*step)(void *sim);
    int (*finished)(const void *sim);                           /* checked before every step */
    fm_status (*frame)(void *sim, int64_t frame, fm_error *err); /* computes and writes frame `frame` */
    int32_t steps_per_frame;
    int32_t frame_limit;
    volatile sig_atomic_t *stop; /* may be NULL; non-zero: FM_STOPPED after the frame being written */
} fm_frame_loop;

typedef struct fm_loop_times {
    int64_t frames;          /* frames written */
    double simulate_seconds; /* in step() */
    double output_seconds;   /* in frame() */
} fm_loop_times;

fm_status fm_frame_loop_run(const fm_frame_loop *loop, fm_loop_times *times, fm_error *err);

#endif
