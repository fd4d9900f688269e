/* Cache writer throughput on the words scene (examples/words/scene.json) at a chosen agent count.
 *
 *   bench_cache [--agents N] [--frames F] [--launch-seconds S] [--threads T] [--dir DIR] [--scene FILE] [--level L]
 *
 * 1. Runs F frames without a cache: the step rate without writing.
 * 2. Runs the same F frames (same seed, same frames) writing a cache of tet_vertices, id and
 *    phase, as `flockmorph run` does, once per variant (lossless, delta, quantum 1e-4, delta + quantum):
 *    the step rate with writing (wall time, finish included) and the compression ratio.
 * 3. Feeds the frames, read back into memory, to a bare writer as fast as it takes them: the
 *    writer's own throughput in raw and compressed MB/s (MB = 10^6 bytes).
 * The scene's launch rate is raised so every agent launches within the first S seconds (default
 * 1 s): all of them move, the hard case for compression. Prints one JSON object. */
#define _POSIX_C_SOURCE 200809L
#include "cache_format.h" /* fm_cache_writer_wait_seconds */
#include "flockmorph/flockmorph.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

static double clock_seconds(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double now(void) { return clock_seconds(CLOCK_MONOTONIC); }

/* CPU seconds of every thread of the process: on a shared machine wall time alone says little. */
static double cpu_now(void) { return clock_seconds(CLOCK_PROCESS_CPUTIME_ID); }

typedef struct timing {
    double wall, cpu;
} timing;

static timing since(timing start) { return (timing){now() - start.wall, cpu_now() - start.cpu}; }
static timing start_timing(void) { return (timing){now(), cpu_now()}; }

typedef struct variant {
    const char *name;
    int delta;
    double quantum;
} variant;

static const variant VARIANTS[] = {
    {"lossless", 0, 0}, {"delta", 1, 0}, {"quantum_1e-4", 0, 1e-4}, {"delta_quantum_1e-4", 1, 1e-4}};
#define VARIANT_COUNT (sizeof VARIANTS / sizeof VARIANTS[0])

static const fm_cache_attr ATTRS[] = {FM_ATTR_TET_VERTICES, FM_ATTR_ID, FM_ATTR_PHASE}; /* as tools/cli_run.c */
enum { ATTR_COUNT = sizeof ATTRS / sizeof ATTRS[0] };

static fm_cache_options options_for(const variant *v, const fm_scene_def *def)
{
    fm_cache_options o = fm_default_cache_options();
    o.compression_level = def->compression_level;
    o.delta = v->delta, o.quantum = v->quantum;
    return o;
}

/* One run of the scene from a fresh state, writing to `path` under `opts` (NULL: no cache).
 * Returns its time (finish included); stats in *rs, the step loop's wait for the writer in *wait. */
static timing timed_run(const fm_morph_model *model, int threads, double frame_rate, const char *path,
                        const fm_cache_options *opts, fm_morph_run_stats *rs, double *wait)
{
    fm_error err = {0};
    fm_morph_state *state = fm_morph_state_create(model, threads, &err);
    if (!state) fprintf(stderr, "bench_cache: %s\n", err.message), exit(4);
    timing t0 = start_timing();
    fm_cache_writer *w = NULL;
    if (path) w = fm_cache_writer_create_attrs(path, (uint64_t)fm_morph_model_get_info(model).agents,
                                               frame_rate, ATTRS, ATTR_COUNT, opts, &err);
    if (path && !w) fprintf(stderr, "bench_cache: %s\n", err.message), exit(3);
    fm_status st = fm_morph_run(model, state, w, NULL, NULL, rs, &err);
    *wait = w ? fm_cache_writer_wait_seconds(w) : 0;
    if (st == FM_OK && w) st = fm_cache_writer_finish(w, &err);
    else if (w) fm_cache_writer_abort(w);
    timing t = since(t0);
    if (st != FM_OK) fprintf(stderr, "bench_cache: %s\n", err.message), exit((int)st);
    fm_morph_state_destroy(state);
    return t;
}

/* The frames of a cache in memory, attributes one after another per frame; the ids (0 … n−1,
 * the same in every frame) once. */
typedef struct frames {
    uint32_t count;
    uint64_t agents;
    float *tets;
    uint32_t *ids;
    uint8_t *phases;
} frames;

static frames load_frames(const char *path)
{
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    if (!r) fprintf(stderr, "bench_cache: %s\n", err.message), exit(2);
    frames f = {fm_cache_frames(r), fm_cache_agents(r), NULL, NULL, NULL};
    f.tets = malloc(sizeof(float) * 12 * f.agents * f.count);
    f.ids = malloc(sizeof(uint32_t) * f.agents);
    f.phases = malloc(f.agents * f.count);
    if (!f.tets || !f.ids || !f.phases) fprintf(stderr, "bench_cache: out of memory for the frames\n"), exit(4);
    if (f.count > 0 && fm_cache_read_attr(r, 0, FM_ATTR_ID, f.ids, &err) != FM_OK)
        fprintf(stderr, "bench_cache: %s\n", err.message), exit(2);
    for (uint32_t k = 0; k < f.count; k++)
        if (fm_cache_read_attr(r, k, FM_ATTR_TET_VERTICES, f.tets + 12 * f.agents * k, &err) != FM_OK ||
            fm_cache_read_attr(r, k, FM_ATTR_PHASE, f.phases + f.agents * k, &err) != FM_OK)
            fprintf(stderr, "bench_cache: %s\n", err.message), exit(2);
    fm_cache_close(r);
    return f;
}

/* The time a bare writer takes for all frames, finish included. */
static timing timed_writer(const frames *f, const char *path, const fm_cache_options *opts)
{
    fm_error err = {0};
    timing t0 = start_timing();
    fm_cache_writer *w = fm_cache_writer_create_attrs(path, f->agents, 24, ATTRS, ATTR_COUNT, opts, &err);
    fm_status st = w ? FM_OK : err.status;
    for (uint32_t k = 0; k < f->count && st == FM_OK; k++) {
        const void *data[ATTR_COUNT] = {f->tets + 12 * f->agents * k, f->ids, f->phases + f->agents * k};
        st = fm_cache_writer_add_frame_attrs(w, data, &err);
    }
    if (st == FM_OK) st = fm_cache_writer_finish(w, &err);
    else if (w) fm_cache_writer_abort(w);
    if (st != FM_OK) fprintf(stderr, "bench_cache: %s\n", err.message), exit((int)st);
    return since(t0);
}

/* The 1-minute load average, to judge wall times on a shared machine (-1 if unknown). */
static double load_average(void)
{
    double load = -1;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f && fscanf(f, "%lf", &load) != 1) load = -1;
    if (f) fclose(f);
    return load;
}

static double file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (double)st.st_size : 0;
}

int main(int argc, char **argv)
{
    long agents = 100000, frame_count = 48, threads = omp_get_max_threads();
    int level = 0, level_given = 0;
    double launch_seconds = 1;
    const char *dir = "/tmp", *scene = FM_SOURCE_DIR "/examples/words/scene.json";
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--agents")) agents = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--frames")) frame_count = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--launch-seconds")) launch_seconds = atof(argv[i + 1]);
        else if (!strcmp(argv[i], "--threads")) threads = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--dir")) dir = argv[i + 1];
        else if (!strcmp(argv[i], "--scene")) scene = argv[i + 1];
        else if (!strcmp(argv[i], "--level")) level = atoi(argv[i + 1]), level_given = 1;
        else
            return fprintf(stderr, "usage: bench_cache [--agents N] [--frames F] [--launch-seconds S] [--threads T] [--dir DIR] "
                                   "[--scene FILE] [--level L]\n"), 1;
    }
    fm_scene_def def;
    fm_error err = {0};
    if (fm_scene_load(scene, &def, &err) != FM_OK)
        return fprintf(stderr, "bench_cache: %s\n", err.message), 2;
    def.n = agents;
    def.launch_rate = (double)agents / launch_seconds;
    def.frame_limit = (int32_t)frame_count;
    if (level_given) def.compression_level = level;
    double t0 = now();
    fm_morph_model *model = fm_morph_model_build(&def, NULL, NULL, &err);
    if (!model) return fprintf(stderr, "bench_cache: %s\n", err.message), 2;
    double prep = now() - t0;

    fm_morph_run_stats base;
    double no_wait;
    timing plain = timed_run(model, (int)threads, def.frame_rate, NULL, NULL, &base, &no_wait);
    double agent_steps = (double)agents * (double)base.run.steps, raw_frame = (double)agents * (48 + 4 + 1);
    printf("{\"agents\": %ld, \"frames\": %lld, \"steps\": %lld, \"threads\": %ld, \"launch_seconds\": %g, "
           "\"preprocess_seconds\": %.2f,\n \"raw_mb_per_frame\": %.3f,\n"
           " \"no_cache\": {\"wall_seconds\": %.3f, \"cpu_seconds\": %.3f, \"agent_steps_per_second\": %.4g},\n"
           " \"variants\": [",
           agents, (long long)base.run.frames, (long long)base.run.steps, threads, launch_seconds, prep, raw_frame / 1e6,
           plain.wall, plain.cpu, agent_steps / plain.wall);
    fm_morph_run_stats_free(&base);

    char path[4096];
    frames f = {0};
    for (size_t v = 0; v < VARIANT_COUNT; v++) {
        fm_cache_options opts = options_for(&VARIANTS[v], &def);
        fm_morph_run_stats rs;
        double wait;
        snprintf(path, sizeof path, "%s/bench_cache_%s.fmc", dir, VARIANTS[v].name);
        timing run = timed_run(model, (int)threads, def.frame_rate, path, &opts, &rs, &wait);
        fm_cache_reader *r = fm_cache_open(path, &err);
        if (!r) return fprintf(stderr, "bench_cache: %s\n", err.message), 2;
        double raw = (double)fm_cache_raw_bytes(r), packed = (double)fm_cache_compressed_bytes(r);
        fm_cache_close(r);
        if (v == 0) f = load_frames(path);
        timing writer = timed_writer(&f, path, &opts);
        printf("%s\n  {\"name\": \"%s\", \"level\": %d, \"delta\": %s, \"key_interval\": %d, \"quantum\": %g, "
               "\"run_wall_seconds\": %.3f, \"run_cpu_seconds\": %.3f, \"run_wait_seconds\": %.3f, \"agent_steps_per_second\": %.4g, "
               "\"slowdown\": %.3f, \"compression_ratio\": %.3f, \"file_mb\": %.2f,\n"
               "   \"writer_wall_seconds\": %.3f, \"writer_cpu_seconds\": %.3f, \"writer_raw_mb_per_second\": %.1f, "
               "\"writer_compressed_mb_per_second\": %.1f, \"writer_raw_mb_per_cpu_second\": %.1f}",
               v ? "," : "", VARIANTS[v].name, opts.compression_level, opts.delta ? "true" : "false", opts.key_interval, opts.quantum,
               run.wall, run.cpu, wait, agent_steps / run.wall, run.wall / plain.wall, raw / packed, file_size(path) / 1e6,
               writer.wall, writer.cpu, raw / writer.wall / 1e6, packed / writer.wall / 1e6, raw / writer.cpu / 1e6);
        fm_morph_run_stats_free(&rs);
        remove(path);
    }
    printf("\n ],\n \"load_average\": %.1f}\n", load_average());
    free(f.tets), free(f.ids), free(f.phases);
    fm_morph_model_destroy(model);
    return 0;
}
