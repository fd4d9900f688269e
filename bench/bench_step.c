/* Step throughput at a chosen agent count, with a per-stage breakdown.
 *
 *   bench_step [--scene FILE] [--agents N] [--steps S] [--threads T] [--synthesis 0|1]
 *
 * Loads the scene (default: examples/castling/scene.json: path, baked curl noise, an obstacle and
 * MDE, the whole velocity model), sets n = N and launches every agent at t = 0 so all of them are in
 * flight, then times S steps; with --synthesis 1 every step also computes every tet's four vertices
 * (FM §6, what a renderer needs each step). Prints one JSON object. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "morph.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

int main(int argc, char **argv)
{
    long agents = 100000, steps = 20, threads = omp_get_max_threads(), synthesis = 1;
    char scene[4096];
    snprintf(scene, sizeof scene, "%s/examples/castling/scene.json", FM_SOURCE_DIR);
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--agents")) agents = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--steps")) steps = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--threads")) threads = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--synthesis")) synthesis = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--scene")) snprintf(scene, sizeof scene, "%s", argv[i + 1]);
        else return fprintf(stderr, "usage: bench_step [--scene FILE] [--agents N] [--steps S] [--threads T] [--synthesis 0|1]\n"), 1;
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
