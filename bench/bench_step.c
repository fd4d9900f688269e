/* Step throughput on the words scene (CASA -> 2014) at a chosen agent count.
 *
 *   bench_step [--agents N] [--steps S] [--threads T]
 *
 * Launches every agent at t = 0, so all of them are in flight, then times S steps and one frame of
 * vertices. Prints one JSON object. The throughput-issue benchmark suite will extend this. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime in strict C17 (clang's omp.h does not pull it in) */
#include "flockmorph/flockmorph.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    long agents = 100000, steps = 20, threads = omp_get_max_threads();
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--agents")) agents = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--steps")) steps = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--threads")) threads = atol(argv[i + 1]);
        else return fprintf(stderr, "usage: bench_step [--agents N] [--steps S] [--threads T]\n"), 1;
    }
    fm_scene_def def = fm_default_scene_def();
    snprintf(def.source.path, sizeof def.source.path, "%s/examples/words/casa.obj", FM_SOURCE_DIR);
    snprintf(def.target.path, sizeof def.target.path, "%s/examples/words/y2014.obj", FM_SOURCE_DIR);
    def.source.translate[0] = -10, def.target.translate[0] = 10;
    def.path_point_count = 1, def.path_points[0][2] = 8;
    def.n = agents;
    def.launch_rate = 1e12;        /* everyone in flight from the first step */
    def.frame_rate = 240;          /* short steps: nobody reaches the target within the run */
    fm_error err = {0};
    double t0 = now();
    fm_model *model = fm_model_build(&def, NULL, NULL, &err);
    if (!model) return fprintf(stderr, "bench_step: %s\n", err.message), 2;
    double prep = now() - t0;
    fm_state *state = fm_state_create(model, (int)threads, &err);
    float *frame = malloc(sizeof(float) * 12 * (size_t)agents);
    if (!state || !frame) return fprintf(stderr, "bench_step: out of memory\n"), 4;
    fm_step(model, state); /* warm-up: launches everyone, touches every page */
    t0 = now();
    for (long s = 0; s < steps; s++) fm_step(model, state);
    double step_seconds = now() - t0;
    t0 = now();
    fm_state_tet_vertices(model, state, frame);
    double frame_seconds = now() - t0;
    fm_state_info info = fm_state_get_info(state);
    printf("{\"agents\": %ld, \"threads\": %ld, \"steps\": %ld, \"in_flight\": %lld, \"preprocess_seconds\": %.3f, "
           "\"agent_steps_per_second\": %.4g, \"ns_per_agent_step\": %.3f, \"frame_ns_per_agent\": %.3f}\n",
           agents, threads, steps, (long long)info.count[FM_PHASE_FLYING], prep,
           (double)agents * (double)steps / step_seconds, 1e9 * step_seconds / ((double)agents * (double)steps),
           1e9 * frame_seconds / (double)agents);
    free(frame);
    fm_state_destroy(state);
    fm_model_destroy(model);
    return 0;
}
