/* Perlin's improved gradient noise and the curl of three of them (FM eq 5): the scalar inline
 * functions the style fields (src/world/fields.c) evaluate and bake with, and the kernel that adds
 * the direct (unbaked) style velocity to a range of agents, with its SIMD variants
 * (kernel_noise_simd.c: FM_WD agents at once in double, the same operations in the same order, so
 * the same bits). */
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

/* Perlin's gradients (h & 15): the 12 cube edges, 4 of them repeated. */
static const double GX[16] = {1, -1, 1, -1, 1, -1, 1, -1, 0, 0, 0, 0, 1, 0, -1, 0};
static const double GY[16] = {1, 1, -1, -1, 0, 0, 0, 0, 1, -1, 1, -1, 1, -1, 1, -1};
static const double GZ[16] = {0, 0, 0, 0, 1, 1, -1, -1, 1, 1, -1, -1, 0, 1, 0, -1};

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

/* One improved-Perlin noise N and its analytic gradient (in lattice units) at L. */
FM_HOT void perlin(const uint8_t *P, const lattice *L, double *value, double g[3])
{
    const int X = L->c[0], Y = L->c[1], Z = L->c[2];
    const int A = P[X] + Y, AA = P[A] + Z, AB = P[A + 1] + Z;
    const int B = P[X + 1] + Y, BA = P[B] + Z, BB = P[B + 1] + Z;
    const int h[8] = {P[AA] & 15,     P[BA] & 15,     P[AB] & 15,     P[BB] & 15,
                      P[AA + 1] & 15, P[BA + 1] & 15, P[AB + 1] & 15, P[BB + 1] & 15};
    const double fx = L->f[0], fy = L->f[1], fz = L->f[2];
    const double dx[2] = {fx, fx - 1}, dy[2] = {fy, fy - 1}, dz[2] = {fz, fz - 1};
    double gx[8], gy[8], gz[8], val[8];
#define FM_CORNER(c)                                                                         \
    gx[c] = GX[h[c]], gy[c] = GY[h[c]], gz[c] = GZ[h[c]];                                    \
    val[c] = gx[c] * dx[(c) & 1] + gy[c] * dy[((c) >> 1) & 1] + gz[c] * dz[(c) >> 2]
    FM_CORNER(0); FM_CORNER(1); FM_CORNER(2); FM_CORNER(3);
    FM_CORNER(4); FM_CORNER(5); FM_CORNER(6); FM_CORNER(7);
#undef FM_CORNER
    const double s0 = L->s[0], s1 = L->s[1], s2 = L->s[2];
    const double x00 = lerp(s0, val[0], val[1]), x10 = lerp(s0, val[2], val[3]);
    const double x01 = lerp(s0, val[4], val[5]), x11 = lerp(s0, val[6], val[7]);
    const double y0 = lerp(s1, x00, x10), y1 = lerp(s1, x01, x11);
    *value = lerp(s2, y0, y1);
    /* dn/ds_d of the trilinear form */
    const double dn0 = lerp(s2, lerp(s1, val[1] - val[0], val[3] - val[2]),
                            lerp(s1, val[5] - val[4], val[7] - val[6]));
    const double dn1 = lerp(s2, x10 - x00, x11 - x01);
    const double dn2 = y1 - y0;
    g[0] = trilerp(gx, L->s) + L->ds[0] * dn0;
    g[1] = trilerp(gy, L->s) + L->ds[1] * dn1;
    g[2] = trilerp(gz, L->s) + L->ds[2] * dn2;
}

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
 * in double, the fields' own order of operations. Other agents untouched. */
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
    double s[3] = {0, 0, 0};
    for (int i = 0; i < f->count; i++) noise_curl_add(&f->noise[i], x, f->t, s);
    fm_style_add(f->m, f->b, f->w, x, s, v, a);
}

typedef void fm_curl_add_fn(const fm_curl_view *f, const float *const p[3], const uint8_t *phase, uint8_t flying,
                            int64_t begin, int64_t end, float *const v[3]);
FM_SIMD_DECLARE(fm_curl_add_fn, fm_kernel_curl_add);

#endif
