/* The throughput benchmark suite (docs/performance.md); `bench_suite --help` for the options.
 *
 * --mode morph (the default): for every N, builds the scene (default examples/castling: global
 * path, curl noise baked on a grid, an obstacle's distance field, MDE) with n = N, launches every
 * agent at t = 0 so all are in flight, and times S full steps, each followed by the synthesis of
 * every tet's four vertices (FM §6), with 1 and with T threads; a small N repeats the S steps from
 * the start (up to 25 times, about 5·10^6 agent-steps in all) and reports the fastest repetition.
 * Also measures, in the same run, the machine's STREAM triad bandwidth and peak fused multiply-add
 * rate, and prints the achieved fraction of each (the roofline), the SIMD kernels' speedup over
 * their scalar twins, the thread speedup and whether 1 and T threads gave the same bits. With
 * --scenarios 1 it also runs the four examples (FM Table I).
 *
 * --mode flock: the shape flock's step the same way (suite_flock.h).
 *
 * Prints one JSON document on stdout; progress on stderr. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "bench_args.h"
#include "kernels.h"
#include "roofline.h"
#include "morph.h"
#include "simd.h"
#include "suite.h"
#include "suite_flock.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char USAGE[] =
    "usage: bench_suite [--mode morph|flock] [--agents N[,N...]] [--steps S] [--threads T] [--scene FILE]\n"
    "                   [--sampling random|mosaic|stratified] [--density-sweep 0|1] [--scenarios 0|1]\n"
    "                   [--machine 0|1]\n"
    "\n"
    "Times S steps at each agent count N with 1 and T threads and prints one JSON document on\n"
    "stdout (docs/performance.md); progress goes to stderr.\n"
    "\n"
    "  --mode morph     the tetra flock morph: the full step and the synthesis of every tet's\n"
    "                   vertices, all agents in flight (the default; scene examples/castling)\n"
    "  --mode flock     the shape flock: its step and its frame (position, velocity, orientation,\n"
    "                   phase) from the first step on (scene examples/flock_suzanne_torus)\n"
    "  --agents N,...   agent counts, up to 8, comma-separated (default 100000)\n"
    "  --steps S        timed steps per repetition (default 10)\n"
    "  --threads T      the thread count beside 1 (default: OpenMP's)\n"
    "  --scene FILE     the scene, with n set to each N (a morph scene for morph, shape_flock for flock)\n"
    "  --sampling M     flock only: sample the surfaces this way instead of the scene's\n"
    "                   shape_flock.sampling (random prepares 10^6 agents fastest)\n"
    "  --density-sweep 1  flock only: throughput at the first N against the mean neighbour\n"
    "                   count, the radii scaled 0.7 to 3.2 times, T threads (docs/performance.md)\n"
    "  --scenarios 1    morph only: also run the four FM examples (Table I)\n"
    "  --machine 0      skip measuring the STREAM triad and the FMA peak\n"
    "  -h, --help       this text\n";

static void parse(int argc, char **argv, suite_options *o)
{
    o->mode = SUITE_MORPH, o->agent_count = 0, o->steps = 10, o->threads = omp_get_max_threads();
    o->scenarios = 0, o->machine = 1, o->sampling = -1, o->density_sweep = 0, o->scene[0] = 0;
    static const char *const modes[] = {"morph", "flock"}, *const samplings[] = {"random", "mosaic", "stratified"};
    static const char *const flags[] = {"0", "1"};
    bench_args a = bench_args_begin("bench_suite", USAGE, argc, argv);
    while (bench_next(&a)) {
        if (bench_is(&a, "--agents")) {
            const char *list = bench_value(&a);
            o->agent_count = 0;
            for (const char *s = list; *s;) {
                char one[32];
                size_t len = strcspn(s, ",");
                if (o->agent_count == SUITE_MAX_SIZES) bench_usage_error(&a, "--agents takes at most %d counts", SUITE_MAX_SIZES);
                snprintf(one, sizeof one, "%.*s", (int)(len < sizeof one - 1 ? len : sizeof one - 1), s);
                o->agents[o->agent_count++] = bench_parse_long(&a, "--agents", one, 1, 1000000000L);
                s += len + (s[len] == ',');
            }
            if (o->agent_count == 0) bench_usage_error(&a, "--agents needs at least one count");
        } else if (bench_is(&a, "--steps")) o->steps = bench_long(&a, 1, 1000000000L);
        else if (bench_is(&a, "--threads")) o->threads = bench_long(&a, 1, 1024);
        else if (bench_is(&a, "--scenarios")) o->scenarios = bench_choice(&a, flags, 2);
        else if (bench_is(&a, "--machine")) o->machine = bench_choice(&a, flags, 2);
        else if (bench_is(&a, "--density-sweep")) o->density_sweep = bench_choice(&a, flags, 2);
        else if (bench_is(&a, "--mode")) o->mode = (suite_mode)bench_choice(&a, modes, 2);
        else if (bench_is(&a, "--sampling")) o->sampling = bench_choice(&a, samplings, 3);
        else if (bench_is(&a, "--scene")) snprintf(o->scene, sizeof o->scene, "%s", bench_value(&a));
        else bench_unknown(&a);
    }
    if (o->mode == SUITE_FLOCK && o->scenarios) bench_usage_error(&a, "--scenarios is for --mode morph");
    if (o->mode == SUITE_MORPH && o->sampling >= 0) bench_usage_error(&a, "--sampling is for --mode flock");
    if (o->mode == SUITE_MORPH && o->density_sweep) bench_usage_error(&a, "--density-sweep is for --mode flock");
    if (o->agent_count == 0) o->agents[o->agent_count++] = 100000;
    if (!o->scene[0])
        snprintf(o->scene, sizeof o->scene, "%s/examples/%s", FM_SOURCE_DIR,
                 o->mode == SUITE_FLOCK ? "flock_suzanne_torus/scene.json" : "castling/rook.json");
}

static uint64_t state_hash(const fm_morph_state *s, const float *frame)
{
    uint64_t h = SUITE_FNV_BASIS;
    h = suite_fnv(h, frame, sizeof(float) * 12 * (size_t)s->n);
    h = suite_fnv(h, s->phase, (size_t)s->n);
    for (int k = 0; k < 3; k++) h = suite_fnv(h, s->v[k], sizeof(float) * (size_t)s->n);
    return h;
}

typedef struct step_result {
    double agent_steps_per_second, ns_per_agent_step, stage_ns[FM_STAGE_COUNT + 1];
    double path_ns_simd, path_ns_scalar;
    uint64_t hash;
    int64_t in_flight;
    long repetitions;
} step_result;

/* Times the path kernel (FM eq 3) alone on the state's agents at the given SIMD level. */
static double time_path_kernel(const fm_morph_model *m, fm_morph_state *s, fm_simd level)
{
    fm_simd before = fm_simd_level();
    fm_simd_set_level(level);
    const fm_path_view path = {{m->key_q[0], m->key_q[1], m->key_q[2]}, {m->key_f[0], m->key_f[1], m->key_f[2]},
                               m->key_count, (float)(0.5 * m->def.path_width), (float)m->def.path_attraction};
    float speed = (float)(m->def.omega1 * m->def.speed0);
    double best = INFINITY;
    for (int rep = 0; rep < 5; rep++) {
        double t0 = fm_seconds();
        fm_kernel_global_velocity(&path, (const float *const *)s->p, s->phase, s->active_begin, s->active_end, speed, s->v);
        best = fmin(best, fm_seconds() - t0);
    }
    fm_simd_set_level(before);
    return 1e9 * best / (double)(s->active_end - s->active_begin);
}

/* One repetition (a suite_once_fn): a fresh state, a warm-up step, then S timed steps each with
 * the synthesis. */
typedef struct morph_run {
    const fm_morph_model *m;
    int threads;
    long steps;
    float *frame;
} morph_run;

static int run_once(void *ctx, void *result, double *seconds, uint64_t *hash)
{
    const morph_run *run = ctx;
    const fm_morph_model *m = run->m;
    step_result *r = result;
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(m, run->threads, &err);
    if (!s) return fprintf(stderr, "bench_suite: %s\n", err.message), -1;
    fm_morph_step(m, s); /* launches everyone, touches every page */
    memset(s->stage_seconds, 0, sizeof s->stage_seconds);
    double synth = 0, t0 = fm_seconds();
    for (long k = 0; k < run->steps; k++) {
        fm_morph_step(m, s);
        double t1 = fm_seconds();
        fm_morph_tet_vertices(m, s, run->frame);
        synth += fm_seconds() - t1;
    }
    *seconds = fm_seconds() - t0;
    double agent_steps = (double)m->n * (double)run->steps;
    r->agent_steps_per_second = agent_steps / *seconds;
    r->ns_per_agent_step = 1e9 * *seconds / agent_steps;
    for (int k = 0; k < FM_STAGE_COUNT; k++) r->stage_ns[k] = 1e9 * s->stage_seconds[k] / agent_steps;
    r->stage_ns[FM_STAGE_COUNT] = 1e9 * synth / agent_steps;
    *hash = state_hash(s, run->frame);
    r->in_flight = s->count[FM_PHASE_FLYING] + s->count[FM_PHASE_HOMING];
    r->path_ns_simd = time_path_kernel(m, s, fm_simd_level()); /* the level in use (FM_SIMD may lower it) */
    r->path_ns_scalar = time_path_kernel(m, s, FM_SIMD_SCALAR);
    fm_morph_state_destroy(s);
    return 0;
}

/* The fastest of suite_repetitions(n, S) runs; every run must end in the same bits. */
static int run_steps(const fm_morph_model *m, int threads, long steps, step_result *r)
{
    morph_run run = {m, threads, steps, fm_alloc(sizeof(float) * 12 * (size_t)m->n)};
    if (!run.frame) return fprintf(stderr, "bench_suite: out of memory\n"), -1;
    step_result scratch = {0};
    const long reps = suite_repetitions(m->n, steps);
    uint64_t hash = 0;
    int rc = suite_fastest(reps, run_once, &run, r, &scratch, sizeof *r, &hash);
    r->hash = hash, r->repetitions = reps;
    fm_free(run.frame);
    return rc;
}

/* ns per agent of a step in which every agent waits at the source: what idle agents cost. */
static double idle_ns_per_agent(fm_morph_model *m, long steps)
{
    const double rate = m->launch_rate;
    m->launch_rate = 1e-9; /* agent 0 launches, nobody else */
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(m, 1, &err);
    double ns = NAN;
    if (s) {
        fm_morph_step(m, s);
        double t0 = fm_seconds();
        for (long k = 0; k < steps; k++) fm_morph_step(m, s);
        ns = 1e9 * (fm_seconds() - t0) / ((double)m->n * (double)steps);
    }
    fm_morph_state_destroy(s);
    m->launch_rate = rate;
    return ns;
}

static fm_morph_model *build(const suite_options *o, long agents, double *prep)
{
    fm_scene_def def;
    fm_error err = {0};
    if (fm_scene_load(o->scene, &def, &err) != FM_OK) return fprintf(stderr, "bench_suite: %s\n", err.message), NULL;
    def.n = agents;
    def.launch_rate = 1e12; /* everyone in flight from the first step */
    double t0 = fm_seconds();
    fm_morph_model *m = fm_morph_model_build(&def, NULL, NULL, &err);
    *prep = fm_seconds() - t0;
    if (!m) return fprintf(stderr, "bench_suite: %s\n", err.message), NULL;
    /* MDE's d_min is a distance between neighbouring tets: keep it in proportion to the tet size,
     * which shrinks as n^(-1/3) from the scene's own count. */
    fm_morph_model_info mi = fm_morph_model_get_info(m);
    double scene_n = (double)(mi.source_tets > mi.target_tets ? mi.source_tets : mi.target_tets);
    if (agents > scene_n) m->def.d_min *= cbrt(scene_n / (double)agents);
    return m;
}

static void print_stages(const char *key, const double *ns)
{
    printf("\"%s\": {", key);
    for (int k = 0; k <= FM_STAGE_COUNT; k++)
        printf("\"%s\": %.2f%s", k < FM_STAGE_COUNT ? fm_stage_names[k] : "synthesis", ns[k], k < FM_STAGE_COUNT ? ", " : "}");
}

static int bench_size(const suite_options *o, long agents, const fm_machine *mc, int first)
{
    double prep;
    fprintf(stderr, "bench_suite: n = %ld: building\n", agents);
    fm_morph_model *m = build(o, agents, &prep);
    if (!m) return -1;
    step_result one, many;
    fprintf(stderr, "bench_suite: n = %ld: %ld steps, 1 thread\n", agents, o->steps);
    if (run_steps(m, 1, o->steps, &one)) return fm_morph_model_destroy(m), -1;
    many = one;
    if (o->threads > 1) {
        fprintf(stderr, "bench_suite: n = %ld: %ld steps, %ld threads\n", agents, o->steps, o->threads);
        if (run_steps(m, (int)o->threads, o->steps, &many)) return fm_morph_model_destroy(m), -1;
    }
    double idle_ns = idle_ns_per_agent(m, o->steps);
    fm_cost cost = fm_step_cost(m, many.stage_ns);
    fm_roofline rl = fm_roofline_of(&cost, many.agent_steps_per_second, mc);
    printf("%s\n    {\"agents\": %ld, \"threads\": %ld, \"steps\": %ld, \"in_flight\": %lld, \"d_min\": %.5g, "
           "\"preprocess_seconds\": %.2f, \"bytes_per_agent\": %.0f,\n     \"agent_steps_per_second\": %.4g, "
           "\"steps_per_second\": %.4g, \"ns_per_agent_step\": %.2f, ",
           first ? "" : ",", agents, o->threads, o->steps, (long long)many.in_flight, m->def.d_min, prep,
           suite_bytes_per_agent(m->n), many.agent_steps_per_second, many.agent_steps_per_second / (double)agents,
           many.ns_per_agent_step);
    print_stages("stage_ns_per_agent", many.stage_ns);
    printf(",\n     \"one_thread\": {\"agent_steps_per_second\": %.4g, ", one.agent_steps_per_second);
    print_stages("stage_ns_per_agent", one.stage_ns);
    printf("},\n     \"bytes_per_agent_step\": %.0f, \"flops_per_agent_step\": %.0f, \"achieved_gbps\": %.2f, "
           "\"achieved_gflops\": %.2f, \"roofline_fraction\": %.3f, \"bound\": \"%s\",\n",
           cost.bytes, cost.flops, rl.gbps, rl.gflops, rl.fraction, rl.bound);
    printf("     \"simd_speedup\": {\"path\": %.2f, \"path_ns_per_agent\": {\"%s\": %.2f, \"scalar\": %.2f}},\n",
           many.path_ns_scalar / many.path_ns_simd, fm_simd_name(fm_simd_level()), many.path_ns_simd, many.path_ns_scalar);
    printf("     \"thread_speedup\": %.2f, \"deterministic\": %s, \"idle_ns_per_agent\": %.3f, \"repetitions\": %ld}",
           many.agent_steps_per_second / one.agent_steps_per_second,
           one.hash != 0 && one.hash == many.hash ? "true" : "false", idle_ns, many.repetitions);
    fflush(stdout);
    fm_morph_model_destroy(m);
    return 0;
}

/* FM Table I, for comparison (Core 2 Duo E7500, 2009). */
/* The scene file of each: castling's rook, the row the paper times (examples/castling/scene.json is
 * the whole two-part castling, a shot). */
static const struct { const char *name, *file; double fps, mde; } TABLE_I[] = {
    {"words", "scene.json", 185.4, 0.13}, {"moon", "scene.json", 31.3, 0.72}, {"creatures", "scene.json", 178, 0.63},
    {"castling", "rook.json", 13.1, 1.27}};

static void bench_scenarios(int threads)
{
    printf(",\n  \"scenarios\": [");
    for (int i = 0; i < 4; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/examples/%s/%s", FM_SOURCE_DIR, TABLE_I[i].name, TABLE_I[i].file);
        fm_scene_def def;
        fm_error err = {0};
        fprintf(stderr, "bench_suite: scenario %s\n", TABLE_I[i].name);
        fm_morph_model *m = fm_scene_load(path, &def, &err) == FM_OK ? fm_morph_model_build(&def, NULL, NULL, &err) : NULL;
        fm_morph_state *s = m ? fm_morph_state_create(m, threads, &err) : NULL;
        fm_morph_run_stats rs = {0};
        if (!s || fm_morph_run(m, s, NULL, NULL, NULL, &rs, &err) != FM_OK) {
            fprintf(stderr, "bench_suite: %s: %s\n", TABLE_I[i].name, err.message);
        } else {
            printf("%s\n    {\"scenario\": \"%s\", \"agents\": %lld, \"steps_per_second\": %.1f, \"mde_percent\": %.2f, "
                   "\"paper_fps\": %.1f, \"paper_mde_percent\": %.2f}",
                   i ? "," : "", TABLE_I[i].name, (long long)m->n, (double)rs.run.steps / rs.run.simulate_seconds,
                   100 * rs.mde_fraction_mean, TABLE_I[i].fps, TABLE_I[i].mde);
        }
        fm_morph_run_stats_free(&rs);
        fm_morph_state_destroy(s);
        fm_morph_model_destroy(m);
    }
    printf("\n  ]");
}

int main(int argc, char **argv)
{
    suite_options o;
    parse(argc, argv, &o);
    fm_machine mc = {0};
    if (o.machine) {
        fprintf(stderr, "bench_suite: measuring the machine (STREAM triad, FMA peak, clock)\n");
        mc = fm_measure_machine((int)o.threads);
    }
    printf("{\n  \"machine\": {\"cpu\": \"%s\", \"threads\": %ld, \"simd\": \"%s\", \"stream_triad_gbps\": %.2f, "
           "\"peak_gflops\": %.1f, \"clock_ghz\": %.2f},\n  \"runs\": [",
           mc.cpu, o.threads, fm_simd_name(fm_simd_level()), mc.triad_gbps, mc.peak_gflops, mc.clock_ghz);
    if (o.mode == SUITE_FLOCK) {
        if (suite_flock(&o)) return 2;
    } else {
        for (int i = 0; i < o.agent_count; i++)
            if (bench_size(&o, o.agents[i], &mc, i == 0)) return 2;
    }
    printf("\n  ]");
    if (o.scenarios) bench_scenarios((int)o.threads);
    printf("\n}\n");
    return 0;
}
