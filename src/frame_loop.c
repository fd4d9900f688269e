/* The generic frame loop (frame_loop.h), used by the shape flock (flock_run.c). The tetra morph's
 * loop in run.c is the same loop plus checkpoints and resume. */
#include "frame_loop.h"

fm_status fm_frame_loop_run(const fm_frame_loop *loop, fm_loop_times *times, fm_error *err)
{
    *times = (fm_loop_times){0, 0, 0};
    double t0 = fm_seconds();
    fm_status st = loop->frame(loop->sim, 0, err);
    times->output_seconds += fm_seconds() - t0;
    times->frames = 1;
    while (st == FM_OK && !loop->finished(loop->sim) && times->frames < loop->frame_limit) {
        if (loop->stop && *loop->stop) return FM_STOPPED;
        t0 = fm_seconds();
        for (int32_t k = 0; k < loop->steps_per_frame && !loop->finished(loop->sim); k++) loop->step(loop->sim);
        double t1 = fm_seconds();
        times->simulate_seconds += t1 - t0;
        st = loop->frame(loop->sim, times->frames, err);
        times->output_seconds += fm_seconds() - t1;
        times->frames++;
    }
    return st;
}
