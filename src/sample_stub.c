/* TEMPORARY (branch scf): area-weighted random sampling and random matching only, until branch
 * `sample` is merged; see src/sample.h. */
#include "sample.h"

#include <math.h>
#include <stdlib.h>

fm_sample_opts fm_default_sample_opts(void) { return (fm_sample_opts){.method = FM_SAMPLE_RANDOM, .seed = 1}; }

static double tri_area(const fm_mesh *m, int64_t t)
{
    const double *a = m->v + 3 * m->tri[3 * t], *b = m->v + 3 * m->tri[3 * t + 1], *c = m->v + 3 * m->tri[3 * t + 2];
    double u[3], v[3];
    for (int k = 0; k < 3; k++) u[k] = b[k] - a[k], v[k] = c[k] - a[k];
    double x = u[1] * v[2] - u[2] * v[1], y = u[2] * v[0] - u[0] * v[2], z = u[0] * v[1] - u[1] * v[0];
    return 0.5 * sqrt(x * x + y * y + z * z);
}

fm_status fm_sample_surface(const fm_mesh *mesh, int64_t n, const fm_sample_opts *opts, fm_samples *out, fm_error *err)
{
    if (opts->method != FM_SAMPLE_RANDOM)
        return fm_fail(err, FM_ERR_INPUT, "mosaic and stratified sampling arrive with branch sample; use \"random\"");
    double *cdf = malloc(sizeof(double) * (size_t)mesh->nt);
    out->p = malloc(sizeof(float) * 3 * (size_t)n), out->tri = malloc(sizeof(int32_t) * (size_t)n);
    out->bary = malloc(sizeof(float) * 3 * (size_t)n), out->n = n;
    if (!cdf || !out->p || !out->tri || !out->bary) return free(cdf), fm_samples_free(out), fm_fail(err, FM_ERR_MEMORY, "out of memory");
    double total = 0;
    for (int64_t t = 0; t < mesh->nt; t++) cdf[t] = total += tri_area(mesh, t);
    for (int64_t i = 0; i < n; i++) {
        double u = fm_random_unit(opts->seed, 1, (uint64_t)i) * total;
        int64_t lo = 0, hi = mesh->nt - 1;
        while (lo < hi) {
            int64_t mid = (lo + hi) / 2;
            if (cdf[mid] < u) lo = mid + 1;
            else hi = mid;
        }
        double r1 = sqrt(fm_random_unit(opts->seed, 2, (uint64_t)i)), r2 = fm_random_unit(opts->seed, 3, (uint64_t)i);
        out->tri[i] = (int32_t)lo;
        out->bary[3 * i] = (float)(1 - r1), out->bary[3 * i + 1] = (float)(r1 * (1 - r2)), out->bary[3 * i + 2] = (float)(r1 * r2);
    }
    free(cdf);
    fm_samples_eval(out, mesh->v, mesh->tri, out->p);
    return FM_OK;
}

void fm_samples_free(fm_samples *s)
{
    free(s->p), free(s->tri), free(s->bary);
    s->p = NULL, s->tri = NULL, s->bary = NULL, s->n = 0;
}

void fm_samples_eval(const fm_samples *s, const double *v, const int32_t *tri, float *p_out)
{
    for (int64_t i = 0; i < s->n; i++) {
        const int32_t *t = tri + 3 * s->tri[i];
        for (int k = 0; k < 3; k++)
            p_out[3 * i + k] = (float)(s->bary[3 * i] * v[3 * t[0] + k] + s->bary[3 * i + 1] * v[3 * t[1] + k] +
                                       s->bary[3 * i + 2] * v[3 * t[2] + k]);
    }
}

fm_status fm_match_agents(const float *agents, const float *samples, int64_t n, fm_match_method m, uint64_t seed,
                          int64_t *out, fm_error *err)
{
    (void)agents, (void)samples;
    if (m != FM_MATCH_RANDOM) return fm_fail(err, FM_ERR_INPUT, "spherical matching arrives with branch sample");
    for (int64_t i = 0; i < n; i++) out[i] = i;
    for (int64_t i = n - 1; i > 0; i--) {
        int64_t j = (int64_t)(fm_random_bits(seed, 4, (uint64_t)i) % (uint64_t)(i + 1)), t = out[i];
        out[i] = out[j], out[j] = t;
    }
    return FM_OK;
}
