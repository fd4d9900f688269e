/* TEMPORARY (branch scf): the surface sampling API as branch `sample` defines it in its brief, so
 * the shape flock builds before that branch is merged. Replaced by the real src/sample.h on merge;
 * src/sample_stub.c goes then. */
#ifndef FM_SAMPLE_H
#define FM_SAMPLE_H

#include "prep.h"

#include <stdint.h>

typedef enum fm_sample_method { FM_SAMPLE_RANDOM = 0, FM_SAMPLE_MOSAIC = 1, FM_SAMPLE_STRATIFIED = 2 } fm_sample_method;
typedef struct fm_sample_opts {
    fm_sample_method method;
    uint64_t seed;
    int iterations;
    int manhattan;
    double k, w;
    double lambda;
} fm_sample_opts;
fm_sample_opts fm_default_sample_opts(void);
typedef struct fm_samples { float *p; int32_t *tri; float *bary; int64_t n; } fm_samples;
fm_status fm_sample_surface(const fm_mesh *mesh, int64_t n, const fm_sample_opts *opts, fm_samples *out, fm_error *err);
void fm_samples_free(fm_samples *s);
void fm_samples_eval(const fm_samples *s, const double *mesh_vertices, const int32_t *tri, float *p_out);
typedef enum fm_match_method { FM_MATCH_RANDOM = 0, FM_MATCH_SPHERICAL = 1 } fm_match_method;
fm_status fm_match_agents(const float *agents, const float *samples, int64_t n, fm_match_method m,
                          uint64_t seed, int64_t *out, fm_error *err);

#endif
