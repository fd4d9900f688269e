/* Step throughput at a chosen agent count, with a per-stage breakdown; `bench_step --help` for the
 * options.
 *
 * Loads the scene (default: examples/castling/rook.json: path, baked curl noise, an obstacle and
 * MDE, the whole velocity model), sets n = N and launches every agent at t = 0 so all of them are in
 * flight, then times S steps; with --synthesis 1 every step also computes every tet's four vertices
 * (FM §6, what a renderer needs each step). Prints one JSON object. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "bench_args.h"
#include "morph.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static const char USAGE[] =
    "usage: bench_step [--scene FILE] [--agents N] [--steps S] [--threads T] [--synthesis 0|1]\n"
    "\n"
    "One run of the tetra morph's step at N agents, all in flight, on T threads: one JSON object\n"
    "on stdout with the per-stage times and the CPU time (docs/performance.md).\n"
    "\n"
    "  --scene FILE     a tetra morph scene, n set to N (default examples/castling)\n"
    "  --agents N       agents (default 100000)\n"
    "  --steps S        timed steps after one warm-up step (default 20)\n"
    "  --threads T      threads (default: OpenMP's)\n"
    "  --synthesis 0|1  also compute every tet's vertices after each step (default 1)\n"
    "  -h, --help       this text\n";

int main(int argc, char **argv)
{
    long agents = 100000, steps = 20, threads = omp_get_max_threads(), synthesis = 1;
    char scene[4096];
    snprintf(scene, sizeof scene, "%s/examples/castling/rook.json", FM_SOURCE_DIR);
    static const char *const flags[] = {"0", "1"};
    bench_args a = bench_args_begin("bench_step", USAGE, argc, argv);
    while (bench_next(&a)) {
        if (bench_is(&a, "--agents")) agents = bench_long(&a, 1, 1000000000L);
        else if (bench_is(&a, "--steps")) steps = bench_long(&a, 1, 1000000000L);
        else if (bench_is(&a, "--threads")) threads = bench_long(&a, 1, 1024);
        else if (bench_is(&a, "--synthesis")) synthesis = bench_choice(&a, flags, 2);
        else if (bench_is(&a, "--scene")) snprintf(scene, sizeof scene, "%s", bench_value(&a));
        else bench_unknown(&a);
    }
    fm_scene_def def;
    fm_error err = {0};
    if (fm_scene_load(scene, &def, &err) != FM_OK) return fprintf(stderr, "bench_step: %s\n", err.message), 2;
    def.n = agents;
    def.launch_rate = 1e12; /* everyone in flight from the first step */
    double t0 = fm_seconds();
    fm_morph_model *model = fm_morph_model_build(&def, NULL, NULL, &err);
    if (!model) return fprintf(stderr, "bench_step: %s\n", err.message), 2;
    double prep = fm_seconds() - t0;
    /* MDE's d_min is a distance between neighbouring tets: keep it in proportion to the tet size,
     * which shrinks as n^(-1/3) from the scene's own count (the larger tet count of its meshes). */
    fm_morph_model_info mi = fm_morph_model_get_info(model);
    double scene_n = (double)(mi.source_tets > mi.target_tets ? mi.source_tets : mi.target_tets);
    model->def.d_min *= cbrt(scene_n / (double)agents);
    fm_morph_state *state = fm_morph_state_create(model, (int)threads, &err);
    float *frame = malloc(sizeof(float) * 12 * (size_t)agents);
    if (!state || !frame) return fprintf(stderr, "bench_step: out of memory\n"), 4;
    fm_morph_step(model, state); /* warm-up: launches everyone, touches every page */
    memset(state->stage_seconds, 0, sizeof state->stage_seconds);
    double synth_seconds = 0;
    struct timespec c0, c1;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c0);
    t0 = fm_seconds();
    for (long s = 0; s < steps; s++) {
        fm_morph_step(model, state);
        if (synthesis) {
            double t1 = fm_seconds();
            fm_morph_tet_vertices(model, state, frame);
            synth_seconds += fm_seconds() - t1;
        }
    }
    double seconds = fm_seconds() - t0;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c1);
    double cpu_seconds = (double)(c1.tv_sec - c0.tv_sec) + 1e-9 * (double)(c1.tv_nsec - c0.tv_nsec);
    fm_morph_info info = fm_morph_get_info(state);
    double agent_steps = (double)agents * (double)steps;
    printf("{\"scene\": \"%s\", \"agents\": %ld, \"threads\": %ld, \"steps\": %ld, \"in_flight\": %lld, "
           "\"d_min\": %.5g, \"rest_spacing\": %.5g, \"preprocess_seconds\": %.3f, \"agent_steps_per_second\": %.4g, \"steps_per_second\": %.4g, "
           "\"ns_per_agent_step\": %.3f, \"cpu_ns_per_agent_step\": %.3f, \"stage_ns_per_agent\": {",
           scene, agents, threads, steps, (long long)(info.run.count[FM_PHASE_FLYING] + info.run.count[FM_PHASE_HOMING]), model->def.d_min, cbrt(mi.source_volume / (double)agents), prep,
           agent_steps / seconds, (double)steps / seconds, 1e9 * seconds / agent_steps, 1e9 * cpu_seconds / agent_steps);
    for (int k = 0; k < FM_STAGE_COUNT; k++)
        printf("\"%s\": %.2f, ", fm_stage_names[k], 1e9 * state->stage_seconds[k] / agent_steps);
    printf("\"synthesis\": %.2f}}\n", 1e9 * synth_seconds / agent_steps);
    free(frame);
    fm_morph_state_destroy(state);
    fm_morph_model_destroy(model);
    return 0;
}
