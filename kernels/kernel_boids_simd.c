/* The boids' walk over the grid in its order, SIMD (kernel_boids.h): per agent, FM_W candidates at a
 * time are tested against its widest radius and the hits packed into a short list; the list is then
 * taken FM_W neighbours at a time through fm_boids_add's float operations, lane by lane in the same
 * order, and each term, rounded to fixed point, is added in 64-bit integer lanes. Integer sums do not
 * depend on which lane or in which order a neighbour was added, so every variant gives the scalar
 * twin's bits. Compiled three times (simd.h). */
#include "kernel_boids.h"
#include "simd.h"

/* Fixed-point lanes: `qv` holds 64-bit integer sums, qv_add adds the FM_W lanes of a float vector
 * (scaled, clamped: fixed() below) rounded to nearest even, as fm_boids_fixed does. */
#if FM_W == 16
typedef __m512i qv;
static inline qv qv_zero(void) { return _mm512_setzero_si512(); }
static inline qv qv_add(qv acc, fv x)
{
    const __m512i lo = _mm512_cvtps_epi64(_mm512_castps512_ps256(x)); /* MXCSR's rounding: to nearest even */
    const __m512i hi = _mm512_cvtps_epi64(_mm512_extractf32x8_ps(x, 1));
    return _mm512_add_epi64(acc, _mm512_add_epi64(lo, hi));
}
static inline fv fv_max(fv a, fv b) { return _mm512_max_ps(a, b); }
static inline fv fv_min(fv a, fv b) { return _mm512_min_ps(a, b); }
static inline fv fv_and(fv a, fv b) { return _mm512_and_ps(a, b); }
#elif FM_W == 8 || FM_W == 4
#if FM_W == 8
typedef __m256i qv;
static inline qv qv_zero(void) { return _mm256_setzero_si256(); }
/* 4 floats to 4 int64: the double's mantissa rounds x + 1.5 2^52 (|x| < 2^51), as fm_boids_fixed */
static inline __m256i fixed4(__m128 x)
{
    const __m256d y = _mm256_add_pd(_mm256_cvtps_pd(x), _mm256_set1_pd(0x1.8p52));
    return _mm256_sub_epi64(_mm256_castpd_si256(y), _mm256_set1_epi64x(INT64_C(0x4338000000000000)));
}
static inline qv qv_add(qv acc, fv x)
{
    return _mm256_add_epi64(acc, _mm256_add_epi64(fixed4(_mm256_castps256_ps128(x)), fixed4(_mm256_extractf128_ps(x, 1))));
}
static inline fv fv_max(fv a, fv b) { return _mm256_max_ps(a, b); }
static inline fv fv_min(fv a, fv b) { return _mm256_min_ps(a, b); }
static inline fv fv_and(fv a, fv b) { return _mm256_and_ps(a, b); }
#else
typedef __m128i qv;
static inline qv qv_zero(void) { return _mm_setzero_si128(); }
/* the two low floats of x to 2 int64, as fixed4 */
static inline __m128i fixed2(__m128 x)
{
    const __m128d y = _mm_add_pd(_mm_cvtps_pd(x), _mm_set1_pd(0x1.8p52));
    return _mm_sub_epi64(_mm_castpd_si128(y), _mm_set1_epi64x(INT64_C(0x4338000000000000)));
}
static inline qv qv_add(qv acc, fv x) { return _mm_add_epi64(acc, _mm_add_epi64(fixed2(x), fixed2(_mm_movehl_ps(x, x)))); }
static inline fv fv_max(fv a, fv b) { return _mm_max_ps(a, b); }
static inline fv fv_min(fv a, fv b) { return _mm_min_ps(a, b); }
static inline fv fv_and(fv a, fv b) { return _mm_and_ps(a, b); }
#endif
#else
typedef uint64_t qv;
static inline qv qv_zero(void) { return 0; }
static inline qv qv_add(qv acc, fv x) { return acc + (uint64_t)fm_boids_fixed(x); }
static inline fv fv_max(fv a, fv b) { return a > b ? a : b; }
static inline fv fv_min(fv a, fv b) { return a < b ? a : b; }
static inline fv fv_and(fv a, fv b)
{
    uint32_t x, y;
    memcpy(&x, &a, 4), memcpy(&y, &b, 4), x &= y;
    memcpy(&a, &x, 4);
    return a;
}
#endif

/* x * scale clamped to +-FM_BOIDS_FIXED_CLAMP (NaN to the lower bound: max's second operand): ready
 * for qv_add. */
static inline fv fixed(fv x, fv scale)
{
    const fv clamp = fv_set1(FM_BOIDS_FIXED_CLAMP);
    return fv_min(fv_max(fv_mul(x, scale), fv_sub(fv_set1(0.0f), clamp)), clamp);
}

/* The agent's fixed-point sums in lanes. */
typedef struct lane_sums {
    qv rule[FM_BOIDS_RULES][3], weight[2];
} lane_sums;

/* Agents waiting for their steering, FM_WD at a time: their sums in lanes (sums[l]: agent l's),
 * velocities and parameters, by lane. */
typedef struct steer_batch {
    lane_sums sums[FM_WD];
    double v[3][FM_WD], weight[FM_BOIDS_RULES][FM_WD], max_speed[FM_WD], max_force[FM_WD], radius[FM_WD];
    int32_t agent[FM_WD];
    int n;
} steer_batch;

/* Lane l: the total of the lanes of a[l], as (double)(int64_t), the scalar steering's conversion.
 * Where a qv has FM_WD lanes, the FM_WD agents' sums are added side by side (a transposed
 * reduction: pairs of lanes, then pairs of pairs), instead of each reduced across its own lanes;
 * integer sums, so the same totals in any order. */
static inline dv totals_of(const qv a[FM_WD])
{
#if FM_W == 16
    __m512i pair[4], quad[2];
    for (int i = 0; i < 4; i++) /* lanes 2j, 2j+1: a[2i]'s and a[2i+1]'s sums of their 128-bit chunk j */
        pair[i] = _mm512_add_epi64(_mm512_unpacklo_epi64(a[2 * i], a[2 * i + 1]), _mm512_unpackhi_epi64(a[2 * i], a[2 * i + 1]));
    for (int i = 0; i < 2; i++) /* chunks of a[4i .. 4i+3], the chunk pairs (0, 1) and (2, 3) added */
        quad[i] = _mm512_add_epi64(_mm512_shuffle_i64x2(pair[2 * i], pair[2 * i + 1], 0x88),
                                   _mm512_shuffle_i64x2(pair[2 * i], pair[2 * i + 1], 0xdd));
    const __m512i total = _mm512_add_epi64(_mm512_shuffle_i64x2(quad[0], quad[1], 0x88), _mm512_shuffle_i64x2(quad[0], quad[1], 0xdd));
    return _mm512_cvtepi64_pd(total);
#else
    int64_t total[FM_WD];
#if FM_W == 8
    const __m256i p01 = _mm256_add_epi64(_mm256_unpacklo_epi64(a[0], a[1]), _mm256_unpackhi_epi64(a[0], a[1]));
    const __m256i p23 = _mm256_add_epi64(_mm256_unpacklo_epi64(a[2], a[3]), _mm256_unpackhi_epi64(a[2], a[3]));
    const __m256i sum = _mm256_add_epi64(_mm256_permute2x128_si256(p01, p23, 0x20), _mm256_permute2x128_si256(p01, p23, 0x31));
    /* |sum| < 2^51 (always, but for a flock of millions of neighbours): the double's mantissa takes
     * it exactly, as fixed4 rounds the other way; otherwise converted one by one */
    const __m256i shifted = _mm256_srli_epi64(_mm256_add_epi64(sum, _mm256_set1_epi64x(INT64_C(1) << 51)), 52);
    if (_mm256_testz_si256(shifted, shifted))
        return _mm256_sub_pd(_mm256_castsi256_pd(_mm256_add_epi64(sum, _mm256_set1_epi64x(INT64_C(0x4338000000000000)))),
                             _mm256_set1_pd(0x1.8p52));
    _mm256_storeu_si256((__m256i *)(void *)total, sum);
#elif FM_W == 4
    _mm_storeu_si128((__m128i *)(void *)total, _mm_add_epi64(_mm_unpacklo_epi64(a[0], a[1]), _mm_unpackhi_epi64(a[0], a[1])));
#else
    for (int l = 0; l < FM_WD; l++) total[l] = (int64_t)a[l]; /* one lane each */
#endif
    double d[FM_WD];
    for (int l = 0; l < FM_WD; l++) d[l] = (double)total[l];
    return dv_load(d);
#endif
}

/* fm_boids_steer for the batch's agents (lanes past n repeat earlier ones, whose results are not
 * written): the same double operations in the same order, lane by lane, so the same bits. A
 * cohesion radius that is not > 0 adds nothing (its term selected away: the force, never -0, is
 * unchanged by the +0 added instead). */
static void steer_lanes(steer_batch *t, const fm_boids_viewer *w, float *const f[3])
{
    const dv max_speed = dv_load(t->max_speed), inv_unit = dv_set1(w->inv_unit_scale), floor = dv_set1(FM_BOIDS_WEIGHT_FLOOR);
    const dv zero = dv_set1(0.0);
    dv force[3] = {zero, zero, zero};
    qv column[FM_WD];
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        dv total = zero;
        if (r != FM_BOIDS_SEPARATION) { /* the separation's sum w is not used */
            for (int l = 0; l < FM_WD; l++) column[l] = t->sums[l].weight[r - 1];
            total = dv_mul(totals_of(column), inv_unit);
        }
        const dv weight = dv_load(t->weight[r]);
        const dv norm = dv_div(dv_set1(1.0), dv_max(total, floor)), inv_scale = dv_set1(w->inv_scale[r]); /* total: finite */
        for (int k = 0; k < 3; k++) {
            for (int l = 0; l < FM_WD; l++) column[l] = t->sums[l].rule[r][k];
            const dv sum = dv_mul(totals_of(column), inv_scale);
            if (r == FM_BOIDS_SEPARATION) {
                force[k] = dv_sub(force[k], dv_mul(dv_mul(weight, max_speed), sum));
            } else if (r == FM_BOIDS_COHESION) {
                const dv radius = dv_load(t->radius);
                const dv term = dv_div(dv_mul(dv_mul(dv_mul(weight, max_speed), sum), norm), radius);
                force[k] = dv_add(force[k], dv_blend(dv_gt(radius, zero), term, zero));
            } else {
                const dv v = dv_load(t->v[k]);
                force[k] = dv_add(force[k], dv_mul(dv_mul(weight, dv_sub(sum, dv_mul(total, v))), norm));
            }
        }
    }
    const dv len = dv_sqrt(dv_add(dv_add(dv_mul(force[0], force[0]), dv_mul(force[1], force[1])), dv_mul(force[2], force[2])));
    const dv max_force = dv_load(t->max_force);
    const dv scale = dv_blend(dv_gt(len, max_force), dv_div(max_force, len), dv_set1(1.0));
    double out[3][FM_WD];
    for (int k = 0; k < 3; k++) dv_store(out[k], dv_mul(force[k], scale));
    for (int l = 0; l < t->n; l++)
        for (int k = 0; k < 3; k++) f[k][t->agent[l]] = (float)out[k][l];
    t->n = 0;
}

/* The next agent's sums in the batch, zeroed. */
static lane_sums *next_sums(steer_batch *t)
{
    lane_sums *s = &t->sums[t->n];
    for (int r = 0; r < FM_BOIDS_RULES; r++)
        for (int q = 0; q < 3; q++) s->rule[r][q] = qv_zero();
    s->weight[0] = s->weight[1] = qv_zero();
    return s;
}

/* Agent a (its sums in next_sums), velocity and parameters into the batch, which is steered when
 * full. */
static void steer_later(steer_batch *t, const fm_boids_view *b, int32_t a, const float v[3], const fm_boids_viewer *w,
                        float *const f[3])
{
    const int l = t->n++;
    for (int r = 0; r < FM_BOIDS_RULES; r++) t->weight[r][l] = b->weight[r][a];
    for (int k = 0; k < 3; k++) t->v[k][l] = v[k];
    t->max_speed[l] = b->max_speed[a], t->max_force[l] = b->max_force[a], t->radius[l] = b->radius[FM_BOIDS_COHESION][a];
    t->agent[l] = a;
    if (t->n == FM_WD) steer_lanes(t, w, f);
}

/* The packed hits of one agent: offsets, squared distances and entries (for the velocities), with
 * room for one more vector past HIT_FLUSH. */
enum { HIT_FLUSH = 128, HIT_ROOM = HIT_FLUSH + 2 * FM_W };
typedef struct hits {
    float dx[HIT_ROOM], dy[HIT_ROOM], dz[HIT_ROOM], d2[HIT_ROOM];
    int32_t entry[HIT_ROOM];
    int n;
} hits;

/* The viewer's scalars in every lane. */
typedef struct lane_viewer {
    fv unit[3], inv_r[FM_BOIDS_RULES], lo[FM_BOIDS_RULES], scale[FM_BOIDS_RULES], unit_scale;
} lane_viewer;

static lane_viewer lanes_of(const fm_boids_viewer *w)
{
    lane_viewer l;
    for (int k = 0; k < 3; k++) l.unit[k] = fv_set1(w->unit[k]);
    for (int r = 0; r < FM_BOIDS_RULES; r++)
        l.inv_r[r] = fv_set1(w->inv_r[r]), l.lo[r] = fv_set1(w->lo[r]), l.scale[r] = fv_set1(w->scale[r]);
    l.unit_scale = fv_set1(w->unit_scale);
    return l;
}

/* fm_boids_add for the hits h[o .. o + FM_W) of which the first `count` are real. */
static inline void add_lanes(lane_sums *s, const hits *h, int o, int count, const float *const c[6],
                             const lane_viewer *w)
{
    static const float lane_number[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
    const fv one = fv_set1(1.0f), zero = fv_set1(0.0f), two = fv_set1(2.0f), three = fv_set1(3.0f);
    const fv valid = fv_lt(fv_load(lane_number), fv_set1((float)count));
    const fv d[3] = {fv_load(h->dx + o), fv_load(h->dy + o), fv_load(h->dz + o)};
    const fv d2 = fv_select(valid, fv_load(h->d2 + o), one);
    const fv dist = fv_sqrt(d2), inv_dist = fv_div(one, dist);
    const fv cosine = fv_mul(fv_add(fv_add(fv_mul(w->unit[0], d[0]), fv_mul(w->unit[1], d[1])), fv_mul(w->unit[2], d[2])),
                             inv_dist);
    iv at; /* past the hits: earlier agents' entries, or the zeros the walk started with: in bounds */
    memcpy(&at, h->entry + o, sizeof at);
    const fv vb[3] = {fv_gather(c[3], at), fv_gather(c[4], at), fv_gather(c[5], at)};
    const fv band = fv_set1(0.5f / FM_BOIDS_CONE_BAND);
    for (int r = 0; r < FM_BOIDS_RULES; r++) {
        const fv rho = fv_mul(dist, w->inv_r[r]);
        fv t = fv_mul(fv_sub(cosine, w->lo[r]), band);
        const fv in = fv_and(valid, fv_and(fv_lt(rho, one), fv_gt(t, zero)));
        t = fv_min(t, one);
        const fv g = fv_mul(fv_mul(t, t), fv_sub(three, fv_mul(two, t)));
        /* a rule's weight is 0 in the lanes it does not see: its terms over the offsets, finite in
         * every lane (the hits' and earlier hits'), are then 0 as the scalar walk's skip; a
         * neighbour's velocity may not be finite, so those terms are 0 by selection */
        if (r == FM_BOIDS_SEPARATION) {
            const fv near = fv_sub(one, rho);
            const fv push = fv_select(in, fv_mul(fv_mul(fv_mul(fv_mul(g, near), near), fv_add(one, fv_mul(two, rho))), inv_dist), zero);
            for (int k = 0; k < 3; k++) s->rule[r][k] = qv_add(s->rule[r][k], fixed(fv_mul(push, d[k]), w->scale[r]));
            continue;
        }
        const fv q = fv_sub(one, fv_mul(rho, rho));
        const fv weight = fv_select(in, fv_mul(fv_mul(g, q), q), zero);
        for (int k = 0; k < 3; k++) {
            const fv term = r == FM_BOIDS_COHESION ? fv_mul(weight, d[k]) : fv_select(in, fv_mul(weight, vb[k]), zero);
            s->rule[r][k] = qv_add(s->rule[r][k], fixed(term, w->scale[r]));
        }
        s->weight[r - 1] = qv_add(s->weight[r - 1], fixed(weight, w->unit_scale));
    }
}

/* The hits h[0 .. n) through add_lanes: whole vectors only (the rest moved to the front), or all of
 * them when `all`. */
static void flush(hits *h, lane_sums *s, const float *const c[6], const lane_viewer *w, int all)
{
    int o = 0;
    for (; o + FM_W <= h->n; o += FM_W) add_lanes(s, h, o, FM_W, c, w);
    const int rest = h->n - o;
    if (all && rest > 0) {
        add_lanes(s, h, o, rest, c, w);
        h->n = 0;
        return;
    }
    for (int l = 0; l < rest; l++)
        h->dx[l] = h->dx[o + l], h->dy[l] = h->dy[o + l], h->dz[l] = h->dz[o + l], h->d2[l] = h->d2[o + l],
        h->entry[l] = h->entry[o + l];
    h->n = rest;
}

#if FM_W == 8
/* For each mask of 8 lanes, its set lanes in order, 4 bits each (the rest 0). */
static const uint32_t COMPRESS8[256] = {
    0x00000000, 0x00000000, 0x00000001, 0x00000010, 0x00000002, 0x00000020, 0x00000021, 0x00000210,
    0x00000003, 0x00000030, 0x00000031, 0x00000310, 0x00000032, 0x00000320, 0x00000321, 0x00003210,
    0x00000004, 0x00000040, 0x00000041, 0x00000410, 0x00000042, 0x00000420, 0x00000421, 0x00004210,
    0x00000043, 0x00000430, 0x00000431, 0x00004310, 0x00000432, 0x00004320, 0x00004321, 0x00043210,
    0x00000005, 0x00000050, 0x00000051, 0x00000510, 0x00000052, 0x00000520, 0x00000521, 0x00005210,
    0x00000053, 0x00000530, 0x00000531, 0x00005310, 0x00000532, 0x00005320, 0x00005321, 0x00053210,
    0x00000054, 0x00000540, 0x00000541, 0x00005410, 0x00000542, 0x00005420, 0x00005421, 0x00054210,
    0x00000543, 0x00005430, 0x00005431, 0x00054310, 0x00005432, 0x00054320, 0x00054321, 0x00543210,
    0x00000006, 0x00000060, 0x00000061, 0x00000610, 0x00000062, 0x00000620, 0x00000621, 0x00006210,
    0x00000063, 0x00000630, 0x00000631, 0x00006310, 0x00000632, 0x00006320, 0x00006321, 0x00063210,
    0x00000064, 0x00000640, 0x00000641, 0x00006410, 0x00000642, 0x00006420, 0x00006421, 0x00064210,
    0x00000643, 0x00006430, 0x00006431, 0x00064310, 0x00006432, 0x00064320, 0x00064321, 0x00643210,
    0x00000065, 0x00000650, 0x00000651, 0x00006510, 0x00000652, 0x00006520, 0x00006521, 0x00065210,
    0x00000653, 0x00006530, 0x00006531, 0x00065310, 0x00006532, 0x00065320, 0x00065321, 0x00653210,
    0x00000654, 0x00006540, 0x00006541, 0x00065410, 0x00006542, 0x00065420, 0x00065421, 0x00654210,
    0x00006543, 0x00065430, 0x00065431, 0x00654310, 0x00065432, 0x00654320, 0x00654321, 0x06543210,
    0x00000007, 0x00000070, 0x00000071, 0x00000710, 0x00000072, 0x00000720, 0x00000721, 0x00007210,
    0x00000073, 0x00000730, 0x00000731, 0x00007310, 0x00000732, 0x00007320, 0x00007321, 0x00073210,
    0x00000074, 0x00000740, 0x00000741, 0x00007410, 0x00000742, 0x00007420, 0x00007421, 0x00074210,
    0x00000743, 0x00007430, 0x00007431, 0x00074310, 0x00007432, 0x00074320, 0x00074321, 0x00743210,
    0x00000075, 0x00000750, 0x00000751, 0x00007510, 0x00000752, 0x00007520, 0x00007521, 0x00075210,
    0x00000753, 0x00007530, 0x00007531, 0x00075310, 0x00007532, 0x00075320, 0x00075321, 0x00753210,
    0x00000754, 0x00007540, 0x00007541, 0x00075410, 0x00007542, 0x00075420, 0x00075421, 0x00754210,
    0x00007543, 0x00075430, 0x00075431, 0x00754310, 0x00075432, 0x00754320, 0x00754321, 0x07543210,
    0x00000076, 0x00000760, 0x00000761, 0x00007610, 0x00000762, 0x00007620, 0x00007621, 0x00076210,
    0x00000763, 0x00007630, 0x00007631, 0x00076310, 0x00007632, 0x00076320, 0x00076321, 0x00763210,
    0x00000764, 0x00007640, 0x00007641, 0x00076410, 0x00007642, 0x00076420, 0x00076421, 0x00764210,
    0x00007643, 0x00076430, 0x00076431, 0x00764310, 0x00076432, 0x00764320, 0x00764321, 0x07643210,
    0x00000765, 0x00007650, 0x00007651, 0x00076510, 0x00007652, 0x00076520, 0x00076521, 0x00765210,
    0x00007653, 0x00076530, 0x00076531, 0x00765310, 0x00076532, 0x00765320, 0x00765321, 0x07653210,
    0x00007654, 0x00076540, 0x00076541, 0x00765410, 0x00076542, 0x00765420, 0x00765421, 0x07654210,
    0x00076543, 0x00765430, 0x00765431, 0x07654310, 0x00765432, 0x07654320, 0x07654321, 0x76543210,
};
#endif

/* Appends the lanes of bit mask m to the hits: candidates at entries entry[0 .. FM_W), or with entry
 * NULL at entries j, j + 1, .... */
static inline void pack(hits *h, unsigned m, fv dx, fv dy, fv dz, fv d2, const int32_t *entry, int32_t j)
{
#if FM_W == 16
    const __mmask16 k = (__mmask16)m;
    const int n = h->n;
    _mm512_storeu_ps(h->dx + n, _mm512_maskz_compress_ps(k, dx)); /* to a register, then stored: a */
    _mm512_storeu_ps(h->dy + n, _mm512_maskz_compress_ps(k, dy)); /* compress straight to memory is */
    _mm512_storeu_ps(h->dz + n, _mm512_maskz_compress_ps(k, dz)); /* slow on AMD's Zen 4 */
    _mm512_storeu_ps(h->d2 + n, _mm512_maskz_compress_ps(k, d2));
    const __m512i entries = entry ? _mm512_loadu_si512((const void *)entry)
                                  : _mm512_add_epi32(_mm512_set1_epi32(j), _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9,
                                                                                             10, 11, 12, 13, 14, 15));
    _mm512_storeu_si512((void *)(h->entry + n), _mm512_maskz_compress_epi32(k, entries));
    h->n = n + __builtin_popcount(m);
#elif FM_W == 8
    /* AVX2 has no compress: the lanes of m moved to the front by one permute each, its indices
     * from a table of the 256 masks (4 bits a lane) */
    const __m256i at = _mm256_and_si256(_mm256_srlv_epi32(_mm256_set1_epi32((int)COMPRESS8[m]), _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28)),
                                        _mm256_set1_epi32(7));
    const int n = h->n;
    _mm256_storeu_ps(h->dx + n, _mm256_permutevar8x32_ps(dx, at));
    _mm256_storeu_ps(h->dy + n, _mm256_permutevar8x32_ps(dy, at));
    _mm256_storeu_ps(h->dz + n, _mm256_permutevar8x32_ps(dz, at));
    _mm256_storeu_ps(h->d2 + n, _mm256_permutevar8x32_ps(d2, at));
    const __m256i entries = entry ? _mm256_loadu_si256((const __m256i *)(const void *)entry)
                                  : _mm256_add_epi32(_mm256_set1_epi32(j), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    _mm256_storeu_si256((__m256i *)(void *)(h->entry + n), _mm256_permutevar8x32_epi32(entries, at));
    h->n = n + __builtin_popcount(m);
#else
    float t[4][FM_W];
    fv_store(t[0], dx), fv_store(t[1], dy), fv_store(t[2], dz), fv_store(t[3], d2);
    while (m) {
        const int l = __builtin_ctz(m);
        m &= m - 1;
        const int n = h->n++;
        h->dx[n] = t[0][l], h->dy[n] = t[1][l], h->dz[n] = t[2][l], h->d2[n] = t[3][l], h->entry[n] = entry ? entry[l] : j + l;
    }
#endif
}

/* Candidates l = 0 .. n - 1 at x[l], y[l], z[l], grid entry entry[l] (or, with entry NULL, first + l):
 * a range of the grid's entries in place, or a cell's run (below). */
typedef struct span {
    const float *x, *y, *z;
    const int32_t *entry;
    int32_t first, n;
} span;

/* The candidates within r2_max of p (and not on it), FM_W at a time, into the hits, which are added
 * whenever HIT_FLUSH of them wait. Lanes past n (the next range's, padding, or a run's earlier
 * copies: finite) are masked off. A vector without hits is packed too (nothing moves): about half
 * of them have hits, at random, and the branch around them cost more in mispredictions than the
 * empty packing does. */
static void scan_span(hits *h, lane_sums *s, const float *const c[6], span q, const float p[3], fv r2_max,
                      const lane_viewer *w)
{
    const fv px = fv_set1(p[0]), py = fv_set1(p[1]), pz = fv_set1(p[2]), zero = fv_set1(0.0f);
    for (int32_t j = 0; j < q.n; j += FM_W) {
        const fv dx = fv_sub(fv_load(q.x + j), px), dy = fv_sub(fv_load(q.y + j), py), dz = fv_sub(fv_load(q.z + j), pz);
        const fv d2 = fv_add(fv_add(fv_mul(dx, dx), fv_mul(dy, dy)), fv_mul(dz, dz));
        unsigned m = fv_mask(fv_and(fv_lt(d2, r2_max), fv_gt(d2, zero)));
        if (q.n - j < FM_W) m &= (1u << (q.n - j)) - 1;
        pack(h, m, dx, dy, dz, d2, q.entry ? q.entry + j : NULL, q.first + j);
        if (h->n >= HIT_FLUSH) flush(h, s, c, w, 0);
    }
}

/* The candidates of one cell's 27 cells in one run: the agents of a cell, walked in a row, share
 * them, and an agent scans ~5 full vectors instead of 9 ranges' partial ones. Past n: earlier
 * copies (finite, in the grid), masked off. */
enum { RUN_MAX = 512 };
typedef struct candidates {
    float x[RUN_MAX + FM_W], y[RUN_MAX + FM_W], z[RUN_MAX + FM_W];
    int32_t entry[RUN_MAX + FM_W];
    int n;
} candidates;

/* The `count` ranges' entries into run; 0 (run unchanged) where they are more than RUN_MAX. Whole
 * vectors are copied (the grid's soa has FM_GRID_SOA_PAD floats past its capacity), each range's
 * over the tail of the one before. */
static int gather_run(const fm_grid *g, const int32_t *ranges, int count, candidates *run)
{
    int n = 0;
    for (int ri = 0; ri < count; ri++) n += ranges[2 * ri + 1] - ranges[2 * ri];
    if (n > RUN_MAX) return 0;
    n = 0;
    for (int ri = 0; ri < count; ri++) {
        const int32_t b = ranges[2 * ri], len = ranges[2 * ri + 1] - b;
        for (int32_t o = 0; o < len; o += FM_W) {
            fv_store(run->x + n + o, fv_load(g->soa[0] + b + o));
            fv_store(run->y + n + o, fv_load(g->soa[1] + b + o));
            fv_store(run->z + n + o, fv_load(g->soa[2] + b + o));
        }
        for (int32_t o = 0; o < len; o += FM_W) iv_store(run->entry + n + o, iv_iota(b + o)); /* past len: overwritten */
        n += len;
    }
    run->n = n;
    return 1;
}

/* Agent a at entry k (viewer's scales set): its sums over the run of its cell's candidates, or
 * with run NULL over the `count` ranges, then its force. */
static void boids_entry(const fm_grid *g, const fm_boids_view *b, int64_t k, int32_t a, const candidates *run,
                        const int32_t *ranges, int count, hits *h, fm_boids_viewer *viewer, steer_batch *later,
                        float *const f[3])
{
    const float *const *c = (const float *const *)g->soa;
    const float x[3] = {c[0][k], c[1][k], c[2][k]}, v[3] = {c[3][k], c[4][k], c[5][k]};
    float r2_max;
    fm_boids_viewer_init(b, a, v, viewer, &r2_max);
    const lane_viewer w = lanes_of(viewer);
    lane_sums *s = next_sums(later);
    h->n = 0;
    if (run) {
        scan_span(h, s, c, (span){run->x, run->y, run->z, run->entry, 0, run->n}, x, fv_set1(r2_max), &w);
    } else {
        for (int ri = 0; ri < count; ri++) {
            const int32_t b = ranges[2 * ri], e = ranges[2 * ri + 1];
            scan_span(h, s, c, (span){c[0] + b, c[1] + b, c[2] + b, NULL, b, e - b}, x, fv_set1(r2_max), &w);
        }
    }
    flush(h, s, c, &w, 1);
    steer_later(later, b, a, v, viewer, f);
}

void FM_SIMD_VARIANT(fm_kernel_boids_listed)(const fm_grid *g, const fm_boids_view *b, const uint8_t *phase,
                                             uint8_t phase_sel, int64_t first, int64_t last, float *const f[3])
{
    hits h;
    memset(&h, 0, sizeof h); /* lanes past the hits are loaded (and not used): defined, entries in bounds */
    static _Thread_local candidates run; /* 8 KB: off the stack */
    memset(run.entry + RUN_MAX, 0, sizeof(int32_t) * FM_W); /* lanes past a full run: entries in bounds */
    int32_t ranges[2 * FM_GRID_MAX_RANGES], cell[3] = {0, 0, 0};
    int count = -1, in_run = 0; /* the ranges of `cell` (and their run), which the agents of one cell, walked
                                   in a row, share */
    fm_boids_viewer viewer;
    fm_boids_viewer_scales(b, &viewer);
    steer_batch later;
    memset(&later, 0, sizeof later); /* lanes past a last, partial batch: defined */
    for (int64_t k = first; k < last; k++) {
        const int32_t a = g->quad[k >> 2].i[k & 3];
        if (phase[a] != phase_sel) continue;
        const float x[3] = {g->soa[0][k], g->soa[1][k], g->soa[2][k]};
        const int32_t at[3] = {fm_grid_coord(fm_grid_scaled(g, x[0])), fm_grid_coord(fm_grid_scaled(g, x[1])),
                               fm_grid_coord(fm_grid_scaled(g, x[2]))}; /* as fm_grid_ranges places x */
        if (count < 0 || at[0] != cell[0] || at[1] != cell[1] || at[2] != cell[2]) {
            count = fm_grid_ranges(g, x[0], x[1], x[2], ranges), memcpy(cell, at, sizeof cell);
            in_run = gather_run(g, ranges, count, &run);
        }
        boids_entry(g, b, k, a, in_run ? &run : NULL, ranges, count, &h, &viewer, &later, f);
    }
    if (later.n > 0) steer_lanes(&later, &viewer, f);
}
