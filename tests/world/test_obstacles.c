/* Obstacles (FM §5.3): the OpenVDB grid d_t against Embree's exact signed distance, the exact
 * distance against analytic and brute-force references, signs inside and out, the gradient's
 * direction, refusals and bad input, and thread safety. Every mesh is generated here. */
#include "kernel_sdf.h"
#include "obstacles.h"
#include "test_macros.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define PI 3.14159265358979323846

/* ------------------------------------------------------------------ meshes */

static fm_mesh mesh_new(int64_t nv, int64_t nt)
{
    fm_mesh m = {calloc((size_t)(3 * nv), sizeof(double)), nv, calloc((size_t)(3 * nt), sizeof(int32_t)), nt};
    return m;
}

static void mesh_del(fm_mesh *m)
{
    free(m->v);
    free(m->tri);
    memset(m, 0, sizeof *m);
}

/* Axis-aligned box c +- h, outward counter-clockwise triangles. */
static fm_mesh make_box(const double c[3], const double h[3])
{
    fm_mesh m = mesh_new(8, 12);
    for (int i = 0; i < 8; i++)
        for (int k = 0; k < 3; k++) m.v[3 * i + k] = c[k] + ((i >> k) & 1 ? h[k] : -h[k]);
    static const int32_t f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, /* -z, +z */
                                     {0, 1, 4}, {1, 5, 4}, {2, 6, 3}, {3, 6, 7}, /* -y, +y */
                                     {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}}; /* -x, +x */
    memcpy(m.tri, f, sizeof f);
    return m;
}

static double box_sdf(const double c[3], const double h[3], const double p[3])
{
    double q[3], out = 0, in = -INFINITY;
    for (int k = 0; k < 3; k++) {
        q[k] = fabs(p[k] - c[k]) - h[k];
        out += q[k] > 0 ? q[k] * q[k] : 0;
        in = fmax(in, q[k]);
    }
    return in > 0 ? sqrt(out) : in;
}

/* Icosphere: the icosahedron subdivided `level` times, vertices projected onto the sphere. */
typedef struct edge_cache {
    int64_t *key;
    int32_t *val;
    size_t cap;
} edge_cache;

static int32_t midpoint(edge_cache *ec, double *v, int32_t *nv, int32_t a, int32_t b)
{
    int64_t key = (int64_t)(a < b ? a : b) << 32 | (int64_t)(a < b ? b : a);
    size_t h = (size_t)(((uint64_t)key * 0x9E3779B97F4A7C15ull) >> 20) % ec->cap;
    while (ec->key[h] != -1 && ec->key[h] != key) h = (h + 1) % ec->cap;
    if (ec->key[h] == key) return ec->val[h];
    int32_t i = (*nv)++;
    double len = 0;
    for (int k = 0; k < 3; k++) v[3 * i + k] = 0.5 * (v[3 * a + k] + v[3 * b + k]), len += v[3 * i + k] * v[3 * i + k];
    for (int k = 0; k < 3; k++) v[3 * i + k] /= sqrt(len);
    ec->key[h] = key, ec->val[h] = i;
    return i;
}

static fm_mesh make_icosphere(int level, const double c[3], double r)
{
    int64_t nt = 20, nv = 12;
    for (int l = 0; l < level; l++) nv += nt * 3 / 2, nt *= 4;
    fm_mesh m = mesh_new(nv, nt);
    const double t = (1.0 + sqrt(5.0)) / 2.0;
    const double base[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    const int32_t faces[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11},
                                  {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                  {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8}, {3, 8, 9},
                                  {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    for (int i = 0; i < 12; i++) {
        double len = sqrt(base[i][0] * base[i][0] + base[i][1] * base[i][1] + base[i][2] * base[i][2]);
        for (int k = 0; k < 3; k++) m.v[3 * i + k] = base[i][k] / len;
    }
    memcpy(m.tri, faces, sizeof faces);
    int32_t cur_nv = 12;
    int64_t cur_nt = 20;
    int32_t *tmp = malloc(sizeof(int32_t) * 3 * (size_t)nt);
    for (int l = 0; l < level; l++) {
        edge_cache ec = {malloc(sizeof(int64_t) * (size_t)cur_nt * 4), malloc(sizeof(int32_t) * (size_t)cur_nt * 4),
                         (size_t)cur_nt * 4};
        for (size_t i = 0; i < ec.cap; i++) ec.key[i] = -1;
        for (int64_t f = 0; f < cur_nt; f++) {
            int32_t a = m.tri[3 * f], b = m.tri[3 * f + 1], cc = m.tri[3 * f + 2];
            int32_t ab = midpoint(&ec, m.v, &cur_nv, a, b), bc = midpoint(&ec, m.v, &cur_nv, b, cc),
                    ca = midpoint(&ec, m.v, &cur_nv, cc, a);
            int32_t nf[4][3] = {{a, ab, ca}, {b, bc, ab}, {cc, ca, bc}, {ab, bc, ca}};
            memcpy(tmp + 12 * f, nf, sizeof nf);
        }
        cur_nt *= 4;
        memcpy(m.tri, tmp, sizeof(int32_t) * 3 * (size_t)cur_nt);
        free(ec.key);
        free(ec.val);
    }
    free(tmp);
    for (int64_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++) m.v[3 * i + k] = c[k] + r * m.v[3 * i + k];
    return m;
}

/* Torus about the z axis through c: major radius R, minor radius r. */
static fm_mesh make_torus(const double c[3], double R, double r, int nu, int nv)
{
    fm_mesh m = mesh_new((int64_t)nu * nv, 2 * (int64_t)nu * nv);
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++) {
            double u = 2 * PI * i / nu, w = 2 * PI * j / nv, *p = m.v + 3 * ((int64_t)i * nv + j);
            p[0] = c[0] + (R + r * cos(w)) * cos(u);
            p[1] = c[1] + (R + r * cos(w)) * sin(u);
            p[2] = c[2] + r * sin(w);
        }
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++) {
            int32_t a = i * nv + j, b = ((i + 1) % nu) * nv + j, cc = ((i + 1) % nu) * nv + (j + 1) % nv,
                    d = i * nv + (j + 1) % nv;
            int32_t *t = m.tri + 6 * ((int64_t)i * nv + j);
            t[0] = a, t[1] = b, t[2] = cc, t[3] = a, t[4] = cc, t[5] = d;
        }
    return m;
}

/* ------------------------------------------------------------------ brute-force references */

static double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static double seg_dist2(const double *p, const double *a, const double *b)
{
    double ab[3], ap[3];
    for (int k = 0; k < 3; k++) ab[k] = b[k] - a[k], ap[k] = p[k] - a[k];
    double t = dot(ap, ab) / dot(ab, ab);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double d[3];
    for (int k = 0; k < 3; k++) d[k] = p[k] - (a[k] + t * ab[k]);
    return dot(d, d);
}

/* Distance to a triangle by projection onto its plane and an inside test by edge cross
   products, else the nearest edge: a different method from the library's Voronoi regions. */
static double tri_dist2(const double *p, const double *a, const double *b, const double *c)
{
    double e1[3], e2[3], n[3], ap[3];
    for (int k = 0; k < 3; k++) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], ap[k] = p[k] - a[k];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1], n[1] = e1[2] * e2[0] - e1[0] * e2[2], n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double s = dot(ap, n) / dot(n, n), q[3];
    for (int k = 0; k < 3; k++) q[k] = p[k] - s * n[k];
    const double *v[3] = {a, b, c};
    int inside = 1;
    for (int e = 0; e < 3; e++) {
        const double *u = v[e], *w = v[(e + 1) % 3];
        double uw[3], uq[3], x[3];
        for (int k = 0; k < 3; k++) uw[k] = w[k] - u[k], uq[k] = q[k] - u[k];
        x[0] = uw[1] * uq[2] - uw[2] * uq[1], x[1] = uw[2] * uq[0] - uw[0] * uq[2], x[2] = uw[0] * uq[1] - uw[1] * uq[0];
        if (dot(x, n) < 0) inside = 0;
    }
    if (inside) return s * s * dot(n, n);
    double d = seg_dist2(p, a, b);
    d = fmin(d, seg_dist2(p, b, c));
    return fmin(d, seg_dist2(p, c, a));
}

static double brute_dist(const fm_mesh *m, const double *p)
{
    double best = INFINITY;
    for (int64_t t = 0; t < m->nt; t++)
        best = fmin(best, tri_dist2(p, m->v + 3 * (int64_t)m->tri[3 * t], m->v + 3 * (int64_t)m->tri[3 * t + 1],
                                    m->v + 3 * (int64_t)m->tri[3 * t + 2]));
    return sqrt(best);
}

/* Generalised winding number (Van Oosterom & Strackee): +-1 inside, 0 outside. */
static double winding(const fm_mesh *m, const double *p)
{
    double total = 0;
    for (int64_t t = 0; t < m->nt; t++) {
        double a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = m->v[3 * (int64_t)m->tri[3 * t] + k] - p[k];
            b[k] = m->v[3 * (int64_t)m->tri[3 * t + 1] + k] - p[k];
            c[k] = m->v[3 * (int64_t)m->tri[3 * t + 2] + k] - p[k];
        }
        double la = sqrt(dot(a, a)), lb = sqrt(dot(b, b)), lc = sqrt(dot(c, c));
        double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
        double den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        total += 2 * atan2(det, den);
    }
    return total / (4 * PI);
}

static void random_point(uint64_t *rng, const double lo[3], const double hi[3], double p[3])
{
    for (int k = 0; k < 3; k++) p[k] = lo[k] + (hi[k] - lo[k]) * test_uniform(rng);
}

static void mesh_box(const fm_mesh *m, double lo[3], double hi[3], double pad)
{
    for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (int64_t i = 0; i < m->nv; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], m->v[3 * i + k]), hi[k] = fmax(hi[k], m->v[3 * i + k]);
    for (int k = 0; k < 3; k++) lo[k] -= pad, hi[k] += pad;
}

/* p == closest + sd * normal, |normal| == 1 */
static int consistent(const double p[3], double sd, const double c[3], const double n[3])
{
    double err = 0;
    for (int k = 0; k < 3; k++) err = fmax(err, fabs(c[k] + sd * n[k] - p[k]));
    return err < 1e-12 && fabs(sqrt(dot(n, n)) - 1) < 1e-12;
}

/* ------------------------------------------------------------------ tests */

static void test_kernel_linear_field(void)
{
    /* A linear field is reproduced exactly by trilinear interpolation, gradient included. */
    enum { N0 = 5, N1 = 4, N2 = 6 };
    static float d[N0 * N1 * N2];
    const float a = 0.25f, b = -0.5f, c = 0.75f, e = 0.125f, h = 0.5f, o[3] = {-1.0f, 2.0f, 0.5f};
    for (int k = 0; k < N2; k++)
        for (int j = 0; j < N1; j++)
            for (int i = 0; i < N0; i++)
                d[i + N0 * (j + N1 * k)] = a * (o[0] + h * i) + b * (o[1] + h * j) + c * (o[2] + h * k) + e;
    fm_sdf_view s = {d, {N0, N1, N2}, {o[0], o[1], o[2]}, h, 10.0f};
    uint64_t rng = 1;
    for (int n = 0; n < 1000; n++) {
        float x = o[0] + (float)(test_uniform(&rng) * h * (N0 - 1)), y = o[1] + (float)(test_uniform(&rng) * h * (N1 - 1)),
              z = o[2] + (float)(test_uniform(&rng) * h * (N2 - 1)), g[3];
        float v = fm_sdf_sample(&s, x, y, z, g);
        ENSURE_NEAR(v, a * x + b * y + c * z + e, 1e-5);
        ENSURE_NEAR(g[0], a, 1e-5);
        ENSURE_NEAR(g[1], b, 1e-5);
        ENSURE_NEAR(g[2], c, 1e-5);
    }
    /* the last node is inside the grid; beyond it, or NaN, reads far with a zero gradient */
    float g[3];
    float last = fm_sdf_sample(&s, o[0] + h * (N0 - 1), o[1] + h * (N1 - 1), o[2] + h * (N2 - 1), g);
    ENSURE_NEAR(last, d[N0 * N1 * N2 - 1], 1e-6);
    ENSURE_NEAR(g[0], a, 1e-5);
    ENSURE(fm_sdf_sample(&s, o[0] - 0.01f, o[1], o[2], g) == 10.0f && g[0] == 0 && g[1] == 0 && g[2] == 0);
    ENSURE(fm_sdf_sample(&s, o[0], o[1] + h * N1, o[2], g) == 10.0f);
    ENSURE(fm_sdf_sample(&s, NAN, o[1], o[2], g) == 10.0f && g[0] == 0);
    ENSURE(fm_sdf_sample(&s, o[0], o[1], o[2], NULL) == d[0]);
    fm_sdf_view empty = {0};
    empty.far = 3.0f;
    ENSURE(fm_sdf_sample(&empty, 0, 0, 0, g) == 3.0f && g[0] == 0);
}

static void test_closest_box(void)
{
    const double c[3] = {0.1, -0.2, 0.3}, h[3] = {0.5, 0.7, 0.4};
    fm_mesh box = make_box(c, h);
    fm_error err = {0};
    fm_obstacles *o = fm_obstacles_build(&box, 1, 0.05, 0.2, &err);
    ENSURE_MSG(o, "%s", err.message);
    if (!o) return mesh_del(&box);
    uint64_t rng = 7;
    double lo[3], hi[3];
    for (int k = 0; k < 3; k++) lo[k] = c[k] - h[k] - 0.4, hi[k] = c[k] + h[k] + 0.4;
    double worst = 0;
    int inside = 0, bad_sign = 0, bad_geom = 0;
    for (int n = 0; n < 20000; n++) {
        double p[3], q[3], nrm[3];
        random_point(&rng, lo, hi, p);
        if (n % 4 == 0) /* many near the surface: snap one coordinate onto a face plane +- a little */
            p[n / 4 % 3] = c[n / 4 % 3] + (n % 8 ? 1 : -1) * h[n / 4 % 3] + 1e-3 * (test_uniform(&rng) - 0.5);
        double sd = fm_obstacles_closest(o, p, q, nrm), ref = box_sdf(c, h, p);
        worst = fmax(worst, fabs(sd - ref));
        inside += ref < 0;
        bad_sign += (ref < 0) != (sd < 0);
        bad_geom += !consistent(p, sd, q, nrm) || fabs(box_sdf(c, h, q)) > 1e-12;
    }
    ENSURE_MSG(worst <= 1e-9, "worst |d - analytic| %.3g", worst);
    ENSURE_MSG(bad_sign == 0, "%d wrong signs", bad_sign);
    ENSURE_MSG(bad_geom == 0, "%d closest points or normals inconsistent", bad_geom);
    ENSURE(inside > 1000);
    /* special points: the centre, a corner, an edge midpoint, a face centre, far away */
    const double special[][3] = {{0.1, -0.2, 0.3}, {0.6, 0.5, 0.7}, {0.6, -0.2, 0.7}, {0.1, -0.9, 0.3},
                                 {0.7, 0.6, 0.8}, {0.1, -0.2, 50.0}, {-0.35, -0.2, 0.3}};
    for (size_t i = 0; i < sizeof special / sizeof special[0]; i++)
        ENSURE_NEAR(fm_obstacles_closest(o, special[i], NULL, NULL), box_sdf(c, h, special[i]), 1e-12);
    double nrm[3], q[3];
    ENSURE(isnan(fm_obstacles_closest(o, (double[3]){NAN, 0, 0}, q, nrm)) && isnan(q[0]) && isnan(nrm[0]));
    fm_obstacles_destroy(o);

    /* the same box inside out (every triangle flipped) gives the same signed distances */
    for (int64_t t = 0; t < box.nt; t++) {
        int32_t tmp = box.tri[3 * t + 1];
        box.tri[3 * t + 1] = box.tri[3 * t + 2], box.tri[3 * t + 2] = tmp;
    }
    o = fm_obstacles_build(&box, 1, 0.05, 0.2, &err);
    ENSURE_MSG(o, "%s", err.message);
    if (o) {
        worst = 0;
        for (int n = 0; n < 2000; n++) {
            double p[3];
            random_point(&rng, lo, hi, p);
            worst = fmax(worst, fabs(fm_obstacles_closest(o, p, NULL, NULL) - box_sdf(c, h, p)));
        }
        ENSURE_MSG(worst <= 1e-9, "inside-out box: worst %.3g", worst);
        fm_sdf_view s = fm_obstacles_sdf(o);
        ENSURE(fm_sdf_sample(&s, 0.1f, -0.2f, 0.3f, NULL) < 0);
    }
    fm_obstacles_destroy(o);
    mesh_del(&box);
}

/* Exact distances against brute force over the triangles; signs against the winding number. */
static void check_brute_force(const fm_mesh *m, const char *name, int points, uint64_t seed)
{
    fm_error err = {0};
    fm_obstacles *o = fm_obstacles_build(m, 1, 0.05, 0.15, &err);
    ENSURE_MSG(o, "%s: %s", name, err.message);
    if (!o) return;
    double lo[3], hi[3];
    mesh_box(m, lo, hi, 0.5);
    uint64_t rng = seed;
    double worst = 0;
    int bad_sign = 0, bad_geom = 0, inside = 0;
    for (int n = 0; n < points; n++) {
        double p[3], q[3], nrm[3];
        random_point(&rng, lo, hi, p);
        if (n % 3 == 0) { /* near the surface: pull a random vertex out or in a little */
            int64_t v = (int64_t)(test_uniform(&rng) * (double)m->nv);
            for (int k = 0; k < 3; k++) p[k] = m->v[3 * v + k] + 0.02 * (test_uniform(&rng) - 0.5);
        }
        double sd = fm_obstacles_closest(o, p, q, nrm), ref = brute_dist(m, p);
        worst = fmax(worst, fabs(fabs(sd) - ref));
        double w = winding(m, p);
        int in = fabs(w) > 0.5;
        inside += in;
        if (ref > 1e-9) bad_sign += in != (sd < 0);
        bad_geom += !consistent(p, sd, q, nrm);
    }
    ENSURE_MSG(worst <= 1e-9, "%s: worst |d - brute force| %.3g", name, worst);
    ENSURE_MSG(bad_sign == 0, "%s: %d wrong signs", name, bad_sign);
    ENSURE_MSG(bad_geom == 0, "%s: %d closest points or normals inconsistent", name, bad_geom);
    ENSURE_MSG(inside > points / 20, "%s: only %d points inside", name, inside);
    fm_obstacles_destroy(o);
}

static void test_closest_icosphere(void)
{
    fm_mesh s = make_icosphere(3, (double[3]){0.3, -0.1, 0.2}, 1.0);
    check_brute_force(&s, "icosphere", 3000, 11);
    /* convex: inside exactly when behind every face plane */
    fm_error err = {0};
    fm_obstacles *o = fm_obstacles_build(&s, 1, 0.05, 0.15, &err);
    uint64_t rng = 5;
    int bad = 0;
    for (int n = 0; o && n < 5000; n++) {
        double p[3], lo[3] = {-1, -1.4, -1}, hi[3] = {1.6, 1.2, 1.4};
        random_point(&rng, lo, hi, p);
        int in = 1;
        for (int64_t t = 0; t < s.nt; t++) {
            const double *a = s.v + 3 * (int64_t)s.tri[3 * t], *b = s.v + 3 * (int64_t)s.tri[3 * t + 1],
                         *c = s.v + 3 * (int64_t)s.tri[3 * t + 2];
            double e1[3], e2[3], nn[3], ap[3];
            for (int k = 0; k < 3; k++) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], ap[k] = p[k] - a[k];
            nn[0] = e1[1] * e2[2] - e1[2] * e2[1], nn[1] = e1[2] * e2[0] - e1[0] * e2[2], nn[2] = e1[0] * e2[1] - e1[1] * e2[0];
            if (dot(ap, nn) > 0) in = 0;
        }
        bad += in != (fm_obstacles_closest(o, p, NULL, NULL) < 0);
    }
    ENSURE_MSG(bad == 0, "icosphere: %d signs disagree with the face planes", bad);
    fm_obstacles_destroy(o);
    mesh_del(&s);
}

static void test_closest_torus(void)
{
    fm_mesh t = make_torus((double[3]){-0.2, 0.1, 0.05}, 1.0, 0.35, 48, 24);
    check_brute_force(&t, "torus", 2000, 13);
    mesh_del(&t);
}

/* The grid d_t against the exact distance: within a voxel inside the band, far beyond it. */
static void check_grid(const fm_mesh *meshes, int count, const char *name, double voxel, double band, uint64_t seed)
{
    fm_error err = {0};
    fm_obstacles *o = fm_obstacles_build(meshes, count, voxel, band, &err);
    ENSURE_MSG(o, "%s: %s", name, err.message);
    if (!o) return;
    fm_sdf_view s = fm_obstacles_sdf(o);
    ENSURE(s.d && s.far == (float)band && s.voxel == (float)voxel);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int m = 0; m < count; m++) {
        double l[3], h[3];
        mesh_box(&meshes[m], l, h, band + 4 * voxel);
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], l[k]), hi[k] = fmax(hi[k], h[k]);
    }
    /* the grid covers the band and not much more */
    for (int k = 0; k < 3; k++) {
        ENSURE(s.origin[k] <= lo[k] + 4 * voxel && s.origin[k] >= lo[k] - 2 * voxel);
        double top = s.origin[k] + voxel * (s.n[k] - 1);
        ENSURE(top >= hi[k] - 4 * voxel && top <= hi[k] + 2 * voxel);
    }
    uint64_t rng = seed;
    int near = 0, beyond = 0, deep = 0, bad_near = 0, bad_far = 0, bad_sign = 0;
    double worst = 0;
    for (int n = 0; n < 20000; n++) {
        double p[3];
        random_point(&rng, lo, hi, p);
        double exact = fm_obstacles_closest(o, p, NULL, NULL);
        float g[3], d = fm_sdf_sample(&s, (float)p[0], (float)p[1], (float)p[2], g);
        if (fabs(exact) < band - voxel) {
            near++;
            worst = fmax(worst, fabs(d - exact));
            bad_near += !(fabs(d - exact) <= voxel);
        } else if (exact > band + 2 * voxel) {
            beyond++;
            bad_far += !(d == s.far && g[0] == 0 && g[1] == 0 && g[2] == 0);
        } else if (exact < -band - 2 * voxel) {
            deep++;
            bad_far += !(d == -s.far);
        }
        if (fabs(exact) > voxel) bad_sign += (exact < 0) != (d < 0);
    }
    /* well outside the grid */
    float g[3];
    ENSURE(fm_sdf_sample(&s, (float)hi[0] + 100.0f, 0.0f, 0.0f, g) == s.far && g[0] == 0);
    ENSURE_MSG(bad_near == 0, "%s: %d of %d points in the band off by more than a voxel (worst %.3g, voxel %g)",
               name, bad_near, near, worst, voxel);
    ENSURE_MSG(bad_far == 0, "%s: %d of %d points beyond the band do not read +-far", name, bad_far, beyond + deep);
    ENSURE_MSG(bad_sign == 0, "%s: %d signs differ", name, bad_sign);
    ENSURE_MSG(near > 1000 && beyond > 100, "%s: too few points: %d near, %d beyond", name, near, beyond);
    printf("  %-22s grid %d x %d x %d, %d points in the band: worst |d_t - exact| %.3g voxel (%d beyond, %d deep inside)\n",
           name, s.n[0], s.n[1], s.n[2], near, worst / voxel, beyond, deep);
    fm_obstacles_destroy(o);
}

static void test_grid_matches_exact(void)
{
    fm_mesh box = make_box((double[3]){0.1, -0.2, 0.3}, (double[3]){0.5, 0.7, 0.4});
    fm_mesh sphere = make_icosphere(3, (double[3]){0.3, -0.1, 0.2}, 1.0);
    fm_mesh torus = make_torus((double[3]){-0.2, 0.1, 0.05}, 1.0, 0.35, 48, 24);
    check_grid(&box, 1, "box", 0.02, 0.1, 21);
    check_grid(&sphere, 1, "icosphere", 0.03, 0.3, 22);
    check_grid(&torus, 1, "torus", 0.02, 0.12, 23);
    fm_mesh both[2] = {torus, make_box((double[3]){2.5, 0.0, 0.0}, (double[3]){0.3, 0.3, 0.3})};
    check_grid(both, 2, "torus + box", 0.025, 0.15, 24);
    mesh_del(&both[1]);
    mesh_del(&box);
    mesh_del(&sphere);
    mesh_del(&torus);
}

static void test_union_of_overlapping_boxes(void)
{
    const double ca[3] = {0, 0, 0}, ha[3] = {0.6, 0.3, 0.3}, cb[3] = {0.5, 0.1, 0}, hb[3] = {0.3, 0.5, 0.5};
    fm_mesh m[2] = {make_box(ca, ha), make_box(cb, hb)};
    fm_error err = {0};
    fm_obstacles *o = fm_obstacles_build(m, 2, 0.03, 0.15, &err);
    ENSURE_MSG(o, "%s", err.message);
    if (o) {
        fm_sdf_view s = fm_obstacles_sdf(o);
        uint64_t rng = 31;
        double worst = 0;
        int bad_sign = 0, grid_sign = 0, buried = 0;
        for (int n = 0; n < 20000; n++) {
            double p[3], q[3], nrm[3], lo[3] = {-1, -0.8, -0.8}, hi[3] = {1.1, 0.9, 0.8};
            random_point(&rng, lo, hi, p);
            double sd = fm_obstacles_closest(o, p, q, nrm);
            double ra = box_sdf(ca, ha, p), rb = box_sdf(cb, hb, p), ref = fmin(ra, rb);
            worst = fmax(worst, fabs(sd - ref));
            bad_sign += (sd < 0) != (ref < 0);
            /* inside b, but the nearest triangle is a's buried face */
            buried += rb < 0 && ra > 0 && ra < -rb;
            float d = fm_sdf_sample(&s, (float)p[0], (float)p[1], (float)p[2], NULL);
            if (fabs(ref) > 0.03) grid_sign += (d < 0) != (ref < 0);
        }
        ENSURE_MSG(worst <= 1e-9, "union: worst |d - min(d_a, d_b)| %.3g", worst);
        ENSURE(bad_sign == 0);
        ENSURE_MSG(grid_sign == 0, "union: %d grid signs differ", grid_sign);
        ENSURE(buried > 100);
    }
    fm_obstacles_destroy(o);
    mesh_del(&m[0]);
    mesh_del(&m[1]);
}

static void test_gradient_is_radial(void)
{
    const double c[3] = {0.2, -0.3, 0.1};
    fm_mesh s = make_icosphere(4, c, 1.0);
    fm_error err = {0};
    const double voxel = 0.02, band = 0.25;
    fm_obstacles *o = fm_obstacles_build(&s, 1, voxel, band, &err);
    ENSURE_MSG(o, "%s", err.message);
    if (o) {
        fm_sdf_view v = fm_obstacles_sdf(o);
        uint64_t rng = 41;
        double worst = 0, sum = 0;
        int bad = 0, n = 0;
        for (; n < 5000; n++) {
            double u[3], len;
            do {
                for (int k = 0; k < 3; k++) u[k] = 2 * test_uniform(&rng) - 1;
                len = sqrt(dot(u, u));
            } while (len > 1 || len < 0.1);
            /* outside and inside, from 2 voxels off the surface to 2 voxels short of the band */
            double r = 2 * voxel + (band - 4 * voxel) * test_uniform(&rng);
            r = 1.0 + (n % 2 ? r : -r);
            float g[3];
            fm_sdf_sample(&v, (float)(c[0] + r * u[0] / len), (float)(c[1] + r * u[1] / len),
                          (float)(c[2] + r * u[2] / len), g);
            double gl = sqrt((double)g[0] * g[0] + (double)g[1] * g[1] + (double)g[2] * g[2]);
            double cosang = gl > 0 ? (g[0] * u[0] + g[1] * u[1] + g[2] * u[2]) / (gl * len) : -1;
            double ang = acos(fmin(1.0, cosang)) * 180 / PI;
            worst = fmax(worst, ang);
            sum += ang;
            bad += !(ang <= 5.0) || gl < 0.5 || gl > 1.5;
        }
        ENSURE_MSG(bad == 0, "%d gradients more than 5 degrees off radial or not ~unit (worst %.2f deg)", bad, worst);
        printf("  gradient vs radial: worst %.2f deg, mean %.2f deg over %d points\n", worst, sum / n, n);
    }
    fm_obstacles_destroy(o);
    mesh_del(&s);
}

static void test_voxel_refusal(void)
{
    fm_mesh box = make_box((double[3]){0, 0, 0}, (double[3]){0.5, 0.5, 0.5});
    fm_error err = {0};
    fm_obstacles *o = fm_obstacles_build(&box, 1, 1e-3, 0.1, &err);
    ENSURE(!o);
    ENSURE(err.status == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "voxel size 0.001") && strstr(err.message, "at least"), "%s", err.message);
    const char *at = strstr(err.message, "at least ");
    double suggested = at ? atof(at + 9) : 0;
    /* (1.2 / h)^3 <= 2^27 needs h >= 0.00234 */
    ENSURE_MSG(suggested > 0.0023 && suggested < 0.003, "suggested %g in: %s", suggested, err.message);
    printf("  refusal: %s\n", err.message);
    fm_obstacles_destroy(o);
    mesh_del(&box);
}

static void expect_input_error(const fm_mesh *m, int count, double voxel, double band, const char *want)
{
    fm_error err = {0};
    fm_obstacles *o = fm_obstacles_build(m, count, voxel, band, &err);
    ENSURE(!o);
    ENSURE_MSG(err.status == FM_ERR_INPUT && strstr(err.message, want), "want '%s', got %d '%s'", want,
               (int)err.status, err.message);
    fm_obstacles_destroy(o);
}

static void test_bad_input(void)
{
    fm_mesh box = make_box((double[3]){0, 0, 0}, (double[3]){0.5, 0.5, 0.5});
    expect_input_error(&box, 0, 0.05, 0.1, "no obstacle");
    expect_input_error(NULL, 1, 0.05, 0.1, "no obstacle");
    expect_input_error(&box, 1, 0.0, 0.1, "voxel");
    expect_input_error(&box, 1, NAN, 0.1, "voxel");
    expect_input_error(&box, 1, 0.05, -1.0, "band");
    fm_mesh empty = {0};
    expect_input_error(&empty, 1, 0.05, 0.1, "empty");
    fm_mesh two[2] = {box, {box.v, box.nv, box.tri, 0}};
    expect_input_error(two, 2, 0.05, 0.1, "obstacle 1 is empty");
    fm_mesh open = {box.v, box.nv, box.tri, box.nt - 1};
    expect_input_error(&open, 1, 0.05, 0.1, "hole");
    box.tri[5] = 8;
    expect_input_error(&box, 1, 0.05, 0.1, "refers to vertex 8");
    box.tri[5] = box.tri[4];
    expect_input_error(&box, 1, 0.05, 0.1, "degenerate");
    mesh_del(&box);
    box = make_box((double[3]){0, 0, 0}, (double[3]){0.5, 0.5, 0.5});
    box.v[4] = NAN;
    expect_input_error(&box, 1, 0.05, 0.1, "not finite");
    mesh_del(&box);
    /* a small obstacle far from the origin: float grid coordinates would lose the voxel */
    box = make_box((double[3]){1e4, 0, 0}, (double[3]){0.5, 0.5, 0.5});
    expect_input_error(&box, 1, 0.01, 0.1, "nearer the origin");
    mesh_del(&box);
    /* NULL is harmless */
    fm_obstacles_destroy(NULL);
    fm_sdf_view s = fm_obstacles_sdf(NULL);
    ENSURE(s.d == NULL && fm_sdf_sample(&s, 0, 0, 0, NULL) == 0.0f);
}

static void test_threads_match_serial(void)
{
    fm_mesh m[2] = {make_torus((double[3]){0, 0, 0}, 1.0, 0.35, 48, 24), make_icosphere(2, (double[3]){0.0, 0.0, 0.2}, 0.5)};
    fm_error err = {0};
    fm_obstacles *o = fm_obstacles_build(m, 2, 0.04, 0.2, &err);
    ENSURE_MSG(o, "%s", err.message);
    if (o) {
        enum { N = 10000 };
        double *p = malloc(sizeof(double) * 3 * N), *serial = malloc(sizeof(double) * 7 * N),
               *par = malloc(sizeof(double) * 7 * N);
        uint64_t rng = 51;
        const double lo[3] = {-1.6, -1.6, -0.6}, hi[3] = {1.6, 1.6, 0.8};
        for (int i = 0; i < N; i++) random_point(&rng, lo, hi, p + 3 * i);
        for (int i = 0; i < N; i++) serial[7 * i] = fm_obstacles_closest(o, p + 3 * i, serial + 7 * i + 1, serial + 7 * i + 4);
        int threads = 1;
#pragma omp parallel for schedule(dynamic, 64)
        for (int i = 0; i < N; i++) {
            par[7 * i] = fm_obstacles_closest(o, p + 3 * i, par + 7 * i + 1, par + 7 * i + 4);
#ifdef _OPENMP
            if (i == 0) threads = omp_get_num_threads();
#endif
        }
        ENSURE(memcmp(serial, par, sizeof(double) * 7 * N) == 0);
        printf("  %d points on %d threads: identical to serial\n", N, threads);
        free(p);
        free(serial);
        free(par);
    }
    fm_obstacles_destroy(o);
    mesh_del(&m[0]);
    mesh_del(&m[1]);
}

static void test_timing(void)
{
    /* ~2000 triangles (the 48 x 24 torus, 2304), voxel 1/100 of its size; best of 3 builds */
    fm_mesh t = make_torus((double[3]){0, 0, 0}, 1.0, 0.35, 48, 24);
    double size = 2 * 1.35, voxel = size / 100, band = 0.1 * size, t_grid = INFINITY, t_build = INFINITY;
    fm_error err = {0};
    fm_obstacles *o = NULL;
    for (int rep = 0; rep < 3; rep++) {
        float *d = NULL;
        int32_t n[3];
        float origin[3];
        double t0 = fm_seconds();
        fm_status st = fm_obstacles_vdb_grid(t.v, t.nv, t.tri, t.nt, voxel, band, FM_OBSTACLE_MAX_VOXELS,
                                             &(fm_sdf_names){"obstacle", "the obstacles"}, &d, n, origin, &err);
        t_grid = fmin(t_grid, fm_seconds() - t0);
        ENSURE_MSG(st == FM_OK, "%s", err.message);
        fm_free(d);
        fm_obstacles_destroy(o);
        t0 = fm_seconds();
        o = fm_obstacles_build(&t, 1, voxel, band, &err);
        t_build = fmin(t_build, fm_seconds() - t0);
        ENSURE_MSG(o, "%s", err.message);
    }
    if (o) {
        fm_sdf_view s = fm_obstacles_sdf(o);
        enum { NS = 1000000, NC = 20000 };
        float *q = malloc(sizeof(float) * 3 * NS);
        uint64_t rng = 61;
        for (int i = 0; i < 3 * NS; i++) q[i] = (float)(-1.6 + 3.2 * test_uniform(&rng)) * (i % 3 == 2 ? 0.4f : 1.0f);
        double acc = 0, t0 = fm_seconds();
        for (int i = 0; i < NS; i++) {
            float g[3];
            acc += fm_sdf_sample(&s, q[3 * i], q[3 * i + 1], q[3 * i + 2], g) + g[0];
        }
        double t_random = (fm_seconds() - t0) / NS;
        t0 = fm_seconds(); /* coherent: a walk of small steps, as an agent moves */
        float x = -1.5f, y = -1.5f, z = 0.0f;
        for (int i = 0; i < NS; i++) {
            float g[3];
            acc += fm_sdf_sample(&s, x, y, z, g) + g[0];
            x += 3e-6f, y += 2e-6f, z = 0.3f * sinf(x);
        }
        double t_walk = (fm_seconds() - t0) / NS;
        double t_in = 0, t_all = 0;
        int n_in = 0, n_all = 0;
        for (int i = 0; i < NC; i++) {
            double p[3] = {q[3 * i], q[3 * i + 1], q[3 * i + 2]}, c[3];
            int in = fabsf(fm_sdf_sample(&s, q[3 * i], q[3 * i + 1], q[3 * i + 2], NULL)) < s.far;
            t0 = fm_seconds();
            acc += fm_obstacles_closest(o, p, c, NULL) + c[0];
            double dt = fm_seconds() - t0;
            t_all += dt, n_all++;
            if (in) t_in += dt, n_in++;
        }
        printf("  torus %lld triangles, voxel %.4g (1/100 of its size), band %.3g: grid %d x %d x %d\n"
               "  OpenVDB grid %.3f s; whole build (grid, BVH, exact band values) %.3f s\n"
               "  fm_sdf_sample %.1f ns random, %.1f ns coherent; fm_obstacles_closest %.0f ns in the band, "
               "%.0f ns anywhere (single thread; checksum %g)\n",
               (long long)t.nt, voxel, band, s.n[0], s.n[1], s.n[2], t_grid, t_build, 1e9 * t_random,
               1e9 * t_walk, 1e9 * t_in / n_in, 1e9 * t_all / n_all, acc);
        free(q);
    }
    fm_obstacles_destroy(o);
    mesh_del(&t);
}

int main(void)
{
    RUN_TEST(test_kernel_linear_field);
    RUN_TEST(test_closest_box);
    RUN_TEST(test_closest_icosphere);
    RUN_TEST(test_closest_torus);
    RUN_TEST(test_union_of_overlapping_boxes);
    RUN_TEST(test_grid_matches_exact);
    RUN_TEST(test_gradient_is_radial);
    RUN_TEST(test_voxel_refusal);
    RUN_TEST(test_bad_input);
    RUN_TEST(test_threads_match_serial);
    RUN_TEST(test_timing);
    return test_result();
}
