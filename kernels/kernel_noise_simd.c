/* The direct style velocity, SIMD: FM_W agents at once, the reference's operations
 * (kernel_noise.h: lattice_f_at, perlin_f, noise_curl_add_f, curl_add_agent) in the same
 * order, so the same bits. The lattice point, its cell and offset are FM_WD-wide doubles (two or
 * more rounds per FM_W agents); the offset then goes to float and the noise runs in FM_W float
 * lanes (16 with AVX-512), the affine part in doubles again. The permutation lookups are gathers
 * from tables that stay in L1, one 32-bit gather giving both P[i] and P[i + 1]; the gradients'
 * 16-entry tables are permutes (fv_lookup16). Compiled three times (simd.h). */
#include "kernel_noise.h"
#include "simd.h"

typedef struct lattice_v {
    iv c[3];
    fv f[3], s[3], ds[3];
} lattice_v;

static inline fv lerp_v(fv t, fv a, fv b) { return fv_add(a, fv_mul(t, fv_sub(b, a))); }

/* Whole double vectors per float vector (every x86 level; a build with no vectors runs the
   reference's loop). */
#if FM_W % FM_WD == 0
/* The cells (exact small integers, as floats) and float offsets of FM_W agents' lattice points. */
typedef struct lattice_rows {
    float c[3][FM_W], f[3][FM_W];
} lattice_rows;

/* lattice_at, FM_WD lanes at a time: the cell mod 256 is fl - 256 floor(fl / 256), exact for the
   clamped range, and the offset rounds to float as the reference's cast does. */
static inline void lattice_rows_at(const noise_field *n, const float *const p[3], int64_t a, double t,
                                   lattice_rows *R)
{
    for (int h = 0; h < FM_W; h += FM_WD)
        for (int d = 0; d < 3; d++) {
            const dv q = dv_add(dv_mul(dv_from_floats(p[d] + a + h), dv_set1(n->inv_scale)), dv_set1(t * n->drift[d]));
            const dv x = dv_min(dv_max(q, dv_set1(-1e15)), dv_set1(1e15));
            const dv fl = dv_floor(x);
            const dv wrap = dv_mul(dv_set1(PERM), dv_floor(dv_mul(fl, dv_set1(1.0 / PERM))));
            dv_store_floats(R->c[d] + h, dv_sub(fl, wrap));
            dv_store_floats(R->f[d] + h, dv_sub(x, fl));
        }
}

/* lattice_f_at for FM_W agents */
static inline void lattice_v_at(const noise_field *n, const float *const p[3], int64_t a, double t, lattice_v *L)
{
    lattice_rows R;
    lattice_rows_at(n, p, a, t, &R);
    for (int d = 0; d < 3; d++) {
        const fv f = fv_load(R.f[d]);
        L->c[d] = iv_from_fv(fv_load(R.c[d]));
        L->f[d] = f;
        L->s[d] = fv_mul(fv_mul(fv_mul(f, f), f),
                         fv_add(fv_mul(f, fv_sub(fv_mul(f, fv_set1(6.0f)), fv_set1(15.0f))), fv_set1(10.0f)));
        L->ds[d] = fv_mul(fv_mul(fv_mul(fv_set1(30.0f), f), f),
                          fv_add(fv_mul(f, fv_sub(f, fv_set1(2.0f))), fv_set1(1.0f)));
    }
}

static inline fv trilerp_v(const fv c[8], const fv s[3])
{
    return lerp_v(s[2], lerp_v(s[1], lerp_v(s[0], c[0], c[1]), lerp_v(s[0], c[2], c[3])),
                  lerp_v(s[1], lerp_v(s[0], c[4], c[5]), lerp_v(s[0], c[6], c[7])));
}

/* perlin_f's gradient */
static inline void perlin_v(const uint8_t *P, const lattice_v *L, fv g[3])
{
    const iv X = L->c[0], Y = L->c[1], Z = L->c[2];
    iv A, B, AA, AB, BA, BB; /* P[i] and P[i + 1] of each pair from one gather */
    iv_gather_u8_pair(P, X, &A, &B);
    A = iv_add(A, Y), B = iv_add(B, Y);
    iv_gather_u8_pair(P, A, &AA, &AB);
    iv_gather_u8_pair(P, B, &BA, &BB);
    AA = iv_add(AA, Z), AB = iv_add(AB, Z), BA = iv_add(BA, Z), BB = iv_add(BB, Z);
    const iv corner[4] = {AA, BA, AB, BB}; /* corners c and c + 4 are P[corner] and P[corner + 1] */
    iv hash[8];
    for (int c = 0; c < 4; c++) iv_gather_u8_pair(P, corner[c], &hash[c], &hash[c + 4]);
    const fv one = fv_set1(1.0f);
    const fv dx[2] = {L->f[0], fv_sub(L->f[0], one)}, dy[2] = {L->f[1], fv_sub(L->f[1], one)};
    const fv dz[2] = {L->f[2], fv_sub(L->f[2], one)};
    fv gx[8], gy[8], gz[8], val[8];
    for (int c = 0; c < 8; c++) {
        const iv h = iv_and(hash[c], 15);
        gx[c] = fv_lookup16(GXF, h), gy[c] = fv_lookup16(GYF, h), gz[c] = fv_lookup16(GZF, h);
        val[c] = fv_add(fv_add(fv_mul(gx[c], dx[c & 1]), fv_mul(gy[c], dy[(c >> 1) & 1])), fv_mul(gz[c], dz[c >> 2]));
    }
    const fv s0 = L->s[0], s1 = L->s[1], s2 = L->s[2];
    const fv x00 = lerp_v(s0, val[0], val[1]), x10 = lerp_v(s0, val[2], val[3]);
    const fv x01 = lerp_v(s0, val[4], val[5]), x11 = lerp_v(s0, val[6], val[7]);
    const fv y0 = lerp_v(s1, x00, x10), y1 = lerp_v(s1, x01, x11);
    const fv dn0 = lerp_v(s2, lerp_v(s1, fv_sub(val[1], val[0]), fv_sub(val[3], val[2])),
                          lerp_v(s1, fv_sub(val[5], val[4]), fv_sub(val[7], val[6])));
    const fv dn1 = lerp_v(s2, fv_sub(x10, x00), fv_sub(x11, x01));
    const fv dn2 = fv_sub(y1, y0);
    g[0] = fv_add(trilerp_v(gx, L->s), fv_mul(L->ds[0], dn0));
    g[1] = fv_add(trilerp_v(gy, L->s), fv_mul(L->ds[1], dn1));
    g[2] = fv_add(trilerp_v(gz, L->s), fv_mul(L->ds[2], dn2));
}

/* noise_curl_add_f */
static inline void curl_add_v(const noise_field *n, const float *const p[3], int64_t a, double t, fv v[3])
{
    fv g1[3], g2[3], g3[3];
    lattice_v L;
    lattice_v_at(n, p, a, t, &L);
    perlin_v(n->perm[0], &L, g1);
    perlin_v(n->perm[1], &L, g2);
    perlin_v(n->perm[2], &L, g3);
    const fv amp = fv_set1((float)n->amp);
    v[0] = fv_add(v[0], fv_mul(amp, fv_sub(g3[1], g2[2])));
    v[1] = fv_add(v[1], fv_mul(amp, fv_sub(g1[2], g3[0])));
    v[2] = fv_add(v[2], fv_mul(amp, fv_sub(g2[0], g1[1])));
}

/* fm_style_add's w (m x + b + s) in doubles for FM_W agents, into out. */
static inline void style_lanes(const fm_curl_view *f, const float *const p[3], int64_t a, const float s[3][FM_W],
                               double out[3][FM_W])
{
    const double *m = f->m;
    for (int h = 0; h < FM_W; h += FM_WD) {
        const dv x[3] = {dv_from_floats(p[0] + a + h), dv_from_floats(p[1] + a + h), dv_from_floats(p[2] + a + h)};
        for (int k = 0; k < 3; k++) {
            dv r = dv_add(dv_add(dv_mul(dv_set1(m[3 * k]), x[0]), dv_mul(dv_set1(m[3 * k + 1]), x[1])),
                          dv_mul(dv_set1(m[3 * k + 2]), x[2]));
            r = dv_mul(dv_set1(f->w), dv_add(dv_add(r, dv_set1(f->b[k])), dv_from_floats(s[k] + h)));
            dv_store(out[k] + h, r);
        }
    }
}

/* curl_add_agent for agents a .. a + FM_W - 1, written where flying. */
static inline void curl_add_lanes(const fm_curl_view *f, const float *const p[3], int64_t a, unsigned flying,
                                  float *const v[3])
{
    fv s[3] = {fv_set1(0), fv_set1(0), fv_set1(0)};
    for (int i = 0; i < f->count; i++) curl_add_v(&f->noise[i], p, a, f->t, s);
    float sum[3][FM_W];
    for (int k = 0; k < 3; k++) fv_store(sum[k], s[k]);
    double out[3][FM_W];
    style_lanes(f, p, a, sum, out);
    for (int k = 0; k < 3; k++)
        for (int l = 0; l < FM_W; l++)
            if (flying >> l & 1) v[k][a + l] += (float)out[k][l];
}

#endif

void FM_SIMD_VARIANT(fm_kernel_curl_add)(const fm_curl_view *f, const float *const p[3], const uint8_t *phase,
                                         uint8_t flying, int64_t begin, int64_t end, float *const v[3])
{
    int64_t a = begin;
#if FM_W % FM_WD == 0
    for (; a + FM_W <= end; a += FM_W) {
        unsigned lanes = 0;
        for (int l = 0; l < FM_W; l++) lanes |= (unsigned)(phase[a + l] == flying) << l;
        if (lanes) curl_add_lanes(f, p, a, lanes, v);
    }
#endif
    for (; a < end; a++)
        if (phase[a] == flying) curl_add_agent(f, p, a, v);
}
