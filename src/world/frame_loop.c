/* The frame loop of both modes (frame_loop.h). */
#include "frame_loop.h"

/* When the last checkpoint was taken: every `every` frames and/or `seconds` of wall time. */
typedef struct checkpoint_clock {
    int64_t last_frames;
    double last_time;
} checkpoint_clock;

static int checkpoint_due(int64_t every, double seconds, const checkpoint_clock *clock, int64_t frames)
{
    if (every > 0 && frames - clock->last_frames >= every) return 1;
    return seconds > 0 && fm_seconds() - clock->last_time >= seconds;
}

static fm_status checkpoint(const fm_frame_loop *loop, checkpoint_clock *clock, const fm_loop_times *times,
                            fm_error *err)
{
    fm_status st = loop->cache ? fm_cache_writer_flush(loop->cache, err) : FM_OK;
    if (st == FM_OK && loop->checkpoint) st = loop->checkpoint(loop->sim, times, err);
    clock->last_frames = times->frames, clock->last_time = fm_seconds();
    return st;
}

fm_status fm_frame_loop_run(const fm_frame_loop *loop, fm_loop_times *times, fm_error *err)
{
    *times = (fm_loop_times){loop->resume_frames, 0, 0};
    checkpoint_clock clock = {times->frames, fm_seconds()};
    fm_status st = FM_OK;
    if (!loop->resume_frames) {
        double t0 = fm_seconds();
        st = loop->frame(loop->sim, 0, err);
        times->output_seconds += fm_seconds() - t0;
        times->frames = 1;
    }
    while (st == FM_OK && !loop->finished(loop->sim) && times->frames < loop->frame_limit) {
        if (loop->stop && *loop->stop) {
            st = checkpoint(loop, &clock, times, err);
            return st == FM_OK ? FM_STOPPED : st;
        }
        if (loop->checkpoint && checkpoint_due(loop->checkpoint_every, loop->checkpoint_seconds, &clock, times->frames) &&
            (st = checkpoint(loop, &clock, times, err)) != FM_OK)
            break;
        double t0 = fm_seconds();
        for (int32_t k = 0; k < loop->steps_per_frame && !loop->finished(loop->sim); k++) loop->step(loop->sim);
        double t1 = fm_seconds();
        times->simulate_seconds += t1 - t0;
        st = loop->frame(loop->sim, times->frames, err);
        times->output_seconds += fm_seconds() - t1;
        times->frames++;
    }
    return st;
}
