/* bench_suite --mode flock: the shape flock's step (SCF; src/flock through the public API) at
 * n = N agents, with 1 and with T threads.
 *
 * For every N: loads the scene (default examples/flock_suzanne_torus: stratified samples of
 * Suzanne flying to a torus through a vortex), sets n = N (and the sampling, with --sampling),
 * builds the model, then times S steps from the start of the flight, each followed by the frame a
 * cache needs (fm_flock_frame: position, velocity, orientation, phase), after one untimed warm-up
 * step. Every agent flies from the first step, so all are counted. A small N repeats its S steps
 * from a fresh state (suite_repetitions) and keeps the fastest; every repetition and both thread
 * counts must end in the same bits (`deterministic`). The flock's step does not time its stages
 * itself, so stage_ns_per_agent has the step and the frame.
 *
 * Header-only, included by bench_suite.c alone (as roofline.h), and through the public flock API
 * only: so tools/bench-compare.sh --bench-source current can build this benchmark against an
 * engine from before it, with no change to that engine's CMakeLists.txt. */
#ifndef FM_BENCH_SUITE_FLOCK_H
#define FM_BENCH_SUITE_FLOCK_H

#include "flockmorph/flockmorph.h"
#include "fm_internal.h"
#include "grid.h"
#include "suite.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static const char *const SAMPLING_NAMES[] = {"random", "mosaic", "stratified"};

typedef struct flock_result {
    double agent_steps_per_second, ns_per_agent_step, step_ns, frame_ns;
    int64_t in_flight, bound;
    uint64_t hash;
    long repetitions;
} flock_result;

/* One thread count's runs: the model and the frame's buffers, reused by every repetition. */
typedef struct flock_run {
    const fm_flock_model *m;
    int64_t n;
    int threads;
    long steps;
    float *p, *v, *q;
    uint8_t *phase;
} flock_run;

static uint64_t frame_hash(const flock_run *run)
{
    const size_t n = (size_t)run->n;
    uint64_t h = SUITE_FNV_BASIS;
    h = suite_fnv(h, run->p, sizeof(float) * 3 * n);
    h = suite_fnv(h, run->v, sizeof(float) * 3 * n);
    h = suite_fnv(h, run->q, sizeof(float) * 4 * n);
    return suite_fnv(h, run->phase, n);
}

/* One repetition (a suite_once_fn): a fresh state, a warm-up step, then S timed steps each with
 * its frame. */
static int flock_run_once(void *ctx, void *result, double *seconds, uint64_t *hash)
{
    const flock_run *run = ctx;
    flock_result *r = result;
    fm_error err = {0};
    fm_flock_state *s = fm_flock_state_create(run->m, run->threads, &err);
    if (!s) return fprintf(stderr, "bench_suite: %s\n", err.message), -1;
    fm_flock_step(run->m, s); /* builds the grids, touches every page */
    double frame = 0, t0 = fm_seconds();
    for (long k = 0; k < run->steps; k++) {
        fm_flock_step(run->m, s);
        double t1 = fm_seconds();
        fm_flock_frame(s, run->p, run->v, run->q, run->phase);
        frame += fm_seconds() - t1;
    }
    *seconds = fm_seconds() - t0;
    const double agent_steps = (double)run->n * (double)run->steps;
    r->agent_steps_per_second = agent_steps / *seconds;
    r->ns_per_agent_step = 1e9 * *seconds / agent_steps;
    r->step_ns = 1e9 * (*seconds - frame) / agent_steps;
    r->frame_ns = 1e9 * frame / agent_steps;
    const fm_run_info info = fm_flock_get_info(s);
    r->in_flight = info.count[FM_PHASE_FLYING] + info.count[FM_PHASE_HOMING];
    r->bound = info.count[FM_PHASE_ARRIVED];
    *hash = frame_hash(run);
    fm_flock_state_destroy(s);
    return 0;
}

static int flock_run_steps(flock_run *run, int threads, flock_result *r)
{
    run->threads = threads;
    flock_result scratch = {0};
    const long reps = suite_repetitions(run->n, run->steps);
    uint64_t hash = 0;
    int rc = suite_fastest(reps, flock_run_once, run, r, &scratch, sizeof *r, &hash);
    r->hash = hash, r->repetitions = reps;
    return rc;
}

static fm_flock_model *flock_build(const suite_options *o, long agents, fm_scene_def *def, double *prep)
{
    fm_error err = {0};
    if (fm_scene_load(o->scene, def, &err) != FM_OK) return fprintf(stderr, "bench_suite: %s\n", err.message), NULL;
    if (def->mode != FM_MODE_SHAPE_FLOCK)
        return fprintf(stderr, "bench_suite: --mode flock needs a shape_flock scene; %s is a tetra morph scene\n", o->scene),
               NULL;
    def->n = agents;
    if (o->sampling >= 0) def->flock.sampling = (fm_flock_sampling)o->sampling;
    double t0 = fm_seconds();
    fm_flock_model *m = fm_flock_model_build(def, NULL, NULL, &err);
    *prep = fm_seconds() - t0;
    if (!m) return fprintf(stderr, "bench_suite: %s\n", err.message), NULL;
    for (int i = 0; i < fm_flock_model_warning_count(m); i++)
        fprintf(stderr, "bench_suite: warning: %s\n", fm_flock_model_warning(m, i));
    return m;
}

static void print_json_string(const char *s)
{
    putchar('"');
    for (; *s; s++) {
        if (*s == '"' || *s == '\\') printf("\\%c", *s);
        else if ((unsigned char)*s < 0x20) printf("\\u%04x", (unsigned char)*s);
        else putchar(*s);
    }
    putchar('"');
}

static void flock_print_stages(const flock_result *r)
{
    printf("\"stage_ns_per_agent\": {\"step\": %.2f, \"frame\": %.2f}", r->step_ns, r->frame_ns);
}

static int flock_bench_size(const suite_options *o, long agents, int first)
{
    fm_scene_def def;
    double prep;
    fprintf(stderr, "bench_suite: flock n = %ld: building\n", agents);
    fm_flock_model *m = flock_build(o, agents, &def, &prep);
    if (!m) return -1;
    const fm_flock_model_info mi = fm_flock_model_get_info(m);
    const size_t n = (size_t)agents;
    flock_run run = {m, agents, 1, o->steps, fm_alloc(sizeof(float) * 3 * n), fm_alloc(sizeof(float) * 3 * n),
                     fm_alloc(sizeof(float) * 4 * n), fm_alloc(n)};
    int rc = run.p && run.v && run.q && run.phase ? 0 : (fprintf(stderr, "bench_suite: out of memory\n"), -1);
    flock_result one = {0}, many = {0};
    if (rc == 0) {
        fprintf(stderr, "bench_suite: flock n = %ld: %ld steps, 1 thread\n", agents, o->steps);
        rc = flock_run_steps(&run, 1, &one);
        many = one;
    }
    if (rc == 0 && o->threads > 1) {
        fprintf(stderr, "bench_suite: flock n = %ld: %ld steps, %ld threads\n", agents, o->steps, o->threads);
        rc = flock_run_steps(&run, (int)o->threads, &many);
    }
    if (rc == 0) {
        printf("%s\n    {\"mode\": \"flock\", \"scene\": ", first ? "" : ",");
        print_json_string(o->scene);
        printf(", \"sampling\": \"%s\", \"agents\": %ld, \"threads\": %ld, \"steps\": %ld, \"in_flight\": %lld, "
               "\"bound\": %lld, \"max_perception_radius\": %.5g, \"preprocess_seconds\": %.2f, \"bytes_per_agent\": %.0f,\n"
               "     \"agent_steps_per_second\": %.4g, \"steps_per_second\": %.4g, \"ns_per_agent_step\": %.2f, ",
               SAMPLING_NAMES[def.flock.sampling], agents, o->threads, o->steps, (long long)many.in_flight,
               (long long)many.bound, mi.max_radius, prep, suite_bytes_per_agent(agents), many.agent_steps_per_second,
               many.agent_steps_per_second / (double)agents, many.ns_per_agent_step);
        flock_print_stages(&many);
        printf(",\n     \"one_thread\": {\"agent_steps_per_second\": %.4g, ", one.agent_steps_per_second);
        flock_print_stages(&one);
        printf("},\n     \"thread_speedup\": %.2f, \"deterministic\": %s, \"repetitions\": %ld}",
               many.agent_steps_per_second / one.agent_steps_per_second,
               one.hash != 0 && one.hash == many.hash ? "true" : "false", many.repetitions);
        fflush(stdout);
    }
    fm_free(run.p), fm_free(run.v), fm_free(run.q), fm_free(run.phase);
    fm_flock_model_destroy(m);
    return rc;
}

/* The density sweep (--density-sweep 1, issue 40), after FLAME GPU 2's "circles" benchmark: the
 * step's throughput at N agents against the mean number of neighbours. The flock's radii are in
 * spacings (shape-flock.md), so scaling the shapes' volume leaves every agent's neighbour count as
 * it was; the sweep scales the three rules' radii instead (radius, or radius_j where the scene
 * gives the paper's J), which is the same density of agents per perception volume. */
static const double SWEEP_FACTORS[] = {0.7, 1.0, 1.5, 2.2, 3.2};

static void scale_radii(fm_scene_def *def, double f)
{
    fm_boid_rule_def *rules[3] = {&def->flock.separation, &def->flock.cohesion, &def->flock.alignment};
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 2; k++) rules[r]->radius[k] *= f, rules[r]->radius_j[k] *= f;
}

/* The mean number of other agents within `radius` of each of up to 10^4 agents spread over the
 * frame (positions xyz xyz ...), counted on a grid of that cell independently of the engine's. */
static double mean_neighbours(const float *xyz, int64_t n, double radius)
{
    float *p[3] = {fm_alloc(sizeof(float) * (size_t)n), fm_alloc(sizeof(float) * (size_t)n),
                   fm_alloc(sizeof(float) * (size_t)n)};
    fm_grid g;
    double mean = NAN;
    if (p[0] && p[1] && p[2] && fm_grid_init(&g, n, NULL) == FM_OK) {
        for (int64_t a = 0; a < n; a++) p[0][a] = xyz[3 * a], p[1][a] = xyz[3 * a + 1], p[2][a] = xyz[3 * a + 2];
        fm_grid_build(&g, (const float *const *)p, NULL, n, (float)radius, 1);
        const int64_t stride = n > 10000 ? n / 10000 : 1;
        int64_t sampled = 0, found = 0;
        for (int64_t a = 0; a < n; a += stride, sampled++) {
            int32_t rk[2 * FM_GRID_MAX_RANGES];
            const int nr = fm_grid_ranges(&g, p[0][a], p[1][a], p[2][a], rk);
            for (int r = 0; r < nr; r++)
                for (int32_t k = rk[2 * r]; k < rk[2 * r + 1]; k++) {
                    const fm_grid_quad *e = &g.quad[k >> 2];
                    const double dx = e->x[k & 3] - p[0][a], dy = e->y[k & 3] - p[1][a], dz = e->z[k & 3] - p[2][a];
                    found += e->i[k & 3] != a && dx * dx + dy * dy + dz * dz < radius * radius;
                }
        }
        mean = (double)found / (double)sampled;
        fm_grid_free(&g);
    }
    fm_free(p[0]), fm_free(p[1]), fm_free(p[2]);
    return mean;
}

/* One point of the sweep: the radii times f, T threads only (a point at 200 neighbours costs ten
 * times one at 15). */
static int sweep_point(const suite_options *o, long agents, double f, int first)
{
    fm_scene_def def;
    fm_error err = {0};
    if (fm_scene_load(o->scene, &def, &err) != FM_OK) return fprintf(stderr, "bench_suite: %s\n", err.message), -1;
    def.n = agents;
    if (o->sampling >= 0) def.flock.sampling = (fm_flock_sampling)o->sampling;
    scale_radii(&def, f);
    fprintf(stderr, "bench_suite: density sweep, n = %ld, radii x %.2f\n", agents, f);
    fm_flock_model *m = fm_flock_model_build(&def, NULL, NULL, &err);
    if (!m) return fprintf(stderr, "bench_suite: %s\n", err.message), -1;
    const double radius = fm_flock_model_get_info(m).max_radius;
    const size_t n = (size_t)agents;
    flock_run run = {m, agents, 1, o->steps, fm_alloc(sizeof(float) * 3 * n), fm_alloc(sizeof(float) * 3 * n),
                     fm_alloc(sizeof(float) * 4 * n), fm_alloc(n)};
    flock_result r = {0};
    int rc = run.p && run.v && run.q && run.phase ? flock_run_steps(&run, (int)o->threads, &r)
                                                  : (fprintf(stderr, "bench_suite: out of memory\n"), -1);
    if (rc == 0) {
        printf("%s\n    {\"radius_factor\": %.2f, \"max_perception_radius\": %.5g, \"mean_neighbours\": %.1f, "
               "\"agents\": %ld, \"threads\": %ld, \"steps\": %ld, \"agent_steps_per_second\": %.4g, "
               "\"ns_per_agent_step\": %.2f}",
               first ? "" : ",", f, radius, mean_neighbours(run.p, agents, radius), agents, o->threads, o->steps,
               r.agent_steps_per_second, r.ns_per_agent_step);
        fflush(stdout);
    }
    fm_free(run.p), fm_free(run.v), fm_free(run.q), fm_free(run.phase);
    fm_flock_model_destroy(m);
    return rc;
}

static int suite_flock(const suite_options *o)
{
    if (o->density_sweep) {
        for (int i = 0; i < (int)(sizeof SWEEP_FACTORS / sizeof *SWEEP_FACTORS); i++)
            if (sweep_point(o, o->agents[0], SWEEP_FACTORS[i], i == 0)) return -1;
        return 0;
    }
    for (int i = 0; i < o->agent_count; i++)
        if (flock_bench_size(o, o->agents[i], i == 0)) return -1;
    return 0;
}

#endif
