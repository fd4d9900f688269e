/* The exporters on plain arrays (include/flockmorph/export.h), without a cache: tets and points
 * to PLY and OBJ re-imported with assimp, VTK's compressed and raw layouts decoded with Python's
 * xml and zlib modules (tests/check_vtk.py), OpenVDB points read back through the adapter. */
#define _POSIX_C_SOURCE 200809L
#include "export.h" /* fm_vdb_points_read */
#include "test_export_helpers.h"
#include "full_disk.h"

#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

enum { NT = 40, NP = 300 };

static uint64_t rng_state = 0x51ed27f3a1c2b9e5ull;

static double uniform(double lo, double hi) { return lo + (hi - lo) * test_uniform(&rng_state); }

static double volume6(const float *t)
{
    double e[3][3];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) e[i][k] = (double)t[3 * (i + 1) + k] - t[k];
    return e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
           e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
}

/* n positively oriented tets scattered over [-20, 20]^3, each about a unit across. */
static void random_tets(float *v, size_t n)
{
    for (size_t t = 0; t < n; t++) {
        float *tv = v + 12 * t;
        double c[3] = {uniform(-20, 20), uniform(-20, 20), uniform(-20, 20)};
        do {
            for (int k = 0; k < 12; k++) tv[k] = (float)(c[k % 3] + uniform(-0.5, 0.5));
        } while (fabs(volume6(tv)) < 1e-3);
        if (volume6(tv) < 0)
            for (int k = 0; k < 3; k++) {
                float tmp = tv[3 + k];
                tv[3 + k] = tv[6 + k], tv[6 + k] = tmp;
            }
    }
}

typedef struct point_set {
    float pos[3 * NP], vel[3 * NP];
    uint32_t ids[NP];
    uint8_t phases[NP];
} point_set;

static void random_points(point_set *p)
{
    for (size_t i = 0; i < NP; i++) {
        for (int k = 0; k < 3; k++) p->pos[3 * i + k] = (float)uniform(-30, 30), p->vel[3 * i + k] = (float)uniform(-5, 5);
        p->ids[i] = (uint32_t)(7 * (NP - i) + 1000); /* not the array order */
        p->phases[i] = (uint8_t)(i % 4);
    }
}

static fm_status write_frame(const fm_export_frame *f, fm_export_format format, const char *name, char *path)
{
    fm_error err = {0};
    export_tmp(path, name);
    remove(path);
    fm_status st = fm_export_frame_write(f, format, NULL, path, &err);
    ENSURE_MSG(st == FM_OK, "%s: %s", name, err.message);
    return st;
}

/* ---------------------------------------------------------------- PLY and OBJ */

static void test_tets_ply_obj_through_assimp(void)
{
    static float v[12 * NT];
    random_tets(v, NT);
    fm_export_frame f = {.n = NT, .tet_vertices = v};
    char path[FM_PATH_MAX];
    if (write_frame(&f, FM_EXPORT_PLY, "formats_tets.ply", path) == FM_OK) export_check_assimp_tets(path, v, NT, 0);
    /* OBJ prints %.9g; assimp's own float parser reads it back to about 1e-7 */
    if (write_frame(&f, FM_EXPORT_OBJ, "formats_tets.obj", path) == FM_OK) export_check_assimp_tets(path, v, NT, 1e-6);
}

static void test_points_ply(void)
{
    static point_set p;
    random_points(&p);
    char path[FM_PATH_MAX];
    fm_export_frame f = {.n = NP, .positions = p.pos, .velocities = p.vel, .ids = p.ids};
    if (write_frame(&f, FM_EXPORT_PLY, "formats_points.ply", path) == FM_OK) {
        export_check_assimp_points(path, p.pos, NP, 0);
        export_check_ply_points(path, p.pos, p.vel, p.ids, NP);
    }
    f.velocities = NULL;
    if (write_frame(&f, FM_EXPORT_PLY, "formats_points_novel.ply", path) == FM_OK)
        export_check_ply_points(path, p.pos, NULL, p.ids, NP);
}

static void test_points_obj(void)
{
    static point_set p;
    random_points(&p);
    char path[FM_PATH_MAX], line[256];
    fm_export_frame f = {.n = NP, .positions = p.pos, .velocities = p.vel, .ids = p.ids};
    if (write_frame(&f, FM_EXPORT_OBJ, "formats_points.obj", path) != FM_OK) return;
    export_check_assimp_points(path, p.pos, NP, 1e-6);
    FILE *fp = fopen(path, "r");
    int v = 0, other = 0;
    while (fp && fgets(line, sizeof line, fp)) v += line[0] == 'v' && line[1] == ' ', other += line[0] != 'v' && line[0] != '#';
    if (fp) fclose(fp);
    ENSURE_MSG(v == NP && other == 0, "%d v lines and %d others", v, other);
}

/* ---------------------------------------------------------------- VTK */

/* Writes what a tet .vtu should hold into expected: the vertices, ids, velocities, phases and
 * groups. */
static void expect_tets(const char *expected, const float *v, const uint32_t *ids, const float *vel,
                        const uint8_t *phases, const uint8_t *groups, size_t n)
{
    export_write_raw(expected, v, 48 * n, 0);
    export_write_raw(expected, ids, 4 * n, 1);
    export_write_raw(expected, vel, 12 * n, 1);
    if (phases) export_write_raw(expected, phases, n, 1);
    if (groups) export_write_raw(expected, groups, n, 1);
}

static void test_vtu_tets(void)
{
    static float v[12 * NT], vel[3 * NT];
    static uint8_t phases[NT], groups[NT];
    random_tets(v, NT);
    uint32_t ids[NT];
    for (int i = 0; i < NT; i++) ids[i] = (uint32_t)i, phases[i] = (uint8_t)(3 - i % 4), groups[i] = (uint8_t)(i % 3);
    for (int i = 0; i < 3 * NT; i++) vel[i] = (float)uniform(-5, 5);
    char path[FM_PATH_MAX], expected[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    fm_export_frame f = {.n = NT, .tet_vertices = v, .velocities = vel, .phases = phases, .groups = groups};
    if (write_frame(&f, FM_EXPORT_VTK, "formats_tets.vtu", path) != FM_OK) return;
    expect_tets(export_tmp(expected, "formats_tets.expected"), v, ids, vel, phases, groups, NT);
    snprintf(args, sizeof args, "vtu '%s' '%s' tets agent_id velocity phase group", path, expected);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    /* the checker can fail: one coordinate off by one ulp, then one velocity */
    uint32_t bits;
    memcpy(&bits, &v[17], 4), bits ^= 1, memcpy(&v[17], &bits, 4);
    expect_tets(expected, v, ids, vel, phases, groups, NT);
    ENSURE_MSG(export_run_check_vtk(args, 1) == 1, "check_vtk.py missed a changed coordinate");
    memcpy(&bits, &v[17], 4), bits ^= 1, memcpy(&v[17], &bits, 4);
    vel[3 * NT - 2] = -vel[3 * NT - 2];
    expect_tets(expected, v, ids, vel, phases, groups, NT);
    ENSURE_MSG(export_run_check_vtk(args, 1) == 1, "check_vtk.py missed a changed velocity");
}

static void test_vtu_points(void)
{
    static point_set p;
    static float orient[4 * NP], xyzw[4 * NP];
    random_points(&p);
    for (int i = 0; i < NP; i++) { /* w, x, y, z as the cache stores them; the file: x, y, z, w */
        for (int c = 0; c < 4; c++) orient[4 * i + c] = (float)uniform(-1, 1);
        for (int c = 0; c < 4; c++) xyzw[4 * i + c] = orient[4 * i + (c + 1) % 4];
    }
    char path[FM_PATH_MAX], expected[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    fm_export_frame f = {.n = NP, .positions = p.pos, .velocities = p.vel, .ids = p.ids, .orientations = orient};
    if (write_frame(&f, FM_EXPORT_VTK, "formats_points.vtu", path) != FM_OK) return;
    export_write_raw(export_tmp(expected, "formats_points.expected"), p.pos, sizeof p.pos, 0);
    export_write_raw(expected, p.vel, sizeof p.vel, 1);
    export_write_raw(expected, p.ids, sizeof p.ids, 1);
    export_write_raw(expected, xyzw, sizeof xyzw, 1);
    snprintf(args, sizeof args, "vtu '%s' '%s' points velocity id orient", path, expected);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    /* a changed id is caught, and so is the cache's order w, x, y, z */
    p.ids[NP / 2]++;
    export_write_raw(expected, p.pos, sizeof p.pos, 0);
    export_write_raw(expected, p.vel, sizeof p.vel, 1);
    export_write_raw(expected, p.ids, sizeof p.ids, 1);
    export_write_raw(expected, xyzw, sizeof xyzw, 1);
    ENSURE_MSG(export_run_check_vtk(args, 1) == 1, "check_vtk.py missed a changed id");
    p.ids[NP / 2]--;
    export_write_raw(expected, p.pos, sizeof p.pos, 0);
    export_write_raw(expected, p.vel, sizeof p.vel, 1);
    export_write_raw(expected, p.ids, sizeof p.ids, 1);
    export_write_raw(expected, orient, sizeof orient, 1);
    ENSURE_MSG(export_run_check_vtk(args, 1) == 1, "check_vtk.py took orient as w, x, y, z");
}

static long file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

/* Overwrites 8 bytes at offset `at` of the appended data (after its '_') with v, little-endian. */
static void poke_appended(const char *path, long at, uint64_t v)
{
    FILE *fp = fopen(path, "r+b");
    char buf[8192];
    size_t len = fp ? fread(buf, 1, sizeof buf - 1, fp) : 0;
    buf[len] = 0;
    const char *mark = strstr(buf, "<AppendedData encoding=\"raw\">");
    const char *underscore = mark ? strchr(mark, '_') : NULL;
    ENSURE_MSG(underscore != NULL, "%s: no appended data", path);
    unsigned char le[8];
    for (int k = 0; k < 8; k++) le[k] = (unsigned char)(v >> (8 * k));
    if (underscore) ENSURE(fseek(fp, (long)(underscore + 1 - buf) + at, SEEK_SET) == 0 && fwrite(le, 1, 8, fp) == 8);
    if (fp) fclose(fp);
}

/* n tets of a jittered lattice's cubes, 6 to a cube (Kuhn's: corner, then one step along each
 * axis in one of the 6 orders), each positively oriented: neighbours share their vertices, as a
 * tetrahedralised mesh's do, which is what lets a frame's coordinates compress. */
static void lattice_tets(float *v, size_t n)
{
    enum { L = 8 }; /* (L - 1)^3 cubes */
    static float grid[L][L][L][3];
    static const int order[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int i = 0; i < L * L * L; i++) {
        const int at[3] = {i / (L * L), i / L % L, i % L};
        for (int k = 0; k < 3; k++) grid[at[0]][at[1]][at[2]][k] = (float)(at[k] + uniform(-0.2, 0.2));
    }
    for (size_t t = 0; t < n && t < 6 * (L - 1) * (L - 1) * (L - 1); t++) {
        int cube = (int)(t / 6), at[3] = {cube / ((L - 1) * (L - 1)), cube / (L - 1) % (L - 1), cube % (L - 1)};
        float *tv = v + 12 * t;
        for (int j = 0; j < 4; j++) {
            if (j > 0) at[order[t % 6][j - 1]]++;
            memcpy(tv + 3 * j, grid[at[0]][at[1]][at[2]], sizeof(float) * 3);
        }
        if (volume6(tv) < 0)
            for (int k = 0; k < 3; k++) {
                float tmp = tv[3 + k];
                tv[3 + k] = tv[6 + k], tv[6 + k] = tmp;
            }
    }
}

/* Enough tets for several blocks: 2048 make Points three whole 32 KiB blocks (the header's
 * last-block size 0) and connectivity two; the other arrays one partial block. The default
 * (compressed) and raw layouts hold the same values, the compressed file of these lattice tets
 * is well under the raw one (a real frame: a third), and a wrong block size in a header is
 * caught. */
static void test_vtu_blocks(void)
{
    enum { NB = 2048 };
    static float v[12 * NB], vel[3 * NB];
    static uint32_t ids[NB];
    lattice_tets(v, NB);
    for (int i = 0; i < NB; i++) ids[i] = (uint32_t)i;
    for (int i = 0; i < 3 * NB; i++) vel[i] = (float)uniform(-5, 5);
    fm_export_frame f = {.n = NB, .tet_vertices = v, .velocities = vel};
    char zpath[FM_PATH_MAX], rpath[FM_PATH_MAX], expected[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    fm_export_options raw = fm_default_export_options();
    raw.vtk_zlib_level = 0;
    fm_error err = {0};
    if (write_frame(&f, FM_EXPORT_VTK, "formats_blocks.vtu", zpath) != FM_OK) return;
    ENSURE_MSG(fm_export_frame_write(&f, FM_EXPORT_VTK, &raw, export_tmp(rpath, "formats_blocks_raw.vtu"), &err) == FM_OK,
               "%s", err.message);
    expect_tets(export_tmp(expected, "formats_blocks.expected"), v, ids, vel, NULL, NULL, NB);
    snprintf(args, sizeof args, "vtu '%s' '%s' tets agent_id velocity", zpath, expected);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    snprintf(args, sizeof args, "vtu-raw '%s' '%s' tets agent_id velocity", rpath, expected);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    long z = file_size(zpath), r = file_size(rpath);
    ENSURE_MSG(z > 0 && z < 0.6 * r, "compressed %ld bytes against raw %ld", z, r);
    /* Points' header: [3, 32768, 0, sizes]; a block size of 32767 no longer matches the blocks */
    snprintf(args, sizeof args, "vtu '%s' '%s' tets agent_id velocity", zpath, expected);
    poke_appended(zpath, 8, 32767);
    ENSURE_MSG(export_run_check_vtk(args, 1) == 1, "check_vtk.py missed a wrong block size");
    poke_appended(zpath, 8, 32768);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed after the repair", args);
    poke_appended(zpath, 16, 100); /* and a partial last block that is not there */
    ENSURE_MSG(export_run_check_vtk(args, 1) == 1, "check_vtk.py missed a wrong last-block size");
    raw.vtk_zlib_level = 10;
    ENSURE(fm_export_frame_write(&f, FM_EXPORT_VTK, &raw, rpath, &err) == FM_ERR_USAGE);
}

static void test_pvd(void)
{
    char pvd[FM_PATH_MAX], file[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    static const char *const names[] = {"formats_00003.vtu", "formats_00004.vtu", "formats_00009.vtu"};
    const double rate = 30.0, times[] = {3 / rate, 4 / rate, 9 / rate};
    for (int i = 0; i < 3; i++) export_write_raw(export_tmp(file, names[i]), "", 0, 0);
    fm_error err = {0};
    ENSURE_MSG(fm_export_pvd(export_tmp(pvd, "formats.pvd"), names, times, 3, &err) == FM_OK, "%s", err.message);
    snprintf(args, sizeof args, "pvd '%s' 30 3 4 9", pvd);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    snprintf(args, sizeof args, "pvd '%s' 24 3 4 9", pvd); /* wrong times are caught */
    ENSURE_MSG(export_run_check_vtk(args, 1) == 1, "check_vtk.py missed wrong timesteps");
    /* names are XML-escaped */
    const char *odd[] = {"a&b<\"c\">.vtu"};
    ENSURE_MSG(fm_export_pvd(pvd, odd, times, 1, &err) == FM_OK, "%s", err.message);
    char text[1024] = "";
    FILE *fp = fopen(pvd, "r");
    size_t len = fp ? fread(text, 1, sizeof text - 1, fp) : 0;
    if (fp) fclose(fp);
    text[len] = 0;
    ENSURE_MSG(strstr(text, "file=\"a&amp;b&lt;&quot;c&quot;&gt;.vtu\"") != NULL, "%s", text);
    const double bad_time[] = {NAN};
    ENSURE(fm_export_pvd(pvd, odd, bad_time, 1, &err) == FM_ERR_INPUT);
}

/* ---------------------------------------------------------------- VDB */

/* Reads path back and checks it against positions, velocities and ids: each id once; positions
 * to OpenVDB's float offset within a voxel; velocities bit for bit. */
static void check_vdb(const char *path, const float *pos, const float *vel, const uint32_t *ids, size_t n,
                      double *voxel)
{
    size_t m = 0;
    float *rp, *rv;
    int32_t *rid;
    fm_error err = {0};
    fm_status st = fm_vdb_points_read(path, &m, &rp, &rv, &rid, voxel, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    if (st != FM_OK) return;
    ENSURE_MSG(m == n, "%s: %zu points read, %zu written", path, m, n);
    size_t bad_pos = 0, bad_vel = 0, unmatched = 0;
    for (size_t j = 0; j < m && m == n; j++) {
        size_t i = 0;
        while (i < n && (ids ? (int64_t)ids[i] : (int64_t)i) != rid[j]) i++;
        if (i == n) {
            unmatched++;
            continue;
        }
        for (int k = 0; k < 3; k++) {
            double want = pos[3 * i + k], tol = 4 * (*voxel * 0x1p-24 + fabs(want) * 0x1p-24);
            bad_pos += !(fabs(rp[3 * j + k] - want) <= tol);
            bad_vel += memcmp(&rv[3 * j + k], vel ? &vel[3 * i + k] : &(float){0}, 4) != 0;
        }
    }
    ENSURE_MSG(unmatched == 0 && bad_pos == 0 && bad_vel == 0, "%s: %zu ids unmatched, %zu positions and "
               "%zu velocity components differ", path, unmatched, bad_pos, bad_vel);
    free(rp), free(rv), free(rid);
}

static void test_vdb_points(void)
{
    static point_set p;
    random_points(&p);
    char path[FM_PATH_MAX];
    double voxel = 0;
    fm_export_frame f = {.n = NP, .positions = p.pos, .velocities = p.vel, .ids = p.ids};
    if (write_frame(&f, FM_EXPORT_VDB, "formats_points.vdb", path) == FM_OK)
        check_vdb(path, p.pos, p.vel, p.ids, NP, &voxel);
    /* the automatic voxel holds about 8 points: 300 points over 60^3 give a voxel near 60 / (300/8)^(1/3) */
    ENSURE_MSG(voxel > 60 / cbrt(NP / 8.0) / 3 && voxel < 60 / cbrt(NP / 8.0) * 3, "voxel %g", voxel);
    fm_export_options o = fm_default_export_options();
    o.voxel_size = 0.25;
    fm_error err = {0};
    ENSURE_MSG(fm_export_frame_write(&f, FM_EXPORT_VDB, &o, path, &err) == FM_OK, "%s", err.message);
    check_vdb(path, p.pos, p.vel, p.ids, NP, &voxel);
    ENSURE_MSG(voxel == 0.25, "voxel %g, asked for 0.25", voxel);
}

/* Tets become points at their centroids; no ids means ids 0..n-1, no velocities zero. */
static void test_vdb_tets(void)
{
    static float v[12 * NT], c[3 * NT];
    random_tets(v, NT);
    for (int t = 0; t < NT; t++)
        for (int k = 0; k < 3; k++)
            c[3 * t + k] = (float)((v[12 * t + k] + (double)v[12 * t + 3 + k] + v[12 * t + 6 + k] + v[12 * t + 9 + k]) / 4);
    char path[FM_PATH_MAX];
    double voxel = 0;
    fm_export_frame f = {.n = NT, .tet_vertices = v};
    if (write_frame(&f, FM_EXPORT_VDB, "formats_tets.vdb", path) == FM_OK) check_vdb(path, c, NULL, NULL, NT, &voxel);
}

static void test_vdb_errors(void)
{
    float pos[6] = {0, 0, 0, 1, NAN, 0};
    char path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    export_tmp(path, "formats_bad.vdb");
    snprintf(partial, sizeof partial, "%s.partial", path);
    remove(path);
    fm_export_frame f = {.n = 2, .positions = pos};
    fm_error err = {0};
    ENSURE(fm_export_frame_write(&f, FM_EXPORT_VDB, NULL, path, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "agent 1") && strstr(err.message, "non-finite"), "%s", err.message);
    pos[4] = 1e9f; /* a billion units at a millimetre voxel is past int32 index space */
    fm_export_options o = fm_default_export_options();
    o.voxel_size = 1e-3;
    ENSURE(fm_export_frame_write(&f, FM_EXPORT_VDB, &o, path, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "voxel size of at least"), "%s", err.message);
    ENSURE(!export_file_exists(path) && !export_file_exists(partial));
    /* reading something that is not a VDB fails with a message, not an exception */
    size_t n;
    float *rp, *rv;
    int32_t *rid;
    export_write_raw(path, "not a vdb file", 14, 0);
    ENSURE(fm_vdb_points_read(path, &n, &rp, &rv, &rid, NULL, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, path) != NULL, "%s", err.message);
    ENSURE(rp == NULL && n == 0);
    remove(path);
    ENSURE(fm_vdb_points_read(path, &n, &rp, &rv, &rid, NULL, &err) == FM_ERR_INPUT);
}

/* PLY and VDB store ids as int32: a larger id is refused, VTK's UInt32 takes it; tets' point ids
 * (4 id + the vertex) lower the limits of PLY and VTK. */
static void test_id_limits(void)
{
    float pos[6] = {0, 0, 0, 1, 1, 1};
    uint32_t ids[2] = {5, 0x80000000u};
    fm_export_frame f = {.n = 2, .positions = pos, .ids = ids};
    static const fm_export_format formats[] = {FM_EXPORT_PLY, FM_EXPORT_VDB, FM_EXPORT_VTK};
    for (int i = 0; i < 3; i++) {
        char name[64], path[FM_PATH_MAX];
        snprintf(name, sizeof name, "formats_ids.%s", fm_export_extension(formats[i]));
        export_tmp(path, name);
        remove(path);
        fm_error err = {0};
        fm_status st = fm_export_frame_write(&f, formats[i], NULL, path, &err);
        if (formats[i] == FM_EXPORT_VTK) {
            ENSURE_MSG(st == FM_OK, "%s: %s", name, err.message);
        } else {
            ENSURE_MSG(st == FM_ERR_INPUT && strstr(err.message, "2147483648"), "%s: %d %s", name, (int)st, err.message);
            ENSURE(!export_file_exists(path));
        }
    }
    /* Tets: a tet's point ids go to 4 id + 3, so PLY takes ids up to (2^31 - 4) / 4 and VTK (UInt32)
     * up to 2^30 - 1; VDB (one point a tet) the int32 ids. */
    float tets[24] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 2, 0, 0, 3, 0, 0, 2, 1, 0, 2, 0, 1};
    static const struct { fm_export_format format; uint32_t fits, too_big; } tet_cases[] = {
        {FM_EXPORT_PLY, 536870911u, 536870912u}, {FM_EXPORT_VTK, 1073741823u, 1073741824u},
        {FM_EXPORT_VDB, 2147483647u, 2147483648u}};
    for (int i = 0; i < 3; i++) {
        char name[64], path[FM_PATH_MAX];
        snprintf(name, sizeof name, "formats_tet_ids.%s", fm_export_extension(tet_cases[i].format));
        export_tmp(path, name);
        for (int big = 0; big < 2; big++) {
            uint32_t tet_ids[2] = {7, big ? tet_cases[i].too_big : tet_cases[i].fits};
            fm_export_frame t = {.n = 2, .tet_vertices = tets, .ids = tet_ids};
            fm_error err = {0};
            remove(path);
            fm_status st = fm_export_frame_write(&t, tet_cases[i].format, NULL, path, &err);
            if (!big) ENSURE_MSG(st == FM_OK, "%s, id %u: %s", name, tet_ids[1], err.message);
            else ENSURE_MSG(st == FM_ERR_INPUT && !export_file_exists(path) &&
                                (tet_cases[i].format == FM_EXPORT_VDB || strstr(err.message, "point ids")),
                            "%s, id %u: %d %s", name, tet_ids[1], (int)st, err.message);
        }
    }
}

/* ---------------------------------------------------------------- every format */

/* No agents: every format writes a valid empty file. */
static void test_empty_frames(void)
{
    static const fm_export_format formats[] = {FM_EXPORT_PLY, FM_EXPORT_OBJ, FM_EXPORT_VTK, FM_EXPORT_VDB};
    char name[64], path[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    static const float none[12];
    for (int i = 0; i < 4; i++) {
        fm_export_frame f = {.n = 0, .tet_vertices = none};
        snprintf(name, sizeof name, "formats_empty.%s", fm_export_extension(formats[i]));
        write_frame(&f, formats[i], name, path);
    }
    snprintf(args, sizeof args, "vtu '%s' /dev/null tets agent_id", export_tmp(path, "formats_empty.vtu"));
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    double voxel;
    check_vdb(export_tmp(path, "formats_empty.vdb"), NULL, NULL, NULL, 0, &voxel);
}

/* A write that fails (a full disk, tests/helpers/full_disk.h): FM_ERR_IO naming the path, no file
 * left. */
static void test_write_failure(void)
{
    char dir[FM_PATH_MAX];
    if (full_disk_mount(export_tmp(dir, "formats_full_disk"), 0) != 0) return;
    static float v[12 * 2000];
    random_tets(v, 2000);
    static const fm_export_format formats[] = {FM_EXPORT_VTK, FM_EXPORT_VDB, FM_EXPORT_PLY};
    for (int i = 0; i < 3; i++) {
        char name[64], path[FM_PATH_MAX];
        snprintf(name, sizeof name, "formats_full_disk/full.%s", fm_export_extension(formats[i]));
        export_tmp(path, name);
        fm_export_frame f = {.n = 2000, .tet_vertices = v};
        fm_error err = {0};
        fm_status st = fm_export_frame_write(&f, formats[i], NULL, path, &err);
        ENSURE_MSG(st == FM_ERR_IO, "%s: status %d: %s", name, (int)st, err.message);
        ENSURE_MSG(strstr(err.message, path) && strstr(err.message, "No space left"), "%s", err.message);
        ENSURE_MSG(!export_file_exists(path) && files_in(dir) == 1, "%s: a file was left", name);
    }
    full_disk_unmount(dir);
}

/* ---------------------------------------------------------------- point caches */

static fm_pointcache_writer *pc_create(fm_export_format format, size_t points, size_t frames, const char *name,
                                       char *path, fm_error *err)
{
    fm_pointcache_options o = {format, points, frames, 3, 2, 24};
    export_tmp(path, name);
    remove(path);
    return fm_pointcache_create(path, &o, err);
}

/* A short or overlong sequence, a value that is not finite, a full disk: an error naming the
 * file, and nothing under its name; and what the headers refuse up front. */
static void test_pointcache_errors(void)
{
    static const float xyz[6] = {1, 2, 3, 4, 5, 6};
    const float bad[6] = {1, 2, 3, 4, NAN, 6};
    char path[FM_PATH_MAX];
    fm_error err = {0};
    fm_pointcache_writer *w = pc_create(FM_EXPORT_PC2, 2, 2, "pc_short.pc2", path, &err);
    ENSURE(w && fm_pointcache_add(w, xyz, &err) == FM_OK);
    ENSURE_MSG(w && fm_pointcache_finish(w, &err) == FM_ERR_USAGE && strstr(err.message, "1 of the 2"), "%s", err.message);
    ENSURE(!export_file_exists(path));
    w = pc_create(FM_EXPORT_MDD, 2, 1, "pc_long.mdd", path, &err);
    ENSURE(w && fm_pointcache_add(w, xyz, &err) == FM_OK);
    ENSURE(w && fm_pointcache_add(w, xyz, &err) == FM_ERR_USAGE && strstr(err.message, "one too many"));
    ENSURE(w && fm_pointcache_finish(w, &err) == FM_OK && export_file_exists(path));
    w = pc_create(FM_EXPORT_PC2, 2, 1, "pc_nan.pc2", path, &err);
    ENSURE_MSG(w && fm_pointcache_add(w, bad, &err) == FM_ERR_INPUT && strstr(err.message, "point 1 of sample 0"),
               "%s", err.message);
    fm_pointcache_abort(w);
    ENSURE(!export_file_exists(path));
    fm_pointcache_options o = {FM_EXPORT_MDD, 2, 1, 0, 1, 0}; /* MDD needs a frame rate */
    ENSURE(!fm_pointcache_create(export_tmp(path, "pc_rate.mdd"), &o, &err) && err.status == FM_ERR_INPUT);
    o = (fm_pointcache_options){FM_EXPORT_PC2, (size_t)INT32_MAX + 1, 1, 0, 1, 24};
    ENSURE(!fm_pointcache_create(path, &o, &err) && strstr(err.message, "int32"));
    o = (fm_pointcache_options){FM_EXPORT_PLY, 2, 1, 0, 1, 24};
    ENSURE(!fm_pointcache_create(path, &o, &err) && err.status == FM_ERR_USAGE);
    fm_export_frame f = {.n = 2, .positions = xyz};
    ENSURE(fm_export_frame_write(&f, FM_EXPORT_PC2, NULL, path, &err) == FM_ERR_USAGE && strstr(err.message, "sequence"));
    char dir[FM_PATH_MAX];
    if (full_disk_mount(export_tmp(dir, "pc_full_disk"), 0) != 0) return;
    export_tmp(path, "pc_full_disk/full.pc2");
    static float big[3 * 100000];
    fm_pointcache_options full = {FM_EXPORT_PC2, 100000, 1, 0, 1, 24};
    w = fm_pointcache_create(path, &full, &err);
    fm_status st = w ? fm_pointcache_add(w, big, &err) : err.status;
    if (st == FM_OK) st = fm_pointcache_finish(w, &err);
    else fm_pointcache_abort(w);
    ENSURE_MSG(st == FM_ERR_IO && strstr(err.message, "No space left"), "status %d: %s", (int)st, err.message);
    ENSURE(!export_file_exists(path) && files_in(dir) == 1);
    full_disk_unmount(dir);
}

static void test_format_names(void)
{
    ENSURE(fm_export_format_named("PC2") == FM_EXPORT_PC2 && fm_export_format_of_path("a.mdd") == FM_EXPORT_MDD);
    ENSURE(fm_export_format_named("ply") == FM_EXPORT_PLY && fm_export_format_named("OBJ") == FM_EXPORT_OBJ);
    ENSURE(fm_export_format_named("vtk") == FM_EXPORT_VTK && fm_export_format_named("Vdb") == FM_EXPORT_VDB);
    ENSURE(fm_export_format_named("vtu") == FM_EXPORT_UNKNOWN && fm_export_format_named("") == FM_EXPORT_UNKNOWN);
    ENSURE(fm_export_format_of_path("a/b.VTU") == FM_EXPORT_VTK && fm_export_format_of_path("x.vdb") == FM_EXPORT_VDB);
    ENSURE(fm_export_format_of_path("a.vtk") == FM_EXPORT_UNKNOWN && fm_export_format_of_path("a.ply/b") == FM_EXPORT_UNKNOWN);
    ENSURE(!strcmp(fm_export_extension(FM_EXPORT_VTK), "vtu") && !strcmp(fm_export_extension(FM_EXPORT_UNKNOWN), ""));
}

static void test_centroids_and_differences(void)
{
    const float tet[12] = {0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 4};
    float c[3], d[3];
    fm_tet_centroids(tet, 1, c);
    ENSURE(c[0] == 0.25f && c[1] == 0.5f && c[2] == 1.0f);
    const float a[3] = {1, 2, 3}, b[3] = {2, 0, 3.5f};
    fm_finite_difference(a, b, 1, 0.5, d);
    ENSURE(d[0] == 2.0f && d[1] == -4.0f && d[2] == 1.0f);
}

int main(void)
{
    RUN_TEST(test_tets_ply_obj_through_assimp);
    RUN_TEST(test_points_ply);
    RUN_TEST(test_points_obj);
    RUN_TEST(test_vtu_tets);
    RUN_TEST(test_vtu_points);
    RUN_TEST(test_vtu_blocks);
    RUN_TEST(test_pvd);
    RUN_TEST(test_vdb_points);
    RUN_TEST(test_vdb_tets);
    RUN_TEST(test_vdb_errors);
    RUN_TEST(test_id_limits);
    RUN_TEST(test_empty_frames);
    RUN_TEST(test_write_failure);
    RUN_TEST(test_pointcache_errors);
    RUN_TEST(test_format_names);
    RUN_TEST(test_centroids_and_differences);
    return test_result();
}
