/* Checkpoint save and load on one process (docs/resume.md), either mode.
 *
 *   bench_checkpoint [--scene FILE] [--agents N] [--repeats R] [--dir DIR]
 *
 * Builds the scene's model with n = N (default: examples/words/scene.json, 10^6 agents; a shape
 * flock scene such as examples/flock_suzanne_torus/scene.json benchmarks the flock), saves its
 * fresh state R times with the mode's fm_*_checkpoint_save (fsync and rename included) and loads
 * it R times into a fresh state (every checksum checked). Prints one JSON object: the file's
 * bytes and each repeat's save and load seconds, wall clock. On a shared machine run it
 * alternately against the build it is compared with. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct options {
    const char *scene, *dir;
    long agents, repeats;
} options;

static int parse(int argc, char **argv, options *o)
{
    *o = (options){FM_SOURCE_DIR "/examples/words/scene.json", "/tmp", 1000000, 3};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!v) return fprintf(stderr, "%s needs a value\n", a), 0;
        if (!strcmp(a, "--scene")) o->scene = v;
        else if (!strcmp(a, "--dir")) o->dir = v;
        else if (!strcmp(a, "--agents")) o->agents = atol(v);
        else if (!strcmp(a, "--repeats")) o->repeats = atol(v);
        else return fprintf(stderr, "unknown option %s\n", a), 0;
        i++;
    }
    return o->agents > 0 && o->repeats > 0;
}

typedef struct bench_run {
    void *model;
    int flock;
} bench_run;

static fm_status save(const bench_run *b, void *state, const char *path, fm_error *err)
{
    if (b->flock) {
        fm_flock_run_stats stats;
        memset(&stats, 0, sizeof stats);
        stats.run.frames = 1;
        return fm_flock_checkpoint_save(path, b->model, state, &stats, err);
    }
    fm_morph_run_stats stats;
    memset(&stats, 0, sizeof stats);
    stats.run.frames = 1;
    return fm_morph_checkpoint_save(path, b->model, state, &stats, err);
}

static void *create(const bench_run *b, fm_error *err)
{
    return b->flock ? (void *)fm_flock_state_create(b->model, 1, err) : (void *)fm_morph_state_create(b->model, 1, err);
}

static void destroy(const bench_run *b, void *state)
{
    if (b->flock) fm_flock_state_destroy(state);
    else fm_morph_state_destroy(state);
}

static fm_status load(const bench_run *b, void *state, const char *path, fm_error *err)
{
    fm_status st;
    if (b->flock) {
        fm_flock_run_stats stats;
        if ((st = fm_flock_checkpoint_load(path, b->model, state, &stats, err)) == FM_OK) fm_flock_run_stats_free(&stats);
    } else {
        fm_morph_run_stats stats;
        if ((st = fm_morph_checkpoint_load(path, b->model, state, &stats, err)) == FM_OK) fm_morph_run_stats_free(&stats);
    }
    return st;
}

int main(int argc, char **argv)
{
    options o;
    if (!parse(argc, argv, &o)) return fprintf(stderr, "usage: bench_checkpoint [--scene F] [--agents N] [--repeats R] [--dir D]\n"), 1;
    fm_scene_def def;
    fm_error err = {0};
    if (fm_scene_load(o.scene, &def, &err) != FM_OK) return fprintf(stderr, "%s\n", err.message), 1;
    def.n = (int64_t)o.agents;
    bench_run b = {NULL, def.mode == FM_MODE_SHAPE_FLOCK};
    b.model = b.flock ? (void *)fm_flock_model_build(&def, NULL, NULL, &err) : (void *)fm_morph_model_build(&def, NULL, NULL, &err);
    void *state = b.model ? create(&b, &err) : NULL;
    if (!state) return fprintf(stderr, "%s\n", err.message), 1;
    char path[4096];
    snprintf(path, sizeof path, "%s/bench_checkpoint.fmck", o.dir);
    printf("{\"agents\": %ld, \"mode\": \"%s\", \"save_seconds\": [", o.agents, b.flock ? "shape_flock" : "tetra_morph");
    for (long r = 0; r < o.repeats; r++) {
        double t0 = now();
        if (save(&b, state, path, &err) != FM_OK) return fprintf(stderr, "%s\n", err.message), 1;
        printf("%s%.4f", r ? ", " : "", now() - t0);
    }
    printf("], \"load_seconds\": [");
    for (long r = 0; r < o.repeats; r++) {
        void *fresh = create(&b, &err);
        double t0 = now();
        if (!fresh || load(&b, fresh, path, &err) != FM_OK) return fprintf(stderr, "%s\n", err.message), 1;
        printf("%s%.4f", r ? ", " : "", now() - t0);
        destroy(&b, fresh);
    }
    struct stat st;
    printf("], \"file_bytes\": %lld}\n", stat(path, &st) == 0 ? (long long)st.st_size : -1LL);
    remove(path);
    destroy(&b, state);
    if (b.flock) fm_flock_model_destroy(b.model);
    else fm_morph_model_destroy(b.model);
    return 0;
}
