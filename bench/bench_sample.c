/* Surface sampling (SCF §3): time and uniformity of random, mosaic and stratified sampling.
 *
 *   bench_sample [--mesh PATH] [--method random|mosaic|stratified] [--n N] [--threads T]
 *                [--iterations I] [--step S] [--k K] [--lambda L] [--oversample O] [--manhattan] [--seed S]
 *
 * Without --method/--n it runs the standard set on examples/creatures/suzanne.obj: every method at
 * N = 10^4 and 10^5, random and stratified also at 10^6. Prints one JSON object; per run the
 * wall and CPU seconds (all threads; on a shared machine the wall time varies), and the mean and coefficient of variation of the nearest-neighbour distances (lower
 * CV = more uniform). */
#include "geom.h"
#include "sample.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static const char *method_name[] = {"random", "mosaic", "stratified"};

static int parse_method(const char *s)
{
    for (int m = 0; m < 3; m++)
        if (!strcmp(s, method_name[m])) return m;
    return -1;
}

/* One run; prints its JSON object (preceded by a comma unless first). 0 on success. */
static int run(const fm_mesh *mesh, int64_t n, fm_sample_opts opts, int first)
{
    fm_error err = {0};
    fm_samples s;
    double t0 = fm_seconds();
    clock_t c0 = clock();
    fm_status st = fm_sample_surface(mesh, n, &opts, &s, &err);
    double seconds = fm_seconds() - t0, cpu = (double)(clock() - c0) / CLOCKS_PER_SEC;
    if (st != FM_OK) return fprintf(stderr, "bench_sample: %s\n", err.message), (int)st;
    double mean = 0, cv = 0;
    st = fm_points_nn_stats(s.p, s.n, opts.threads, &mean, &cv, &err);
    if (st != FM_OK) return fprintf(stderr, "bench_sample: %s\n", err.message), (int)st;
    printf("%s\n    {\"method\": \"%s\", \"n\": %lld, \"seconds\": %.3f, \"cpu_seconds\": %.3f, \"us_per_sample\": %.3f, "
           "\"nn_mean\": %.6g, \"nn_cv\": %.4f}",
           first ? "" : ",", method_name[opts.method], (long long)n, seconds, cpu, 1e6 * seconds / (double)n, mean, cv);
    fflush(stdout);
    fm_samples_free(&s);
    return 0;
}

int main(int argc, char **argv)
{
    char mesh_path[FM_PATH_MAX];
    snprintf(mesh_path, sizeof mesh_path, "%s/examples/creatures/suzanne.obj", FM_SOURCE_DIR);
    fm_sample_opts opts = fm_default_sample_opts();
    opts.threads = omp_get_max_threads();
    int method = -1;
    long long n = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--manhattan")) opts.manhattan = 1;
        else if (!v) return fprintf(stderr, "bench_sample: %s needs a value\n", a), 1;
        else if (!strcmp(a, "--mesh")) snprintf(mesh_path, sizeof mesh_path, "%s", v), i++;
        else if (!strcmp(a, "--method")) method = parse_method(v), i++;
        else if (!strcmp(a, "--n")) n = atoll(v), i++;
        else if (!strcmp(a, "--threads")) opts.threads = atoi(v), i++;
        else if (!strcmp(a, "--iterations")) opts.iterations = atoi(v), i++;
        else if (!strcmp(a, "--step")) opts.step = atof(v), i++;
        else if (!strcmp(a, "--k")) opts.k = atof(v), i++;
        else if (!strcmp(a, "--lambda")) opts.lambda = atof(v), i++;
        else if (!strcmp(a, "--oversample")) opts.oversample = atof(v), i++;
        else if (!strcmp(a, "--seed")) opts.seed = strtoull(v, NULL, 10), i++;
        else return fprintf(stderr, "bench_sample: unknown option %s\n", a), 1;
        if (method < -1 || (!strcmp(a, "--method") && method < 0))
            return fprintf(stderr, "bench_sample: method must be random, mosaic or stratified\n"), 1;
    }
    fm_mesh mesh = {0};
    fm_error err = {0};
    if (fm_mesh_load(mesh_path, &mesh, &err) != FM_OK) return fprintf(stderr, "bench_sample: %s\n", err.message), 2;
    printf("{\"mesh\": \"%s\", \"triangles\": %lld, \"threads\": %d, \"iterations\": %d, \"step\": %g, \"k\": %g, "
           "\"lambda\": %g, \"oversample\": %g, \"manhattan\": %d, \"runs\": [",
           mesh_path, (long long)mesh.nt, opts.threads, opts.iterations, opts.step, opts.k, opts.lambda, opts.oversample,
           opts.manhattan);
    int rc = 0, first = 1;
    for (int m = 0; m < 3 && rc == 0; m++) {
        if (method >= 0 && m != method) continue;
        opts.method = (fm_sample_method)m;
        for (long long size = 10000; size <= 1000000 && rc == 0; size *= 10) {
            if (n > 0 && size != 10000) break;
            if (n == 0 && size == 1000000 && m == FM_SAMPLE_MOSAIC) continue; /* too slow for the standard set */
            rc = run(&mesh, n > 0 ? n : size, opts, first);
            first = 0;
        }
    }
    printf("\n]}\n");
    fm_mesh_free(&mesh);
    return rc;
}
