/* fm_run: the frame loop around fm_step, with the end-state checks reported in stats.json. */
#include "frame_loop.h"
#include "sim.h"
#include "cache_format.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static double signed_volume6(const float *t)
{
    double a[3], b[3], c[3];
    for (int k = 0; k < 3; k++)
        a[k] = (double)t[3 + k] - t[k], b[k] = (double)t[6 + k] - t[k], c[k] = (double)t[9 + k] - t[k];
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

int64_t fm_count_inverted_tets(const float *verts, size_t n)
{
    int64_t count = 0;
#pragma omp parallel for reduction(+ : count) schedule(static)
    for (int64_t i = 0; i < (int64_t)n; i++) count += !(signed_volume6(verts + 12 * i) > 0);
    return count;
}

/* Largest distance between an agent's vertex and its target tet's matching vertex. */
static double max_vertex_error(const fm_model *m, const fm_state *s, const float *verts)
{
    double worst = 0;
    for (int64_t a = 0; a < s->n; a++) {
        if (s->target[a] < 0) return INFINITY;
        const uint8_t *perm = fm_even_permutations[s->perm[a]];
        const double *t = m->tgt + 12 * s->target[a];
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++) worst = fmax(worst, fabs((double)verts[12 * a + 3 * i + k] - t[3 * perm[i] + k]));
    }
    return worst;
}

static int each_target_taken_once(const fm_state *s)
{
    if (s->n < 1) return 1;
    uint8_t *taken = calloc((size_t)s->n, 1);
    if (!taken) return 0;
    int ok = 1;
    for (int64_t a = 0; a < s->n && ok; a++) {
        int64_t t = s->target[a];
        ok = t >= 0 && t < s->n && !taken[t];
        if (ok) taken[t] = 1;
    }
    free(taken);
    return ok;
}

/* Hands the frame to the cache in the attributes it was created with: the tetra morph has tet
 * vertices and phases. */
static fm_status cache_frame(const fm_state *s, fm_cache_writer *cache, const float *verts, uint8_t *phases,
                             fm_error *err)
{
    const cache_layout *l = fm_cache_writer_layout(cache);
    const void *data[CACHE_MAX_ATTRS];
    for (int i = 0; i < l->attr_count; i++) {
        if (l->attrs[i]->attr == FM_ATTR_TET_VERTICES) data[i] = verts;
        else if (l->attrs[i]->attr == FM_ATTR_PHASE) fm_state_phases(s, phases), data[i] = phases;
        else return fm_fail(err, FM_ERR_USAGE, "the tetra morph cannot write the cache attribute '%s'", l->attrs[i]->name);
    }
    return fm_cache_writer_add_frame_attrs(cache, data, err);
}

/* Frame k: the tet vertices (and phases), written to the cache, with the inverted-tet count. */
static fm_status emit_frame(const fm_model *m, const fm_state *s, float *verts, uint8_t *phases, fm_cache_writer *cache,
                            fm_run_stats *stats, fm_error *err)
{
    fm_state_tet_vertices(m, s, verts);
    stats->inverted_tet_frames += fm_count_inverted_tets(verts, (size_t)s->n);
    return cache ? cache_frame(s, cache, verts, phases, err) : FM_OK;
}

void fm_run_stats_free(fm_run_stats *stats)
{
    free(stats->mde_fraction);
    stats->mde_fraction = NULL;
}

/* Records the frame's MDE fraction (FM Table I's last column) from the step counters. */
static fm_status record_mde(const fm_state *s, int64_t frame, int64_t *flying_before, int64_t *mde_before,
                            fm_run_stats *stats, int64_t *frames_with_flyers, int64_t *capacity, fm_error *err)
{
    int64_t flying = s->flying_agent_steps - *flying_before, mde = s->mde_agent_steps - *mde_before;
    double f = flying > 0 ? (double)mde / (double)flying : NAN;
    int64_t slot = frame - 1;
    if (slot >= *capacity) { /* grows by doubling */
        double *grown = realloc(stats->mde_fraction, sizeof(double) * (size_t)(2 * *capacity));
        if (!grown) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the per-frame statistics");
        stats->mde_fraction = grown, *capacity *= 2;
    }
    stats->mde_fraction[slot] = f;
    if (flying > 0) stats->mde_fraction_mean += f, ++*frames_with_flyers;
    *flying_before = s->flying_agent_steps, *mde_before = s->mde_agent_steps;
    return FM_OK;
}

/* What the frame loop's callbacks share. */
typedef struct tetra_run {
    const fm_model *m;
    fm_state *s;
    float *verts;
    uint8_t *phases;
    fm_cache_writer *cache;
    fm_run_progress_fn progress;
    void *user;
    fm_run_stats *stats;
    int64_t flying_before, mde_before, frames_with_flyers, capacity;
} tetra_run;

static void tetra_step(void *sim)
{
    tetra_run *r = sim;
    fm_step(r->m, r->s);
}

static int tetra_finished(const void *sim)
{
    const tetra_run *r = sim;
    return r->s->count[FM_PHASE_ARRIVED] == r->s->n;
}

static fm_status tetra_frame(void *sim, int64_t frame, fm_error *err)
{
    tetra_run *r = sim;
    fm_status st = emit_frame(r->m, r->s, r->verts, r->phases, r->cache, r->stats, err);
    if (frame == 0 || st != FM_OK) return st;
    st = record_mde(r->s, frame, &r->flying_before, &r->mde_before, r->stats, &r->frames_with_flyers, &r->capacity, err);
    if (r->progress) {
        fm_state_info info = fm_state_get_info(r->s);
        r->progress(&info, frame, r->user);
    }
    return st;
}

fm_status fm_run(const fm_model *m, fm_state *s, fm_cache_writer *cache, fm_run_progress_fn progress,
                 void *user, fm_run_stats *stats, fm_error *err)
{
    memset(stats, 0, sizeof *stats);
    tetra_run r = {m, s, fm_alloc(sizeof(float) * 12 * (size_t)s->n), fm_alloc((size_t)s->n), cache, progress, user,
                   stats, s->flying_agent_steps, s->mde_agent_steps, 0, 1024};
    stats->mde_fraction = malloc(sizeof(double) * (size_t)r.capacity);
    if (!r.verts || !r.phases || !stats->mde_fraction) {
        fm_free(r.verts), fm_free(r.phases), fm_run_stats_free(stats);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame of %lld agents", (long long)s->n);
    }
    const fm_frame_loop loop = {&r, tetra_step, tetra_finished, tetra_frame, m->steps_per_frame, m->def.frame_limit};
    fm_loop_times times;
    fm_status st = fm_frame_loop_run(&loop, &times, err);
    stats->frames = times.frames;
    stats->simulate_seconds = times.simulate_seconds;
    stats->output_seconds = times.output_seconds;
    stats->steps = s->step;
    stats->all_arrived = s->count[FM_PHASE_ARRIVED] == s->n;
    stats->stopped_at_frame_limit = !stats->all_arrived;
    stats->final_max_vertex_error = max_vertex_error(m, s, r.verts);
    stats->target_tets_filled_once = each_target_taken_once(s);
    stats->morph_fallbacks = s->morph_fallbacks;
    stats->mde_fraction_mean = r.frames_with_flyers ? stats->mde_fraction_mean / (double)r.frames_with_flyers : 0.0;
    stats->min_obstacle_clearance = s->min_clearance;
    fm_free(r.verts), fm_free(r.phases);
    return st;
}

fm_status fm_frame_loop_run(const fm_frame_loop *loop, fm_loop_times *times, fm_error *err)
{
    *times = (fm_loop_times){0, 0, 0};
    double t0 = fm_seconds();
    fm_status st = loop->frame(loop->sim, 0, err);
    times->output_seconds += fm_seconds() - t0;
    times->frames = 1;
    while (st == FM_OK && !loop->finished(loop->sim) && times->frames < loop->frame_limit) {
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
