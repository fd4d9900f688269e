/* Surface sampling for the shape-constrained flock (SCF §3): N destination points on a target
 * triangle mesh, and the correspondence between agents and those points (SCF §3, "Point
 * Correspondence Establishment"). Preprocessing: nothing here runs in the step loop except
 * fm_samples_eval, which moves samples with a deforming target.
 *
 * Methods (docs/sampling.md has the measurements and how we read the paper):
 *   random      area-weighted uniform points: the baseline, and the mosaic's start;
 *   mosaic      surface mosaic sampling (Lai et al. 2006 as SCF revises it): the random start
 *               relaxed by the repulsion of eqs 1-5, forces restricted to the tangent plane, each
 *               point projected back onto the mesh with an exact (Embree) closest-point query;
 *   stratified  Nehab & Shilane 2004: an octree voxelization, one sample per occupied leaf drawn
 *               with the density lambda e^(-lambda d) around the voxel centre, then minimum-distance
 *               elimination down to exactly N.
 * Every method is deterministic for a seed and gives the same bits for any thread count. */
#ifndef FM_SAMPLE_H
#define FM_SAMPLE_H

#include "geom.h" /* fm_mesh: welded closed triangle mesh, doubles */
#include "scene_internal.h" /* the sampling defaults */

#include <stdint.h>

typedef enum fm_sample_method { FM_SAMPLE_RANDOM = 0, FM_SAMPLE_MOSAIC = 1, FM_SAMPLE_STRATIFIED = 2 } fm_sample_method;

typedef struct fm_sample_opts {
    fm_sample_method method;
    uint64_t seed;
    int iterations;     /* mosaic: repulsion iterations (eq 5 applied this many times; 0 = none) */
    int manhattan;      /* mosaic: 1 = Manhattan dis_ij (Table I line 4), 0 = Euclidean. The same
                           metric both selects the neighbours (dis_ij < A) and enters E_ij (eq 2) */
    double k;           /* mosaic eq 1: neighbourhood A = k sqrt(M/N), M the surface area */
    double w;           /* mosaic eq 3: sigma = w sqrt(M/N). The paper prints sigma = w M/N, which
                           is an area, not a length: taken literally it changes with the model's
                           scale (for M = 1, N = 10^4 it is 1e-4 against a spacing of 0.01, and
                           E_ij underflows to 0). We read M/N in eq 3 as the same length as in eq 1 */
    double lambda;      /* stratified: the density lambda e^(-lambda d), d the distance to the
                           voxel centre in voxel edges (so lambda is free of the model's scale) */
    /* Beyond the paper's parameters (zero takes the default): */
    double step;        /* mosaic: eq 5's delta t in units of sqrt(M/N) */
    double oversample;  /* stratified: occupied voxels (candidates) aimed for per sample, >= 1 */
    int threads;        /* OpenMP threads; 0 = omp_get_max_threads(). Results do not depend on it */
    const volatile sig_atomic_t *cancel; /* the studio's (NULL: none): where it is set, the mosaic stops
                           before its next iteration with FM_STOPPED (fm_build_stage) */
} fm_sample_opts;

fm_sample_opts fm_default_sample_opts(void);

/* N points on the surface: positions (3 floats each), the triangle each lies on and its barycentric
 * coordinates (3 floats each, summing to 1 to float rounding), so samples can follow a deforming
 * mesh with fixed connectivity (SCF §3: sampled once, on the first frame of the sequence). A
 * position is by definition fm_samples_eval of its (tri, bary) on the sampled mesh.
 * Arrays from fm_alloc; free with fm_samples_free. */
typedef struct fm_samples {
    float *p;
    int32_t *tri;
    float *bary;
    int64_t n;
} fm_samples;

/* Exactly n samples (1 <= n <= FM_SAMPLE_MAX) of the mesh (valid indices, finite vertices, no
 * repeated vertex in a triangle, positive area; it need not be closed). opts NULL = fm_default_sample_opts(). Errors: FM_ERR_INPUT for
 * a bad mesh or option (the message names it), FM_ERR_MEMORY, FM_ERR_INTERNAL (Embree). On failure
 * *out is zeroed. */
#define FM_SAMPLE_MAX (INT64_C(1) << 28)
fm_status fm_sample_surface(const fm_mesh *mesh, int64_t n, const fm_sample_opts *opts, fm_samples *out,
                            fm_error *err);
void fm_samples_free(fm_samples *s); /* zeroes *s; a zeroed or freed one is fine */

/* Re-evaluates sample positions on a mesh with the same connectivity (deforming targets):
 * p_out[i] = sum_k bary[i][k] * v[tri[tri[i]][k]], in double, rounded to float. mesh_vertices: 3
 * doubles per vertex; tri: 3 indices per triangle (the sampled mesh's). Pure; OpenMP over samples. */
void fm_samples_eval(const fm_samples *s, const double *mesh_vertices, const int32_t *tri, float *p_out);

/* Agent-to-sample correspondence (SCF §3, "Point Correspondence Establishment"). out[a] is the
 * sample index of agent a, a permutation of 0..n-1.
 *   random     a uniform random permutation from seed ("a random assignment suffices in most
 *              scenarios");
 *   spherical  agents and samples are projected onto unit spheres around their own centroids and
 *              matched by direction, so that overlapping consecutive shapes keep their layout (the
 *              paper's temporal coherence). Both sets are ranked along a 3D Hilbert curve through
 *              their directions and matched rank to rank, then pairs of agents near each other on
 *              the curve swap samples while that brings both closer in direction (a few
 *              deterministic passes). seed is unused.
 * agents, samples: 3 floats per point. FM_ERR_INPUT for n < 0, missing arrays or a non-finite
 * coordinate (named); FM_ERR_MEMORY. */
typedef enum fm_match_method { FM_MATCH_RANDOM = 0, FM_MATCH_SPHERICAL = 1 } fm_match_method;
fm_status fm_match_agents(const float *agents, const float *samples, int64_t n, fm_match_method m,
                          uint64_t seed, int64_t *out, fm_error *err);

/* Uncrossing (beyond SCF, for eq 11's blend): with x_a = agents[a] and y_a = samples[match[a]], each
 * less its set's centroid, eq 11 carries agent a's offset from the flock's centre from x_a to y_a,
 * (1 - u) x_a + u y_a at path fraction u. Two agents whose offset difference turns by more than 90
 * degrees, (x_a - x_b) . (y_a - y_b) < 0, pass through each other's neighbourhoods on the way (the
 * flock folds); swapping their samples undoes that and lowers the summed squared travel
 * sum |x_a - y_a|^2, so repeated swaps converge. Agents that start apart can meet on the way, so
 * the pairs compared are the neighbours on hash grids (grid.h, cells of about four spacings, 4
 * extent / sqrt(n), points on a surface) of the source layout and of the layouts (1 - w) x + w y at
 * w = 1/4, 1/2, 3/4; each round tries every agent, in index order, against its neighbours in each
 * layout, the first round every agent, later rounds only those whose sample changed in the round
 * before (only their pairs can have turned crossing); at most 32 rounds, sequential, depending only
 * on the input.
 * match: a permutation, changed in place. FM_ERR_MEMORY. */
fm_status fm_match_uncross(const float *agents, const float *samples, int64_t n, int64_t *match, fm_error *err);

/* SCF's correspondence by projection ("spherically projecting source positions on the first shape
 * onto the surface of the second shape, and let these projected points subject to energy
 * optimization"): point a of `from` (n points, 3 floats each) is seen from their centroid along the
 * unit direction u_a; the point c + rho u_a, c the mesh's area-weighted centroid and rho its largest
 * vertex distance from c (a sphere around the mesh), goes to its closest point of the mesh; then the
 * mosaic's relaxation (opts: iterations, k, w, step, the metric; method ignored) spreads the points
 * evenly, each keeping its index, so out's sample a is point a's. Errors as fm_sample_surface's, and
 * FM_ERR_INPUT for a non-finite point of `from` (named). */
fm_status fm_sample_projected(const fm_mesh *mesh, const float *from, int64_t n, const fm_sample_opts *opts,
                              fm_samples *out, fm_error *err);

/* The mesh's surface area (the sum of its triangles'). */
double fm_mesh_area(const fm_mesh *m);

/* Uniformity: the mean and the coefficient of variation (standard deviation / mean) of every
 * point's Euclidean distance to its nearest other point (exact, on the hash grid of grid.h; n >= 2;
 * coincident points count as distance 0). Same result for any thread count. */
fm_status fm_points_nn_stats(const float *p, int64_t n, int threads, double *mean, double *cv, fm_error *err);

/* ---------------------------------------------------------------- internal to sample*.c */

/* What every method needs: the mesh, its triangle areas and their running sums, the total M. */
typedef struct fm_sample_ctx {
    const fm_mesh *mesh;
    fm_sample_opts opts;  /* defaults filled in */
    int threads;
    int64_t n;
    double area;          /* M */
    double *cdf;          /* nt: cdf[t] = area of triangles 0..t */
} fm_sample_ctx;

/* Area-weighted uniform samples into out (allocated by the caller: n entries), with doubles. */
void fm_sample_random_into(const fm_sample_ctx *c, double *x, int32_t *tri);
/* The mosaic's work is bounded: FM_ERR_INPUT, naming the iterations and k and the iterations that
 * fit, when its estimated CPU time is over FM_SAMPLE_MOSAIC_MAX_SECONDS and over what the default
 * iterations and k take for n points (sample_mosaic.c, docs/limits.md). */
#define FM_SAMPLE_MOSAIC_MAX_SECONDS 300.0
fm_status fm_sample_mosaic(const fm_sample_ctx *c, double *x, int32_t *tri, fm_error *err);
/* The same relaxation from the points given in x (near the mesh: first projected onto it), each
 * point keeping its index. */
fm_status fm_sample_mosaic_from(const fm_sample_ctx *c, double *x, int32_t *tri, fm_error *err);
fm_status fm_sample_stratified(const fm_sample_ctx *c, double *x, int32_t *tri, fm_error *err);

/* The index along a 3D Hilbert curve (Skilling, "Programming the Hilbert curve", 2004;
   AxesToTranspose, then the bits interleaved) of the point p, quantized as (p - lo) * scale
   rounded and clamped to [0, 2^21 - 1] per axis. */
#define FM_HILBERT_BITS 21
uint64_t fm_hilbert_key(const double p[3], const double lo[3], double scale);

/* Sorting by a key, ties by index (so the order is total and the same everywhere). */
typedef struct fm_keyed {
    uint64_t key;
    int64_t i;
} fm_keyed;
void fm_keyed_sort(fm_keyed *k, int64_t n);

/* Barycentric coordinates of a point q on triangle t (clamped to the triangle, summing to 1). */
void fm_sample_barycentric(const fm_mesh *mesh, int32_t t, const double q[3], double b[3]);

#endif
