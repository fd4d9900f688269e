/* Surface sampling (SCF §3): every sample on the surface and reproduced by its (triangle,
 * barycentrics), exactly N of them, mosaic and stratified more uniform than random by a stated
 * margin on two meshes, determinism for a seed and across thread counts, evaluation on deformed
 * meshes, the agent-sample correspondence, the uniformity measure itself, and bad input. */
#include "closest.h"
#include "fm_internal.h"
#include "geom.h"
#include "sample.h"
#include "test_macros.h"
#include "test_mesh_helpers.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define N_SAMPLES 3000

static const char *const mesh_names[2] = {"suzanne", "torus"};

static fm_mesh load_mesh(const char *name)
{
    char path[FM_PATH_MAX];
    snprintf(path, sizeof path, "%s/examples/creatures/%s.obj", FM_SOURCE_DIR, name);
    fm_mesh m = {0};
    fm_error err = {0};
    ENSURE_MSG(fm_mesh_load(path, &m, &err) == FM_OK, "%s", err.message);
    return m;
}

static fm_samples sample(const fm_mesh *m, int64_t n, fm_sample_method method, uint64_t seed, int threads)
{
    fm_sample_opts o = fm_default_sample_opts();
    o.method = method, o.seed = seed, o.threads = threads;
    fm_samples s;
    fm_error err = {0};
    fm_status st = fm_sample_surface(m, n, &o, &s, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    return s;
}

static double nn_cv(const fm_samples *s)
{
    double mean = 0, cv = 0;
    fm_error err = {0};
    ENSURE_MSG(fm_points_nn_stats(s->p, s->n, 0, &mean, &cv, &err) == FM_OK, "%s", err.message);
    return cv;
}

/* Exactly n; each sample within 1e-5 of the diagonal of the surface (Embree); its (tri, bary)
   valid and giving back its position. */
static void check_on_surface(const fm_mesh *m, const fm_closest *surface, const fm_samples *s, int64_t n, const char *what)
{
    ENSURE_MSG(s->n == n, "%s: %lld samples, want %lld", what, (long long)s->n, (long long)n);
    const double tol = 1e-5 * bbox_diagonal(m);
    double worst = 0, worst_eval = 0;
    int bad_tri = 0, bad_bary = 0;
    float *again = malloc(sizeof(float) * 3 * (size_t)s->n);
    fm_samples_eval(s, m->v, m->tri, again);
    for (int64_t i = 0; i < s->n; i++) {
        double p[3] = {s->p[3 * i], s->p[3 * i + 1], s->p[3 * i + 2]};
        worst = fmax(worst, fm_closest_point(surface, p, INFINITY, NULL, NULL));
        bad_tri += s->tri[i] < 0 || s->tri[i] >= m->nt;
        const float *b = s->bary + 3 * i;
        bad_bary += !(b[0] >= 0 && b[1] >= 0 && b[2] >= 0 && fabs((double)b[0] + b[1] + b[2] - 1) < 1e-6);
        for (int k = 0; k < 3; k++) worst_eval = fmax(worst_eval, fabs((double)again[3 * i + k] - p[k]));
    }
    printf("  %-22s farthest from the surface %.2e (limit %.2e)\n", what, worst, tol);
    ENSURE_MSG(worst <= tol, "%s: a sample %.3g from the surface", what, worst);
    ENSURE_MSG(bad_tri == 0 && bad_bary == 0, "%s: %d bad triangles, %d bad barycentrics", what, bad_tri, bad_bary);
    ENSURE_MSG(worst_eval == 0, "%s: (tri, bary) misses the position by %.3g", what, worst_eval);
    free(again);
}

static void test_samples_on_surface(void)
{
    for (int mi = 0; mi < 2; mi++) {
        fm_mesh m = load_mesh(mesh_names[mi]);
        fm_error err = {0};
        fm_closest *surface = fm_closest_build(&m, 1, "test mesh", 0, &err);
        ENSURE_MSG(surface, "%s", err.message);
        static const char *method[3] = {"random", "mosaic", "stratified"};
        for (int k = 0; k < 3 && surface; k++) {
            for (int64_t n = 1; n <= N_SAMPLES; n += N_SAMPLES - 1) { /* 1 and N */
                fm_samples s = sample(&m, n, (fm_sample_method)k, 7, 0);
                char what[64];
                snprintf(what, sizeof what, "%s %s n=%lld", mesh_names[mi], method[k], (long long)n);
                check_on_surface(&m, surface, &s, n, what);
                fm_samples_free(&s);
            }
        }
        fm_closest_destroy(surface);
        fm_mesh_free(&m);
    }
}

/* Measured (N = 3000, seed 7): random CV 0.52 on both meshes, mosaic 0.080 (suzanne) and 0.053
   (torus), stratified 0.13. Asserted: mosaic at least 60 % lower than random, stratified at least 50 % lower,
   and mosaic below stratified (the paper's "if the uniform point distribution is not required"). */
static void test_uniformity(void)
{
    for (int mi = 0; mi < 2; mi++) {
        fm_mesh m = load_mesh(mesh_names[mi]);
        fm_samples r = sample(&m, N_SAMPLES, FM_SAMPLE_RANDOM, 7, 0);
        fm_samples mo = sample(&m, N_SAMPLES, FM_SAMPLE_MOSAIC, 7, 0);
        fm_samples st = sample(&m, N_SAMPLES, FM_SAMPLE_STRATIFIED, 7, 0);
        double cr = nn_cv(&r), cm = nn_cv(&mo), cs = nn_cv(&st);
        printf("  %-8s nearest-neighbour CV: random %.3f, mosaic %.3f (%.0f %% lower), stratified %.3f (%.0f %% lower)\n",
               mesh_names[mi], cr, cm, 100 * (1 - cm / cr), cs, 100 * (1 - cs / cr));
        ENSURE_MSG(cm <= 0.4 * cr, "%s: mosaic CV %.3f vs random %.3f", mesh_names[mi], cm, cr);
        ENSURE_MSG(cs <= 0.5 * cr, "%s: stratified CV %.3f vs random %.3f", mesh_names[mi], cs, cr);
        ENSURE_MSG(cm < cs, "%s: mosaic CV %.3f vs stratified %.3f", mesh_names[mi], cm, cs);
        fm_samples_free(&r), fm_samples_free(&mo), fm_samples_free(&st);
        fm_mesh_free(&m);
    }
}

/* Manhattan dis_ij (Table I) also relaxes the random start. */
static void test_mosaic_manhattan(void)
{
    fm_mesh m = load_mesh("torus");
    fm_sample_opts o = fm_default_sample_opts();
    o.method = FM_SAMPLE_MOSAIC, o.manhattan = 1;
    fm_samples s, r = sample(&m, N_SAMPLES, FM_SAMPLE_RANDOM, o.seed, 0);
    fm_error err = {0};
    ENSURE_MSG(fm_sample_surface(&m, N_SAMPLES, &o, &s, &err) == FM_OK, "%s", err.message);
    double cm = nn_cv(&s), cr = nn_cv(&r);
    printf("  manhattan mosaic CV %.3f, random %.3f\n", cm, cr);
    ENSURE_MSG(cm <= 0.5 * cr, "manhattan mosaic CV %.3f vs random %.3f", cm, cr);
    fm_samples_free(&s), fm_samples_free(&r);
    fm_mesh_free(&m);
}

static int same_samples(const fm_samples *a, const fm_samples *b)
{
    return a->n == b->n && !memcmp(a->p, b->p, sizeof(float) * 3 * (size_t)a->n) &&
           !memcmp(a->tri, b->tri, sizeof(int32_t) * (size_t)a->n) &&
           !memcmp(a->bary, b->bary, sizeof(float) * 3 * (size_t)a->n);
}

static void test_deterministic(void)
{
    fm_mesh m = load_mesh("suzanne");
    for (int k = 0; k < 3; k++) {
        fm_samples a = sample(&m, N_SAMPLES, (fm_sample_method)k, 11, 1);
        fm_samples b = sample(&m, N_SAMPLES, (fm_sample_method)k, 11, 2);
        fm_samples c = sample(&m, N_SAMPLES, (fm_sample_method)k, 11, 2);
        fm_samples d = sample(&m, N_SAMPLES, (fm_sample_method)k, 12, 2);
        ENSURE_MSG(same_samples(&a, &b), "method %d: 1 and 2 threads differ", k);
        ENSURE_MSG(same_samples(&b, &c), "method %d: two runs differ", k);
        ENSURE_MSG(!same_samples(&c, &d), "method %d: seeds 11 and 12 agree", k);
        fm_samples_free(&a), fm_samples_free(&b), fm_samples_free(&c), fm_samples_free(&d);
    }
    fm_mesh_free(&m);
}

/* On the undeformed mesh eval gives the positions back bit for bit; under x -> A x + b it gives
   A p + b to float precision (the barycentric combination commutes with an affine map). */
static void test_eval_follows_affine_deformation(void)
{
    fm_mesh m = load_mesh("torus");
    fm_samples s = sample(&m, N_SAMPLES, FM_SAMPLE_MOSAIC, 3, 0);
    float *p = malloc(sizeof(float) * 3 * (size_t)s.n);
    fm_samples_eval(&s, m.v, m.tri, p);
    ENSURE(!memcmp(p, s.p, sizeof(float) * 3 * (size_t)s.n));
    const double A[3][3] = {{1.3, 0.2, -0.1}, {0.05, 0.8, 0.3}, {-0.2, 0.1, 1.1}}, b[3] = {4, -2, 7.5};
    double *v = malloc(sizeof(double) * 3 * (size_t)m.nv);
    for (int64_t i = 0; i < m.nv; i++)
        for (int r = 0; r < 3; r++)
            v[3 * i + r] = b[r] + A[r][0] * m.v[3 * i] + A[r][1] * m.v[3 * i + 1] + A[r][2] * m.v[3 * i + 2];
    fm_samples_eval(&s, v, m.tri, p);
    double worst = 0, scale = 0;
    for (int64_t i = 0; i < s.n; i++)
        for (int r = 0; r < 3; r++) {
            /* the reference from the float position: A p + b in double */
            double want = b[r] + A[r][0] * s.p[3 * i] + A[r][1] * s.p[3 * i + 1] + A[r][2] * s.p[3 * i + 2];
            worst = fmax(worst, fabs(p[3 * i + r] - want));
            scale = fmax(scale, fabs(want));
        }
    printf("  affine deformation: worst error %.3g at coordinates up to %.3g\n", worst, scale);
    ENSURE_MSG(worst <= 4e-7 * scale, "affine: worst %.3g at scale %.3g", worst, scale);
    free(v), free(p);
    fm_samples_free(&s);
    fm_mesh_free(&m);
}

/* ------------------------------------------------------------------ correspondence */

/* n points uniformly on the sphere (centre c, radius r). */
static float *sphere_points(int64_t n, const double c[3], double r, uint64_t seed)
{
    float *p = malloc(sizeof(float) * 3 * (size_t)n);
    for (int64_t i = 0; i < n; i++) {
        double z = 2 * test_uniform(&seed) - 1, phi = 6.283185307179586 * test_uniform(&seed), s = sqrt(1 - z * z);
        double d[3] = {s * cos(phi), s * sin(phi), z};
        for (int k = 0; k < 3; k++) p[3 * i + k] = (float)(c[k] + r * d[k]);
    }
    return p;
}

static int is_permutation(const int64_t *out, int64_t n)
{
    char *seen = calloc((size_t)n, 1);
    int ok = 1;
    for (int64_t i = 0; i < n && ok; i++) {
        ok = out[i] >= 0 && out[i] < n && !seen[out[i]];
        if (ok) seen[out[i]] = 1;
    }
    free(seen);
    return ok;
}

static double mean_distance(const float *a, const float *s, const int64_t *out, int64_t n)
{
    double sum = 0;
    for (int64_t i = 0; i < n; i++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += ((double)a[3 * i + k] - s[3 * out[i] + k]) * ((double)a[3 * i + k] - s[3 * out[i] + k]);
        sum += sqrt(d2);
    }
    return sum / (double)n;
}

/* Agents on a sphere of radius 1 and samples on a concentric sphere of radius 2 (both centred
   away from the origin): spherical matching pairs them radially, so the mean distance stays near
   the gap 1; random pairs average about 2.2. Measured (n = 20000): spherical 1.03, random 2.17. */
static void test_match(void)
{
    const int64_t n = 20000;
    const double c[3] = {3, -1, 2};
    float *agents = sphere_points(n, c, 1.0, 1), *samples = sphere_points(n, c, 2.0, 2);
    int64_t *rnd = malloc(sizeof(int64_t) * (size_t)n), *sph = malloc(sizeof(int64_t) * (size_t)n),
            *again = malloc(sizeof(int64_t) * (size_t)n);
    fm_error err = {0};
    ENSURE_MSG(fm_match_agents(agents, samples, n, FM_MATCH_RANDOM, 5, rnd, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(fm_match_agents(agents, samples, n, FM_MATCH_SPHERICAL, 5, sph, &err) == FM_OK, "%s", err.message);
    ENSURE(is_permutation(rnd, n) && is_permutation(sph, n));
    double dr = mean_distance(agents, samples, rnd, n), ds = mean_distance(agents, samples, sph, n);
    printf("  nested spheres, mean agent-sample distance: random %.3f, spherical %.3f (radial gap 1)\n", dr, ds);
    ENSURE_MSG(ds < 0.6 * dr && ds < 1.1, "spherical %.3f vs random %.3f", ds, dr);
    /* deterministic; random depends on its seed */
    ENSURE(fm_match_agents(agents, samples, n, FM_MATCH_SPHERICAL, 6, again, &err) == FM_OK);
    ENSURE(!memcmp(again, sph, sizeof(int64_t) * (size_t)n));
    ENSURE(fm_match_agents(agents, samples, n, FM_MATCH_RANDOM, 6, again, &err) == FM_OK);
    ENSURE(is_permutation(again, n) && memcmp(again, rnd, sizeof(int64_t) * (size_t)n) != 0);
    /* small counts */
    ENSURE(fm_match_agents(agents, samples, 1, FM_MATCH_SPHERICAL, 0, again, &err) == FM_OK && again[0] == 0);
    ENSURE(fm_match_agents(NULL, NULL, 0, FM_MATCH_SPHERICAL, 0, NULL, &err) == FM_OK);
    free(agents), free(samples), free(rnd), free(sph), free(again);
}

static double dist2f(const float *a, const float *b)
{
    double d[3] = {(double)a[0] - b[0], (double)a[1] - b[1], (double)a[2] - b[2]};
    return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

/* match[a] = a, then 4000 swaps of agents at most 2 apart on a side x side grid (an LCG's). */
static void jumble(int64_t *match, int side)
{
    uint64_t x = 12345;
    for (int64_t a = 0; a < (int64_t)side * side; a++) match[a] = a;
    for (int s = 0; s < 4000; s++) {
        x = x * 6364136223846793005u + 1442695040888963407u;
        const int i = (int)((x >> 33) % (uint64_t)side), j = (int)((x >> 45) % (uint64_t)side);
        const int di = (int)((x >> 20) % 5) - 2, dj = (int)((x >> 10) % 5) - 2;
        if (i + di < 0 || i + di >= side || j + dj < 0 || j + dj >= side) continue;
        const int64_t a = (int64_t)i * side + j, b = (int64_t)(i + di) * side + (j + dj), t = match[a];
        match[a] = match[b], match[b] = t;
    }
}

/* Uncrossing (fm_match_uncross): agents on a 30 x 30 grid layer, samples on the same grid stretched
 * x2 along x and tilted, matched as the grid matches them but jumbled locally (as a projection
 * folds): many grid-neighbour pairs cross ((x_a - x_b) . (y_a - y_b) < 0, counted here over the
 * grid's 4-neighbours, not by the engine's curve windows). After uncrossing few do, the summed squared travel is lower, and it is still a
 * permutation, the same each time. */
static void test_uncross(void)
{
    enum { SIDE = 30, NP = SIDE * SIDE };
    float *agents = malloc(sizeof(float) * 3 * NP), *samples = malloc(sizeof(float) * 3 * NP);
    int64_t *match = malloc(sizeof(int64_t) * NP), *again = malloc(sizeof(int64_t) * NP);
    for (int i = 0; i < SIDE; i++)
        for (int j = 0; j < SIDE; j++) {
            float *a = agents + 3 * (i * SIDE + j), *b = samples + 3 * (i * SIDE + j);
            a[0] = (float)i, a[1] = (float)j, a[2] = 0;
            b[0] = 2.0f * i + 5, b[1] = (float)j, b[2] = 0.5f * i;
        }
    fm_error err = {0};
    jumble(match, SIDE);
    double before = 0, after = 0;
    int crossed_before = 0, crossed_after = 0, pairs = 0;
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) ENSURE_MSG(fm_match_uncross(agents, samples, NP, match, &err) == FM_OK, "%s", err.message);
        double travel = 0;
        int crossed = 0;
        pairs = 0;
        for (int64_t a = 0; a < NP; a++) {
            travel += dist2f(agents + 3 * a, samples + 3 * match[a]);
            const int i = (int)(a / SIDE), j = (int)(a % SIDE);
            for (int e = 0; e < 2; e++) {
                const int ni = i + (e == 0), nj = j + (e == 1);
                if (ni >= SIDE || nj >= SIDE) continue;
                const int64_t b = ni * SIDE + nj;
                const float *xa = agents + 3 * a, *xb = agents + 3 * b, *ya = samples + 3 * match[a], *yb = samples + 3 * match[b];
                double dot = 0;
                for (int k = 0; k < 3; k++) dot += ((double)xa[k] - xb[k]) * ((double)ya[k] - yb[k]);
                crossed += dot < 0, pairs++;
            }
        }
        if (pass == 0) before = travel, crossed_before = crossed;
        else after = travel, crossed_after = crossed;
    }
    printf("  uncrossing a jumbled match: crossing neighbour pairs %d -> %d of %d; squared travel %.0f -> %.0f\n",
           crossed_before, crossed_after, pairs, before, after);
    ENSURE(is_permutation(match, NP));
    ENSURE_MSG(crossed_before > pairs / 3 && crossed_after < pairs / 50, "%d of %d pairs cross", crossed_after, pairs);
    ENSURE(after < before);
    jumble(again, SIDE);
    ENSURE(fm_match_uncross(agents, samples, NP, again, &err) == FM_OK && !memcmp(again, match, sizeof(int64_t) * NP));
    ENSURE(fm_match_uncross(agents, samples, 1, again, &err) == FM_OK);
    free(agents), free(samples), free(match), free(again);
}

/* Crossing pairs, (x_a - x_b) . (y_a - y_b) < 0, among those closer than r in the layout half-way,
 * (x + y) / 2 (the centroids cancel in the differences): all pairs, counted by brute force. */
static int crossing_midway(const float *agents, const float *samples, const int64_t *match, int64_t n, double r, int *pairs)
{
    int crossed = 0;
    *pairs = 0;
    for (int64_t a = 0; a < n; a++)
        for (int64_t b = a + 1; b < n; b++) {
            double mid = 0, dot = 0;
            for (int k = 0; k < 3; k++) {
                const double dx = (double)agents[3 * a + k] - agents[3 * b + k];
                const double dy = (double)samples[3 * match[a] + k] - samples[3 * match[b] + k];
                mid += 0.25 * (dx + dy) * (dx + dy), dot += dx * dy;
            }
            if (mid < r * r) crossed += dot < 0, (*pairs)++;
        }
    return crossed;
}

/* Agents that start apart can meet on the way: a sphere's points matched by direction to a torus's
 * fold through each other half-way, where no pair is neighbours at the start. Uncrossing compares the
 * neighbours of the layouts on the way too, so none of the pairs that come within two spacings of
 * each other half-way crosses. */
static void test_uncross_midway(void)
{
    enum { NP = 1500 };
    float *agents = malloc(sizeof(float) * 3 * NP), *samples = malloc(sizeof(float) * 3 * NP);
    int64_t *match = malloc(sizeof(int64_t) * NP);
    for (int64_t i = 0; i < NP; i++) {
        const double u = 2 * fm_random_unit(7, 0, (uint64_t)i) - 1, t = 6.283185307 * fm_random_unit(7, 1, (uint64_t)i);
        const double p = 6.283185307 * fm_random_unit(7, 2, (uint64_t)i), q = 6.283185307 * fm_random_unit(7, 3, (uint64_t)i);
        const double rho = sqrt(1 - u * u);
        float *a = agents + 3 * i, *b = samples + 3 * i;
        a[0] = (float)(3 * rho * cos(t)), a[1] = (float)(3 * rho * sin(t)), a[2] = (float)(3 * u);
        b[0] = (float)((4 + 1.5 * cos(q)) * cos(p)), b[1] = (float)((4 + 1.5 * cos(q)) * sin(p)), b[2] = (float)(1.5 * sin(q));
    }
    fm_error err = {0};
    ENSURE(fm_match_agents(agents, samples, NP, FM_MATCH_SPHERICAL, 1, match, &err) == FM_OK);
    const double spacing = 11.0 / sqrt((double)NP); /* the points' extent over sqrt(n), as uncrossing's cells */
    int pairs_before, pairs_after;
    const int before = crossing_midway(agents, samples, match, NP, 2 * spacing, &pairs_before);
    ENSURE_MSG(fm_match_uncross(agents, samples, NP, match, &err) == FM_OK, "%s", err.message);
    const int after = crossing_midway(agents, samples, match, NP, 2 * spacing, &pairs_after);
    printf("  sphere -> torus by direction: pairs within two spacings half-way that cross %d of %d -> %d of %d\n",
           before, pairs_before, after, pairs_after);
    ENSURE(is_permutation(match, NP));
    ENSURE_MSG(before > pairs_before / 20 && after == 0, "%d of %d pairs cross half-way", after, pairs_after);
    free(agents), free(samples), free(match);
}

/* Mean over the points a of `from` of the distance between out's point a and out's point of a's
 * nearest neighbour in `from` (all pairs): how well the projection keeps neighbours together. */
static double neighbour_spread(const float *from, const float *out, int64_t n)
{
    double sum = 0;
    for (int64_t a = 0; a < n; a++) {
        double best = INFINITY;
        int64_t who = -1;
        for (int64_t b = 0; b < n; b++) {
            double d2 = 0;
            for (int k = 0; k < 3 && b != a; k++) d2 += ((double)from[3 * a + k] - from[3 * b + k]) * ((double)from[3 * a + k] - from[3 * b + k]);
            if (b != a && d2 < best) best = d2, who = b;
        }
        double e2 = 0;
        for (int k = 0; k < 3; k++) e2 += ((double)out[3 * a + k] - out[3 * who + k]) * ((double)out[3 * a + k] - out[3 * who + k]);
        sum += sqrt(e2);
    }
    return sum / (double)n;
}

/* SCF's projection and relaxation (fm_sample_projected): points of a sphere around the torus
 * projected onto it land on it; the relaxation spreads them (the nearest-neighbour CV at least
 * halves against the bare projection) while each point stays near its projection and neighbours
 * stay neighbours (their spread far below a random assignment's); 1 and 2 threads agree bit for bit. */
static void test_projected(void)
{
    fm_mesh m = load_mesh("torus");
    const int64_t n = 2000;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, c[3];
    for (int64_t i = 0; i < m.nv; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], m.v[3 * i + k]), hi[k] = fmax(hi[k], m.v[3 * i + k]);
    for (int k = 0; k < 3; k++) c[k] = 0.5 * (lo[k] + hi[k]) + 0.3;
    float *from = sphere_points(n, c, 1.0, 11);
    fm_sample_opts o = fm_default_sample_opts();
    fm_samples bare, relaxed, two;
    fm_error err = {0};
    o.iterations = 0;
    ENSURE_MSG(fm_sample_projected(&m, from, n, &o, &bare, &err) == FM_OK, "%s", err.message);
    o = fm_default_sample_opts(), o.threads = 1;
    ENSURE_MSG(fm_sample_projected(&m, from, n, &o, &relaxed, &err) == FM_OK, "%s", err.message);
    o.threads = 2;
    ENSURE_MSG(fm_sample_projected(&m, from, n, &o, &two, &err) == FM_OK, "%s", err.message);
    fm_closest *surface = fm_closest_build(&m, 1, "torus", 0, &err);
    check_on_surface(&m, surface, &bare, n, "projected");
    check_on_surface(&m, surface, &relaxed, n, "projected, relaxed");
    fm_closest_destroy(surface);
    ENSURE(same_samples(&relaxed, &two));
    double moved = 0, spacing = 0, area = 0;
    for (int64_t t = 0; t < m.nt; t++) {
        const double *a = m.v + 3 * m.tri[3 * t], *b = m.v + 3 * m.tri[3 * t + 1], *d = m.v + 3 * m.tri[3 * t + 2];
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        const double x[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        area += 0.5 * sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    }
    spacing = sqrt(area / (double)n);
    for (int64_t a = 0; a < n; a++)
        moved += sqrt(dist2f(bare.p + 3 * a, relaxed.p + 3 * a)) / (double)n;
    int64_t *rnd = malloc(sizeof(int64_t) * (size_t)n);
    float *shuffled = malloc(sizeof(float) * 3 * (size_t)n);
    ENSURE(fm_match_agents(from, relaxed.p, n, FM_MATCH_RANDOM, 3, rnd, &err) == FM_OK);
    for (int64_t a = 0; a < n; a++) memcpy(shuffled + 3 * a, relaxed.p + 3 * rnd[a], 3 * sizeof(float));
    const double cv_bare = nn_cv(&bare), cv = nn_cv(&relaxed);
    const double spread = neighbour_spread(from, relaxed.p, n), spread_random = neighbour_spread(from, shuffled, n);
    printf("  projected onto the torus: nn CV %.3f bare, %.3f relaxed; moved %.2f spacings; neighbours %.3f apart "
           "(random %.3f)\n", cv_bare, cv, moved / spacing, spread, spread_random);
    ENSURE_MSG(cv < 0.5 * cv_bare, "relaxation: CV %g against %g", cv, cv_bare);
    ENSURE_MSG(moved < 3 * spacing, "the relaxation moved points %g (spacing %g)", moved, spacing);
    ENSURE_MSG(spread < 0.2 * spread_random, "neighbours %g apart against %g at random", spread, spread_random);
    from[7] = NAN;
    fm_samples_free(&two);
    ENSURE(fm_sample_projected(&m, from, n, &o, &two, &err) == FM_ERR_INPUT && strstr(err.message, "point 2 is not finite"));
    free(rnd), free(shuffled), free(from);
    fm_samples_free(&bare), fm_samples_free(&relaxed), fm_samples_free(&two);
    fm_mesh_free(&m);
}

/* ------------------------------------------------------------------ the measure, bad input */

/* A square lattice of spacing 0.5 has every nearest neighbour at 0.5 (CV 0). Moving point (0.5, 0)
   to (0.1, 0) gives it and (0, 0) a neighbour at 0.1 and changes no other. */
static void test_nn_stats(void)
{
    enum { SIDE = 40, NP = SIDE * SIDE };
    float *p = malloc(sizeof(float) * 3 * NP);
    for (int i = 0; i < NP; i++) p[3 * i] = 0.5f * (float)(i % SIDE), p[3 * i + 1] = 0.5f * (float)(i / SIDE), p[3 * i + 2] = 7;
    double mean = 0, cv = 1;
    fm_error err = {0};
    ENSURE(fm_points_nn_stats(p, NP, 2, &mean, &cv, &err) == FM_OK);
    ENSURE_NEAR(mean, 0.5, 1e-12);
    ENSURE_NEAR(cv, 0.0, 1e-9);
    p[3] = 0.1f;
    ENSURE(fm_points_nn_stats(p, NP, 1, &mean, &cv, &err) == FM_OK);
    double want_mean = ((NP - 2) * 0.5 + 2 * 0.1) / NP;
    double want_sd = sqrt(((NP - 2) * (0.5 - want_mean) * (0.5 - want_mean) + 2 * (0.1 - want_mean) * (0.1 - want_mean)) / NP);
    ENSURE_NEAR(mean, want_mean, 1e-8);
    ENSURE_NEAR(cv, want_sd / want_mean, 1e-6);
    /* two points far apart: their distance */
    const float two[6] = {0, 0, 0, 3, 4, 0};
    ENSURE(fm_points_nn_stats(two, 2, 1, &mean, &cv, &err) == FM_OK);
    ENSURE_NEAR(mean, 5.0, 1e-6);
    ENSURE_NEAR(cv, 0.0, 1e-12);
    ENSURE(fm_points_nn_stats(two, 1, 1, &mean, &cv, &err) == FM_ERR_INPUT);
    free(p);
}

/* The mosaic's iterations are bounded by their estimated CPU time (sample_mosaic.c): k 16 and 10^5
 * iterations at 2000 points make every point every other's candidate on the torus, about 40 CPU
 * minutes, and are refused before the first iteration, with the iterations that fit; 10 iterations
 * of the same run pass. */
static void test_mosaic_work_bounded(void)
{
    fm_mesh m = load_mesh("torus");
    fm_sample_opts o = fm_default_sample_opts();
    o.method = FM_SAMPLE_MOSAIC, o.k = 16, o.iterations = 100000, o.threads = 1;
    fm_samples s;
    fm_error err = {0};
    double t0 = fm_seconds();
    fm_status st = fm_sample_surface(&m, 2000, &o, &s, &err);
    ENSURE_MSG(st == FM_ERR_INPUT && strstr(err.message, "mosaic sampling: 100000 iterations over 2000 points with k 16") &&
               strstr(err.message, "more than the limit of 300 CPU s; use at most "), "%d %s", (int)st, err.message);
    ENSURE_MSG(fm_seconds() - t0 < 5, "refused after %.1f s, not before the first iteration", fm_seconds() - t0);
    const char *most = strstr(err.message, "use at most ");
    int fit = most ? atoi(most + 12) : 0;
    ENSURE_MSG(fit > 10 && fit < 100000, "iterations that fit: %d", fit);
    o.iterations = 10;
    ENSURE_MSG(fm_sample_surface(&m, 2000, &o, &s, &err) == FM_OK, "%s", err.message);
    fm_samples_free(&s);
    fm_mesh_free(&m);
}

static void expect_sample_error(const fm_mesh *m, int64_t n, const fm_sample_opts *o, const char *want)
{
    fm_samples s = {(float *)1, NULL, NULL, 5};
    fm_error err = {0};
    fm_status st = fm_sample_surface(m, n, o, &s, &err);
    ENSURE_MSG(st == FM_ERR_INPUT && strstr(err.message, want), "want '%s', got %d '%s'", want, (int)st, err.message);
    ENSURE(s.p == NULL && s.n == 0);
}

static void test_bad_input(void)
{
    fm_mesh m = load_mesh("torus");
    fm_sample_opts o = fm_default_sample_opts();
    expect_sample_error(&m, 0, NULL, "sample count 0");
    expect_sample_error(&m, -3, NULL, "sample count -3");
    expect_sample_error(NULL, 10, NULL, "no mesh");
    o.method = (fm_sample_method)7;
    expect_sample_error(&m, 10, &o, "unknown sampling method 7");
    o = fm_default_sample_opts(), o.k = -1;
    expect_sample_error(&m, 10, &o, "option k");
    o = fm_default_sample_opts(), o.lambda = NAN;
    expect_sample_error(&m, 10, &o, "option lambda");
    o = fm_default_sample_opts(), o.oversample = 0.5;
    expect_sample_error(&m, 10, &o, "option oversample");
    o = fm_default_sample_opts(), o.iterations = -1;
    expect_sample_error(&m, 10, &o, "iterations");
    fm_mesh bad = m;
    bad.nt = 0;
    expect_sample_error(&bad, 10, NULL, "empty");
    double v0 = m.v[4];
    m.v[4] = NAN;
    expect_sample_error(&m, 10, NULL, "vertex 1 is not finite");
    m.v[4] = v0;
    int32_t t0 = m.tri[2];
    m.tri[2] = (int32_t)m.nv;
    expect_sample_error(&m, 10, NULL, "refers to vertex");
    m.tri[2] = t0;
    /* all vertices on one point: no area */
    double *flat = calloc((size_t)(3 * m.nv), sizeof(double));
    fm_mesh zero = {flat, m.nv, m.tri, m.nt};
    expect_sample_error(&zero, 10, NULL, "no surface area");
    free(flat);
    /* an open mesh samples fine (one triangle) */
    double tri_v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    int32_t tri_i[3] = {0, 1, 2};
    fm_mesh one = {tri_v, 3, tri_i, 1};
    for (int k = 0; k < 3; k++) {
        fm_samples s = sample(&one, 50, (fm_sample_method)k, 1, 0);
        for (int64_t i = 0; i < s.n; i++)
            ENSURE(s.p[3 * i + 2] == 0 && s.p[3 * i] >= 0 && s.p[3 * i + 1] >= 0 && s.p[3 * i] + s.p[3 * i + 1] <= 1.000001f);
        fm_samples_free(&s);
    }
    /* correspondence */
    float pts[6] = {0, 0, 0, 1, NAN, 0};
    int64_t out[2];
    fm_error err = {0};
    ENSURE(fm_match_agents(pts, pts, -1, FM_MATCH_RANDOM, 0, out, &err) == FM_ERR_INPUT);
    ENSURE(fm_match_agents(pts, pts, 2, FM_MATCH_SPHERICAL, 0, out, &err) == FM_ERR_INPUT && strstr(err.message, "agent 1"));
    ENSURE(fm_match_agents(pts, pts, 2, (fm_match_method)3, 0, out, &err) == FM_ERR_INPUT);
    ENSURE(fm_match_agents(NULL, pts, 2, FM_MATCH_SPHERICAL, 0, out, &err) == FM_ERR_INPUT);
    fm_samples_free(NULL);
    fm_mesh_free(&m);
}

int main(void)
{
    RUN_TEST(test_samples_on_surface);
    RUN_TEST(test_uniformity);
    RUN_TEST(test_mosaic_manhattan);
    RUN_TEST(test_deterministic);
    RUN_TEST(test_eval_follows_affine_deformation);
    RUN_TEST(test_match);
    RUN_TEST(test_uncross);
    RUN_TEST(test_uncross_midway);
    RUN_TEST(test_projected);
    RUN_TEST(test_nn_stats);
    RUN_TEST(test_bad_input);
    RUN_TEST(test_mosaic_work_bounded);
    return test_result();
}
