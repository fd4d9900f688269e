/* Perlin's improved gradient noise and the curl of three of them (FM eq 5): the scalar inline
 * functions the style fields (src/world/fields.c) evaluate and bake with, and the kernel that adds
 * the direct (unbaked) style velocity to a range of agents, with its SIMD variants
 * (kernel_noise_simd.c: FM_W agents at once, the noise in float after the lattice point, the
 * same operations in the same order, so the same bits). */
#ifndef FM_KERNEL_NOISE_H
#define FM_KERNEL_NOISE_H

#include "kernels.h"
#include "simd.h"

#include <stdint.h>

enum { PERM = 256 };

/* GNU C (GCC, Clang), like the rest of the engine: the per-agent path is forced inline with its
   small loops unrolled, and the grid lookup interpolates a cell's (x, y, z, 0) as one 4-float
   vector (SSE / NEON). */
#define FM_HOT static inline __attribute__((always_inline))
#define FM_UNROLL _Pragma("GCC unroll 8")
typedef float fm_f4 __attribute__((vector_size(16)));

typedef struct noise_field {
    double inv_scale;           /* 1 / scale */
    double gain;                /* magnitude of the potentials (gain or turbulence) */
    double amp;                 /* gain / scale: curl_x of gain * N(x / scale) = amp * grad N */
    double drift[3];            /* lattice units per second: -unit(direction) / period, or 0 */
    uint8_t perm[3][2 * PERM + 4]; /* P1, P2, P3; 4 zero bytes after each, read by 32-bit gathers */
} noise_field;

/* Perlin's gradients (h & 15): the 12 cube edges, 4 of them repeated; in double here and in float
 * for the direct kernel below. */
#define FM_PERLIN_GX {1, -1, 1, -1, 1, -1, 1, -1, 0, 0, 0, 0, 1, 0, -1, 0}
#define FM_PERLIN_GY {1, 1, -1, -1, 0, 0, 0, 0, 1, -1, 1, -1, 1, -1, 1, -1}
#define FM_PERLIN_GZ {0, 0, 0, 0, 1, 1, -1, -1, 1, 1, -1, -1, 0, 1, 0, -1}
static const double GX[16] = FM_PERLIN_GX, GY[16] = FM_PERLIN_GY, GZ[16] = FM_PERLIN_GZ;

/* A point in lattice units: its cell (mod 256), offset f in [0, 1), fade s(f) and s'(f). */
typedef struct lattice {
    int c[3];
    double f[3], s[3], ds[3];
} lattice;

FM_HOT void lattice_at(const double q[3], lattice *L)
{
    FM_UNROLL
    for (int d = 0; d < 3; d++) {
        double x = q[d] >= -1e15 ? q[d] : -1e15; /* keeps the integer conversion defined (NaN too) */
        x = x <= 1e15 ? x : 1e15;
        int64_t i = (int64_t)x;
        i -= x < (double)i; /* floor without a libm call */
        double f = x - (double)i;
        L->c[d] = (int)(i & (PERM - 1));
        L->f[d] = f;
        L->s[d] = f * f * f * (f * (f * 6 - 15) + 10);
        L->ds[d] = 30 * f * f * (f * (f - 2) + 1);
    }
}

FM_HOT double lerp(double t, double a, double b) { return a + t * (b - a); }

/* Corners are indexed x + 2y + 4z. */
FM_HOT double trilerp(const double c[8], const double s[3])
{
    return lerp(s[2], lerp(s[1], lerp(s[0], c[0], c[1]), lerp(s[0], c[2], c[3])),
                lerp(s[1], lerp(s[0], c[4], c[5]), lerp(s[0], c[6], c[7])));
}

/* One improved-Perlin noise N and its analytic gradient (in lattice units) at L, defined for a
   scalar type T (double here, float below for the direct kernel) with its lattice, lerp, trilerp and
   gradient tables: the same operations in the same order for both. */
#define FM_DEFINE_PERLIN(name, T, LATTICE, LERP, TRILERP, GXT, GYT, GZT)                                   \
    FM_HOT void name(const uint8_t *P, const LATTICE *L, T *value, T g[3])                                \
    {                                                                                                      \
        const int X = L->c[0], Y = L->c[1], Z = L->c[2];                                                   \
        const int A = P[X] + Y, AA = P[A] + Z, AB = P[A + 1] + Z;                                          \
        const int B = P[X + 1] + Y, BA = P[B] + Z, BB = P[B + 1] + Z;                                      \
        const int h[8] = {P[AA] & 15,     P[BA] & 15,     P[AB] & 15,     P[BB] & 15,                      \
                          P[AA + 1] & 15, P[BA + 1] & 15, P[AB + 1] & 15, P[BB + 1] & 15};                 \
        const T dx[2] = {L->f[0], L->f[0] - (T)1}, dy[2] = {L->f[1], L->f[1] - (T)1};                     \
        const T dz[2] = {L->f[2], L->f[2] - (T)1};                                                         \
        T gx[8], gy[8], gz[8], val[8];                                                                     \
        FM_UNROLL                                                                                          \
        for (int c = 0; c < 8; c++) {                                                                      \
            gx[c] = GXT[h[c]], gy[c] = GYT[h[c]], gz[c] = GZT[h[c]];                                       \
            val[c] = gx[c] * dx[c & 1] + gy[c] * dy[(c >> 1) & 1] + gz[c] * dz[c >> 2];                    \
        }                                                                                                  \
        const T s0 = L->s[0], s1 = L->s[1], s2 = L->s[2];                                                  \
        const T x00 = LERP(s0, val[0], val[1]), x10 = LERP(s0, val[2], val[3]);                            \
        const T x01 = LERP(s0, val[4], val[5]), x11 = LERP(s0, val[6], val[7]);                            \
        const T y0 = LERP(s1, x00, x10), y1 = LERP(s1, x01, x11);                                          \
        *value = LERP(s2, y0, y1);                                                                         \
        /* dn/ds_d of the trilinear form */                                                                \
        const T dn0 = LERP(s2, LERP(s1, val[1] - val[0], val[3] - val[2]),                                 \
                           LERP(s1, val[5] - val[4], val[7] - val[6]));                                    \
        const T dn1 = LERP(s2, x10 - x00, x11 - x01);                                                      \
        const T dn2 = y1 - y0;                                                                             \
        g[0] = TRILERP(gx, L->s) + L->ds[0] * dn0;                                                         \
        g[1] = TRILERP(gy, L->s) + L->ds[1] * dn1;                                                         \
        g[2] = TRILERP(gz, L->s) + L->ds[2] * dn2;                                                         \
    }

FM_DEFINE_PERLIN(perlin, double, lattice, lerp, trilerp, GX, GY, GZ)

/* The lattice point of a noise field: q = x / scale - (t / period) unit(direction). */
FM_HOT void noise_point(const noise_field *n, const double x[3], double t, double q[3])
{
    FM_UNROLL
    for (int d = 0; d < 3; d++) q[d] = x[d] * n->inv_scale + t * n->drift[d];
}

/* v += curl of gain * (N1, N2, N3)(q(x, t)) (FM eq 5): amp * (dN3/dy - dN2/dz, dN1/dz - dN3/dx,
   dN2/dx - dN1/dy) with the gradients in lattice units. */
FM_HOT void noise_curl_add(const noise_field *n, const double x[3], double t, double v[3])
{
    double q[3], g1[3], g2[3], g3[3], unused;
    lattice L;
    noise_point(n, x, t, q);
    lattice_at(q, &L);
    perlin(n->perm[0], &L, &unused, g1);
    perlin(n->perm[1], &L, &unused, g2);
    perlin(n->perm[2], &L, &unused, g3);
    v[0] += n->amp * (g3[1] - g2[2]);
    v[1] += n->amp * (g1[2] - g3[0]);
    v[2] += n->amp * (g2[0] - g1[1]);
}

/* The direct kernel's noise in float (issue 40): the lattice point, its cell and its offset in
   double as above (so the cell is exact for any position and time), the offset then rounded to
   float and Perlin's gradient, the curl and its sum over the fields in float, which the SIMD
   variants run in FM_W float lanes (16 with AVX-512) instead of FM_WD doubles. The baked grid, the
   potential and fm_fields_velocity keep the double functions above. Error against them over the
   rook's agents: docs/performance.md, "Fourth pass". */
static const float GXF[16] = FM_PERLIN_GX, GYF[16] = FM_PERLIN_GY, GZF[16] = FM_PERLIN_GZ;

typedef struct lattice_f {
    int c[3];
    float f[3], s[3], ds[3];
} lattice_f;

/* s(f) and s'(f) in float, the operations of lattice_at. */
FM_HOT float fade_f(float f) { return f * f * f * (f * (f * 6.0f - 15.0f) + 10.0f); }
FM_HOT float fade_df(float f) { return 30.0f * f * f * (f * (f - 2.0f) + 1.0f); }

FM_HOT void lattice_f_at(const double q[3], lattice_f *L)
{
    lattice D;
    lattice_at(q, &D); /* its s and ds are dead code here: the compiler drops them */
    FM_UNROLL
    for (int d = 0; d < 3; d++) {
        const float f = (float)D.f[d];
        L->c[d] = D.c[d], L->f[d] = f, L->s[d] = fade_f(f), L->ds[d] = fade_df(f);
    }
}

FM_HOT float lerp_f(float t, float a, float b) { return a + t * (b - a); }

FM_HOT float trilerp_f(const float c[8], const float s[3])
{
    return lerp_f(s[2], lerp_f(s[1], lerp_f(s[0], c[0], c[1]), lerp_f(s[0], c[2], c[3])),
                  lerp_f(s[1], lerp_f(s[0], c[4], c[5]), lerp_f(s[0], c[6], c[7])));
}

/* perlin in float (the curl needs only the gradient: the value is dead code once inlined). */
FM_DEFINE_PERLIN(perlin_f, float, lattice_f, lerp_f, trilerp_f, GXF, GYF, GZF)

/* noise_curl_add in float after the lattice point. */
FM_HOT void noise_curl_add_f(const noise_field *n, const double x[3], double t, float v[3])
{
    double q[3];
    float g1[3], g2[3], g3[3], unused;
    lattice_f L;
    noise_point(n, x, t, q);
    lattice_f_at(q, &L);
    perlin_f(n->perm[0], &L, &unused, g1);
    perlin_f(n->perm[1], &L, &unused, g2);
    perlin_f(n->perm[2], &L, &unused, g3);
    const float amp = (float)n->amp;
    v[0] += amp * (g3[1] - g2[2]);
    v[1] += amp * (g1[2] - g3[0]);
    v[2] += amp * (g2[0] - g1[1]);
}

/* The direct style velocity of fields.c for the kernel: omega2 * (m x + b + the curl noises). */
typedef struct fm_curl_view {
    const noise_field *noise;
    int count;
    double m[9], b[3];
    double t;        /* time (the wind's drift) */
    double w;        /* omega2 */
} fm_curl_view;

/* For agents a in [begin, end) with phase[a] == flying:
 *     v[k][a] += (float)(w * ((m x)_k + b_k + sum of the curl noises_k)),  x = (double)p[.][a],
 * the affine part in double, the fields' own order of operations, and the sum of the curl noises in
 * float (noise_curl_add_f). Other agents untouched. */
void fm_kernel_curl_add(const fm_curl_view *f, const float *const p[3], const uint8_t *phase, uint8_t flying,
                        int64_t begin, int64_t end, float *const v[3]);
void fm_kernel_curl_add_ref(const fm_curl_view *f, const float *const p[3], const uint8_t *phase, uint8_t flying,
                            int64_t begin, int64_t end, float *const v[3]);

/* v[.][a] += (float)(w * (m x + b + s)): the style velocity from its affine part and its noise s. */
FM_HOT void fm_style_add(const double m[9], const double b[3], double w, const double x[3], const double s[3],
                         float *const v[3], int64_t a)
{
    v[0][a] += (float)(w * (m[0] * x[0] + m[1] * x[1] + m[2] * x[2] + b[0] + s[0]));
    v[1][a] += (float)(w * (m[3] * x[0] + m[4] * x[1] + m[5] * x[2] + b[1] + s[1]));
    v[2][a] += (float)(w * (m[6] * x[0] + m[7] * x[1] + m[8] * x[2] + b[2] + s[2]));
}

/* One agent, the reference's way: the variants use it for the agents after their last full vector. */
FM_HOT void curl_add_agent(const fm_curl_view *f, const float *const p[3], int64_t a, float *const v[3])
{
    const double x[3] = {p[0][a], p[1][a], p[2][a]};
    float s[3] = {0, 0, 0};
    for (int i = 0; i < f->count; i++) noise_curl_add_f(&f->noise[i], x, f->t, s);
    const double sd[3] = {s[0], s[1], s[2]};
    fm_style_add(f->m, f->b, f->w, x, sd, v, a);
}

typedef void fm_curl_add_fn(const fm_curl_view *f, const float *const p[3], const uint8_t *phase, uint8_t flying,
                            int64_t begin, int64_t end, float *const v[3]);
FM_SIMD_DECLARE(fm_curl_add_fn, fm_kernel_curl_add);

#endif
