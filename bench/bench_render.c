/* Preview renderer throughput on a cache (default: the words example's, made by
 * tools/run-example.sh).
 *
 *   bench_render [--cache FILE] [--frames K] [--size WxH] [--view V] [--samples N] [--threads T]
 *                [--color index|value]
 *
 * Renders K frames spread evenly over the cache with the camera fitted to the whole animation, as
 * `flockmorph render` does, and prints one JSON object: wall and CPU milliseconds per frame, and
 * the same for a 1x1 image (the Embree scene build and fixed costs, without the rays). --color value
 * colours the tets by a value per tet on the colormap (FM_COLOUR_VALUE, as `render --color speed`
 * draws; the value is the first vertex's height, so the CLI's reading of a second frame is not
 * counted); the default is by index. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double clock_seconds(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct timing {
    double wall_ms, cpu_ms; /* per frame */
} timing;

/* Per-tet values for --color value: each tet's first vertex's height. */
static void heights(const float *verts, size_t n, float *values)
{
    for (size_t i = 0; i < n; i++) values[i] = verts[12 * i + 2];
}

/* Renders `count` frames of `frames` spread evenly, coloured by index or (c non-NULL) by value, its
 * values array being `values`; NAN on failure. */
static timing render_frames(fm_cache_reader *r, float *verts, const fm_render_opts *o,
                            const fm_render_colours *c, float *values, long count)
{
    timing t = {NAN, NAN};
    fm_error err = {0};
    fm_renderer *rr = fm_renderer_create(o, &err);
    unsigned char *rgb = malloc(3 * (size_t)o->width * (size_t)o->height);
    double wall = 0, cpu = 0;
    uint32_t frames = fm_cache_frames(r);
    for (long i = 0; rr && rgb && i < count; i++) {
        uint32_t f = (uint32_t)((double)(frames - 1) * (double)(i + 1) / (double)(count + 1));
        if (fm_cache_read_frame(r, f, verts, &err) != FM_OK) break;
        if (c) heights(verts, fm_cache_agents(r), values);
        double w0 = clock_seconds(CLOCK_MONOTONIC), c0 = clock_seconds(CLOCK_PROCESS_CPUTIME_ID);
        if (fm_renderer_draw_tets_coloured(rr, verts, fm_cache_agents(r), c, rgb, &err) != FM_OK) break;
        wall += clock_seconds(CLOCK_MONOTONIC) - w0;
        cpu += clock_seconds(CLOCK_PROCESS_CPUTIME_ID) - c0;
        if (i == count - 1) t.wall_ms = 1e3 * wall / (double)count, t.cpu_ms = 1e3 * cpu / (double)count;
    }
    if (err.message[0]) fprintf(stderr, "bench_render: %s\n", err.message);
    free(rgb);
    fm_renderer_destroy(rr);
    return t;
}

static void animation_bounds(fm_cache_reader *r, float *verts, double b[6])
{
    fm_error err = {0};
    for (int k = 0; k < 3; k++) b[k] = INFINITY, b[3 + k] = -INFINITY;
    for (uint32_t f = 0; f < fm_cache_frames(r); f++) {
        if (fm_cache_read_frame(r, f, verts, &err) != FM_OK) return;
        for (size_t i = 0; i < 12 * fm_cache_agents(r); i++) {
            int k = (int)(i % 3);
            if (isfinite(verts[i])) b[k] = fmin(b[k], verts[i]), b[3 + k] = fmax(b[3 + k], verts[i]);
        }
    }
}

int main(int argc, char **argv)
{
    const char *cache = FM_SOURCE_DIR "/out/words/frames.fmc", *view = "persp", *colour = "index";
    long count = 8, threads = omp_get_max_threads(), samples = 1;
    int width = 960, height = 540;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--cache")) cache = argv[i + 1];
        else if (!strcmp(argv[i], "--frames")) count = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--threads")) threads = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--samples")) samples = atol(argv[i + 1]);
        else if (!strcmp(argv[i], "--view")) view = argv[i + 1];
        else if (!strcmp(argv[i], "--color") && (!strcmp(argv[i + 1], "index") || !strcmp(argv[i + 1], "value")))
            colour = argv[i + 1];
        else if (!strcmp(argv[i], "--size") && sscanf(argv[i + 1], "%dx%d", &width, &height) == 2) continue;
        else return fprintf(stderr, "usage: bench_render [--cache FILE] [--frames K] [--size WxH] [--view V] [--samples N] [--threads T] [--color index|value]\n"), 1;
    }
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(cache, &err);
    if (!r) return fprintf(stderr, "bench_render: %s (tools/run-example.sh makes the words cache)\n", err.message), 2;
    float *verts = malloc(sizeof(float) * 12 * (fm_cache_agents(r) ? fm_cache_agents(r) : 1));
    if (!verts || count < 1) return fprintf(stderr, "bench_render: out of memory or no frames\n"), 4;
    double bounds[6];
    animation_bounds(r, verts, bounds);
    fm_render_opts o = fm_default_render_opts();
    if (fm_render_set_view(&o, view, &err) != FM_OK) return fprintf(stderr, "bench_render: %s\n", err.message), 1;
    o.width = width, o.height = height, o.samples = (int)samples, o.threads = (int)threads;
    o.bounds = bounds;
    float *values = malloc(sizeof(float) * (fm_cache_agents(r) ? fm_cache_agents(r) : 1));
    if (!values) return fprintf(stderr, "bench_render: out of memory\n"), 4;
    const double top = bounds[5] > bounds[2] ? bounds[5] : bounds[2] + 1.0;
    const fm_render_colours by_value = {FM_COLOUR_VALUE, values, bounds[2], top, NULL};
    const fm_render_colours *c = strcmp(colour, "value") ? NULL : &by_value;
    timing full = render_frames(r, verts, &o, c, values, count);
    o.width = o.height = 1, o.samples = 1;
    timing fixed = render_frames(r, verts, &o, c, values, count);
    printf("{\"cache\": \"%s\", \"agents\": %llu, \"frames\": %ld, \"size\": \"%dx%d\", \"view\": \"%s\", "
           "\"samples\": %ld, \"threads\": %ld, \"color\": \"%s\", \"wall_ms_per_frame\": %.1f, \"cpu_ms_per_frame\": %.1f, "
           "\"scene_wall_ms_per_frame\": %.1f, \"scene_cpu_ms_per_frame\": %.1f}\n",
           cache, (unsigned long long)fm_cache_agents(r), count, width, height, view, samples, threads, colour,
           full.wall_ms, full.cpu_ms, fixed.wall_ms, fixed.cpu_ms);
    free(values);
    free(verts);
    fm_cache_close(r);
    return isnan(full.wall_ms) ? 3 : 0;
}
