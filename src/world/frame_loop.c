/* The frame loop of both modes (frame_loop.h). */
#include "frame_loop.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

fm_run_control fm_default_run_control(void)
{
    fm_run_control c;
    memset(&c, 0, sizeof c);
    return c;
}

/* When the last checkpoint was taken: every `every` frames and/or `seconds` of wall time. */
typedef struct checkpoint_clock {
    int64_t last_frames;
    double last_time;
} checkpoint_clock;

static int takes_checkpoints(const fm_run_control *c)
{
    return c->checkpoint_path || c->checkpoint;
}

static int checkpoint_due(const fm_run_control *c, const checkpoint_clock *clock, int64_t frames)
{
    if (c->checkpoint_every > 0 && frames - clock->last_frames >= c->checkpoint_every) return 1;
    return c->checkpoint_seconds > 0 && fm_seconds() - clock->last_time >= c->checkpoint_seconds;
}

static fm_status checkpoint(const fm_frame_loop *loop, checkpoint_clock *clock, const fm_run_totals *times,
                            fm_error *err)
{
    const fm_run_control *c = loop->control;
    fm_status st = loop->cache ? fm_cache_writer_flush(loop->cache, err) : FM_OK;
    st = fm_dist_agree(loop->dist, st, err); /* on P ranks only rank 0 has the cache; the save is collective */
    if (st == FM_OK && loop->sync) st = loop->sync(loop->sim, err); /* collective, agreed */
    if (st == FM_OK && c->checkpoint_path) st = loop->save(loop->sim, c->checkpoint_path, err);
    if (st == FM_OK && c->checkpoint) st = c->checkpoint(times->frames, c->checkpoint_user, err);
    clock->last_frames = times->frames, clock->last_time = fm_seconds();
    return st;
}

/* Whether any rank says yes (one process: whether this one does). */
static int agreed(const fm_frame_loop *loop, int yes)
{
    int64_t v = yes;
    fm_dist_max_i64(loop->dist, &v, 1);
    return v != 0;
}

fm_status fm_frame_loop_run(const fm_frame_loop *loop, fm_error *err)
{
    const fm_run_control *c = loop->control;
    fm_run_totals *times = loop->totals;
    checkpoint_clock clock = {times->frames, fm_seconds()};
    fm_status st = FM_OK;
    if (!times->frames) {
        double t0 = fm_seconds();
        st = loop->frame(loop->sim, 0, err);
        times->output_seconds += fm_seconds() - t0;
        times->frames = 1;
    }
    while (st == FM_OK && !loop->finished(loop->sim) && times->frames < loop->frame_limit) {
        const int planned = c->stop_frames > 0 && times->frames >= c->stop_frames; /* the same on every rank */
        if (planned || agreed(loop, c->stop && *c->stop)) {
            st = checkpoint(loop, &clock, times, err); /* the cache flushed at least */
            return st == FM_OK ? FM_STOPPED : st;
        }
        if (takes_checkpoints(c) && agreed(loop, checkpoint_due(c, &clock, times->frames)) &&
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

fm_status fm_frame_check_runaway(const float *pos, int per_agent, int64_t n, const double lo[3], const double hi[3],
                                 int64_t frame, const char *hint, fm_error *err)
{
    return fm_frame_check_runaway_from(pos, per_agent, 0, n, lo, hi, frame, hint, err);
}

fm_status fm_frame_check_runaway_from(const float *pos, int per_agent, int64_t first_agent, int64_t n, const double lo[3],
                                      const double hi[3], int64_t frame, const char *hint, fm_error *err)
{
    double size = 0, min[3], max[3];
    for (int k = 0; k < 3; k++) size = fmax(size, hi[k] - lo[k]);
    for (int k = 0; k < 3; k++) min[k] = lo[k] - FM_RUNAWAY_SCENES * size, max[k] = hi[k] + FM_RUNAWAY_SCENES * size;
    const int64_t points = n * per_agent / 3;
    int64_t first = INT64_MAX; /* the first bad value: the same for any thread count */
#pragma omp parallel for num_threads(fm_threads(0)) reduction(min : first) schedule(static)
    for (int64_t i = 0; i < points; i++) { /* x, y, z of one point; a bad one is rare */
        const float *q = pos + 3 * i;
        if (!(q[0] >= min[0] && q[0] <= max[0] && q[1] >= min[1] && q[1] <= max[1] && q[2] >= min[2] && q[2] <= max[2]))
            for (int k = 0; k < 3; k++)
                if (!(q[k] >= min[k] && q[k] <= max[k]) && 3 * i + k < first) first = 3 * i + k;
    }
    if (first == INT64_MAX) return FM_OK;
    const int64_t agent = first_agent + first / per_agent;
    const float *p = pos + first - first % 3;
    char where[96];
    if (isfinite(pos[first])) snprintf(where, sizeof where, "flew over %g scene sizes out of the scene", FM_RUNAWAY_SCENES);
    else snprintf(where, sizeof where, "is not finite");
    return fm_fail(err, FM_ERR_INPUT,
                   "frame %lld: agent %lld %s (%g, %g, %g): the simulation ran away; check the parameters that set "
                   "speeds and forces: %s", (long long)frame, (long long)agent, where, p[0], p[1], p[2], hint);
}

fm_status fm_frame_rows_room(double **rows, int64_t count, int width, int64_t *capacity, fm_error *err)
{
    if (count <= *capacity) return FM_OK;
    int64_t cap = *capacity > 0 ? *capacity : 1024;
    while (cap < count) cap *= 2;
    double *grown = realloc(*rows, sizeof(double) * (size_t)width * (size_t)cap);
    if (!grown) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the per-frame statistics");
    *rows = grown, *capacity = cap;
    return FM_OK;
}

int64_t fm_frame_loop_group_start(const fm_group_def *group, const int64_t *done_step, double dt)
{
    const int64_t from = group->after < 0 ? 0 : done_step[group->after];
    return from < 0 ? -1 : from + (int64_t)ceil(group->start / dt - 1e-9);
}

void fm_frame_loop_shot_progress(const fm_run_control *c, int64_t k, int64_t step, double dt,
                                 const int64_t *const *counts, const int *writes, int groups)
{
    if (k == 0 || !c->progress) return;
    fm_run_info info = {.step = step, .time = (double)step * dt};
    for (int g = 0; g < groups; g++)
        for (int p = 0; writes[g] && p < 4; p++) info.count[p] += counts[g][p];
    c->progress(&info, k, c->progress_user);
}
