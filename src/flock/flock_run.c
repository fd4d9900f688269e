/* fm_flock_run: the shape flock's frames through the shared frame loop, the flock measures of every
 * frame (flock_measures.c) and its end-state measures (distance to the destinations, the bound
 * fraction, the tracking lag). */
#include "cache_format.h"
#include "flock.h"
#include "frame_loop.h"
#include "frame_share.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The attributes of a flock cache, in the order fm_flock_run hands them over. */
static const fm_cache_attr FLOCK_ATTRS[] = {FM_ATTR_POSITION, FM_ATTR_VELOCITY, FM_ATTR_ORIENTATION, FM_ATTR_ID,
                                            FM_ATTR_PHASE};
enum { FLOCK_ATTR_COUNT = sizeof FLOCK_ATTRS / sizeof FLOCK_ATTRS[0] };

fm_cache_writer *fm_flock_cache_create(const char *path, const fm_flock_model *m, const fm_cache_options *opts, fm_error *err)
{
    fm_cache_options o = opts ? *opts : fm_default_cache_options();
    return fm_cache_writer_create_attrs(path, (uint64_t)m->n, m->def.frame_rate, FLOCK_ATTRS, FLOCK_ATTR_COUNT, &o, err);
}

typedef struct flock_run {
    const fm_flock_model *m;
    fm_flock_state *s;
    float *position, *velocity, *orientation;
    uint8_t *phase;
    fm_cache_writer *cache;
    const fm_run_control *c;
    fm_flock_run_stats *stats;
    int64_t capacity;  /* rows of stats->measures */
    fm_frame_share share; /* on P ranks: this rank's share of every frame (the cache written in parallel) */
} flock_run;

static void flock_step(void *sim)
{
    flock_run *r = sim;
    fm_flock_step(r->m, r->s);
}

/* A static target with binding is done when every agent is bound (a travelling one once it has
 * stopped, too); floating agents and a deforming target keep going to the frame limit. */
static int flock_finished(const void *sim)
{
    const flock_run *r = sim;
    const fm_flock_def *f = &r->m->def.flock;
    return f->deform == FM_DEFORM_NONE && f->arrival_mode == FM_ARRIVAL_BIND && r->s->count[FM_PHASE_ARRIVED] == r->s->n &&
           r->s->time >= fm_flock_target_travel_end(&r->m->target);
}

/* What sets the shape flock's speeds and forces, for a runaway's message. */
static const char *const FLOCK_FORCES = "shape_flock.mass, max_speed and max_force, the boids weights, the fuzzy "
                                        "weights, damping and external_gain, speed0, time.time_step";

/* Frame k on one process (s: the store), or on rank 0 holding every agent (s: its view): checked,
 * written, measured. */
static fm_status write_and_measure(flock_run *r, fm_flock_state *s, int64_t frame, fm_error *err)
{
    fm_flock_frame(s, r->position, r->velocity, r->orientation, r->phase);
    fm_status st = fm_frame_check_runaway(r->position, 3, s->n, r->m->scene_lo, r->m->scene_hi, frame, FLOCK_FORCES, err);
    if (st != FM_OK) return st;
    if (r->cache) {
        const void *data[FLOCK_ATTR_COUNT] = {r->position, r->velocity, r->orientation, fm_cache_writer_ids(r->cache),
                                              r->phase}; /* ids 0 … n−1: frames are in id order */
        st = fm_cache_writer_add_frame_attrs(r->cache, data, err);
    }
    if (st != FM_OK || frame == 0) return st; /* frame 0 is the rest state: no step made it, nothing to measure */
    st = fm_frame_rows_room(&r->stats->measures, frame, FM_FLOCK_MEASURES, &r->capacity, err);
    if (st != FM_OK) return st;
    fm_flock_measure_frame_look(r->m, s, &r->s->look, frame, r->stats->measures + (size_t)(frame - 1) * FM_FLOCK_MEASURES);
    if (r->m->info.deforming && r->s->time >= fm_flock_leaders_end(r->m)) { /* tracking lag */
        double mean, max;
        fm_flock_distance(s, &mean, &max);
        r->s->lag_sum += mean;
        r->stats->tracking_frames++;
    }
    return FM_OK;
}

/* On P ranks: every rank's agents gathered on rank 0, which writes and measures the frame; every
 * rank returns the outcome (a failed step's, else rank 0's). */
static fm_status dist_frame(flock_run *r, int64_t frame, fm_error *err)
{
    fm_flock_state *s = r->s;
    if (s->dist_status != FM_OK) return *err = s->dist_error, err->status = s->dist_status;
    fm_flock_state *view = fm_flock_dist_gather(s, 1, err);
    fm_status st = view ? FM_OK : err->status;
    if (st == FM_OK && fm_dist_rank(s->dist) == 0) st = write_and_measure(r, view, frame, err);
    fm_flock_dist_release(s);
    return fm_dist_agree(s->dist, st, err);
}

/* On P ranks with the cache written in parallel: frame k's measures from the ranks' shares (on rank
 * 0, which keeps the rows), and the tracking lag. */
static fm_status measure_shared(flock_run *r, fm_flock_state *view, int64_t frame, fm_error *err)
{
    fm_flock_state *s = r->s;
    const int root = fm_dist_rank(s->dist) == 0;
    double scratch[FM_FLOCK_MEASURES];
    fm_status st = root ? fm_frame_rows_room(&r->stats->measures, frame, FM_FLOCK_MEASURES, &r->capacity, err) : FM_OK;
    if ((st = fm_dist_agree(s->dist, st, err)) != FM_OK) return st;
    double *out = root ? r->stats->measures + (size_t)(frame - 1) * FM_FLOCK_MEASURES : scratch;
    st = fm_flock_measure_frame_shared(r->m, s, view, frame, out, err);
    if (st == FM_OK && r->m->info.deforming && s->time >= fm_flock_leaders_end(r->m)) { /* tracking lag */
        double mean, max;
        fm_flock_distance_blocks(view, 0, view->slots, s->dist, &mean, &max);
        s->lag_sum += root ? mean : 0;
        r->stats->tracking_frames++;
    }
    return st;
}

/* On P ranks with the cache written in parallel: each rank takes its share of the frame's agents,
 * checks and encodes them, rank 0 appends the blocks; the measures are summed from the shares. */
static fm_status shared_frame(flock_run *r, int64_t frame, fm_error *err)
{
    fm_flock_state *s = r->s;
    if (s->dist_status != FM_OK) return *err = s->dist_error, err->status = s->dist_status;
    const int64_t first = fm_frame_share_first(&r->share), end = fm_frame_share_end(&r->share);
    fm_flock_state *view = fm_flock_dist_share(s, r->share.begin, err);
    fm_status st = view ? FM_OK : err->status;
    if (st == FM_OK) {
        fm_flock_frame_range(view, 0, view->slots, r->position, r->velocity, r->orientation, r->phase); /* the share's */
        st = fm_frame_check_runaway_from(r->position, 3, first, end - first, r->m->scene_lo, r->m->scene_hi,
                                         frame, FLOCK_FORCES, err);
    }
    const void *by_kind[CACHE_ATTR_KINDS] = {[FM_ATTR_POSITION] = r->position, [FM_ATTR_VELOCITY] = r->velocity,
                                             [FM_ATTR_ORIENTATION] = r->orientation, [FM_ATTR_PHASE] = r->phase};
    if ((st = fm_dist_agree(s->dist, st, err)) == FM_OK)
        st = fm_frame_share_write(&r->share, s->dist, r->cache, by_kind, (uint32_t)frame, &s->slabs->totals.bytes_sent, err);
    if (st == FM_OK && frame > 0) st = measure_shared(r, view, frame, err);
    fm_flock_dist_release(s);
    return st;
}

static fm_status flock_frame(void *sim, int64_t frame, fm_error *err)
{
    flock_run *r = sim;
    fm_status st = r->share.on ? shared_frame(r, frame, err)
                 : r->s->dist  ? dist_frame(r, frame, err)
                               : write_and_measure(r, r->s, frame, err);
    if (st == FM_OK && frame > 0 && r->c->progress) {
        fm_run_info info = fm_flock_get_info(r->s);
        r->c->progress(&info, frame, r->c->progress_user);
    }
    return st;
}

/* The loop's checkpoint (the cache already flushed): the state and the statistics so far. */
/* Before a checkpoint on P ranks: every rank's blocks of the cache on disk. */
static fm_status flock_sync(void *sim, fm_error *err) { return fm_frame_share_sync(&((flock_run *)sim)->share, err); }

static fm_status flock_save(void *sim, const char *path, fm_error *err)
{
    const flock_run *r = sim;
    if (r->s->dist) return fm_flock_dist_checkpoint_save(path, r->m, r->s, r->stats, r->stats->run.frames, err);
    return fm_flock_checkpoint_save(path, r->m, r->s, r->stats, err);
}

/* On P ranks the cache is written in parallel when each rank's share is a run of whole FM_BLOCK
 * blocks (pieces of a multiple of FM_BLOCK agents, as the default's): the measures sum blocks in
 * block order. Otherwise rank 0 gathers every frame. */
static fm_status start_share(flock_run *r, fm_error *err)
{
    fm_status st = fm_frame_share_start(&r->share, r->s->dist, r->cache, r->s->threads, r->c->resume, err);
    if (st == FM_OK && r->share.on && r->share.share.enc.l.piece_agents % FM_BLOCK != 0) fm_frame_share_free(&r->share);
    fm_frame_share_commit(&r->share, r->cache);
    return st;
}

/* The frame's arrays: every agent's, or with the cache written by P ranks the rank's share's. */
static fm_status alloc_frame(flock_run *r, fm_error *err)
{
    const size_t n = (size_t)(r->share.on ? fm_frame_share_end(&r->share) - fm_frame_share_first(&r->share) : r->s->n);
    r->position = fm_alloc(sizeof(float) * 3 * n), r->velocity = fm_alloc(sizeof(float) * 3 * n);
    r->orientation = fm_alloc(sizeof(float) * 4 * n), r->phase = fm_alloc(n);
    if (r->position && r->velocity && r->orientation && r->phase) return FM_OK;
    return fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame of %lld agents", (long long)n);
}

/* The end-state distances to the destinations: on P ranks summed from the ranks' blocks
 * (collective). */
static void final_distance(flock_run *r, fm_flock_run_stats *stats)
{
    fm_flock_state *s = r->s;
    fm_error ignored = {0};
    if (!s->dist) return fm_flock_distance(s, &stats->final_mean_distance, &stats->final_max_distance);
    const fm_flock_state *view = fm_flock_dist_blocks(s, &ignored);
    stats->final_mean_distance = stats->final_max_distance = NAN;
    if (view) fm_flock_distance_blocks(view, 0, view->slots, s->dist, &stats->final_mean_distance, &stats->final_max_distance);
    fm_flock_dist_release(s);
}

void fm_flock_run_stats_free(fm_flock_run_stats *stats)
{
    free(stats->measures);
    stats->measures = NULL;
}

/* The measures' summaries: the mean over the frames with agents in flight, summed in frame order (so
 * a resumed run adds the same numbers in the same order), and the frame nearest half the path time. */
static void summarise_measures(const fm_flock_model *m, fm_flock_run_stats *stats)
{
    const int64_t rows = stats->run.frames - 1;
    for (int i = 0; i < FM_FLOCK_MEASURES; i++) {
        double sum = 0;
        int64_t count = 0;
        for (int64_t f = 0; f < rows; f++) {
            const double x = stats->measures[f * FM_FLOCK_MEASURES + i];
            if (!isnan(x) && stats->measures[f * FM_FLOCK_MEASURES + FM_FLOCK_IN_FLIGHT] > 0) sum += x, count++;
        }
        stats->measures_mean[i] = count > 0 ? sum / (double)count : NAN;
        stats->measures_mid_flight[i] = NAN;
    }
    const int64_t mid = (int64_t)llround(0.5 * fm_flock_leaders_end(m) * m->def.frame_rate);
    /* the look's figures are every FM_LOOK_EVERY-th frame's: the one nearest mid-flight */
    const int64_t look_mid = FM_MAX(FM_LOOK_EVERY, (mid + FM_LOOK_EVERY / 2) / FM_LOOK_EVERY * FM_LOOK_EVERY);
    if (rows > 0 && mid >= 1)
        for (int i = 0; i < FM_FLOCK_MEASURES; i++) {
            const int look = i >= FM_FLOCK_PERSISTENCE;
            if (look && look_mid > rows) continue;
            stats->measures_mid_flight[i] = stats->measures[(FM_MIN(look ? look_mid : mid, rows) - 1) * FM_FLOCK_MEASURES + i];
        }
}

fm_status fm_flock_run_controlled(const fm_flock_model *m, fm_flock_state *s, fm_cache_writer *cache,
                                  const fm_run_control *c, fm_flock_run_stats *stats, fm_error *err)
{
    if (!c->resume) memset(stats, 0, sizeof *stats), s->lag_sum = 0;
    flock_run r = {.m = m, .s = s, .cache = cache, .c = c, .stats = stats};
    /* capacity 0: a resumed run's array holds exactly its frames so far */
    fm_status st = fm_frame_rows_room(&stats->measures, FM_MAX(stats->run.frames, 1), FM_FLOCK_MEASURES, &r.capacity, err);
    if ((st = fm_dist_agree(s->dist, st, err)) == FM_OK) st = start_share(&r, err);
    if (st == FM_OK) st = fm_dist_agree(s->dist, alloc_frame(&r, err), err);
    if (st == FM_OK) {
        const fm_frame_loop loop = {&r, flock_step, flock_finished, flock_frame, flock_save, m->steps_per_frame,
                                    m->def.frame_limit, c, &stats->run, cache, s->dist, flock_sync};
        st = fm_frame_loop_run(&loop, err);
    }
    stats->run.steps = s->step;
    stats->all_bound = s->count[FM_PHASE_ARRIVED] == s->n;
    stats->stopped_at_frame_limit = !flock_finished(&r);
    final_distance(&r, stats);
    fm_frame_share_free(&r.share);
    stats->bound_fraction = (double)s->count[FM_PHASE_ARRIVED] / (double)s->n;
    stats->tracking_lag = stats->tracking_frames > 0 ? s->lag_sum / (double)stats->tracking_frames : NAN;
    if (stats->measures) summarise_measures(m, stats);
    fm_free(r.position), fm_free(r.velocity), fm_free(r.orientation), fm_free(r.phase);
    return st;
}

fm_status fm_flock_run(const fm_flock_model *m, fm_flock_state *s, fm_cache_writer *cache, fm_run_progress_fn progress,
                       void *user, fm_flock_run_stats *stats, fm_error *err)
{
    fm_run_control c = fm_default_run_control();
    c.progress = progress, c.progress_user = user;
    return fm_flock_run_controlled(m, s, cache, &c, stats, err);
}
