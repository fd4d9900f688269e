/* Style velocity fields V_l (FM §5.2, eqs 5-6; SCF eqs 7-8).
 *
 * V_l(x, t) is the sum of the scene's fields:
 *   CURL_NOISE  FM eq 5: V = curl P, P(x) = gain * (P1(x/scale), P2(x/scale), P3(x/scale)), three
 *               improved-Perlin noises (quintic fade) with their own permutations; the gradient is
 *               analytic, so V is exactly divergence-free (Bridson et al. 2007). |V| ~ gain/scale.
 *   WIND        speed * unit(direction) + curl of turbulence * (P1, P2, P3)(q(x, t)), with
 *                 q(x, t) = x / scale - (t / period) * unit(direction)      (period 0: t ignored)
 *               i.e. the turbulence pattern is carried downwind at scale/period units per second
 *               (one noise cell per period). Each time slice is a curl, so divergence-free for every t.
 *   GRAVITY     speed * unit(direction).
 *   VORTEX      SCF eqs 7-8: strength * (unit(axis) x (x - center)); axis (0,1,0) gives eq 8 exactly.
 *
 * The noise parts (curl noise, wind turbulence) can be baked on a grid; the affine parts (gravity,
 * wind mean, vortices) are always added exactly, inside and outside the grid. */
#ifndef FM_FIELDS_H
#define FM_FIELDS_H

#include "fm_internal.h"

#include <stdint.h>

typedef struct fm_fields fm_fields;

/* defs: count fields (count may be 0: V_l = 0). seed: the scene seed (each field's three Perlin
   permutations come from splitmix64 streams of it; equal seeds give equal fields). If res is not
   NULL and res[0..2] > 0, the noise parts are baked onto a res[0] x res[1] x res[2] grid of cell
   centres spanning [lo, hi] (a float vector per cell) and sampled trilinearly (clamped at the grid
   edge); otherwise evaluated directly. Validates the defs (finite numbers, scale > 0 for noise,
   period >= 0, a non-zero direction for wind/gravity, non-zero axis for vortex) and fails with
   FM_ERR_INPUT naming "style.fields[i].<key>"; NULL on failure. */
fm_fields *fm_fields_create(const fm_field_def *defs, int count, uint64_t seed, const int32_t res[3],
                            const double lo[3], const double hi[3], fm_error *err);
void fm_fields_destroy(fm_fields *f);

/* 1 if V_l depends on t: a wind with period > 0 and turbulence != 0. */
int fm_fields_time_varying(const fm_fields *f);

/* 1 if a grid is used: res was given and some field has a noise part (affine-only sets need none). */
int fm_fields_baked(const fm_fields *f);

/* The reference: V_l(x, t) (FM eq 5, SCF eq 8) in double, evaluated directly (never from the grid). */
void fm_fields_eval(const fm_fields *f, const double x[3], double t, double v[3]);

/* The vector potential of V_l's noise parts at (x, t): the sum over curl-noise and wind fields of
   gain * (P1, P2, P3)(q) (FM eq 5's P), so that V_l = curl psi + the affine parts. For tests. */
void fm_fields_potential(const fm_fields *f, const double x[3], double t, double psi[3]);

/* Makes the baked grid valid for time t: bakes it the first time, and re-bakes it when the fields
   are time-varying and t changed; parallel over grid rows with `threads` OpenMP threads (<= 0: the
   OpenMP default); each cell is computed alone, so the grid does not depend on the thread count.
   No allocation. No-op when not baked. */
void fm_fields_prepare(fm_fields *f, double t, int threads);

/* The step kernel (FM eq 6's omega2 * V_l term): for agents a in [begin, end) with
   phase[a] == FM_PHASE_FLYING, v[k][a] += w * V_l(p(a), t), the noise parts from the grid
   (trilinear, after fm_fields_prepare(f, t, ...)) or directly (the affine parts in the double code
   of fm_fields_eval, the curl noise in float after the lattice point: kernel_noise.h); other
   agents untouched. No allocation; safe to call from many threads. */
void fm_fields_add_block(const fm_fields *f, const float *const p[3], const uint8_t *phase,
                         int64_t begin, int64_t end, double t, float w, float *const v[3]);

/* ---------------------------------------------------------------- whether to bake (issue 14)
 *
 * A baked grid can only carry noise it resolves. tests/world/test_fields.c measures the relative
 * RMS error of the trilinear grid against direct evaluation (curl noise): 5% at 8 cells per noise
 * scale, 18% at 4, 53% at 2 and 113% at castling's old 0.31, where the baked values are noise of
 * the grid itself and no longer divergence-free. A grid with cells over a quarter of the scale is
 * therefore never baked, and one that passes is baked only if its measured error is at most a
 * tenth of the field (FM_FIELD_MAX_BAKE_ERROR): then the grid's error is a small part of the
 * motion rather than motion of its own. */
#define FM_FIELD_CELLS_PER_SCALE 4.0
#define FM_FIELD_MAX_BAKE_ERROR 0.1

/* The largest cell edge of a res grid over [lo, hi] and the smallest noise scale of the fields
 * (INFINITY without noise parts); 1 if the grid resolves them (cell <= scale / 4). */
int fm_fields_grid_resolves(const fm_field_def *defs, int count, const int32_t res[3], const double lo[3],
                            const double hi[3], double *cell, double *scale);

/* The baked noise parts against direct evaluation at n deterministic points spread over the grid,
   at time t (call fm_fields_prepare(f, t, ...) first): RMS |baked - direct| / RMS |direct|. 0 when
   not baked or without noise. */
double fm_fields_bake_error(const fm_fields *f, double t, int n);

/* How a mode's state should evaluate the scene's fields, decided once at the model build. */
typedef struct fm_field_plan {
    int baked;          /* 1: bake the noise parts on style.grid */
    double cell, scale; /* the grid's largest cell edge and the smallest noise scale */
    double bake_error;  /* fm_fields_bake_error at t = 0 when baked; NaN otherwise */
    char warning[512];  /* non-empty when style.grid was given but cannot resolve the noise */
} fm_field_plan;

/* Bakes when style.grid is given, the fields have noise parts and the grid resolves them (cells of
   at most a quarter of the smallest noise scale and a measured bake error of at most
   FM_FIELD_MAX_BAKE_ERROR); when it does not, the fields are evaluated directly and `warning` says
   so with the numbers (grid over [lo, hi], the scene bounds the state bakes over). */
fm_status fm_fields_plan(const fm_scene_def *def, const double lo[3], const double hi[3], fm_field_plan *plan,
                         fm_error *err);

#endif
