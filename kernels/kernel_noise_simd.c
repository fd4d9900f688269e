/* The direct style velocity, SIMD: FM_WD agents at once in double (simd.h's dv lanes), the
 * reference's operations (kernel_noise.h: lattice_at, perlin, noise_curl_add, curl_add_agent) in
 * the same order, so the same bits. The permutation lookups are gathers from tables that stay in L1,
 * one 32-bit gather giving both P[i] and P[i + 1]; the gradients' 16-entry tables are permutes
 * across two registers with AVX-512 (dv_lookup16). Compiled three times (simd.h). */
#include "kernel_noise.h"
#include "simd.h"

typedef struct lattice_v {
    di c[3];
    dv f[3], s[3], ds[3];
} lattice_v;

static inline dv lerp_v(dv t, dv a, dv b) { return dv_add(a, dv_mul(t, dv_sub(b, a))); }

/* lattice_at: the cell mod 256 is fl - 256 floor(fl / 256), exact for the clamped range. */
static inline void lattice_v_at(const dv q[3], lattice_v *L)
{
    for (int d = 0; d < 3; d++) {
        const dv x = dv_min(dv_max(q[d], dv_set1(-1e15)), dv_set1(1e15));
        const dv fl = dv_floor(x), f = dv_sub(x, fl);
        const dv wrap = dv_mul(dv_set1(PERM), dv_floor(dv_mul(fl, dv_set1(1.0 / PERM))));
        L->c[d] = di_from_dv(dv_sub(fl, wrap));
        L->f[d] = f;
        L->s[d] = dv_mul(dv_mul(dv_mul(f, f), f),
                         dv_add(dv_mul(f, dv_sub(dv_mul(f, dv_set1(6)), dv_set1(15))), dv_set1(10)));
        L->ds[d] = dv_mul(dv_mul(dv_mul(dv_set1(30), f), f), dv_add(dv_mul(f, dv_sub(f, dv_set1(2))), dv_set1(1)));
    }
}

static inline dv trilerp_v(const dv c[8], const dv s[3])
{
    return lerp_v(s[2], lerp_v(s[1], lerp_v(s[0], c[0], c[1]), lerp_v(s[0], c[2], c[3])),
                  lerp_v(s[1], lerp_v(s[0], c[4], c[5]), lerp_v(s[0], c[6], c[7])));
}

/* perlin's gradient (the value is not needed for the curl). */
static inline void perlin_v(const uint8_t *P, const lattice_v *L, dv g[3])
{
    const di X = L->c[0], Y = L->c[1], Z = L->c[2];
    di A, B, AA, AB, BA, BB; /* P[i] and P[i + 1] of each pair from one gather */
    di_gather_u8_pair(P, X, &A, &B);
    A = di_add(A, Y), B = di_add(B, Y);
    di_gather_u8_pair(P, A, &AA, &AB);
    di_gather_u8_pair(P, B, &BA, &BB);
    AA = di_add(AA, Z), AB = di_add(AB, Z), BA = di_add(BA, Z), BB = di_add(BB, Z);
    const di corner[4] = {AA, BA, AB, BB}; /* corners c and c + 4 are P[corner] and P[corner + 1] */
    di hash[8];
    for (int c = 0; c < 4; c++) di_gather_u8_pair(P, corner[c], &hash[c], &hash[c + 4]);
    const dv dx[2] = {L->f[0], dv_sub(L->f[0], dv_set1(1))}, dy[2] = {L->f[1], dv_sub(L->f[1], dv_set1(1))};
    const dv dz[2] = {L->f[2], dv_sub(L->f[2], dv_set1(1))};
    dv gx[8], gy[8], gz[8], val[8];
    for (int c = 0; c < 8; c++) {
        const di h = di_and(hash[c], 15);
        gx[c] = dv_lookup16(GX, h), gy[c] = dv_lookup16(GY, h), gz[c] = dv_lookup16(GZ, h);
        val[c] = dv_add(dv_add(dv_mul(gx[c], dx[c & 1]), dv_mul(gy[c], dy[(c >> 1) & 1])), dv_mul(gz[c], dz[c >> 2]));
    }
    const dv s0 = L->s[0], s1 = L->s[1], s2 = L->s[2];
    const dv x00 = lerp_v(s0, val[0], val[1]), x10 = lerp_v(s0, val[2], val[3]);
    const dv x01 = lerp_v(s0, val[4], val[5]), x11 = lerp_v(s0, val[6], val[7]);
    const dv y0 = lerp_v(s1, x00, x10), y1 = lerp_v(s1, x01, x11);
    const dv dn0 = lerp_v(s2, lerp_v(s1, dv_sub(val[1], val[0]), dv_sub(val[3], val[2])),
                          lerp_v(s1, dv_sub(val[5], val[4]), dv_sub(val[7], val[6])));
    const dv dn1 = lerp_v(s2, dv_sub(x10, x00), dv_sub(x11, x01));
    const dv dn2 = dv_sub(y1, y0);
    g[0] = dv_add(trilerp_v(gx, L->s), dv_mul(L->ds[0], dn0));
    g[1] = dv_add(trilerp_v(gy, L->s), dv_mul(L->ds[1], dn1));
    g[2] = dv_add(trilerp_v(gz, L->s), dv_mul(L->ds[2], dn2));
}

/* noise_curl_add */
static inline void curl_add_v(const noise_field *n, const dv x[3], double t, dv v[3])
{
    dv q[3], g1[3], g2[3], g3[3];
    for (int d = 0; d < 3; d++) q[d] = dv_add(dv_mul(x[d], dv_set1(n->inv_scale)), dv_set1(t * n->drift[d]));
    lattice_v L;
    lattice_v_at(q, &L);
    perlin_v(n->perm[0], &L, g1);
    perlin_v(n->perm[1], &L, g2);
    perlin_v(n->perm[2], &L, g3);
    const dv amp = dv_set1(n->amp);
    v[0] = dv_add(v[0], dv_mul(amp, dv_sub(g3[1], g2[2])));
    v[1] = dv_add(v[1], dv_mul(amp, dv_sub(g1[2], g3[0])));
    v[2] = dv_add(v[2], dv_mul(amp, dv_sub(g2[0], g1[1])));
}

/* curl_add_agent for agents a .. a + FM_WD - 1, written where flying. */
static inline void curl_add_lanes(const fm_curl_view *f, const float *const p[3], int64_t a, unsigned flying,
                                  float *const v[3])
{
    const dv x[3] = {dv_from_floats(p[0] + a), dv_from_floats(p[1] + a), dv_from_floats(p[2] + a)};
    dv s[3] = {dv_set1(0), dv_set1(0), dv_set1(0)};
    for (int i = 0; i < f->count; i++) curl_add_v(&f->noise[i], x, f->t, s);
    const double *m = f->m;
    for (int k = 0; k < 3; k++) {
        dv r = dv_add(dv_add(dv_mul(dv_set1(m[3 * k]), x[0]), dv_mul(dv_set1(m[3 * k + 1]), x[1])),
                      dv_mul(dv_set1(m[3 * k + 2]), x[2]));
        r = dv_mul(dv_set1(f->w), dv_add(dv_add(r, dv_set1(f->b[k])), s[k]));
        double out[FM_WD];
        dv_store(out, r);
        for (int l = 0; l < FM_WD; l++)
            if (flying >> l & 1) v[k][a + l] += (float)out[l];
    }
}

void FM_SIMD_VARIANT(fm_kernel_curl_add)(const fm_curl_view *f, const float *const p[3], const uint8_t *phase,
                                         uint8_t flying, int64_t begin, int64_t end, float *const v[3])
{
    int64_t a = begin;
    for (; a + FM_WD <= end; a += FM_WD) {
        unsigned lanes = 0;
        for (int l = 0; l < FM_WD; l++) lanes |= (unsigned)(phase[a + l] == flying) << l;
        if (lanes) curl_add_lanes(f, p, a, lanes, v);
    }
    for (; a < end; a++)
        if (phase[a] == flying) curl_add_agent(f, p, a, v);
}
