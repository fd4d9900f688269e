/* Style velocity fields V_l (FM §5.2, eq 5; SCF eqs 7-8). See fields.h for the definitions.
 *
 * Noise: Perlin's improved gradient noise (2002: quintic fade 6s^5 - 15s^4 + 10s^3, the 12 cube-edge
 * gradients, a 256-entry permutation doubled to 512). Its gradient is computed analytically from
 * the trilinear form n = lerp_z(lerp_y(lerp_x(corner values))) with fade weights s:
 *   dn/dx_d = trilerp(gradient_d of the corners) + s'(f_d) * dn/ds_d,
 * so curl P is the exact curl of a C2 potential and exactly divergence-free (Bridson et al. 2007).
 * The three potentials of a field share one lattice cell and fade; only the permutations differ. */
#include "fields.h"
#include "kernel_noise.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

typedef struct field {
    fm_field_kind kind;
    double unit[3];     /* wind, gravity: unit(direction); vortex: unit(axis) */
    double speed;       /* wind, gravity */
    double center[3];   /* vortex */
    double strength;    /* vortex */
    int noise;          /* index into fm_fields.noise, -1 if the field has no noise part */
} field;

struct fm_fields {
    int count, noise_count;
    field *fields;
    noise_field *noise;
    double m[9], b[3];  /* the affine parts summed: gravity, wind mean, vortices: m x + b */
    int time_varying;
    /* the baked grid of the noise parts: 4 floats (x, y, z, 0) per cell, x fastest */
    int baked, grid_valid;
    double grid_t;
    int32_t res[3];
    double lo[3], h[3];
    double inv_h[3], uoff[3], umax[3]; /* cell coordinate u = x * inv_h + uoff, clamped to [0, umax] */
    int32_t imax[3];                    /* largest lower corner index: max(res - 2, 0) */
    int64_t stride[3], step[3];         /* floats per index; step = stride, or 0 along a 1-cell axis */
    float *grid;
};

/* Potential `which` (0..2) of field `index`: a Fisher-Yates shuffle driven by its own splitmix64
   stream, which starts at a point derived from the scene seed, the field index and `which`. */
static void make_perm(uint64_t seed, int index, int which, uint8_t perm[2 * PERM])
{
    uint64_t s = seed;
    s = fm_splitmix64(&s) + 0xD1B54A32D192ED03ull * (uint64_t)(3 * (int64_t)index + which + 1);
    for (int i = 0; i < PERM; i++) perm[i] = (uint8_t)i;
    for (int i = PERM - 1; i > 0; i--) {
        int j = (int)(((fm_splitmix64(&s) >> 32) * (uint64_t)(i + 1)) >> 32);
        uint8_t tmp = perm[i];
        perm[i] = perm[j];
        perm[j] = tmp;
    }
    memcpy(perm + PERM, perm, PERM);
}

/* The sum of all noise parts at (x, t). */
FM_HOT void noise_sum(const fm_fields *f, const double x[3], double t, double v[3])
{
    v[0] = v[1] = v[2] = 0;
    for (int i = 0; i < f->noise_count; i++) noise_curl_add(&f->noise[i], x, t, v);
}

/* ---------------------------------------------------------------- creation */

static int finite3(const double a[3]) { return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]); }

static double norm3(const double a[3]) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

static fm_status bad(fm_error *err, int i, const char *key, const char *what)
{
    return fm_fail(err, FM_ERR_INPUT, "style.fields[%d].%s: %s", i, key, what);
}

static fm_status check_def(const fm_field_def *d, int i, fm_error *err)
{
    switch (d->kind) {
    case FM_FIELD_CURL_NOISE:
        if (!isfinite(d->gain)) return bad(err, i, "gain", "must be a finite number");
        if (!isfinite(d->scale) || !(d->scale > 0)) return bad(err, i, "scale", "must be > 0 for curl noise");
        return FM_OK;
    case FM_FIELD_WIND:
        if (!finite3(d->direction)) return bad(err, i, "direction", "must be finite");
        if (!(norm3(d->direction) > 0)) return bad(err, i, "direction", "must be non-zero for a wind");
        if (!isfinite(d->speed)) return bad(err, i, "speed", "must be a finite number");
        if (!isfinite(d->turbulence)) return bad(err, i, "turbulence", "must be a finite number");
        if (!isfinite(d->period) || !(d->period >= 0)) return bad(err, i, "period", "must be >= 0 (0: frozen)");
        if (d->turbulence != 0 && (!isfinite(d->scale) || !(d->scale > 0)))
            return bad(err, i, "scale", "must be > 0 for a wind with turbulence");
        return FM_OK;
    case FM_FIELD_GRAVITY:
        if (!finite3(d->direction)) return bad(err, i, "direction", "must be finite");
        if (!(norm3(d->direction) > 0)) return bad(err, i, "direction", "must be non-zero for gravity");
        if (!isfinite(d->speed)) return bad(err, i, "speed", "must be a finite number");
        return FM_OK;
    case FM_FIELD_VORTEX:
        if (!finite3(d->center)) return bad(err, i, "center", "must be finite");
        if (!finite3(d->axis)) return bad(err, i, "axis", "must be finite");
        if (!(norm3(d->axis) > 0)) return bad(err, i, "axis", "must be non-zero for a vortex");
        if (!isfinite(d->strength)) return bad(err, i, "strength", "must be a finite number");
        return FM_OK;
    }
    return fm_fail(err, FM_ERR_INPUT, "style.fields[%d].kind: unknown field kind %d", i, (int)d->kind);
}

static void unit3(const double a[3], double u[3])
{
    double n = norm3(a);
    for (int d = 0; d < 3; d++) u[d] = a[d] / n;
}

fm_fields *fm_fields_create(const fm_field_def *defs, int count, uint64_t seed, const int32_t res[3],
                            const double lo[3], const double hi[3], fm_error *err)
{
    if (count < 0 || (count > 0 && !defs)) {
        fm_fail(err, FM_ERR_INPUT, "style.fields: bad field list (count %d)", count);
        return NULL;
    }
    int noise_count = 0;
    for (int i = 0; i < count; i++) {
        if (check_def(&defs[i], i, err) != FM_OK) return NULL;
        noise_count += (defs[i].kind == FM_FIELD_CURL_NOISE && defs[i].gain != 0) ||
                       (defs[i].kind == FM_FIELD_WIND && defs[i].turbulence != 0);
    }
    const int want_grid = res && res[0] > 0 && res[1] > 0 && res[2] > 0 && noise_count > 0;
    if (want_grid) {
        if (!lo || !hi || !finite3(lo) || !finite3(hi)) {
            fm_fail(err, FM_ERR_INPUT, "field_grid: the grid bounds must be finite");
            return NULL;
        }
        for (int d = 0; d < 3; d++)
            if (!(hi[d] > lo[d])) {
                fm_fail(err, FM_ERR_INPUT, "field_grid: empty grid bounds along axis %d (%g .. %g)", d,
                        lo[d], hi[d]);
                return NULL;
            }
        if ((double)res[0] * res[1] * res[2] > (double)(1 << 28)) {
            fm_fail(err, FM_ERR_INPUT, "field_grid: %d x %d x %d cells is more than 2^28", res[0], res[1],
                    res[2]);
            return NULL;
        }
    }

    fm_fields *f = fm_alloc(sizeof *f);
    if (!f) goto oom;
    f->count = count;
    f->noise_count = noise_count;
    f->fields = fm_alloc(sizeof(field) * (size_t)(count > 0 ? count : 1));
    f->noise = fm_alloc(sizeof(noise_field) * (size_t)(noise_count > 0 ? noise_count : 1));
    if (!f->fields || !f->noise) goto oom;

    int ni = 0;
    for (int i = 0; i < count; i++) {
        const fm_field_def *d = &defs[i];
        field *fl = &f->fields[i];
        fl->kind = d->kind;
        fl->noise = -1;
        if (d->kind == FM_FIELD_WIND || d->kind == FM_FIELD_GRAVITY) {
            unit3(d->direction, fl->unit);
            fl->speed = d->speed;
            for (int k = 0; k < 3; k++) f->b[k] += d->speed * fl->unit[k];
        } else if (d->kind == FM_FIELD_VORTEX) {
            /* strength * (a x (x - c)) = strength * [a]_x x - strength * (a x c) */
            double *a = fl->unit, s = d->strength;
            const double *c = d->center;
            unit3(d->axis, a);
            memcpy(fl->center, c, sizeof fl->center);
            fl->strength = s;
            f->m[1] -= s * a[2], f->m[2] += s * a[1];
            f->m[3] += s * a[2], f->m[5] -= s * a[0];
            f->m[6] -= s * a[1], f->m[7] += s * a[0];
            f->b[0] -= s * (a[1] * c[2] - a[2] * c[1]);
            f->b[1] -= s * (a[2] * c[0] - a[0] * c[2]);
            f->b[2] -= s * (a[0] * c[1] - a[1] * c[0]);
        }
        const double gain = d->kind == FM_FIELD_CURL_NOISE ? d->gain
                            : d->kind == FM_FIELD_WIND     ? d->turbulence
                                                           : 0;
        if (gain != 0) {
            noise_field *n = &f->noise[ni];
            fl->noise = ni++;
            n->inv_scale = 1.0 / d->scale;
            n->gain = gain;
            n->amp = gain / d->scale;
            if (d->kind == FM_FIELD_WIND && d->period > 0) {
                for (int k = 0; k < 3; k++) n->drift[k] = -fl->unit[k] / d->period;
                f->time_varying = 1;
            }
            memset(n->perm, 0, sizeof n->perm); /* the gathers' padding too */
            for (int w = 0; w < 3; w++) make_perm(seed, i, w, n->perm[w]);
        }
    }

    if (want_grid) {
        f->baked = 1;
        int64_t stride = 4;
        for (int d = 0; d < 3; d++) {
            f->res[d] = res[d];
            f->lo[d] = lo[d];
            f->h[d] = (hi[d] - lo[d]) / res[d];
            f->inv_h[d] = res[d] / (hi[d] - lo[d]);
            f->uoff[d] = -lo[d] * f->inv_h[d] - 0.5; /* cell i's centre is at lo + (i + 1/2) h */
            f->umax[d] = res[d] - 1;
            f->imax[d] = res[d] >= 2 ? res[d] - 2 : 0;
            f->stride[d] = stride;
            f->step[d] = res[d] >= 2 ? stride : 0;
            stride *= res[d];
        }
        f->grid = fm_alloc(sizeof(float) * (size_t)stride);
        if (!f->grid) goto oom;
    }
    return f;
oom:
    fm_fields_destroy(f);
    fm_fail(err, FM_ERR_MEMORY, "out of memory for the style fields");
    return NULL;
}

void fm_fields_destroy(fm_fields *f)
{
    if (!f) return;
    fm_free(f->fields);
    fm_free(f->noise);
    fm_free(f->grid);
    fm_free(f);
}

int fm_fields_time_varying(const fm_fields *f) { return f->time_varying; }

int fm_fields_baked(const fm_fields *f) { return f->baked; }

/* ---------------------------------------------------------------- evaluation */

void fm_fields_eval(const fm_fields *f, const double x[3], double t, double v[3])
{
    v[0] = v[1] = v[2] = 0;
    for (int i = 0; i < f->count; i++) {
        const field *fl = &f->fields[i];
        switch (fl->kind) {
        case FM_FIELD_WIND:
        case FM_FIELD_GRAVITY:
            for (int k = 0; k < 3; k++) v[k] += fl->speed * fl->unit[k];
            break;
        case FM_FIELD_VORTEX: { /* SCF eqs 7-8 */
            const double *a = fl->unit;
            const double p[3] = {x[0] - fl->center[0], x[1] - fl->center[1], x[2] - fl->center[2]};
            v[0] += fl->strength * (a[1] * p[2] - a[2] * p[1]);
            v[1] += fl->strength * (a[2] * p[0] - a[0] * p[2]);
            v[2] += fl->strength * (a[0] * p[1] - a[1] * p[0]);
            break;
        }
        case FM_FIELD_CURL_NOISE:
            break;
        }
        if (fl->noise >= 0) noise_curl_add(&f->noise[fl->noise], x, t, v); /* FM eq 5 */
    }
}

void fm_fields_potential(const fm_fields *f, const double x[3], double t, double psi[3])
{
    psi[0] = psi[1] = psi[2] = 0;
    for (int i = 0; i < f->noise_count; i++) {
        const noise_field *n = &f->noise[i];
        double q[3], g[3], val;
        lattice L;
        noise_point(n, x, t, q);
        lattice_at(q, &L);
        for (int k = 0; k < 3; k++) {
            perlin(n->perm[k], &L, &val, g);
            psi[k] += n->gain * val;
        }
    }
}

void fm_fields_prepare(fm_fields *f, double t, int threads)
{
    if (!f->baked || (f->grid_valid && (!f->time_varying || f->grid_t == t))) return;
    const int64_t nx = f->res[0], ny = f->res[1], rows = (int64_t)f->res[1] * f->res[2];
    const fm_fields *cf = f;
    float *grid = f->grid;
#ifdef _OPENMP
    const int nt = fm_threads(threads);
#pragma omp parallel for num_threads(nt) schedule(static)
#else
    (void)threads;
#endif
    for (int64_t r = 0; r < rows; r++) {
        const int64_t j = r % ny, k = r / ny;
        double x[3], v[3];
        x[1] = cf->lo[1] + ((double)j + 0.5) * cf->h[1];
        x[2] = cf->lo[2] + ((double)k + 0.5) * cf->h[2];
        float *out = grid + 4 * nx * r;
        for (int64_t i = 0; i < nx; i++) {
            x[0] = cf->lo[0] + ((double)i + 0.5) * cf->h[0];
            noise_sum(cf, x, t, v);
            out[4 * i + 0] = (float)v[0];
            out[4 * i + 1] = (float)v[1];
            out[4 * i + 2] = (float)v[2];
            out[4 * i + 3] = 0;
        }
    }
    f->grid_valid = 1;
    f->grid_t = t;
}

/* The grid's lookup parameters, copied to locals so the compiler keeps them in registers. */
typedef struct grid_view {
    const float *data;
    double inv_h[3], uoff[3], umax[3];
    int32_t imax[3];
    int64_t stride[3], step[3];
} grid_view;

static grid_view view_of(const fm_fields *f)
{
    grid_view g = {.data = f->grid};
    memcpy(g.inv_h, f->inv_h, sizeof g.inv_h);
    memcpy(g.uoff, f->uoff, sizeof g.uoff);
    memcpy(g.umax, f->umax, sizeof g.umax);
    memcpy(g.imax, f->imax, sizeof g.imax);
    memcpy(g.stride, f->stride, sizeof g.stride);
    memcpy(g.step, f->step, sizeof g.step);
    return g;
}

/* Trilinear interpolation of the baked noise parts, clamped to the grid of cell centres. */
FM_HOT void grid_sample(const grid_view *g, const double x[3], double v[3])
{
    int64_t base = 0;
    float fr[3];
    FM_UNROLL
    for (int d = 0; d < 3; d++) {
        double u = x[d] * g->inv_h[d] + g->uoff[d];
        u = u >= 0 ? u : 0; /* NaN goes to 0 too */
        u = u <= g->umax[d] ? u : g->umax[d];
        int32_t i = (int32_t)u;
        i = i <= g->imax[d] ? i : g->imax[d];
        fr[d] = (float)(u - i);
        base += i * g->stride[d];
    }
    const float *c = g->data + base;
    const int64_t sx = g->step[0], sy = g->step[1], sz = g->step[2];
    fm_f4 k[8]; /* the 8 corner cells, (x, y, z, 0) each */
    memcpy(&k[0], c, 16), memcpy(&k[1], c + sx, 16), memcpy(&k[2], c + sy, 16), memcpy(&k[3], c + sy + sx, 16);
    c += sz;
    memcpy(&k[4], c, 16), memcpy(&k[5], c + sx, 16), memcpy(&k[6], c + sy, 16), memcpy(&k[7], c + sy + sx, 16);
    const fm_f4 tx = {fr[0], fr[0], fr[0], fr[0]}, ty = {fr[1], fr[1], fr[1], fr[1]};
    const fm_f4 tz = {fr[2], fr[2], fr[2], fr[2]};
    const fm_f4 x0 = k[0] + tx * (k[1] - k[0]), x1 = k[2] + tx * (k[3] - k[2]);
    const fm_f4 x2 = k[4] + tx * (k[5] - k[4]), x3 = k[6] + tx * (k[7] - k[6]);
    const fm_f4 y0 = x0 + ty * (x1 - x0), y1 = x2 + ty * (x3 - x2);
    const fm_f4 r = y0 + tz * (y1 - y0);
    v[0] = r[0], v[1] = r[1], v[2] = r[2];
}

void fm_fields_add_block(const fm_fields *f, const float *const p[3], const uint8_t *phase,
                         int64_t begin, int64_t end, double t, float w, float *const v[3])
{
    const float *px = p[0], *py = p[1], *pz = p[2];
    double m[9], b[3];
    memcpy(m, f->m, sizeof m);
    memcpy(b, f->b, sizeof b);
    const double wd = w;
    if (f->baked) {
        const grid_view g = view_of(f);
        for (int64_t a = begin; a < end; a++) {
            if (phase[a] != FM_PHASE_FLYING) continue;
            const double x[3] = {px[a], py[a], pz[a]};
            double s[3];
            grid_sample(&g, x, s);
            fm_style_add(m, b, wd, x, s, v, a);
        }
    } else {
        fm_curl_view cv = {f->noise, f->noise_count, {0}, {0}, t, wd};
        memcpy(cv.m, m, sizeof m);
        memcpy(cv.b, b, sizeof b);
        fm_kernel_curl_add(&cv, p, phase, FM_PHASE_FLYING, begin, end, v);
    }
}

/* ---------------------------------------------------------------- whether to bake */

int fm_fields_grid_resolves(const fm_field_def *defs, int count, const int32_t res[3], const double lo[3],
                            const double hi[3], double *cell, double *scale)
{
    *cell = 0, *scale = INFINITY;
    for (int i = 0; i < count; i++) {
        const fm_field_def *d = &defs[i];
        int noisy = (d->kind == FM_FIELD_CURL_NOISE && d->gain != 0) || (d->kind == FM_FIELD_WIND && d->turbulence != 0);
        if (noisy) *scale = fmin(*scale, d->scale);
    }
    for (int k = 0; k < 3; k++) *cell = fmax(*cell, (hi[k] - lo[k]) / res[k]);
    return *cell * FM_FIELD_CELLS_PER_SCALE <= *scale;
}

double fm_fields_bake_error(const fm_fields *f, double t, int n)
{
    if (!f->baked || f->noise_count == 0 || n < 1) return 0;
    const grid_view g = view_of(f);
    double diff2 = 0, ref2 = 0;
    for (int i = 0; i < n; i++) {
        double x[3], baked[3], direct[3];
        for (int k = 0; k < 3; k++) /* inside the cell centres, where the grid interpolates */
            x[k] = f->lo[k] + f->h[k] * (0.5 + (f->res[k] - 1) * fm_random_unit(0x6261u, (uint64_t)k, (uint64_t)i));
        grid_sample(&g, x, baked);
        noise_sum(f, x, t, direct);
        for (int k = 0; k < 3; k++) diff2 += (baked[k] - direct[k]) * (baked[k] - direct[k]), ref2 += direct[k] * direct[k];
    }
    return ref2 > 0 ? sqrt(diff2 / ref2) : 0;
}

fm_status fm_fields_plan(const fm_scene_def *def, const double lo[3], const double hi[3], fm_field_plan *plan,
                         fm_error *err)
{
    const int32_t *res = def->field_grid;
    *plan = (fm_field_plan){0, 0, INFINITY, NAN, ""};
    if (def->field_count == 0 || !(res[0] > 0 && res[1] > 0 && res[2] > 0)) return FM_OK;
    int resolves = fm_fields_grid_resolves(def->fields, def->field_count, res, lo, hi, &plan->cell, &plan->scale);
    if (isinf(plan->scale)) return FM_OK; /* no noise parts: nothing to bake */
    int need[3]; /* cells of an eighth of the scale: a few percent (fields.h) */
    for (int k = 0; k < 3; k++) need[k] = (int)ceil((hi[k] - lo[k]) * 2 * FM_FIELD_CELLS_PER_SCALE / plan->scale);
    if (!resolves) {
        snprintf(plan->warning, sizeof plan->warning,
                 "cells of up to %.3g units cannot resolve noise of scale %.3g (a cell must be at most a quarter of "
                 "it, %.3g): the style fields are evaluated directly, which is exact but slower; a grid of about "
                 "[%d, %d, %d] would bake them", plan->cell, plan->scale, plan->scale / FM_FIELD_CELLS_PER_SCALE,
                 need[0], need[1], need[2]);
        return FM_OK;
    }
    fm_fields *f = fm_fields_create(def->fields, def->field_count, def->seed, res, lo, hi, err);
    if (!f) return err ? err->status : FM_ERR_INPUT;
    fm_fields_prepare(f, 0, 0);
    double error = fm_fields_bake_error(f, 0, 4096);
    fm_fields_destroy(f);
    if (error > FM_FIELD_MAX_BAKE_ERROR) {
        snprintf(plan->warning, sizeof plan->warning,
                 "the baked style fields differ from the exact ones by %.0f%% (RMS; at most %.0f%% is baked): they are "
                 "evaluated directly, which is exact but slower; a grid of about [%d, %d, %d] would bake them",
                 100 * error, 100 * FM_FIELD_MAX_BAKE_ERROR, need[0], need[1], need[2]);
        return FM_OK;
    }
    plan->baked = 1, plan->bake_error = error;
    return FM_OK;
}
