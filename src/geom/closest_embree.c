/* Exact closest points on triangle meshes (closest.h): validation, an Embree 3 BVH (C API) that
 * only culls, and the closest point of each candidate triangle computed in double. */
#include "closest.h"

#include <embree3/rtcore.h>

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

struct fm_closest {
    RTCDevice device;
    RTCScene scene;
    int count;
    int want_sign;
    int64_t nv, nt;
    double *v;          /* 3 per vertex, all meshes */
    int32_t *tri;       /* 3 per triangle, indices into v */
    int64_t *tri_start; /* count + 1: mesh m owns triangles [tri_start[m], tri_start[m + 1]) */
    double *box;        /* 6 per mesh: min xyz, max xyz */
    double *fn;         /* 3 per triangle: unit face normal, outward with want_sign (0 for a zero-area triangle) */
    double *en;         /* want_sign: 9 per triangle: pseudo-normals of its edges (0,1), (1,2), (2,0) */
    double *vn;         /* want_sign: 3 per vertex: angle-weighted pseudo-normal (not normalised) */
    double scale;       /* largest |coordinate| of any vertex */
    char embree_error[256];
};

/* ------------------------------------------------------------------ geometry helpers */

static void sub3(const double *a, const double *b, double *r)
{
    r[0] = a[0] - b[0], r[1] = a[1] - b[1], r[2] = a[2] - b[2];
}
static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void cross3(const double *a, const double *b, double *r)
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

/* Features of a triangle's closest point. */
enum { F_V0 = 0, F_V1 = 1, F_V2 = 2, F_E01 = 3, F_E12 = 4, F_E20 = 5, F_FACE = 6 };

/* Closest point to p on segment a-b; returns the squared distance, *where = 0 (a), 1 (b) or 2. */
static double closest_on_segment(const double *p, const double *a, const double *b, double *c, int *where)
{
    double ab[3], ap[3];
    sub3(b, a, ab);
    sub3(p, a, ap);
    double len2 = dot3(ab, ab), t = len2 > 0 ? dot3(ap, ab) / len2 : 0;
    if (!(t > 0)) t = 0, *where = 0;
    else if (t >= 1) t = 1, *where = 1;
    else *where = 2;
    for (int k = 0; k < 3; k++) c[k] = *where == 0 ? a[k] : *where == 1 ? b[k] : a[k] + t * ab[k];
    double d[3];
    sub3(p, c, d);
    return dot3(d, d);
}

/* Closest point to p on triangle abc (Ericson, Real-Time Collision Detection, 5.1.5), its
 * feature, and the squared distance. Degenerate triangles fall back to their three edges. */
static double closest_on_triangle(const double *p, const double *a, const double *b, const double *c,
                                  double *out, int *feature)
{
    double ab[3], ac[3], ap[3], bp[3], cp[3], d[3];
    *feature = F_V0;
    memcpy(out, a, sizeof(double) * 3);
    sub3(b, a, ab);
    sub3(c, a, ac);
    sub3(p, a, ap);
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        memcpy(out, a, sizeof(double) * 3), *feature = F_V0;
        goto done;
    }
    sub3(p, b, bp);
    double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        memcpy(out, b, sizeof(double) * 3), *feature = F_V1;
        goto done;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0 && d1 - d3 > 0) {
        double t = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++) out[k] = a[k] + t * ab[k];
        *feature = F_E01;
        goto done;
    }
    sub3(p, c, cp);
    double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        memcpy(out, c, sizeof(double) * 3), *feature = F_V2;
        goto done;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0 && d2 - d6 > 0) {
        double t = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++) out[k] = a[k] + t * ac[k];
        *feature = F_E20;
        goto done;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0 && (d4 - d3) + (d5 - d6) > 0) {
        double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) out[k] = b[k] + t * (c[k] - b[k]);
        *feature = F_E12;
        goto done;
    }
    double sum = va + vb + vc;
    if (sum > 0 && isfinite(sum)) {
        double v = vb / sum, w = vc / sum;
        for (int k = 0; k < 3; k++) out[k] = a[k] + ab[k] * v + ac[k] * w;
        *feature = F_FACE;
        goto done;
    }
    /* Degenerate (zero-area) triangle: the nearest of its edges. */
    {
        static const int ends[3][2] = {{0, 1}, {1, 2}, {2, 0}};
        const double *corner[3] = {a, b, c};
        double best = INFINITY;
        for (int e = 0; e < 3; e++) {
            double q[3];
            int where;
            double dd = closest_on_segment(p, corner[ends[e][0]], corner[ends[e][1]], q, &where);
            if (dd < best) {
                best = dd;
                memcpy(out, q, sizeof q);
                *feature = where == 2 ? F_E01 + e : where == 0 ? ends[e][0] : ends[e][1];
            }
        }
    }
done:
    sub3(p, out, d);
    return dot3(d, d);
}

/* ------------------------------------------------------------------ queries */

typedef struct query {
    const fm_closest *o;
    double p[3];
    double pad;    /* absolute slack for the float BVH */
    int only;      /* restrict to this mesh, or -1 */
    double d2;     /* best squared distance so far */
    int64_t t;     /* its triangle, -1 if none */
    int geom;      /* its mesh */
    int feature;
    double c[3];
} query;

static bool on_primitive(struct RTCPointQueryFunctionArguments *args)
{
    query *q = (query *)args->userPtr;
    const fm_closest *o = q->o;
    if (q->only >= 0 && (int)args->geomID != q->only) return false;
    int64_t t = o->tri_start[args->geomID] + (int64_t)args->primID;
    const int32_t *f = o->tri + 3 * t;
    double c[3];
    int feature;
    double d2 = closest_on_triangle(q->p, o->v + 3 * (int64_t)f[0], o->v + 3 * (int64_t)f[1],
                                    o->v + 3 * (int64_t)f[2], c, &feature);
    if (!(d2 < q->d2 || (d2 == q->d2 && t < q->t))) return false;
    q->d2 = d2, q->t = t, q->geom = (int)args->geomID, q->feature = feature;
    memcpy(q->c, c, sizeof c);
    /* Shrink the search sphere, padded so the float BVH never culls a triangle that is nearer in
       double (float rounding of the point and the vertices is ~6e-8 of the coordinates). */
    float r = nextafterf((float)(sqrt(d2) * (1.0 + 1e-6) + q->pad), INFINITY);
    if (r < args->query->radius) {
        args->query->radius = r;
        return true;
    }
    return false;
}

/* The nearest triangle to p (of mesh `only`, or of any if -1). A finite `hint` is a guess at an
   upper bound of the distance: the search starts with that radius, and is repeated without one if
   nothing within it turns up, so the result is exact either way. */
static void run_query(const fm_closest *o, const double p[3], double pad, int only, double hint, query *q)
{
    q->o = o;
    memcpy(q->p, p, sizeof q->p);
    q->pad = pad, q->only = only;
    for (;;) {
        q->d2 = INFINITY, q->t = -1, q->geom = -1, q->feature = F_FACE;
        struct RTCPointQuery pq;
        pq.x = (float)p[0], pq.y = (float)p[1], pq.z = (float)p[2];
        pq.time = 0.0f;
        pq.radius = isfinite(hint) ? nextafterf((float)(hint * (1.0 + 1e-6) + pad), INFINITY) : INFINITY;
        struct RTCPointQueryContext ctx;
        rtcInitPointQueryContext(&ctx);
        rtcPointQuery(o->scene, &pq, &ctx, on_primitive, q);
        /* Every triangle nearer than the best found was inside the initial sphere. */
        if (!isfinite(hint) || (q->t >= 0 && sqrt(q->d2) <= hint)) return;
        hint = INFINITY;
    }
}

/* The pseudo-normal of the query's closest feature. */
static const double *feature_normal(const fm_closest *o, const query *q)
{
    if (q->feature == F_FACE) return o->fn + 3 * q->t;
    if (q->feature >= F_E01) return o->en + 9 * q->t + 3 * (q->feature - F_E01);
    return o->vn + 3 * (int64_t)o->tri[3 * q->t + q->feature];
}

static double signed_result(const fm_closest *o, const query *q)
{
    double d[3];
    sub3(q->p, q->c, d);
    double dist = sqrt(q->d2);
    return dot3(d, feature_normal(o, q)) < 0 ? -dist : dist;
}

/* A point the queries can take: finite and not beyond 1e30 (NaN fails the test). */
static int query_point_ok(const fm_closest *o, const double p[3])
{
    return o && fabs(p[0]) <= 1e30 && fabs(p[1]) <= 1e30 && fabs(p[2]) <= 1e30;
}

/* The BVH's padding at p: float rounding of the point and of the vertices. */
static double query_pad(const fm_closest *o, const double p[3])
{
    double m = o->scale;
    for (int k = 0; k < 3; k++) m = fmax(m, fabs(p[k]));
    return 1e-6 * m;
}

static void set_nan3(double *x)
{
    if (x) x[0] = x[1] = x[2] = NAN;
}

double fm_closest_point(const fm_closest *o, const double p[3], double hint, double closest[3], int64_t *tri)
{
    if (!query_point_ok(o, p)) {
        set_nan3(closest);
        if (tri) *tri = -1;
        return NAN;
    }
    query best;
    run_query(o, p, query_pad(o, p), -1, hint, &best);
    if (closest) memcpy(closest, best.c, sizeof best.c);
    if (tri) *tri = best.t;
    return sqrt(best.d2);
}

double fm_closest_within(const fm_closest *o, const double p[3], double radius)
{
    if (!query_point_ok(o, p)) return NAN;
    query q;
    q.o = o;
    memcpy(q.p, p, sizeof q.p);
    q.pad = query_pad(o, p), q.only = -1;
    q.d2 = INFINITY, q.t = -1, q.geom = -1, q.feature = F_FACE;
    struct RTCPointQuery pq;
    pq.x = (float)p[0], pq.y = (float)p[1], pq.z = (float)p[2];
    pq.time = 0.0f;
    pq.radius = nextafterf((float)(radius * (1.0 + 1e-6) + q.pad), INFINITY);
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(o->scene, &pq, &ctx, on_primitive, &q);
    return q.t >= 0 && sqrt(q.d2) < radius ? sqrt(q.d2) : INFINITY;
}

double fm_closest_signed(const fm_closest *o, const double p[3], double hint, double closest[3], double normal[3])
{
    if (!query_point_ok(o, p) || !o->want_sign) {
        set_nan3(closest);
        set_nan3(normal);
        return NAN;
    }
    double pad = query_pad(o, p);
    query best, other;
    run_query(o, p, pad, -1, hint, &best);
    double sd = signed_result(o, &best);
    /* The union: p may also be inside another mesh whose surface is farther than the nearest
       triangle (overlapping meshes). Only meshes whose box holds p can contain it. */
    for (int g = 0; g < o->count && o->count > 1; g++) {
        const double *b = o->box + 6 * g;
        if (g == best.geom || p[0] < b[0] || p[1] < b[1] || p[2] < b[2] || p[0] > b[3] ||
            p[1] > b[4] || p[2] > b[5])
            continue;
        run_query(o, p, pad, g, INFINITY, &other);
        if (other.t < 0) continue;
        double s = signed_result(o, &other);
        if (s < sd) sd = s, best = other;
    }

    if (closest) memcpy(closest, best.c, sizeof best.c);
    if (normal) {
        double d[3], len;
        sub3(p, best.c, d);
        len = sqrt(dot3(d, d));
        if (len > 0) {
            double s = sd < 0 ? -1.0 : 1.0;
            for (int k = 0; k < 3; k++) normal[k] = s * d[k] / len;
        } else {
            const double *n = feature_normal(o, &best);
            len = sqrt(dot3(n, n));
            for (int k = 0; k < 3; k++) normal[k] = len > 0 ? n[k] / len : 0.0;
        }
    }
    return sd;
}

const double *fm_closest_face_normal(const fm_closest *o, int64_t t) { return o->fn + 3 * t; }

int64_t fm_closest_first_triangle(const fm_closest *o, int mesh) { return o->tri_start[mesh]; }

fm_closest_soup fm_closest_get_soup(const fm_closest *o)
{
    return (fm_closest_soup){o->v, o->nv, o->tri, o->nt};
}

/* ------------------------------------------------------------------ build */

/* The edge pseudo-normal of an edge is the sum of its two triangles' face normals. */
typedef struct edge_link {
    fm_closest *o;
    int64_t t0; /* the mesh's first triangle in o */
} edge_link;

static void link_edge(int64_t half_a, int64_t half_b, void *user)
{
    const edge_link *l = user;
    int64_t ta = l->t0 + half_a / 3, tb = l->t0 + half_b / 3;
    double *ea = l->o->en + 9 * ta + 3 * (half_a % 3), *eb = l->o->en + 9 * tb + 3 * (half_b % 3);
    for (int k = 0; k < 3; k++) ea[k] = eb[k] = l->o->fn[3 * ta + k] + l->o->fn[3 * tb + k];
}

/* Mesh m must be closed (every edge in exactly two triangles, running opposite ways: the check
   mesh import uses); fills its edge pseudo-normals (face normals must be set). */
static fm_status check_and_link_edges(fm_closest *o, const fm_mesh *mesh, const char *what, int m, fm_error *err)
{
    char name[96];
    snprintf(name, sizeof name, "%s %d", what, m);
    edge_link link = {o, o->tri_start[m]};
    return fm_mesh_pair_edges(mesh, name, link_edge, &link, err);
}

static void on_embree_error(void *user, enum RTCError code, const char *str)
{
    fm_closest *o = user;
    if (!o->embree_error[0]) snprintf(o->embree_error, sizeof o->embree_error, "%s (code %d)", str ? str : "", (int)code);
}

static fm_status build_bvh(fm_closest *o, const fm_mesh *meshes, const char *what, fm_error *err)
{
    o->device = rtcNewDevice(NULL);
    if (!o->device) {
        const enum RTCError e = rtcGetDeviceError(NULL); /* reading it clears it */
        return fm_library_start_failed(err, "Embree's device", (int)e, e == RTC_ERROR_OUT_OF_MEMORY);
    }
    rtcSetDeviceErrorFunction(o->device, on_embree_error, o);
    o->scene = rtcNewScene(o->device);
    for (int m = 0; o->scene && m < o->count; m++) {
        const fm_mesh *mesh = &meshes[m];
        RTCGeometry g = rtcNewGeometry(o->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        if (!g) break;
        float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), (size_t)mesh->nv);
        unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), (size_t)mesh->nt);
        if (vb && ib) {
            for (int64_t i = 0; i < 3 * mesh->nv; i++) vb[i] = (float)mesh->v[i];
            for (int64_t i = 0; i < 3 * mesh->nt; i++) ib[i] = (unsigned)mesh->tri[i];
            rtcCommitGeometry(g);
            rtcAttachGeometryByID(o->scene, g, (unsigned)m);
        }
        rtcReleaseGeometry(g);
        if (!vb || !ib) break;
    }
    if (o->scene) rtcCommitScene(o->scene);
    enum RTCError e = rtcGetDeviceError(o->device);
    if (!o->scene || e != RTC_ERROR_NONE)
        return fm_fail(err, e == RTC_ERROR_OUT_OF_MEMORY ? FM_ERR_MEMORY : FM_ERR_INTERNAL,
                       "Embree failed building the BVH of the %s meshes: %s", what,
                       o->embree_error[0] ? o->embree_error : "unknown error");
    return FM_OK;
}

void fm_closest_destroy(fm_closest *o)
{
    if (!o) return;
    if (o->scene) rtcReleaseScene(o->scene);
    if (o->device) rtcReleaseDevice(o->device);
    fm_free(o->v);
    fm_free(o->tri);
    fm_free(o->tri_start);
    fm_free(o->box);
    fm_free(o->fn);
    fm_free(o->en);
    fm_free(o->vn);
    fm_free(o);
}

fm_status fm_closest_check_mesh(const fm_mesh *mesh, const char *what, int m, fm_error *err)
{
    if (mesh->nv <= 0 || mesh->nt <= 0 || !mesh->v || !mesh->tri)
        return fm_fail(err, FM_ERR_INPUT, "%s %d is empty (%lld vertices, %lld triangles)", what, m,
                       (long long)mesh->nv, (long long)mesh->nt);
    if (mesh->nv > INT32_MAX || mesh->nt > INT32_MAX / 3)
        return fm_fail(err, FM_ERR_INPUT, "%s %d is too large (%lld vertices, %lld triangles)", what, m,
                       (long long)mesh->nv, (long long)mesh->nt);
    for (int64_t i = 0; i < 3 * mesh->nv; i++)
        if (!isfinite(mesh->v[i]))
            return fm_fail(err, FM_ERR_INPUT, "%s %d: vertex %lld is not finite", what, m, (long long)(i / 3));
    for (int64_t t = 0; t < mesh->nt; t++) {
        const int32_t *f = mesh->tri + 3 * t;
        for (int k = 0; k < 3; k++)
            if (f[k] < 0 || f[k] >= mesh->nv)
                return fm_fail(err, FM_ERR_INPUT, "%s %d: triangle %lld refers to vertex %d of %lld",
                               what, m, (long long)t, f[k], (long long)mesh->nv);
        if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2])
            return fm_fail(err, FM_ERR_INPUT, "%s %d: triangle %lld is degenerate (a repeated vertex)",
                           what, m, (long long)t);
    }
    return FM_OK;
}

/* +1 if the closed mesh encloses positive volume (counter-clockwise seen from outside), else -1;
   the signed volume is taken about the first vertex for accuracy. */
static double mesh_orientation(const fm_mesh *mesh)
{
    double vol = 0;
    const double *origin = mesh->v;
    for (int64_t t = 0; t < mesh->nt; t++) {
        double a[3], b[3], c[3], n[3];
        sub3(mesh->v + 3 * (int64_t)mesh->tri[3 * t], origin, a);
        sub3(mesh->v + 3 * (int64_t)mesh->tri[3 * t + 1], origin, b);
        sub3(mesh->v + 3 * (int64_t)mesh->tri[3 * t + 2], origin, c);
        cross3(b, c, n);
        vol += dot3(a, n);
    }
    return vol < 0 ? -1.0 : 1.0;
}

/* Copies mesh m to o at vertex v0 and triangle t0 with its box, its unit face normals (times
   orient) and, when want_sign, its angle-weighted vertex pseudo-normals. */
static void gather_mesh(fm_closest *o, const fm_mesh *mesh, int m, int64_t v0, int64_t t0, double orient)
{
    double *box = o->box + 6 * m;
    for (int k = 0; k < 3; k++) box[k] = INFINITY, box[3 + k] = -INFINITY;
    for (int64_t i = 0; i < mesh->nv; i++)
        for (int k = 0; k < 3; k++) {
            double x = mesh->v[3 * i + k];
            o->v[3 * (v0 + i) + k] = x;
            box[k] = fmin(box[k], x), box[3 + k] = fmax(box[3 + k], x);
            o->scale = fmax(o->scale, fabs(x));
        }
    for (int64_t t = 0; t < mesh->nt; t++) {
        const int32_t *f = mesh->tri + 3 * t;
        int32_t *g = o->tri + 3 * (t0 + t);
        for (int k = 0; k < 3; k++) g[k] = (int32_t)(v0 + f[k]);
        const double *p[3] = {o->v + 3 * (int64_t)g[0], o->v + 3 * (int64_t)g[1], o->v + 3 * (int64_t)g[2]};
        double e1[3], e2[3], n[3];
        sub3(p[1], p[0], e1);
        sub3(p[2], p[0], e2);
        cross3(e1, e2, n);
        double len = sqrt(dot3(n, n));
        double *fn = o->fn + 3 * (t0 + t);
        for (int k = 0; k < 3; k++) fn[k] = len > 0 ? orient * n[k] / len : 0.0;
        for (int k = 0; o->want_sign && k < 3; k++) { /* angle-weighted vertex normals */
            double u[3], w[3], x[3];
            sub3(p[(k + 1) % 3], p[k], u);
            sub3(p[(k + 2) % 3], p[k], w);
            cross3(u, w, x);
            double angle = atan2(sqrt(dot3(x, x)), dot3(u, w));
            double *vn = o->vn + 3 * (int64_t)g[k];
            for (int j = 0; j < 3; j++) vn[j] += angle * fn[j];
        }
    }
}

/* Copies the meshes into one vertex and triangle array with boxes and face normals; with
   want_sign, normals are oriented outward (an inside-out mesh is flipped) and the vertex and edge
   pseudo-normals are built. */
static fm_status gather(fm_closest *o, const fm_mesh *meshes, const char *what, fm_error *err)
{
    int64_t nv = 0, nt = 0;
    for (int m = 0; m < o->count; m++) nv += meshes[m].nv, nt += meshes[m].nt;
    if (nv > INT32_MAX || nt > INT32_MAX / 3)
        return fm_fail(err, FM_ERR_INPUT, "the %s meshes are too large (%lld vertices, %lld triangles)", what,
                       (long long)nv, (long long)nt);
    o->nv = nv, o->nt = nt;
    o->v = fm_alloc(sizeof(double) * 3 * (size_t)nv);
    o->tri = fm_alloc(sizeof(int32_t) * 3 * (size_t)nt);
    o->fn = fm_alloc(sizeof(double) * 3 * (size_t)nt);
    o->tri_start = fm_alloc(sizeof(int64_t) * ((size_t)o->count + 1));
    o->box = fm_alloc(sizeof(double) * 6 * (size_t)o->count);
    if (o->want_sign) {
        o->vn = fm_alloc(sizeof(double) * 3 * (size_t)nv);
        o->en = fm_alloc(sizeof(double) * 9 * (size_t)nt);
    }
    if (!o->v || !o->tri || !o->fn || !o->tri_start || !o->box || (o->want_sign && (!o->vn || !o->en)))
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for %lld %s triangles", (long long)nt, what);

    int64_t v0 = 0, t0 = 0;
    for (int m = 0; m < o->count; m++) {
        const fm_mesh *mesh = &meshes[m];
        o->tri_start[m] = t0;
        gather_mesh(o, mesh, m, v0, t0, o->want_sign ? mesh_orientation(mesh) : 1.0);
        if (o->want_sign) {
            fm_status st = check_and_link_edges(o, mesh, what, m, err);
            if (st != FM_OK) return st;
        }
        v0 += mesh->nv, t0 += mesh->nt;
    }
    o->tri_start[o->count] = t0;
    return FM_OK;
}

fm_closest *fm_closest_build(const fm_mesh *meshes, int count, const char *what, int want_sign, fm_error *err)
{
    if (count <= 0 || !meshes) {
        fm_fail(err, FM_ERR_INPUT, "no %s meshes given (count %d)", what, count);
        return NULL;
    }
    for (int m = 0; m < count; m++)
        if (fm_closest_check_mesh(&meshes[m], what, m, err) != FM_OK) return NULL;
    fm_closest *o = fm_alloc(sizeof *o);
    if (!o) {
        fm_fail(err, FM_ERR_MEMORY, "out of memory for the %s meshes", what);
        return NULL;
    }
    o->count = count;
    o->want_sign = want_sign != 0;
    fm_status st = gather(o, meshes, what, err);
    if (st == FM_OK) st = build_bvh(o, meshes, what, err);
    if (st != FM_OK) {
        fm_closest_destroy(o);
        return NULL;
    }
    return o;
}
