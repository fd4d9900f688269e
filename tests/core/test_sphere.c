/* Tests of fm_min_sphere against a brute-force reference, on degenerate sets and on 10^5..10^6
 * points. */
#include "fm_math.h"
#include "test_macros.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define PI 3.14159265358979323846

/* Containment as the engine's callers see it: |p - c| <= r (1 + 1e-9) + 1e-12. */
#define INSIDE_REL 1e-9
#define INSIDE_ABS 1e-12

static const uint64_t seeds[3] = {1u, 0x9E3779B97F4A7C15u, 12345u};

/* ---------------------------------------------------------------- helpers */

/* splitmix64: deterministic, so failures reproduce. */
static uint64_t rng_state = 0xC0FFEE1234567u;

static double rng_uniform(double lo, double hi) { return lo + (hi - lo) * test_uniform(&rng_state); }

static double rng_gauss(void)
{
    double u = rng_uniform(DBL_MIN, 1.0), v = rng_uniform(0.0, 2.0 * PI);
    return sqrt(-2.0 * log(u)) * cos(v);
}

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static double dist3(const double a[3], const double b[3])
{
    double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
    return sqrt(dot3(d, d));
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static void rng_unit_vector(double v[3])
{
    double n;
    do {
        for (int i = 0; i < 3; ++i) v[i] = rng_gauss();
        n = sqrt(dot3(v, v));
    } while (n < 1e-3);
    for (int i = 0; i < 3; ++i) v[i] /= n;
}

/* Two orthonormal vectors spanning a random plane. */
static void rng_plane(double u[3], double v[3])
{
    double w[3];
    rng_unit_vector(u);
    do {
        rng_unit_vector(w);
        cross3(u, w, v);
    } while (dot3(v, v) < 1e-2);
    double n = sqrt(dot3(v, v));
    for (int i = 0; i < 3; ++i) v[i] /= n;
}

/* Number of points outside the sphere by more than the containment slack. */
static size_t count_outside(const double *p, size_t n, const double c[3], double r)
{
    size_t bad = 0;
    for (size_t i = 0; i < n; ++i)
        if (!(dist3(p + 3 * i, c) <= r * (1.0 + INSIDE_REL) + INSIDE_ABS)) bad++;
    return bad;
}

/* ---------------------------------------------------------------- brute force */

/* m x = b by Gaussian elimination with partial pivoting; -1 if a pivot is exactly 0. A nearly
 * singular system may give a useless sphere, which the containment test then rejects (no
 * sphere containing every point is smaller than the minimal one). */
static int solve3(double m[3][3], double b[3], double x[3])
{
    for (int col = 0; col < 3; ++col) {
        int piv = col;
        for (int row = col + 1; row < 3; ++row)
            if (fabs(m[row][col]) > fabs(m[piv][col])) piv = row;
        if (m[piv][col] == 0.0) return -1;
        for (int k = 0; k < 3; ++k) {
            double t = m[col][k];
            m[col][k] = m[piv][k];
            m[piv][k] = t;
        }
        double t = b[col];
        b[col] = b[piv];
        b[piv] = t;
        for (int row = col + 1; row < 3; ++row) {
            double f = m[row][col] / m[col][col];
            for (int k = col; k < 3; ++k) m[row][k] -= f * m[col][k];
            b[row] -= f * b[col];
        }
    }
    for (int row = 2; row >= 0; --row) {
        double s = b[row];
        for (int k = row + 1; k < 3; ++k) s -= m[row][k] * x[k];
        x[row] = s / m[row][row];
    }
    return isfinite(x[0]) && isfinite(x[1]) && isfinite(x[2]) ? 0 : -1;
}

typedef struct bf_best {
    double r;
    double c[3];
} bf_best;

/* Keeps the sphere centred at c through the points def[0..m-1] if it contains every point
 * (within a slack 10x tighter than the one the library is held to) and is the smallest so far. */
static void bf_consider(const double *p, int n, const double c[3], const int *def, int m,
                        bf_best *best)
{
    double r = 0.0;
    for (int i = 0; i < m; ++i) r = fmax(r, dist3(c, p + 3 * def[i]));
    if (!(r < best->r)) return;
    for (int i = 0; i < n; ++i)
        if (!(dist3(c, p + 3 * i) <= r * (1.0 + 1e-10) + 1e-13)) return;
    best->r = r;
    memcpy(best->c, c, sizeof best->c);
}

/* The sphere with p[i], p[j] as diameter. */
static void bf_pair(const double *p, int n, int i, int j, bf_best *best)
{
    double c[3];
    for (int k = 0; k < 3; ++k) c[k] = 0.5 * (p[3 * i + k] + p[3 * j + k]);
    int def[2] = {i, j};
    bf_consider(p, n, c, def, 2, best);
}

/* Circumcircle of a triangle: centre x (relative to a) with u.x = |u|^2/2, v.x = |v|^2/2 and
 * (u x v).x = 0, i.e. equidistant from the corners and in their plane. */
static void bf_triangle(const double *p, int n, int i, int j, int k, bf_best *best)
{
    const double *a = p + 3 * i;
    double u[3], v[3], w[3], m[3][3], b[3], x[3];
    for (int d = 0; d < 3; ++d) {
        u[d] = p[3 * j + d] - a[d];
        v[d] = p[3 * k + d] - a[d];
    }
    cross3(u, v, w);
    memcpy(m[0], u, sizeof u);
    memcpy(m[1], v, sizeof v);
    memcpy(m[2], w, sizeof w);
    b[0] = 0.5 * dot3(u, u);
    b[1] = 0.5 * dot3(v, v);
    b[2] = 0.0;
    if (solve3(m, b, x) != 0) return;
    double c[3] = {a[0] + x[0], a[1] + x[1], a[2] + x[2]};
    int def[3] = {i, j, k};
    bf_consider(p, n, c, def, 3, best);
}

/* Circumsphere of a tetrahedron: x (relative to a) with e.x = |e|^2/2 for its three edges e
 * from a. */
static void bf_tetra(const double *p, int n, int i, int j, int k, int l, bf_best *best)
{
    const double *a = p + 3 * i;
    const int other[3] = {j, k, l};
    double m[3][3], b[3], x[3];
    for (int row = 0; row < 3; ++row) {
        for (int d = 0; d < 3; ++d) m[row][d] = p[3 * other[row] + d] - a[d];
        b[row] = 0.5 * dot3(m[row], m[row]);
    }
    if (solve3(m, b, x) != 0) return;
    double c[3] = {a[0] + x[0], a[1] + x[1], a[2] + x[2]};
    int def[4] = {i, j, k, l};
    bf_consider(p, n, c, def, 4, best);
}

/* Every sphere defined by 2, 3 or 4 of the points; the smallest one containing them all. */
static bf_best brute_force(const double *p, int n)
{
    bf_best best = {INFINITY, {0, 0, 0}};
    if (n == 1) {
        best.r = 0.0;
        memcpy(best.c, p, sizeof best.c);
    }
    for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j) {
            bf_pair(p, n, i, j, &best);
            for (int k = j + 1; k < n; ++k) {
                bf_triangle(p, n, i, j, k, &best);
                for (int l = k + 1; l < n; ++l) bf_tetra(p, n, i, j, k, l, &best);
            }
        }
    return best;
}

/* ---------------------------------------------------------------- small sets */

/* Worst disagreements with the brute force, printed so the margins are visible. */
typedef struct small_stats {
    int sets;
    double radius, centre, seeds;
} small_stats;

/* fm_min_sphere on p for three seeds: each result contains the points, matches the brute
 * force's radius and centre (the minimal sphere is unique) and the other seeds' radii. */
static void check_small(const double *p, int n, const char *what, small_stats *st)
{
    bf_best bf = brute_force(p, n);
    ENSURE_MSG(isfinite(bf.r), "%s: brute force found nothing (n = %d)", what, n);
    double r0 = 0.0;
    for (int s = 0; s < 3; ++s) {
        double c[3], r;
        ENSURE(fm_min_sphere(p, (size_t)n, seeds[s], c, &r) == 0);
        ENSURE_MSG(count_outside(p, (size_t)n, c, r) == 0, "%s: point outside (n = %d)", what,
                   n);
        double dr = fabs(r - bf.r), dc = dist3(c, bf.c);
        /* Measured differences are ~1e-15 for generic sets; for concyclic and cospherical sets
         * they reach ~1e-12, and it is the brute force that is off: its 1e-10 containment
         * slack lets a near-singular 4-point system's sphere slightly undercut the true one. */
        ENSURE_MSG(dr <= 1e-9 * bf.r + 1e-12, "%s: radius %.17g, brute force %.17g (n = %d)",
                   what, r, bf.r, n);
        /* The radius grows quadratically away from the optimal centre in the worst (flat)
         * direction, so a radius slack of ~1e-10 r permits a centre offset of ~1.4e-5 r; real
         * differences are orders of magnitude smaller and printed below. */
        ENSURE_MSG(dc <= 1e-5 * bf.r + 1e-12, "%s: centre off by %g (r = %g, n = %d)", what, dc,
                   bf.r, n);
        if (s == 0) r0 = r;
        ENSURE_MSG(fabs(r - r0) <= 1e-12 * r0, "%s: seed changes radius %.17g -> %.17g", what,
                   r0, r);
        st->radius = fmax(st->radius, dr / fmax(bf.r, 1e-300));
        st->centre = fmax(st->centre, dc / fmax(bf.r, 1e-300));
        st->seeds = fmax(st->seeds, fabs(r - r0) / fmax(r0, 1e-300));
    }
    st->sets++;
}

static void stats_print(const char *what, const small_stats *st)
{
    printf("  %-26s %3d sets  radius %.1e  centre %.1e  seeds %.1e (relative)\n", what, st->sets,
           st->radius, st->centre, st->seeds);
}

static int rng_count(int lo, int hi) { return lo + (int)(test_uniform(&rng_state) * (hi - lo + 1)); }

static void test_small_random(void)
{
    small_stats st = {0};
    double p[12 * 3];
    for (int t = 0; t < 240; ++t) {
        int n = 1 + t % 12;
        for (int i = 0; i < 3 * n; ++i) p[i] = rng_uniform(-1.0, 1.0);
        check_small(p, n, "random", &st);
    }
    stats_print("random in a cube", &st);
}

static void test_small_on_sphere(void)
{
    /* Every point on the surface: many 4-point subsets have (nearly) the same circumsphere. */
    small_stats st = {0};
    double p[12 * 3];
    for (int t = 0; t < 80; ++t) {
        int n = rng_count(2, 12);
        double c[3] = {rng_uniform(-3, 3), rng_uniform(-3, 3), rng_uniform(-3, 3)};
        double r = rng_uniform(0.5, 2.0);
        for (int i = 0; i < n; ++i) {
            double u[3];
            rng_unit_vector(u);
            for (int k = 0; k < 3; ++k) p[3 * i + k] = c[k] + r * u[k];
        }
        check_small(p, n, "on a sphere", &st);
    }
    stats_print("on a sphere", &st);
}

static void test_small_near_sphere(void)
{
    /* Radii jittered by up to 1e-8: the answer is fixed by the outermost points, and a
     * sphere through any 4 points misses the others by ~1e-8, so a sloppy inside test (or a
     * wrong support point) shows up as a radius error far above 1e-9. */
    small_stats st = {0};
    double p[12 * 3];
    for (int t = 0; t < 80; ++t) {
        int n = rng_count(5, 12);
        for (int i = 0; i < n; ++i) {
            double u[3], r = 1.0 + 1e-8 * rng_uniform(-1, 1);
            rng_unit_vector(u);
            for (int k = 0; k < 3; ++k) p[3 * i + k] = r * u[k];
        }
        check_small(p, n, "near a sphere", &st);
    }
    stats_print("near a sphere", &st);
}

static void test_small_all_equal(void)
{
    small_stats st = {0};
    double p[12 * 3];
    for (int n = 1; n <= 12; ++n) {
        double q[3] = {rng_uniform(-5, 5), rng_uniform(-5, 5), rng_uniform(-5, 5)};
        for (int i = 0; i < n; ++i) memcpy(p + 3 * i, q, sizeof q);
        check_small(p, n, "all equal", &st);
        double c[3], r;
        ENSURE(fm_min_sphere(p, (size_t)n, 7u, c, &r) == 0);
        ENSURE(r == 0.0 && c[0] == q[0] && c[1] == q[1] && c[2] == q[2]);
    }
    stats_print("all equal", &st);
}

static void test_small_collinear(void)
{
    small_stats st = {0};
    double p[12 * 3];
    for (int t = 0; t < 60; ++t) {
        int n = rng_count(2, 12);
        double a[3] = {rng_uniform(-2, 2), rng_uniform(-2, 2), rng_uniform(-2, 2)}, d[3];
        rng_unit_vector(d);
        for (int i = 0; i < n; ++i) {
            double tt = rng_uniform(-1, 1);
            for (int k = 0; k < 3; ++k) p[3 * i + k] = a[k] + tt * d[k];
            /* Every third set repeats points: collinear with duplicates. */
            if (t % 3 == 0 && i % 2 == 1) memcpy(p + 3 * i, p + 3 * (i - 1), 3 * sizeof *p);
        }
        check_small(p, n, "collinear", &st);
    }
    stats_print("collinear", &st);
}

static void test_small_coplanar(void)
{
    small_stats st = {0};
    double p[12 * 3];
    for (int t = 0; t < 80; ++t) {
        int n = rng_count(3, 12);
        double a[3] = {rng_uniform(-2, 2), rng_uniform(-2, 2), rng_uniform(-2, 2)}, u[3], v[3];
        rng_plane(u, v);
        for (int i = 0; i < n; ++i) {
            double s = rng_uniform(-1, 1), tt = rng_uniform(-1, 1);
            for (int k = 0; k < 3; ++k) p[3 * i + k] = a[k] + s * u[k] + tt * v[k];
        }
        check_small(p, n, "coplanar", &st);
    }
    stats_print("coplanar", &st);
}

static void test_small_cocircular(void)
{
    /* Points on one circle: every 4 of them are coplanar and concyclic, so every tetrahedron's
     * circumsphere is degenerate. Also the axis-aligned version, where rounding is exact-ish. */
    small_stats st = {0};
    double p[12 * 3];
    for (int t = 0; t < 60; ++t) {
        int n = rng_count(3, 12);
        double a[3] = {rng_uniform(-2, 2), rng_uniform(-2, 2), rng_uniform(-2, 2)}, u[3], v[3];
        double r = rng_uniform(0.5, 2.0);
        if (t % 4 == 0) {
            double ex[3] = {1, 0, 0}, ey[3] = {0, 1, 0};
            memcpy(u, ex, sizeof u);
            memcpy(v, ey, sizeof v);
        } else {
            rng_plane(u, v);
        }
        for (int i = 0; i < n; ++i) {
            double phi = rng_uniform(0, 2 * PI), cs = r * cos(phi), sn = r * sin(phi);
            for (int k = 0; k < 3; ++k) p[3 * i + k] = a[k] + cs * u[k] + sn * v[k];
        }
        check_small(p, n, "cocircular", &st);
    }
    stats_print("cocircular", &st);
}

static void test_small_duplicates(void)
{
    small_stats st = {0};
    double p[12 * 3], base[4 * 3];
    for (int t = 0; t < 60; ++t) {
        int m = rng_count(1, 4), n = rng_count(2, 12);
        for (int i = 0; i < 3 * m; ++i) base[i] = rng_uniform(-1, 1);
        for (int i = 0; i < n; ++i) memcpy(p + 3 * i, base + 3 * (i % m), 3 * sizeof *p);
        check_small(p, n, "duplicates", &st);
    }
    stats_print("duplicates", &st);
}

static void test_small_regular(void)
{
    /* Symmetric sets where many subsets give the same sphere: square, cube, octahedron,
     * regular tetrahedron, and the cube's corners each listed three times. */
    small_stats st = {0};
    const double square[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 0.5, 0};
    const double octa[] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
    const double tetra[] = {1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1};
    double cube3[24 * 3];
    for (int i = 0; i < 24; ++i)
        for (int k = 0; k < 3; ++k) cube3[3 * i + k] = ((i % 8) >> k) & 1 ? 1.0 : -1.0;
    check_small(square, 5, "square", &st);
    check_small(octa, 6, "octahedron", &st);
    check_small(tetra, 4, "tetrahedron", &st);
    check_small(cube3, 12, "cube corners repeated", &st);
    double c[3], r;
    ENSURE(fm_min_sphere(cube3, 24, 3u, c, &r) == 0);
    ENSURE_NEAR(r, sqrt(3.0), 1e-15);
    ENSURE(fm_min_sphere(tetra, 4, 3u, c, &r) == 0);
    ENSURE_NEAR(r, sqrt(3.0), 1e-15);
    stats_print("regular", &st);
}

/* ---------------------------------------------------------------- special cases */

static void test_edge_cases(void)
{
    double c[3] = {9, 9, 9}, r = 9;
    ENSURE(fm_min_sphere(NULL, 0, 1u, c, &r) == 0);
    ENSURE(c[0] == 0 && c[1] == 0 && c[2] == 0 && r == 0);
    const double one[3] = {1.5, -2.5, 3.25};
    ENSURE(fm_min_sphere(one, 1, 1u, c, &r) == 0);
    ENSURE(c[0] == 1.5 && c[1] == -2.5 && c[2] == 3.25 && r == 0);
    const double two[6] = {1, 2, 3, 3, 2, 1};
    ENSURE(fm_min_sphere(two, 2, 1u, c, &r) == 0);
    ENSURE_NEAR(c[0], 2, 1e-15);
    ENSURE_NEAR(c[1], 2, 1e-15);
    ENSURE_NEAR(c[2], 2, 1e-15);
    ENSURE_NEAR(r, sqrt(2.0), 1e-15);
}

static void test_cube_corners(void)
{
    /* Side 2 centred at (1, -2, 3): centre (1, -2, 3), radius sqrt(3). Also a cube of side
     * 2^-10 far from the origin, where the offset dominates every coordinate (both chosen so
     * the corners are exact in binary: the expected answer is then exact too). */
    const double side[2] = {2.0, 0x1p-10}, at[2][3] = {{1, -2, 3}, {1024, -2048, 512}};
    for (int t = 0; t < 2; ++t) {
        double p[8 * 3];
        for (int i = 0; i < 8; ++i)
            for (int k = 0; k < 3; ++k) p[3 * i + k] = at[t][k] + ((i >> k) & 1 ? 0.5 : -0.5) * side[t];
        for (int s = 0; s < 3; ++s) {
            double c[3], r;
            ENSURE(fm_min_sphere(p, 8, seeds[s], c, &r) == 0);
            double half_diag = 0.5 * sqrt(3.0) * side[t];
            for (int k = 0; k < 3; ++k) ENSURE_NEAR(c[k], at[t][k], 1e-12 * half_diag);
            ENSURE_NEAR(r, half_diag, 1e-12 * half_diag);
            ENSURE(count_outside(p, 8, c, r) == 0);
        }
    }
}

/* ---------------------------------------------------------------- large sets */

/* The minimal sphere's centre lies in the convex hull of the points on its surface: in every
 * direction d some surface point has (p - c).d >= 0, else moving c along -d would shrink the
 * sphere. Checked for many random directions and the axes. "On the surface" and ">= 0" allow
 * 1e-9 r plus the spacing of doubles at the centre, which the centre cannot beat. */
static int is_optimal(const double *p, size_t n, const double c[3], double r)
{
    size_t m = 0, cap = 4096;
    double *surf = malloc(cap * 3 * sizeof *surf);
    if (!surf) return 0;
    double cmax = fmax(fabs(c[0]), fmax(fabs(c[1]), fabs(c[2])));
    double slack = 1e-9 * r + 4.0 * DBL_EPSILON * cmax;
    for (size_t i = 0; i < n && m < cap; ++i)
        if (dist3(p + 3 * i, c) >= r - slack) {
            for (int k = 0; k < 3; ++k) surf[3 * m + k] = p[3 * i + k] - c[k];
            m++;
        }
    int ok = m > 0;
    for (int t = 0; t < 500 && ok; ++t) {
        double d[3] = {0, 0, 0}, best = -INFINITY;
        if (t < 6) d[t / 2] = t % 2 ? -1.0 : 1.0;
        else rng_unit_vector(d);
        for (size_t i = 0; i < m; ++i) best = fmax(best, dot3(surf + 3 * i, d));
        ok = best >= -slack;
    }
    free(surf);
    return ok;
}

/* Runs three seeds on a big set: containment, agreement between seeds, optimality. Returns
 * the first radius. */
static double check_large(const double *p, size_t n, const char *what)
{
    double r0 = 0.0, c0[3] = {0, 0, 0};
    for (int s = 0; s < 3; ++s) {
        double c[3], r;
        clock_t t0 = clock();
        ENSURE(fm_min_sphere(p, n, seeds[s], c, &r) == 0);
        double secs = (double)(clock() - t0) / CLOCKS_PER_SEC;
        size_t bad = count_outside(p, n, c, r);
        ENSURE_MSG(bad == 0, "%s: %zu of %zu points outside", what, bad, n);
        if (s == 0) {
            r0 = r;
            memcpy(c0, c, sizeof c0);
            ENSURE_MSG(is_optimal(p, n, c, r), "%s: sphere is not minimal", what);
            printf("  %-26s n = %zu  r = %.17g  %.3f s\n", what, n, r, secs);
        }
        ENSURE_MSG(fabs(r - r0) <= 1e-12 * r0, "%s: seed changes radius %.17g -> %.17g", what,
                   r0, r);
        ENSURE_MSG(dist3(c, c0) <= 1e-5 * r0 + 1e-12, "%s: seed moves centre by %g", what,
                   dist3(c, c0));
    }
    return r0;
}

static void test_large_random(void)
{
    size_t n = 100000;
    double *p = malloc(n * 3 * sizeof *p);
    ENSURE(p != NULL);
    if (!p) return;
    for (size_t i = 0; i < 3 * n; ++i) p[i] = rng_uniform(-1.0, 1.0);
    double r = check_large(p, n, "uniform in a cube");
    /* 10^5 points come within ~0.05 of the cube's corners: r is just under the half-diagonal. */
    ENSURE(r <= sqrt(3.0) && r > 0.97 * sqrt(3.0));

    /* A small gaussian cloud far from the origin. */
    for (size_t i = 0; i < 3 * n; ++i) p[i] = 1e6 * (double)(i % 3 + 1) + 1e-2 * rng_gauss();
    check_large(p, n, "gaussian at 1e6");
    free(p);
}

static void test_large_degenerate(void)
{
    size_t n = 100000;
    double *p = malloc(n * 3 * sizeof *p);
    ENSURE(p != NULL);
    if (!p) return;
    /* On a sphere of radius 2: every point is on the answer's surface. */
    const double c[3] = {5, -3, 100};
    for (size_t i = 0; i < n; ++i) {
        double u[3];
        rng_unit_vector(u);
        for (int k = 0; k < 3; ++k) p[3 * i + k] = c[k] + 2.0 * u[k];
    }
    double r = check_large(p, n, "on a sphere");
    ENSURE_NEAR(r, 2.0, 2e-9);

    /* Near that sphere, radii jittered by 1e-8 (relative): the outermost points decide. */
    for (size_t i = 0; i < n; ++i) {
        double u[3], rr = 2.0 * (1.0 + 1e-8 * rng_uniform(-1, 1));
        rng_unit_vector(u);
        for (int k = 0; k < 3; ++k) p[3 * i + k] = c[k] + rr * u[k];
    }
    r = check_large(p, n, "near a sphere");
    ENSURE(r <= 2.0 * (1.0 + 1e-8) + 1e-14 && r >= 2.0 * (1.0 - 1e-8));

    /* On a circle of radius 1.5: all 4-point subsets degenerate. */
    double u[3], v[3];
    rng_plane(u, v);
    for (size_t i = 0; i < n; ++i) {
        double phi = rng_uniform(0, 2 * PI);
        for (int k = 0; k < 3; ++k) p[3 * i + k] = c[k] + 1.5 * (cos(phi) * u[k] + sin(phi) * v[k]);
    }
    r = check_large(p, n, "on a circle");
    ENSURE_NEAR(r, 1.5, 1.5e-9);

    /* On a segment of length 4, many duplicates. */
    for (size_t i = 0; i < n; ++i) {
        double t = (double)(int)(test_uniform(&rng_state) * 1000) / 999.0 * 4.0 - 2.0;
        for (int k = 0; k < 3; ++k) p[3 * i + k] = c[k] + t * u[k];
    }
    r = check_large(p, n, "on a segment");
    ENSURE_NEAR(r, 2.0, 2e-9);

    /* All the same point. */
    for (size_t i = 0; i < n; ++i) memcpy(p + 3 * i, c, sizeof c);
    r = check_large(p, n, "all equal");
    ENSURE(r == 0.0);
    free(p);
}

static void test_million(void)
{
    /* n = 10^6 in a ball: the loops must not recurse on n, and must stay near linear time. */
    size_t n = 1000000;
    double *p = malloc(n * 3 * sizeof *p);
    ENSURE(p != NULL);
    if (!p) return;
    for (size_t i = 0; i < n; ++i) {
        double u[3], s = cbrt(rng_uniform(0, 1));
        rng_unit_vector(u);
        for (int k = 0; k < 3; ++k) p[3 * i + k] = s * u[k];
    }
    double c[3], r;
    clock_t t0 = clock();
    ENSURE(fm_min_sphere(p, n, 42u, c, &r) == 0);
    printf("  %-26s n = %zu  r = %.17g  %.3f s\n", "uniform in a ball", n, r,
           (double)(clock() - t0) / CLOCKS_PER_SEC);
    ENSURE(count_outside(p, n, c, r) == 0);
    ENSURE(r <= 1.0 + 1e-15 && r > 0.999);
    ENSURE(is_optimal(p, n, c, r));
    free(p);
}

int main(void)
{
    RUN_TEST(test_edge_cases);
    RUN_TEST(test_cube_corners);
    RUN_TEST(test_small_random);
    RUN_TEST(test_small_on_sphere);
    RUN_TEST(test_small_near_sphere);
    RUN_TEST(test_small_all_equal);
    RUN_TEST(test_small_collinear);
    RUN_TEST(test_small_coplanar);
    RUN_TEST(test_small_cocircular);
    RUN_TEST(test_small_duplicates);
    RUN_TEST(test_small_regular);
    RUN_TEST(test_large_random);
    RUN_TEST(test_large_degenerate);
    RUN_TEST(test_million);
    return test_result();
}
