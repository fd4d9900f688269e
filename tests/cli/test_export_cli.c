/* `flockmorph export` on caches made here, whose agents move on known quadratic paths: a tet
 * cache (format 1), point caches with and without velocity and ids, and a tet cache with phases
 * (format 3). File names and counts for every --frames form, PLY/OBJ sequences re-imported with
 * assimp, VTK (compressed) decoded with Python's xml and zlib modules (tests/check_vtk.py): the
 * tets' centroid velocities and a flock's orient too, VDB read back with the cache's or the
 * finite-difference velocities, byte-identical files for any thread count, and
 * the usage and I/O errors. */
#define _POSIX_C_SOURCE 200809L
#include "export.h" /* fm_vdb_points_read */
#include "test_export_helpers.h"

#include <dirent.h>
#include <jansson.h>
#include <stdint.h>
#include <unistd.h>

enum { AGENTS = 30, FRAMES = 9 };
#define FRAMES_TEXT "9 frames" /* as the error messages count them */
#define RATE 12.0

/* What a test cache holds; every cache has AGENTS agents and FRAMES frames at RATE. */
typedef struct test_cache {
    const char *name;
    int tets;          /* tet vertices, else positions */
    int velocity, ids, phases, orientation;
    char path[FM_PATH_MAX];
    int groups;        /* a shot's group attribute */
} test_cache;

static test_cache g_tets = {"seq.fmc", 1, 0, 0, 0, 0, "", 0};            /* format 1, as fm_cache_writer_create */
static test_cache g_points = {"points.fmc", 0, 1, 1, 0, 0, "", 0};       /* position, velocity, id */
static test_cache g_bare_points = {"bare.fmc", 0, 0, 0, 0, 0, "", 0};    /* position only */
static test_cache g_phased_tets = {"phased.fmc", 1, 0, 0, 1, 0, "", 0}; /* tet vertices and phase */
static test_cache g_flock = {"flock.fmc", 0, 1, 1, 1, 1, "", 0};       /* a shape flock's five attributes */
static test_cache g_flock_shot = {"flock_shot.fmc", 0, 1, 1, 1, 1, "", 1}; /* and a shot's group */
static test_cache g_id_tets = {"idtets.fmc", 1, 0, 1, 1, 0, "", 1};    /* tet vertices, id, phase, group */
static test_cache g_obstacle_tets = {"obst/shot.fmc", 1, 0, 0, 0, 0, "", 0}; /* with obstacles.ply beside it */
static const char *g_cache = g_tets.path;

static float g_frames[FRAMES][12 * AGENTS], g_pos[FRAMES][3 * AGENTS], g_vel[FRAMES][3 * AGENTS];
static uint32_t g_ids[AGENTS];
static uint8_t g_phase[FRAMES][AGENTS], g_group[FRAMES][AGENTS];
static float g_orient[FRAMES][4 * AGENTS]; /* unit quaternions w, x, y, z */
static char g_err[1 << 14], g_out[1 << 14]; /* the last command's stderr and stdout */

/* ---------------------------------------------------------------- the caches */

/* Agent i's position (a tet's centroid) at time t: c0 + v t + a t^2 / 2, so the central difference
 * at an inner frame is exactly v + a t there, and the one-sided ones are off by a dt / 2. */
static void motion(int i, double c0[3], double v[3], double a[3])
{
    for (int k = 0; k < 3; k++) {
        c0[k] = 3.0 * (i % 5) - 6 + k + 0.25 * (i / 5);
        v[k] = 0.5 * ((i * 7 + k * 3) % 11) - 2.5;
        a[k] = 0.2 * ((i * 5 + k) % 7) - 0.6;
    }
}

static void make_frames(void)
{
    static const double shape[12] = {0, 0, 0, 0.4, 0, 0, 0, 0.4, 0, 0, 0, 0.4}; /* positive volume, mean 0.1 */
    for (int f = 0; f < FRAMES; f++) {
        double t = f / RATE;
        for (int i = 0; i < AGENTS; i++) {
            double c0[3], v[3], a[3];
            motion(i, c0, v, a);
            for (int j = 0; j < 12; j++)
                g_frames[f][12 * i + j] = (float)(c0[j % 3] + v[j % 3] * t + 0.5 * a[j % 3] * t * t + shape[j] - 0.1);
            for (int k = 0; k < 3; k++) {
                g_pos[f][3 * i + k] = (float)(c0[k] + v[k] * t + 0.5 * a[k] * t * t);
                g_vel[f][3 * i + k] = (float)(v[k] + a[k] * t);
            }
            g_phase[f][i] = (uint8_t)((i + f) % 4);
            g_group[f][i] = (uint8_t)(f >= FRAMES / 2) + (uint8_t)(i % 2); /* groups 0, 1 and 2 */
            double q[4] = {1.0 + 0.1 * f, 0.3 * (i % 3) - 0.3, 0.2 * (i % 5) - 0.4, 0.1 * (f % 4) + 0.05}, len = 0;
            for (int c = 0; c < 4; c++) len += q[c] * q[c];
            for (int c = 0; c < 4; c++) g_orient[f][4 * i + c] = (float)(q[c] / sqrt(len));
        }
    }
    for (int i = 0; i < AGENTS; i++) g_ids[i] = (uint32_t)(100 + 3 * (AGENTS - i)); /* not the agent order */
}

static const void *attr_data(fm_cache_attr attr, int frame)
{
    switch (attr) {
    case FM_ATTR_TET_VERTICES: return g_frames[frame];
    case FM_ATTR_POSITION: return g_pos[frame];
    case FM_ATTR_VELOCITY: return g_vel[frame];
    case FM_ATTR_ID: return g_ids;
    case FM_ATTR_ORIENTATION: return g_orient[frame];
    case FM_ATTR_GROUP: return g_group[frame];
    default: return g_phase[frame];
    }
}

static void write_cache(test_cache *c)
{
    fm_cache_attr attrs[6];
    int count = 0;
    attrs[count++] = c->tets ? FM_ATTR_TET_VERTICES : FM_ATTR_POSITION;
    if (c->velocity) attrs[count++] = FM_ATTR_VELOCITY;
    if (c->orientation) attrs[count++] = FM_ATTR_ORIENTATION;
    if (c->ids) attrs[count++] = FM_ATTR_ID;
    if (c->phases) attrs[count++] = FM_ATTR_PHASE;
    if (c->groups) attrs[count++] = FM_ATTR_GROUP;
    fm_error err = {0};
    fm_cache_options o = fm_default_cache_options();
    export_tmp(c->path, c->name);
    fm_cache_writer *w = c == &g_tets ? fm_cache_writer_create(c->path, AGENTS, RATE, 1, &err)
                                      : fm_cache_writer_create_attrs(c->path, AGENTS, RATE, attrs, count, &o, &err);
    ENSURE_MSG(w != NULL, "%s: %s", c->name, err.message);
    for (int f = 0; w && f < FRAMES; f++) {
        const void *data[6];
        for (int a = 0; a < count; a++) data[a] = attr_data(attrs[a], f);
        ENSURE(fm_cache_writer_add_frame_attrs(w, data, &err) == FM_OK);
    }
    if (w) ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
}

static void make_caches(void)
{
    make_frames();
    write_cache(&g_tets);
    write_cache(&g_points);
    write_cache(&g_bare_points);
    write_cache(&g_phased_tets);
    write_cache(&g_flock);
    write_cache(&g_flock_shot);
    write_cache(&g_id_tets);
    char dir[FM_PATH_MAX];
    mkdir(export_tmp(dir, "obst"), 0777);
    write_cache(&g_obstacle_tets);
}

/* ---------------------------------------------------------------- running the CLI */

static void read_text(const char *path, char *out, size_t size)
{
    FILE *f = fopen(path, "r");
    size_t n = f ? fread(out, 1, size - 1, f) : 0;
    out[n] = 0;
    if (f) fclose(f);
}

/* Runs `flockmorph ARGS`; returns its exit status, and g_out and g_err get its stdout and stderr. */
static int flockmorph_cmd(const char *args)
{
    char err_path[FM_PATH_MAX], out_path[FM_PATH_MAX], cmd[9 * FM_PATH_MAX];
    export_tmp(err_path, "seq_stderr.txt");
    export_tmp(out_path, "seq_stdout.txt");
    snprintf(cmd, sizeof cmd, "'%s' %s >'%s' 2>'%s'", FM_CLI, args, out_path, err_path);
    int status = system(cmd);
    read_text(err_path, g_err, sizeof g_err);
    read_text(out_path, g_out, sizeof g_out);
    return status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* Runs `flockmorph export CACHE ARGS`; returns its exit status. */
static int export_cmd_on(const char *cache, const char *args)
{
    char cmd[6 * FM_PATH_MAX];
    snprintf(cmd, sizeof cmd, "export '%s' %s", cache, args);
    return flockmorph_cmd(cmd);
}

static int export_cmd(const char *args) { return export_cmd_on(g_cache, args); }

/* A fresh, empty scratch directory. */
static char *fresh_dir(char *dir, const char *name)
{
    char cmd[2 * FM_PATH_MAX];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", export_tmp(dir, name));
    ENSURE(system(cmd) == 0);
    return dir;
}

static int compare_names(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* The directory's file names, sorted and joined by spaces. */
static void list_dir(const char *dir, char *out, size_t size)
{
    char *names[256];
    int n = 0;
    DIR *d = opendir(dir);
    for (struct dirent *e; d && (e = readdir(d)) && n < 256;)
        if (e->d_name[0] != '.') names[n++] = strdup(e->d_name);
    if (d) closedir(d);
    qsort(names, (size_t)n, sizeof names[0], compare_names);
    out[0] = 0;
    for (int i = 0; i < n; i++) {
        snprintf(out + strlen(out), size - strlen(out), "%s%s", i ? " " : "", names[i]);
        free(names[i]);
    }
}

/* seq_<first>.ext, seq_<first + step>.ext .. up to last (and seq.pvd, listed first as the sort
 * puts it), joined. */
static void expected_names_step(int first, int last, int step, const char *ext, int pvd, char *out, size_t size)
{
    snprintf(out, size, "%s", pvd ? "seq.pvd" : "");
    for (int k = first; k <= last; k += step)
        snprintf(out + strlen(out), size - strlen(out), "%sseq_%05d.%s", out[0] ? " " : "", k, ext);
}

static void expected_names(int first, int last, const char *ext, int pvd, char *out, size_t size)
{
    expected_names_step(first, last, 1, ext, pvd, out, size);
}

/* ---------------------------------------------------------------- sequences */

static void test_ply_sequence(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], want[4096], path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format ply --frames 2:5 -o '%s'", fresh_dir(dir, "seq_ply"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    expected_names(2, 5, "ply", 0, want, sizeof want);
    ENSURE_MSG(!strcmp(have, want), "files '%s', expected '%s'", have, want);
    for (int k = 2; k <= 5; k++) {
        snprintf(path, sizeof path, "%s/seq_%05d.ply", dir, k);
        export_check_assimp_tets(path, g_frames[k], AGENTS, 0);
    }
}

static void test_obj_sequence(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format obj --frames -2: -o '%s'", fresh_dir(dir, "seq_obj"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    ENSURE_MSG(!strcmp(have, "seq_00007.obj seq_00008.obj"), "files '%s'", have);
    for (int k = 7; k <= 8; k++) {
        snprintf(path, sizeof path, "%s/seq_%05d.obj", dir, k);
        export_check_assimp_tets(path, g_frames[k], AGENTS, 1e-6);
    }
}

/* Every form of --frames names the files it should, and only those. */
static void test_frame_ranges(void)
{
    static const struct { const char *spec; int first, last, step; } cases[] = {
        {"3:", 3, FRAMES - 1, 1}, {":2", 0, 2, 1}, {"4", 4, 4, 1}, {"-3:", FRAMES - 3, FRAMES - 1, 1},
        {"-3:-2", FRAMES - 3, FRAMES - 2, 1}, {":", 0, FRAMES - 1, 1}, {"-1", FRAMES - 1, FRAMES - 1, 1},
        {"0:0", 0, 0, 1}, {NULL, 0, FRAMES - 1, 1}, {"::2", 0, FRAMES - 1, 2}, {"1:7:3", 1, 7, 3},
        {"1:8:3", 1, 7, 3}, {"-4::5", FRAMES - 4, FRAMES - 4, 5}, {"2:2:9", 2, 2, 9}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], want[4096], frames[64] = "";
        fresh_dir(dir, "seq_range");
        if (cases[i].spec) snprintf(frames, sizeof frames, "--frames %s", cases[i].spec);
        snprintf(args, sizeof args, "--format obj %s -o '%s' --quiet", frames, dir);
        ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
        list_dir(dir, have, sizeof have);
        expected_names_step(cases[i].first, cases[i].last, cases[i].step, "obj", 0, want, sizeof want);
        ENSURE_MSG(!strcmp(have, want), "--frames %s: files '%s', expected '%s'", cases[i].spec ? cases[i].spec : "(none)",
                   have, want);
    }
}

/* Agent positions of a frame as the exporter takes them, floats: a point cache's, or the tets'
 * centroids summed as the exporter sums them (fm_tet_centroids). */
static void float_positions(const test_cache *c, int frame, float out[3 * AGENTS])
{
    for (int i = 0; i < 3 * AGENTS; i++) {
        const float *v = g_frames[frame] + 12 * (i / 3) + i % 3;
        out[i] = c->tets ? (float)(0.25 * ((double)v[0] + v[3] + v[6] + v[9])) : g_pos[frame][i];
    }
}

/* The finite difference of the float positions between frames before and after, computed as the
 * exporter computes it, so equal bit for bit. */
static void difference_velocity(const test_cache *c, int before, int after, float out[3 * AGENTS])
{
    static float xb[3 * AGENTS], xa[3 * AGENTS];
    float_positions(c, before, xb), float_positions(c, after, xa);
    for (int i = 0; i < 3 * AGENTS; i++) out[i] = (float)(((double)xa[i] - xb[i]) / ((after - before) / RATE));
}

/* The velocities the exporter derives for frame k of a cache without them: the documented
 * central difference, one-sided at the first and last frames. */
static void exported_velocity(const test_cache *c, int k, float out[3 * AGENTS])
{
    difference_velocity(c, k > 0 ? k - 1 : k, k < FRAMES - 1 ? k + 1 : k, out);
}

/* Frame k of a tet cache as a .vtu must hold it: the tets, agent_id (the cache's ids, or 0 .. n-1),
 * the centroids' velocity (central difference, one-sided at the ends), and phase and group when the
 * cache has them, as cell data, and a point id unique to each point, 4 agent_id + the vertex;
 * checked by check_vtk.py, which decodes the compressed blocks itself. Returns its exit status. With
 * forward set, the velocity expected is the forward difference from frame k - 1 instead, which
 * the checker must refuse. */
static int check_tet_vtu(const test_cache *c, const char *path, int k, int forward)
{
    char expected[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    uint32_t ids[AGENTS];
    static float v[3 * AGENTS];
    for (uint32_t i = 0; i < AGENTS; i++) ids[i] = c->ids ? g_ids[i] : i;
    if (forward) difference_velocity(c, k - 1, k, v);
    else exported_velocity(c, k, v);
    export_write_raw(export_tmp(expected, "tet_vtu.expected"), g_frames[k], sizeof g_frames[k], 0);
    export_write_raw(expected, ids, sizeof ids, 1);
    export_write_raw(expected, v, sizeof v, 1);
    if (c->phases) export_write_raw(expected, g_phase[k], sizeof g_phase[k], 1);
    if (c->groups) export_write_raw(expected, g_group[k], sizeof g_group[k], 1);
    snprintf(args, sizeof args, "vtu '%s' '%s' tets agent_id velocity%s%s", path, expected, c->phases ? " phase" : "",
             c->groups ? " group" : "");
    int rc = export_run_check_vtk(args, forward);
    ENSURE_MSG(forward || rc == 0, "check_vtk.py %s failed", args);
    return rc;
}

static void test_vtk_sequence(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], want[4096];
    char path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format vtk --frames 1:-2 -o '%s'", fresh_dir(dir, "seq_vtk"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    expected_names(1, FRAMES - 2, "vtu", 1, want, sizeof want);
    ENSURE_MSG(!strcmp(have, want), "files '%s', expected '%s'", have, want);
    for (int k = 1; k <= FRAMES - 2; k++) {
        snprintf(path, sizeof path, "%s/seq_%05d.vtu", dir, k);
        check_tet_vtu(&g_tets, path, k, 0);
    }
    /* a wrong velocity is caught: the forward difference is not what the file holds */
    snprintf(path, sizeof path, "%s/seq_%05d.vtu", dir, 4);
    ENSURE_MSG(check_tet_vtu(&g_tets, path, 4, 1) == 1, "check_vtk.py took the forward difference for %s", path);
    snprintf(args, sizeof args, "pvd '%s/seq.pvd' %.17g", dir, RATE);
    for (int k = 1; k <= FRAMES - 2; k++) snprintf(args + strlen(args), sizeof args - strlen(args), " %d", k);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
}

/* A stride: the .pvd lists only the frames written, at their own times. */
static void test_strided_pvd(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], want[4096];
    snprintf(args, sizeof args, "--format vtk --frames 0::4 -o '%s'", fresh_dir(dir, "seq_vtk_stride"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    expected_names_step(0, 8, 4, "vtu", 1, want, sizeof want);
    ENSURE_MSG(!strcmp(have, want), "files '%s', expected '%s'", have, want);
    snprintf(args, sizeof args, "pvd '%s/seq.pvd' %.17g 0 4 8", dir, RATE);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
}

/* ---------------------------------------------------------------- VDB and velocities */

/* Agent i's position in a frame as the cache holds it: its tet's centroid or its position. */
static void position(const test_cache *c, int frame, int i, double out[3])
{
    for (int k = 0; k < 3; k++) {
        const float *v = g_frames[frame] + 12 * i + k;
        out[k] = c->tets ? 0.25 * ((double)v[0] + v[3] + v[6] + v[9]) : g_pos[frame][3 * i + k];
    }
}

/* The agent whose id this is, or -1. */
static int agent_of(const test_cache *c, int32_t id)
{
    for (int i = 0; i < AGENTS; i++)
        if ((c->ids ? (int64_t)g_ids[i] : i) == id) return i;
    return -1;
}

/* How far one VDB point is from what it should be, as the worst so far in w[]: its position;
 * then its velocity against the cache's (bits), or against the central difference of the
 * cache's positions (one-sided at frames 0 and FRAMES - 1), in units of its float tolerance,
 * and against the motion's own velocity (v + a t inside, a dt / 2 off at the ends). */
static void compare_point(const test_cache *c, int k, int i, const float p[3], const float v[3], double w[3])
{
    int before = k > 0 ? k - 1 : k, after = k < FRAMES - 1 ? k + 1 : k;
    double x[3], xb[3], xa[3], c0[3], mv[3], ma[3], t = k / RATE;
    position(c, k, i, x), position(c, before, i, xb), position(c, after, i, xa);
    motion(i, c0, mv, ma);
    for (int d = 0; d < 3; d++) {
        w[0] = fmax(w[0], fabs(p[d] - x[d]));
        if (c->velocity) {
            w[1] = fmax(w[1], memcmp(&v[d], &g_vel[k][3 * i + d], 4) ? INFINITY : 0);
            continue;
        }
        double fd = (xa[d] - xb[d]) * RATE / (after - before);
        /* the exporter's positions are floats: each off by up to half an ulp (2^-24 relative) */
        double fd_tol = (fabs(xa[d]) + fabs(xb[d])) * 0x1p-24 * RATE / (after - before) + fabs(fd) * 1e-6;
        double exact = mv[d] + ma[d] * t + (before == k ? 0.5 : after == k ? -0.5 : 0.0) * ma[d] / RATE;
        w[1] = fmax(w[1], fabs(v[d] - fd) / fd_tol);
        w[2] = fmax(w[2], fabs(v[d] - exact));
    }
}

/* Reads a .vdb of frame k of cache c and checks every point: each id once, positions,
 * velocities (compare_point). */
static void check_vdb_frame(const test_cache *c, const char *path, int k)
{
    size_t n;
    float *p, *v;
    int32_t *id;
    double voxel, worst[3] = {0, 0, 0};
    fm_error err = {0};
    fm_status st = fm_vdb_points_read(path, &n, &p, &v, &id, &voxel, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    if (st != FM_OK) return;
    ENSURE_MSG(n == AGENTS, "%s: %zu points", path, n);
    int seen[AGENTS] = {0};
    for (size_t j = 0; j < n && n == AGENTS; j++) {
        int i = agent_of(c, id[j]);
        ENSURE_MSG(i >= 0 && !seen[i], "%s: id %d unknown or repeated", path, id[j]);
        if (i < 0 || seen[i]++) continue;
        compare_point(c, k, i, p + 3 * j, v + 3 * j, worst);
    }
    /* positions are floats (|x| < 16: 1e-6) stored by OpenVDB relative to their voxel */
    ENSURE_MSG(worst[0] <= 2e-6 + voxel * 1e-6, "%s: a position is %g from the cache's", path, worst[0]);
    ENSURE_MSG(worst[1] <= 1, "%s: a velocity is %g times the tolerance from the expected one", path, worst[1]);
    /* float positions (ulp 1e-6 at |x| < 16) over 2 dt = 1/6 s: at most ~2e-5 */
    ENSURE_MSG(worst[2] <= 1e-4, "%s: a velocity is %g from the motion's", path, worst[2]);
    free(p), free(v), free(id);
}

static void test_vdb_sequence(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], want[4096], path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format vdb -o '%s'", fresh_dir(dir, "seq_vdb"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    expected_names(0, FRAMES - 1, "vdb", 0, want, sizeof want);
    ENSURE_MSG(!strcmp(have, want), "files '%s', expected '%s'", have, want);
    for (int k = 0; k < FRAMES; k++) {
        snprintf(path, sizeof path, "%s/seq_%05d.vdb", dir, k);
        check_vdb_frame(&g_tets, path, k);
    }
    /* one frame alone has the same velocities (the difference spans the cache, not the range) */
    snprintf(args, sizeof args, "--format vdb --frames 4 -o '%s' --voxel 0.5", fresh_dir(dir, "seq_vdb1"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/seq_00004.vdb", dir);
    check_vdb_frame(&g_tets, path, 4);
    size_t n;
    float *p, *v;
    int32_t *id;
    double voxel = 0;
    fm_error err = {0};
    if (fm_vdb_points_read(path, &n, &p, &v, &id, &voxel, &err) == FM_OK) free(p), free(v), free(id);
    ENSURE_MSG(voxel == 0.5, "--voxel 0.5 gave voxel %g", voxel);
}

/* ---------------------------------------------------------------- the single-file form */

static void test_single_file(void)
{
    char path[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    snprintf(args, sizeof args, "-o '%s'", export_tmp(path, "seq_last.ply"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    export_check_assimp_tets(path, g_frames[FRAMES - 1], AGENTS, 0);
    snprintf(args, sizeof args, "-o '%s' --frame 0", export_tmp(path, "seq_first.vtu"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    check_tet_vtu(&g_tets, path, 0, 0); /* the first frame: the forward difference to frame 1 */
    snprintf(args, sizeof args, "-o '%s' --frame 0", export_tmp(path, "seq_first.vdb"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    check_vdb_frame(&g_tets, path, 0);
}

/* ---------------------------------------------------------------- point caches and phases */

/* The pscale the exporter gives points without --pscale: render's radius for the last frame. */
static float default_pscale(const test_cache *c)
{
    (void)c; /* every point cache here has the same positions */
    return (float)fm_render_point_radius(g_pos[FRAMES - 1], AGENTS);
}

static void test_point_cache(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], want[4096], path[FM_PATH_MAX + 32], expected[FM_PATH_MAX];
    snprintf(args, sizeof args, "--format ply --frames 1:2 -o '%s'", fresh_dir(dir, "pts_ply"));
    ENSURE_MSG(export_cmd_on(g_points.path, args) == 0, "%s: %s", args, g_err);
    float pscale = default_pscale(&g_points);
    for (int k = 1; k <= 2; k++) {
        snprintf(path, sizeof path, "%s/points_%05d.ply", dir, k);
        export_ply_points e = {g_pos[k], g_vel[k], NULL, 1, 1, pscale, (float)(k / RATE), g_ids, NULL, NULL};
        export_check_ply(path, &e, AGENTS);
        export_check_assimp_points(path, g_pos[k], AGENTS, 0);
    }
    snprintf(args, sizeof args, "--format obj --frames -1 -o '%s'", fresh_dir(dir, "pts_obj"));
    ENSURE_MSG(export_cmd_on(g_points.path, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/points_%05d.obj", dir, FRAMES - 1);
    export_check_assimp_points(path, g_pos[FRAMES - 1], AGENTS, 1e-6);
    snprintf(args, sizeof args, "--format vtk --frames :1 -o '%s'", fresh_dir(dir, "pts_vtk"));
    ENSURE_MSG(export_cmd_on(g_points.path, args) == 0, "%s: %s", args, g_err);
    for (int k = 0; k <= 1; k++) {
        export_write_raw(export_tmp(expected, "pts_vtk.expected"), g_pos[k], sizeof g_pos[k], 0);
        export_write_raw(expected, g_vel[k], sizeof g_vel[k], 1);
        export_write_raw(expected, g_ids, sizeof g_ids, 1);
        snprintf(path, sizeof path, "%s/points_%05d.vtu", dir, k);
        snprintf(args, sizeof args, "vtu '%s' '%s' points velocity id", path, expected);
        ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    }
    snprintf(args, sizeof args, "pvd '%s/points.pvd' %.17g 0 1", dir, RATE);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    snprintf(args, sizeof args, "--format vdb -o '%s'", fresh_dir(dir, "pts_vdb"));
    ENSURE_MSG(export_cmd_on(g_points.path, args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    snprintf(want, sizeof want, "points_00000.vdb");
    ENSURE_MSG(strstr(have, want) && strlen(have) == FRAMES * (strlen(want) + 1) - 1, "files '%s'", have);
    for (int k = 0; k < FRAMES; k++) {
        snprintf(path, sizeof path, "%s/points_%05d.vdb", dir, k);
        check_vdb_frame(&g_points, path, k);
    }
}

/* Positions only: ids 0..n-1 and the velocity from the finite difference, in VDB and PLY. */
static void test_point_cache_without_velocity(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format vdb -o '%s'", fresh_dir(dir, "bare_vdb"));
    ENSURE_MSG(export_cmd_on(g_bare_points.path, args) == 0, "%s: %s", args, g_err);
    for (int k = 0; k < FRAMES; k++) {
        snprintf(path, sizeof path, "%s/bare_%05d.vdb", dir, k);
        check_vdb_frame(&g_bare_points, path, k);
    }
    snprintf(args, sizeof args, "--format ply --frames 0:4 -o '%s'", fresh_dir(dir, "bare_ply"));
    ENSURE_MSG(export_cmd_on(g_bare_points.path, args) == 0, "%s: %s", args, g_err);
    static float v[3 * AGENTS];
    for (int k = 0; k <= 4; k += 4) { /* one-sided, then central */
        exported_velocity(&g_bare_points, k, v);
        snprintf(path, sizeof path, "%s/bare_%05d.ply", dir, k);
        export_ply_points e = {g_pos[k], v, NULL, 1, 1, default_pscale(&g_bare_points), (float)(k / RATE), NULL, NULL, NULL};
        export_check_ply(path, &e, AGENTS);
    }
}

/* A tet cache with phases gives VTK cell data phase beside agent_id; one with ids and groups too. */
static void test_phases_in_vtk(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format vtk --frames 2 -o '%s'", fresh_dir(dir, "phase_vtk"));
    ENSURE_MSG(export_cmd_on(g_phased_tets.path, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/phased_00002.vtu", dir);
    FILE *f = fopen(path, "rb");
    char head[4096] = "";
    size_t len = f ? fread(head, 1, sizeof head - 1, f) : 0;
    if (f) fclose(f);
    head[len] = 0;
    ENSURE_MSG(strstr(head, "Name=\"phase\""), "%s has no phase array", path);
    check_tet_vtu(&g_phased_tets, path, 2, 0);
    /* the cache's own ids (not the agent order), phases and groups: cell data, and point ids from them */
    snprintf(args, sizeof args, "--format vtk --frames 0::8 -o '%s'", fresh_dir(dir, "id_vtk"));
    ENSURE_MSG(export_cmd_on(g_id_tets.path, args) == 0, "%s: %s", args, g_err);
    for (int k = 0; k < FRAMES; k += 8) {
        snprintf(path, sizeof path, "%s/idtets_%05d.vtu", dir, k);
        check_tet_vtu(&g_id_tets, path, k, 0);
    }
}

/* A shape flock's .vtu: point data id, velocity (the cache's), orient (x, y, z, w, as Houdini's
 * and the VDB export's) and phase, bit for bit; the last frame too. */
static void test_flock_vtk(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 32], expected[FM_PATH_MAX];
    snprintf(args, sizeof args, "--format vtk --frames 3:-1:5 -o '%s'", fresh_dir(dir, "flock_vtk"));
    ENSURE_MSG(export_cmd_on(g_flock.path, args) == 0, "%s: %s", args, g_err);
    static float xyzw[4 * AGENTS];
    for (int k = 3; k < FRAMES; k += 5) {
        for (int i = 0; i < 4 * AGENTS; i++) xyzw[i] = g_orient[k][4 * (i / 4) + (i % 4 + 1) % 4];
        export_write_raw(export_tmp(expected, "flock_vtk.expected"), g_pos[k], sizeof g_pos[k], 0);
        export_write_raw(expected, g_vel[k], sizeof g_vel[k], 1);
        export_write_raw(expected, g_ids, sizeof g_ids, 1);
        export_write_raw(expected, xyzw, sizeof xyzw, 1);
        export_write_raw(expected, g_phase[k], sizeof g_phase[k], 1);
        snprintf(path, sizeof path, "%s/flock_%05d.vtu", dir, k);
        snprintf(args, sizeof args, "vtu '%s' '%s' points velocity id orient phase", path, expected);
        ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    }
}

/* ---------------------------------------------------------------- Houdini's conventions */

static float read_f32(const unsigned char *p, int big);
static unsigned char *slurp(const char *path, size_t *size);

/* One file's bytes after its header (the header must be `header` exactly), or NULL. */
static unsigned char *ply_body(const char *path, const char *header, size_t body_bytes)
{
    FILE *f = fopen(path, "rb");
    size_t hl = strlen(header);
    unsigned char *buf = malloc(hl + body_bytes + 1);
    size_t got = f && buf ? fread(buf, 1, hl + body_bytes + 1, f) : 0;
    if (f) fclose(f);
    ENSURE_MSG(got == hl + body_bytes, "%s: %zu bytes, expected %zu", path, got, hl + body_bytes);
    ENSURE_MSG(got >= hl && !memcmp(buf, header, hl), "%s: header %.*s", path, (int)hl, buf ? (char *)buf : "");
    if (got == hl + body_bytes && !memcmp(buf, header, hl)) return memmove(buf, buf + hl, body_bytes);
    free(buf);
    return NULL;
}

/* A flock's point PLY with --name, --start and --pscale: orient as x, y, z, w, pscale, age (the
 * frame's time), id, phase, byte for byte. */
static void test_houdini_ply_points(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format ply --frames 3:5:2 --name 'fl.%%04d.ply' --start 1001 --pscale 0.25 -o '%s'",
             fresh_dir(dir, "houdini_ply"));
    ENSURE_MSG(export_cmd_on(g_flock.path, args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    ENSURE_MSG(!strcmp(have, "fl.1001.ply fl.1003.ply"), "files '%s'", have); /* frames 3 and 5 */
    for (int k = 3; k <= 5; k += 2) {
        snprintf(path, sizeof path, "%s/fl.%04d.ply", dir, 998 + k);
        export_ply_points e = {g_pos[k], g_vel[k], g_orient[k], 1, 1, 0.25f, (float)(k / RATE), g_ids, g_phase[k], NULL};
        export_check_ply(path, &e, AGENTS);
    }
}

/* A shot's flock (a group attribute): the PLY carries `uchar group` after phase, byte for byte, in
 * a frame before and one after the groups change. */
static void test_ply_points_with_groups(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format ply --frames 1:%d:%d --pscale 0.25 -o '%s'", FRAMES - 1, FRAMES - 2,
             fresh_dir(dir, "group_ply"));
    ENSURE_MSG(export_cmd_on(g_flock_shot.path, args) == 0, "%s: %s", args, g_err);
    for (int k = 1; k < FRAMES; k += FRAMES - 2) {
        snprintf(path, sizeof path, "%s/flock_shot_%05d.ply", dir, k);
        export_ply_points e = {g_pos[k], g_vel[k], g_orient[k], 1, 1, 0.25f, (float)(k / RATE), g_ids, g_phase[k],
                               g_group[k]};
        export_check_ply(path, &e, AGENTS);
    }
}

/* v' = R(q) v for a unit quaternion w, x, y, z. */
static void rotate(const float q[4], const double v[3], double out[3])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                      {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                      {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
    for (int i = 0; i < 3; i++) out[i] = r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2];
}

/* --up y: positions and velocities (x, z, -y) exactly; each orientation turns the agent's axes
 * as the rotation turns the world: R(q') e = U R(q) e for e = x and z. */
static void test_up_y(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format ply --frames 4 --up y --pscale 1 -o '%s'", fresh_dir(dir, "up_ply"));
    ENSURE_MSG(export_cmd_on(g_flock.path, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/flock_00004.ply", dir);
    enum { RECORD = 12 + 12 + 16 + 4 + 4 + 4 + 1 };
    char header[2048];
    snprintf(header, sizeof header, "ply\nformat binary_little_endian 1.0\ncomment flockmorph " FM_VERSION_STRING
             " points\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\nproperty float vx\n"
             "property float vy\nproperty float vz\nproperty float orientx\nproperty float orienty\n"
             "property float orientz\nproperty float orientw\nproperty float pscale\nproperty float age\n"
             "property int id\nproperty uchar phase\nend_header\n", AGENTS);
    unsigned char *b = ply_body(path, header, (size_t)RECORD * AGENTS);
    double worst = 0;
    for (int i = 0; b && i < AGENTS; i++) {
        float f[10], q[4];
        memcpy(f, b + RECORD * i, sizeof f);
        const float *p = g_pos[4] + 3 * i, *v = g_vel[4] + 3 * i;
        ENSURE(f[0] == p[0] && f[1] == p[2] && f[2] == -p[1] && f[3] == v[0] && f[4] == v[2] && f[5] == -v[1]);
        q[0] = f[9], q[1] = f[6], q[2] = f[7], q[3] = f[8]; /* the file's x, y, z, w */
        for (int axis = 0; axis < 3; axis += 2) {
            double e[3] = {axis == 0, 0, axis == 2}, was[3], now[3];
            rotate(g_orient[4] + 4 * i, e, was);
            rotate(q, e, now);
            double turned[3] = {was[0], was[2], -was[1]};
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(now[c] - turned[c]));
        }
    }
    ENSURE_MSG(worst < 1e-6, "--up y: an orientation is off by %g", worst);
    free(b);
    /* a point cache turned the same way, numbered from --start */
    snprintf(path, sizeof path, "%s/up.pc2", dir);
    snprintf(args, sizeof args, "--frames 4 --up y --start 1001 -o '%s'", path);
    ENSURE_MSG(export_cmd_on(g_flock.path, args) == 0, "%s: %s", args, g_err);
    size_t size;
    unsigned char *pc = slurp(path, &size);
    ENSURE_MSG(size == 32 + 12 * AGENTS && read_f32(pc + 20, 0) == 1001.0f, "%s: %zu bytes, start %g", path, size,
               size >= 32 ? (double)read_f32(pc + 20, 0) : 0.0);
    for (int i = 0; size == 32 + 12 * AGENTS && i < AGENTS; i++)
        ENSURE(read_f32(pc + 32 + 12 * i + 4, 0) == g_pos[4][3 * i + 2] && read_f32(pc + 32 + 12 * i + 8, 0) == -g_pos[4][3 * i + 1]);
    free(pc);
}

/* Frame k's tet vertex velocities as the export derives them: each vertex's central difference,
 * one-sided at the first and last frames, in double from the float vertices. */
static void vertex_velocity(int k, float out[12 * AGENTS])
{
    int before = k > 0 ? k - 1 : k, after = k < FRAMES - 1 ? k + 1 : k;
    for (int i = 0; i < 12 * AGENTS; i++)
        out[i] = (float)(((double)g_frames[after][i] - g_frames[before][i]) / ((after - before) / RATE));
}

static int compare_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* Tet PLY, read back by its header alone: each vertex its position, its own velocity and an id
 * unique to it (4 x the tet's id + the vertex); each face its tet's agent_id, phase and group. */
static void check_tet_ply(const test_cache *c, const char *path, int k)
{
    export_ply_table v, f;
    char names[512];
    if (export_ply_read(path, "vertex", &v) || export_ply_read(path, "face", &f)) return;
    export_ply_col_names(&v, names, sizeof names);
    ENSURE_MSG(!strcmp(names, "x y z vx vy vz id"), "%s: vertex properties '%s'", path, names);
    export_ply_col_names(&f, names, sizeof names);
    char want[128];
    snprintf(want, sizeof want, "vertex_indices# vertex_indices0 vertex_indices1 vertex_indices2 agent_id%s%s",
             c->phases ? " phase" : "", c->groups ? " group" : "");
    ENSURE_MSG(!strcmp(names, want), "%s: face properties '%s', expected '%s'", path, names, want);
    ENSURE_MSG(v.rows == 4 * AGENTS && f.rows == 4 * AGENTS && v.cols == 7, "%s: %ld vertices, %ld faces", path, v.rows, f.rows);
    static float vel[12 * AGENTS];
    vertex_velocity(k, vel);
    uint32_t ids[4 * AGENTS];
    for (long r = 0; v.rows == 4 * AGENTS && v.cols == 7 && r < v.rows; r++) {
        const double *row = v.v + 7 * r;
        uint32_t agent = c->ids ? g_ids[r / 4] : (uint32_t)(r / 4);
        for (int j = 0; j < 3; j++) {
            ENSURE_MSG((float)row[j] == g_frames[k][3 * r + j], "%s: vertex %ld's position", path, r);
            ENSURE_MSG((float)row[3 + j] == vel[3 * r + j], "%s: vertex %ld's velocity %.9g, expected %.9g", path, r,
                       row[3 + j], (double)vel[3 * r + j]);
        }
        ids[r] = (uint32_t)row[6];
        ENSURE_MSG(ids[r] == 4 * agent + (uint32_t)(r % 4), "%s: vertex %ld's id %u", path, r, ids[r]);
    }
    qsort(ids, 4 * AGENTS, sizeof ids[0], compare_u32);
    for (int i = 1; i < 4 * AGENTS; i++) ENSURE_MSG(ids[i] != ids[i - 1], "%s: point id %u twice", path, ids[i]);
    int agent_col = export_ply_col(&f, "agent_id"), phase = export_ply_col(&f, "phase"), group = export_ply_col(&f, "group");
    for (long r = 0; f.rows == 4 * AGENTS && agent_col > 0 && r < f.rows; r++) {
        const double *row = f.v + f.cols * r;
        long t = r / 4;
        ENSURE_MSG(row[agent_col] == (c->ids ? g_ids[t] : (double)t), "%s: face %ld's agent_id %g", path, r, row[agent_col]);
        ENSURE_MSG(phase < 0 || row[phase] == g_phase[k][t], "%s: face %ld's phase", path, r);
        ENSURE_MSG(group < 0 || row[group] == g_group[k][t], "%s: face %ld's group", path, r);
        for (int j = 0; j < 3; j++)
            ENSURE_MSG(row[1 + j] == 4 * t + export_tet_faces[r % 4][j], "%s: face %ld's corners", path, r);
    }
    free(v.v), free(f.v);
}

/* Tet PLY with and without the cache's ids, phases and groups, at the first, an inner and the last
 * frame (the velocity's one-sided and central differences). */
static void test_tet_ply_ids_and_phases(void)
{
    const test_cache *caches[] = {&g_tets, &g_phased_tets, &g_id_tets};
    for (int i = 0; i < 3; i++) {
        char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 96], stem[64];
        snprintf(args, sizeof args, "--format ply --frames 0::4 -o '%s'", fresh_dir(dir, "tet_ids"));
        ENSURE_MSG(export_cmd_on(caches[i]->path, args) == 0, "%s: %s", args, g_err);
        snprintf(stem, sizeof stem, "%.*s", (int)(strlen(caches[i]->name) - 4), caches[i]->name);
        for (int k = 0; k < FRAMES; k += 4) {
            snprintf(path, sizeof path, "%s/%s_%05d.ply", dir, stem, k);
            check_tet_ply(caches[i], path, k);
        }
    }
}

/* A shot flock's VDB: group (int32) after phase, each agent's value. */
static void test_vdb_with_groups(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 32], list[512];
    snprintf(args, sizeof args, "--format vdb --frames %d --pscale 0.5 -o '%s'", FRAMES - 1, fresh_dir(dir, "group_vdb"));
    ENSURE_MSG(export_cmd_on(g_flock_shot.path, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/flock_shot_%05d.vdb", dir, FRAMES - 1);
    fm_error err = {0};
    ENSURE_MSG(fm_vdb_points_list_attrs(path, list, sizeof list, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(!strcmp(list, "P:vec3s v:vec3s id:int32 orient:quats pscale:float age:float phase:int32 group:int32"), "%s",
               list);
    size_t n, m;
    float *p, *v, *group;
    int32_t *id;
    int comps;
    if (fm_vdb_points_read(path, &n, &p, &v, &id, NULL, &err) != FM_OK) return;
    ENSURE(fm_vdb_points_read_attr(path, "group", &m, &comps, &group, &err) == FM_OK && m == n && comps == 1);
    for (size_t j = 0; group && j < n; j++) {
        int i = agent_of(&g_flock_shot, id[j]);
        ENSURE_MSG(i >= 0 && group[j] == g_group[FRAMES - 1][i], "id %d: group %g", id[j], i >= 0 ? (double)group[j] : -1.0);
    }
    free(p), free(v), free(id), free(group);
}

/* The VDB's attributes by name and type, as Houdini names them, and their values. */
static void test_houdini_vdb(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 32], list[512];
    snprintf(args, sizeof args, "--format vdb --frames 2 --pscale 0.5 -o '%s'", fresh_dir(dir, "houdini_vdb"));
    ENSURE_MSG(export_cmd_on(g_flock.path, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/flock_00002.vdb", dir);
    fm_error err = {0};
    ENSURE_MSG(fm_vdb_points_list_attrs(path, list, sizeof list, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(!strcmp(list, "P:vec3s v:vec3s id:int32 orient:quats pscale:float age:float phase:int32"), "%s", list);
    size_t n, m;
    float *p, *v, *orient, *pscale, *age, *phase;
    int32_t *id;
    int comps[4];
    fm_status st = fm_vdb_points_read(path, &n, &p, &v, &id, NULL, &err);
    ENSURE_MSG(st == FM_OK && n == AGENTS, "%s", err.message);
    if (st != FM_OK) return;
    ENSURE(fm_vdb_points_read_attr(path, "orient", &m, &comps[0], &orient, &err) == FM_OK && m == n && comps[0] == 4);
    ENSURE(fm_vdb_points_read_attr(path, "pscale", &m, &comps[1], &pscale, &err) == FM_OK && m == n && comps[1] == 1);
    ENSURE(fm_vdb_points_read_attr(path, "age", &m, &comps[2], &age, &err) == FM_OK && m == n && comps[2] == 1);
    ENSURE(fm_vdb_points_read_attr(path, "phase", &m, &comps[3], &phase, &err) == FM_OK && m == n && comps[3] == 1);
    for (size_t j = 0; j < n && orient && pscale && age && phase; j++) {
        int i = agent_of(&g_flock, id[j]);
        ENSURE_MSG(i >= 0, "id %d", id[j]);
        if (i < 0) continue;
        const float *q = g_orient[2] + 4 * i;
        ENSURE_MSG(orient[4 * j] == q[1] && orient[4 * j + 1] == q[2] && orient[4 * j + 2] == q[3] && orient[4 * j + 3] == q[0],
                   "agent %d: orient (%g %g %g %g)", i, (double)orient[4 * j], (double)orient[4 * j + 1],
                   (double)orient[4 * j + 2], (double)orient[4 * j + 3]);
        ENSURE(pscale[j] == 0.5f && age[j] == (float)(2 / RATE) && phase[j] == g_phase[2][i]);
    }
    free(p), free(v), free(id), free(orient), free(pscale), free(age), free(phase);
    /* tets: centroids with each tet's radius as pscale, and phase */
    snprintf(args, sizeof args, "--format vdb --frames 1 -o '%s'", fresh_dir(dir, "houdini_vdb_tets"));
    ENSURE_MSG(export_cmd_on(g_phased_tets.path, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/phased_00001.vdb", dir);
    ENSURE(fm_vdb_points_list_attrs(path, list, sizeof list, &err) == FM_OK);
    ENSURE_MSG(!strcmp(list, "P:vec3s v:vec3s id:int32 pscale:float age:float phase:int32"), "%s", list);
    ENSURE(fm_vdb_points_read_attr(path, "pscale", &m, &comps[0], &pscale, &err) == FM_OK && m == AGENTS);
    /* every test tet is the same shape: vertices at 0.4 e_k about a corner, the centroid 0.1 (1,1,1)
     * from it, so the farthest vertex is sqrt(0.3^2 + 0.1^2 + 0.1^2) away */
    for (size_t j = 0; pscale && j < m; j++)
        ENSURE_MSG(fabs(pscale[j] - sqrt(0.11)) < 1e-5, "tet pscale %g", (double)pscale[j]);
    free(pscale);
}

/* ---------------------------------------------------------------- axes, scale, presets, obstacles */

/* The obstacle beside g_obstacle_tets: one tet whose vertex 0 is where agent 0's vertex 0 is in
 * frame 0, so the two must land on the same point in every export. */
static double g_obstacle[4][3];

static void write_obstacles(void)
{
    static const double others[3][3] = {{1.5, -2.25, 3.0}, {-0.75, 0.5, -1.25}, {0.125, 4.0, 0.25}};
    for (int k = 0; k < 3; k++) g_obstacle[0][k] = g_frames[0][k];
    memcpy(g_obstacle[1], others, sizeof others);
    static const int32_t tri[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    fm_ply_mesh mesh = {"obstacles.meshes[0] tet.obj", &g_obstacle[0][0], 4, tri, 4};
    char path[FM_PATH_MAX];
    fm_error err = {0};
    ENSURE_MSG(fm_export_ply_meshes(&mesh, 1, NULL, export_tmp(path, "obst/obstacles.ply"), &err) == FM_OK, "%s", err.message);
}

/* p in the export's convention: (x, z, -y) for Y-up, then times scale, each rounded to float. */
static void converted(const double p[3], int up_y, double scale, float out[3])
{
    float f[3] = {(float)p[0], (float)p[1], (float)p[2]};
    float turned[3] = {f[0], up_y ? f[2] : f[1], up_y ? -f[1] : f[2]};
    for (int k = 0; k < 3; k++) out[k] = (float)(scale * turned[k]);
}

/* The file's vertices are the obstacle's, converted, in some order; and obstacle vertex 0 is the
 * point `agent` (a vertex of the exported frame). */
static void check_obstacle_vertices(const char *path, const float *vertices, size_t count, int up_y, double scale,
                                    const float agent[3])
{
    ENSURE_MSG(count == 4, "%s: %zu vertices, expected 4", path, count);
    for (int i = 0; count == 4 && i < 4; i++) {
        float want[3];
        converted(g_obstacle[i], up_y, scale, want);
        int seen = 0;
        for (size_t j = 0; j < count; j++) seen |= !memcmp(vertices + 3 * j, want, sizeof want);
        ENSURE_MSG(seen, "%s: obstacle vertex %d (%g %g %g) is not at (%.9g %.9g %.9g)", path, i, g_obstacle[i][0],
                   g_obstacle[i][1], g_obstacle[i][2], (double)want[0], (double)want[1], (double)want[2]);
        if (i == 0)
            ENSURE_MSG(!memcmp(want, agent, sizeof want), "%s: the obstacle's vertex at (%.9g %.9g %.9g), agent 0's "
                       "vertex at (%.9g %.9g %.9g): not the same point", path, (double)want[0], (double)want[1],
                       (double)want[2], (double)agent[0], (double)agent[1], (double)agent[2]);
    }
}

/* A PLY's vertex element as floats x y z (read by its header alone). */
static size_t ply_xyz(const char *path, float *out, size_t cap, const char *columns)
{
    export_ply_table t;
    if (export_ply_read(path, "vertex", &t)) return 0;
    char names[512];
    export_ply_col_names(&t, names, sizeof names);
    ENSURE_MSG(!strcmp(names, columns), "%s: vertex columns '%s', expected '%s'", path, names, columns);
    size_t n = 0;
    for (long r = 0; r < t.rows && n < cap; r++, n++)
        for (int k = 0; k < 3; k++) out[3 * n + k] = (float)t.v[r * t.cols + k];
    free(t.v);
    return n;
}

/* OBJ `v` lines as floats. */
static size_t obj_xyz(const char *path, float *out, size_t cap)
{
    FILE *f = fopen(path, "r");
    char line[256];
    size_t n = 0;
    while (f && n < cap && fgets(line, sizeof line, f))
        if (sscanf(line, "v %f %f %f", out + 3 * n, out + 3 * n + 1, out + 3 * n + 2) == 3) n++;
    if (f) fclose(f);
    return n;
}

/* --preset houdini turns the obstacles with the frames and names the files Houdini's way from
 * 1001; --up y --scale S turns and scales both (OBJ frames: OBJ obstacles); an explicit --up z wins
 * over the preset's; a point cache gets its obstacles beside it; --no-obstacles writes none. */
static void test_obstacles_follow_the_frames(void)
{
    write_obstacles();
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], path[FM_PATH_MAX + 64];
    float frame[3 * 4 * AGENTS], obstacle[3 * 8];
    const char *tet_columns = "x y z vx vy vz id";
    snprintf(args, sizeof args, "--format ply --frames 0:1 --preset houdini -o '%s'", fresh_dir(dir, "obst_houdini"));
    ENSURE_MSG(export_cmd_on(g_obstacle_tets.path, args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    ENSURE_MSG(!strcmp(have, "shot.1001.ply shot.1002.ply shot_obstacles.ply"), "files '%s'", have);
    snprintf(path, sizeof path, "%s/shot.1001.ply", dir);
    ENSURE(ply_xyz(path, frame, 4 * AGENTS, tet_columns) == 4 * AGENTS);
    snprintf(path, sizeof path, "%s/shot_obstacles.ply", dir);
    check_obstacle_vertices(path, obstacle, ply_xyz(path, obstacle, 8, "x y z"), 1, 1.0, frame);

    snprintf(args, sizeof args, "--format obj --frames 0 --up y --scale 2.5 -o '%s'", fresh_dir(dir, "obst_scale"));
    ENSURE_MSG(export_cmd_on(g_obstacle_tets.path, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/shot_00000.obj", dir);
    ENSURE(obj_xyz(path, frame, 4 * AGENTS) == 4 * AGENTS);
    snprintf(path, sizeof path, "%s/shot_obstacles.obj", dir);
    check_obstacle_vertices(path, obstacle, obj_xyz(path, obstacle, 8), 1, 2.5, frame);

    snprintf(args, sizeof args, "--format ply --frames 0 --preset houdini --up z -o '%s'", fresh_dir(dir, "obst_z"));
    ENSURE_MSG(export_cmd_on(g_obstacle_tets.path, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/shot.1001.ply", dir);
    ENSURE(ply_xyz(path, frame, 4 * AGENTS, tet_columns) == 4 * AGENTS);
    snprintf(path, sizeof path, "%s/shot_obstacles.ply", dir);
    check_obstacle_vertices(path, obstacle, ply_xyz(path, obstacle, 8, "x y z"), 0, 1.0, frame);

    /* a point cache (Maya: Y-up, from frame 1) and its obstacles beside it, halved */
    snprintf(path, sizeof path, "%s/anim.pc2", fresh_dir(dir, "obst_pc2"));
    ENSURE(mkdir(dir, 0777) == 0);
    snprintf(args, sizeof args, "--frames 0:2 --preset maya --scale 0.5 -o '%s'", path);
    ENSURE_MSG(export_cmd_on(g_obstacle_tets.path, args) == 0, "%s: %s", args, g_err);
    size_t size;
    unsigned char *pc = slurp(path, &size);
    ENSURE_MSG(size >= 44 && read_f32(pc + 20, 0) == 1.0f, "%s: start frame %g", path, size >= 24 ? (double)read_f32(pc + 20, 0) : -1.0);
    for (int k = 0; k < 3 && size >= 44; k++) frame[k] = read_f32(pc + 32 + 4 * k, 0);
    free(pc);
    snprintf(path, sizeof path, "%s/anim_obstacles.ply", dir);
    check_obstacle_vertices(path, obstacle, ply_xyz(path, obstacle, 8, "x y z"), 1, 0.5, frame);

    snprintf(args, sizeof args, "--format vtk --frames 0 --preset blender --no-obstacles -o '%s'", fresh_dir(dir, "obst_none"));
    ENSURE_MSG(export_cmd_on(g_obstacle_tets.path, args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    ENSURE_MSG(!strcmp(have, "shot.pvd shot_00001.vtu"), "files '%s'", have);
}

/* ---------------------------------------------------------------- run --up, --scale, --preset */

/* cond, or a failure naming the command and its stderr. */
#define ENSURE_EXIT_MSG(cond, args) ENSURE_MSG(cond, "%s: stderr '%s'", args, g_err)

/* An octahedron flies from x = -10 to x = 10; the obstacle, another, stands behind the source with
 * its +x vertex on the source's -x vertex (-11, 0.3, 0.1): a point of the obstacle that is a vertex
 * of an agent in frame 0 (the rest state, where the tets are the source's own). */
static const float SHARED_VERTEX[3] = {-11.0f, 0.3f, 0.1f};

static void write_axes_scene(char scene[FM_PATH_MAX])
{
    char mesh[FM_PATH_MAX];
    FILE *f = fopen(export_tmp(mesh, "axes_octahedron.obj"), "w");
    ENSURE(f != NULL);
    if (!f) return;
    /* +x -x +y -y +z -z, and a face per octant, turned outward */
    fputs("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
          "f 1 3 5\nf 1 6 3\nf 1 5 4\nf 1 4 6\nf 2 5 3\nf 2 3 6\nf 2 4 5\nf 2 6 4\n", f);
    fclose(f);
    f = fopen(export_tmp(scene, "axes_scene.json"), "w");
    ENSURE(f != NULL);
    if (!f) return;
    fputs("{\n  \"source\": {\"mesh\": \"axes_octahedron.obj\", \"translate\": [-10, 0.3, 0.1]},\n"
          "  \"target\": {\"mesh\": \"axes_octahedron.obj\", \"translate\": [10, 0.3, 0.1]},\n"
          "  \"n\": 32, \"time\": {\"frame_limit\": 2},\n"
          "  \"obstacles\": {\"meshes\": [{\"mesh\": \"axes_octahedron.obj\", \"translate\": [-12, 0.3, 0.1]}],\n"
          "                \"voxel\": 0.25}\n}\n", f); /* a coarse distance grid: a quick run */
    fclose(f);
}

/* `flockmorph run SCENE -o TMP/NAME FLAGS` into a fresh folder; dir gets the folder. */
static void run_scene_into(const char *scene, const char *name, const char *flags, char dir[FM_PATH_MAX])
{
    char args[4 * FM_PATH_MAX];
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet --threads 2 %s", scene, fresh_dir(dir, name), flags);
    ENSURE_MSG(flockmorph_cmd(args) == 0, "%s: %s", args, g_err);
}

/* The index of the first point of xyz (count of them) that is p bit for bit, or -1. */
static long find_point(const float *xyz, size_t count, const float p[3])
{
    for (size_t i = 0; i < count; i++)
        if (!memcmp(xyz + 3 * i, p, 3 * sizeof(float))) return (long)i;
    return -1;
}

/* Every point of a (count of them) is within tol (relative, in each coordinate; 0: bit for bit) of
 * one of b's. */
static int points_in(const float *a, const float *b, size_t count, double tol)
{
    for (size_t i = 0; i < count; i++) {
        int seen = 0;
        for (size_t j = 0; j < count && !seen; j++) {
            seen = tol > 0 || !memcmp(a + 3 * i, b + 3 * j, 3 * sizeof(float));
            for (int k = 0; tol > 0 && k < 3; k++) seen &= fabs((double)a[3 * i + k] - b[3 * j + k]) <= tol * fabs(b[3 * j + k]);
        }
        if (!seen) return 0;
    }
    return 1;
}

/* The same points, perhaps in another order (a mesh read through assimp and written again may come
 * out in another vertex order). */
static int same_points(const float *a, const float *b, size_t count, double tol)
{
    return points_in(a, b, count, tol) && points_in(b, a, count, tol);
}

/* The PLY header's line that names the file's axes, or "" (the whole header is text). */
static void axes_line(const char *path, char *out, size_t size)
{
    char header[4096];
    read_text(path, header, sizeof header);
    const char *line = strstr(header, "comment flockmorph axes: ");
    snprintf(out, size, "%.*s", line ? (int)strcspn(line, "\n") : 0, line ? line : "");
}

/* stats.json's "axes" as compact JSON text. */
static void stats_axes(const char *dir, char *out, size_t size)
{
    char path[FM_PATH_MAX + 16];
    snprintf(path, sizeof path, "%s/stats.json", dir);
    json_t *stats = json_load_file(path, 0, NULL);
    char *text = stats ? json_dumps(json_object_get(stats, "axes"), JSON_COMPACT | JSON_PRESERVE_ORDER) : NULL;
    snprintf(out, size, "%s", text ? text : "(none)");
    free(text);
    json_decref(stats);
}

typedef struct axes_run {
    const char *flags, *name;
    int up_y;
    double scale;
    const char *header, *stats;
} axes_run;

static const axes_run AXES_RUNS[] = {
    {"--preset houdini", "axes_houdini", 1, 1.0, "comment flockmorph axes: up y, scale 1",
     "{\"up\":\"y\",\"scale\":1.0,\"preset\":\"houdini\"}"},
    {"--up y --scale 2.5", "axes_y", 1, 2.5, "comment flockmorph axes: up y, scale 2.5",
     "{\"up\":\"y\",\"scale\":2.5,\"preset\":null}"},
};

/* Frame 0 exported with the run's own flags: the agent's vertex `vertex` lands, bit for bit, on the
 * obstacle's `shared` vertex in the run's obstacles.ply; and the export's obstacles, read back from
 * it, are its vertices again. */
static void check_export_meets_run(const axes_run *r, const char *dir, const float *obstacles, long shared, long vertex)
{
    char out[FM_PATH_MAX], args[4 * FM_PATH_MAX], path[FM_PATH_MAX + 64], cache[FM_PATH_MAX + 16];
    float frame[3 * 4 * 64], exported[3 * 6];
    snprintf(cache, sizeof cache, "%s/frames.fmc", dir);
    snprintf(args, sizeof args, "%s --format ply --frames 0 --name f.%%d.ply -o '%s'", r->flags, fresh_dir(out, "axes_export"));
    ENSURE_MSG(export_cmd_on(cache, args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/f.%d.ply", out, strstr(r->flags, "houdini") ? 1001 : 0);
    size_t n = ply_xyz(path, frame, 4 * 64, "x y z vx vy vz id");
    ENSURE_MSG(vertex >= 0 && (size_t)vertex < n && !memcmp(frame + 3 * vertex, obstacles + 3 * shared, 3 * sizeof(float)),
               "%s: the agent's vertex %ld is at (%.9g %.9g %.9g), the run's obstacle vertex at (%.9g %.9g %.9g)", r->flags,
               vertex, (double)frame[3 * vertex], (double)frame[3 * vertex + 1], (double)frame[3 * vertex + 2],
               (double)obstacles[3 * shared], (double)obstacles[3 * shared + 1], (double)obstacles[3 * shared + 2]);
    snprintf(path, sizeof path, "%s/frames_obstacles.ply", out);
    ENSURE_MSG(ply_xyz(path, exported, 6, "x y z") == 6 && same_points(exported, obstacles, 6, 0),
               "%s: the export's obstacles are not the run's", r->flags);
}

/* An export without flags reads the run's obstacles.ply back into the cache's axes: the engine's
 * vertices exactly after a turn, and within a float's rounding after a scale. So does one given, as
 * --obstacles, the OBJ obstacles an export with the run's flags wrote (their axes in a # line). */
static void check_export_in_cache_axes(const axes_run *r, const char *dir, const float engine[3 * 6])
{
    char out[FM_PATH_MAX], obj_dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 64], cache[FM_PATH_MAX + 16];
    float back[3 * 6];
    snprintf(cache, sizeof cache, "%s/frames.fmc", dir);
    snprintf(args, sizeof args, "%s --format obj --frames 0 -o '%s'", r->flags, fresh_dir(obj_dir, "axes_obj"));
    ENSURE_MSG(export_cmd_on(cache, args) == 0, "%s: %s", args, g_err);
    for (int via_obj = 0; via_obj < 2; via_obj++) {
        snprintf(args, sizeof args, "--format ply --frames 0 -o '%s'%s%s%s", fresh_dir(out, "axes_back"),
                 via_obj ? " --obstacles '" : "", via_obj ? obj_dir : "", via_obj ? "/frames_obstacles.obj'" : "");
        ENSURE_MSG(export_cmd_on(cache, args) == 0, "%s: %s", args, g_err);
        snprintf(path, sizeof path, "%s/frames_obstacles.ply", out);
        ENSURE_MSG(ply_xyz(path, back, 6, "x y z") == 6 && same_points(back, engine, 6, r->scale == 1.0 ? 0 : 1.2e-7),
                   "%s, then export%s: the obstacles are not where the plain run's are", r->flags,
                   via_obj ? " of the OBJ obstacles" : "");
    }
}

/* run --preset houdini and run --up y --scale 2.5 write obstacles.ply as export converts frames:
 * each vertex is the engine's turned and scaled (computed here, from a plain run's file), the
 * obstacle's vertex on an agent's vertex lands on that vertex as export puts it, the header and
 * stats.json (and inspect's provenance) name the convention; an export without flags reads the file
 * back into the cache's axes. */
static void test_run_obstacles_in_the_chosen_axes(void)
{
    char scene[FM_PATH_MAX], plain[FM_PATH_MAX], dir[FM_PATH_MAX], path[FM_PATH_MAX + 64], line[256], text[512];
    float engine[3 * 6], written[3 * 6], want[3 * 6];
    write_axes_scene(scene);
    run_scene_into(scene, "axes_plain", "", plain);
    snprintf(path, sizeof path, "%s/obstacles.ply", plain);
    ENSURE(ply_xyz(path, engine, 6, "x y z") == 6);
    axes_line(path, line, sizeof line);
    ENSURE_MSG(!strcmp(line, "comment flockmorph axes: up z, scale 1"), "%s: '%s'", path, line);
    long shared = find_point(engine, 6, SHARED_VERTEX), vertex = -1;
    fm_error err = {0};
    snprintf(path, sizeof path, "%s/frames.fmc", plain);
    fm_cache_reader *reader = fm_cache_open(path, &err);
    ENSURE_MSG(reader && fm_cache_agents(reader) <= 64, "%s", err.message);
    float frame0[3 * 4 * 64];
    if (reader && fm_cache_agents(reader) <= 64 && fm_cache_read_frame(reader, 0, frame0, &err) == FM_OK)
        vertex = find_point(frame0, 4 * fm_cache_agents(reader), SHARED_VERTEX);
    if (reader) fm_cache_close(reader);
    ENSURE_MSG(shared >= 0 && vertex >= 0, "the obstacle's vertex %ld and an agent's %ld at (-11, 0.3, 0.1)", shared, vertex);
    for (size_t r = 0; r < sizeof AXES_RUNS / sizeof AXES_RUNS[0]; r++) {
        const axes_run *run = &AXES_RUNS[r];
        run_scene_into(scene, run->name, run->flags, dir);
        snprintf(path, sizeof path, "%s/obstacles.ply", dir);
        ENSURE(ply_xyz(path, written, 6, "x y z") == 6);
        for (int i = 0; i < 6; i++) converted((const double[3]){engine[3 * i], engine[3 * i + 1], engine[3 * i + 2]},
                                              run->up_y, run->scale, want + 3 * i);
        ENSURE_MSG(!memcmp(written, want, sizeof want), "%s: obstacles.ply is not the plain run's turned and scaled", run->flags);
        axes_line(path, line, sizeof line);
        ENSURE_MSG(!strcmp(line, run->header), "%s: '%s'", run->flags, line);
        stats_axes(dir, text, sizeof text);
        ENSURE_MSG(!strcmp(text, run->stats), "%s: stats.json's axes %s", run->flags, text);
        snprintf(path, sizeof path, "info '%s/frames.fmc'", dir);
        ENSURE(flockmorph_cmd(path) == 0);
        json_t *info = json_loads(g_out, 0, NULL);
        char *axes = json_dumps(json_object_get(json_object_get(info, "provenance"), "axes"), JSON_COMPACT | JSON_PRESERVE_ORDER);
        ENSURE_MSG(axes && !strcmp(axes, run->stats), "%s: inspect's provenance.axes %s", run->flags, axes ? axes : "(none)");
        free(axes), json_decref(info);
        check_export_meets_run(run, dir, written, shared, vertex);
        check_export_in_cache_axes(run, dir, engine);
    }
}

/* render draws a run's obstacles where they stand in the cache's axes, whatever axes obstacles.ply
 * is in: frame 0 of the runs of test_run_obstacles_in_the_chosen_axes (the same cache, obstacles.ply
 * turned, and turned and scaled) renders to the plain run's bytes, and the obstacle is in the
 * picture (without it the image differs). */
static void test_render_reads_run_obstacles_back(void)
{
    static const char *const runs[] = {"axes_plain", "axes_houdini", "axes_y"};
    char png[FM_PATH_MAX + 16], first[FM_PATH_MAX + 16], args[4 * FM_PATH_MAX];
    size_t first_size = 0, size;
    unsigned char *plain = NULL;
    for (int i = 0; i <= 3; i++) {
        const char *run = runs[i < 3 ? i : 0];
        snprintf(png, sizeof png, "%s/%s.png", FM_TEST_TMP, i < 3 ? run : "axes_none");
        snprintf(args, sizeof args, "render '%s/%s/frames.fmc' --frame 0 --size 96x64 -o '%s'%s", FM_TEST_TMP, run, png,
                 i < 3 ? "" : " --no-obstacles");
        ENSURE_MSG(flockmorph_cmd(args) == 0, "%s: %s", args, g_err);
        unsigned char *bytes = slurp(png, &size);
        if (i == 0) plain = bytes, first_size = size, snprintf(first, sizeof first, "%s", png);
        else {
            int same = size == first_size && !memcmp(bytes, plain, size);
            ENSURE_MSG(i < 3 ? same : !same, "%s %s %s", png, i < 3 ? "differs from" : "is the same as", first);
            free(bytes);
        }
    }
    free(plain);
}

/* run's --up, --scale and --preset are checked as export's, naming the flag; an obstacle file whose
 * header names no convention it can undo is an input error naming it, in export and render alike. */
static void test_run_axes_errors(void)
{
    static const struct { const char *flag, *message; } bad[] = {
        {"--up x", "--up wants z (as the cache) or y (Y-up), not 'x'"},
        {"--scale 2e6", "--scale wants a factor from 1e-6 to 1e6, not '2e6'"},
        {"--preset nuke", "--preset wants houdini, maya or blender, not 'nuke'"},
    };
    char scene[FM_PATH_MAX], dir[FM_PATH_MAX], args[4 * FM_PATH_MAX], path[FM_PATH_MAX + 32], bad_ply[FM_PATH_MAX];
    write_axes_scene(scene);
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(args, sizeof args, "run '%s' -o '%s' %s", scene, fresh_dir(dir, "axes_bad"), bad[i].flag);
        ENSURE_EXIT_MSG(flockmorph_cmd(args) == 1 && strstr(g_err, bad[i].message) &&
                            strstr(g_err, "see 'flockmorph help run'"), args);
    }
    snprintf(path, sizeof path, "%s/axes_houdini/obstacles.ply", FM_TEST_TMP);
    size_t size;
    char header[4096];
    read_text(path, header, sizeof header); /* the header is text */
    const char *line = strstr(header, "axes: up y, scale 1");
    unsigned char *ply = slurp(path, &size);
    ENSURE_MSG(line != NULL, "%s has no axes line", path);
    if (line) ply[line - header + 9] = 'q'; /* up y -> up q */
    export_write_raw(export_tmp(bad_ply, "axes_bad.ply"), ply, size, 0);
    free(ply);
    static const char *const commands[] = {"export '%s/axes_houdini/frames.fmc' --obstacles '%s' --frames 0 --format ply -o '%s'",
                                           "render '%s/axes_houdini/frames.fmc' --obstacles '%s' --frame 0 -o '%s/f.png'"};
    for (int i = 0; i < 2; i++) {
        snprintf(args, sizeof args, commands[i], FM_TEST_TMP, bad_ply, fresh_dir(dir, "axes_bad"));
        if (i == 1) mkdir(dir, 0777);
        ENSURE_EXIT_MSG(flockmorph_cmd(args) == 2 && strstr(g_err, "axes_bad.ply: its header line 'comment flockmorph "
                                                                     "axes: up q, scale 1' does not say 'up y' or 'up z'"),
                        args);
    }
}

/* ---------------------------------------------------------------- point caches (PC2, MDD) */

static uint32_t read_u32(const unsigned char *p, int big)
{
    uint32_t v = 0;
    for (int k = 0; k < 4; k++) v |= (uint32_t)p[big ? 3 - k : k] << (8 * k);
    return v;
}

static float read_f32(const unsigned char *p, int big)
{
    uint32_t bits = read_u32(p, big);
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

/* The whole file, malloc'ed; *size its length. */
static unsigned char *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    unsigned char *buf = malloc(1 << 20);
    *size = f && buf ? fread(buf, 1, 1 << 20, f) : 0;
    if (f) fclose(f);
    return buf;
}

/* What a point cache of cache c over frames first, first + step, ... should hold. */
typedef struct pc_expect {
    const test_cache *c;
    int first, step, count;
} pc_expect;

/* Frame k's points as the cache holds them, and how many. */
static const float *pc_points(const test_cache *c, int k, size_t *points)
{
    *points = c->tets ? 4 * AGENTS : AGENTS;
    return c->tets ? g_frames[k] : g_pos[k];
}

/* Every sample equals the cache's frame bit for bit. */
static void check_samples(const char *path, const unsigned char *data, size_t avail, const pc_expect *e, int big)
{
    size_t points;
    pc_points(e->c, 0, &points);
    ENSURE_MSG(avail == (size_t)e->count * 12 * points, "%s: %zu bytes of samples, expected %zu", path, avail,
               (size_t)e->count * 12 * points);
    for (int j = 0; j < e->count && avail == (size_t)e->count * 12 * points; j++) {
        const float *want = pc_points(e->c, e->first + j * e->step, &points);
        for (size_t i = 0; i < 3 * points; i++) {
            float have = read_f32(data + 4 * (j * 3 * points + i), big);
            ENSURE_MSG(!memcmp(&have, &want[i], 4), "%s: sample %d value %zu is %.9g, the cache's %.9g", path, j,
                       i, (double)have, (double)want[i]);
            if (memcmp(&have, &want[i], 4)) return;
        }
    }
}

/* PC2: the header Blender's Mesh Cache modifier reads, then the samples. */
static void check_pc2(const char *path, const pc_expect *e)
{
    size_t size, points;
    unsigned char *b = slurp(path, &size);
    pc_points(e->c, 0, &points);
    ENSURE_MSG(size >= 32 && !memcmp(b, "POINTCACHE2\0", 12), "%s: no PC2 signature", path);
    if (size >= 32) {
        ENSURE(read_u32(b + 12, 0) == 1);
        ENSURE_MSG(read_u32(b + 16, 0) == points, "%s: %u points", path, read_u32(b + 16, 0));
        ENSURE_MSG(read_f32(b + 20, 0) == (float)e->first, "%s: start %g", path, (double)read_f32(b + 20, 0));
        ENSURE_MSG(read_f32(b + 24, 0) == (float)e->step, "%s: sample rate %g", path, (double)read_f32(b + 24, 0));
        ENSURE_MSG(read_u32(b + 28, 0) == (uint32_t)e->count, "%s: %u samples", path, read_u32(b + 28, 0));
        check_samples(path, b + 32, size - 32, e, 0);
    }
    free(b);
}

/* MDD: big-endian frame count, point count, each frame's time in seconds, then the frames. */
static void check_mdd(const char *path, const pc_expect *e)
{
    size_t size, points, head = 8 + 4 * (size_t)e->count;
    unsigned char *b = slurp(path, &size);
    pc_points(e->c, 0, &points);
    ENSURE_MSG(size >= head && read_u32(b, 1) == (uint32_t)e->count && read_u32(b + 4, 1) == points,
               "%s: header says %u frames of %u points", path, size >= 8 ? read_u32(b, 1) : 0,
               size >= 8 ? read_u32(b + 4, 1) : 0);
    for (int j = 0; size >= head && j < e->count; j++)
        ENSURE_MSG(read_f32(b + 8 + 4 * j, 1) == (float)((e->first + j * e->step) / RATE), "%s: time %d is %g",
                   path, j, (double)read_f32(b + 8 + 4 * j, 1));
    if (size >= head) check_samples(path, b + head, size - head, e, 1);
    free(b);
}

static void test_point_caches(void)
{
    static const struct { test_cache *c; const char *options, *name; int first, step, count; } cases[] = {
        {&g_tets, "", "tets.pc2", 0, 1, FRAMES},           /* by extension: every frame */
        {&g_tets, "--frames 1:7:3", "tets.mdd", 1, 3, 3},  /* 1, 4, 7 */
        {&g_points, "--format pc2 --frames ::2", "pts.cache", 0, 2, 5},
        {&g_points, "--format mdd --frames -3:", "pts.mdd", FRAMES - 3, 1, 3},
        {&g_phased_tets, "--frames 2:6:3", "phased.pc2", 2, 3, 2}, /* 6 is off the stride: 2, 5 */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char path[FM_PATH_MAX], args[3 * FM_PATH_MAX];
        export_tmp(path, cases[i].name);
        remove(path);
        snprintf(args, sizeof args, "%s -o '%s'", cases[i].options, path);
        ENSURE_MSG(export_cmd_on(cases[i].c->path, args) == 0, "%s: %s", args, g_err);
        pc_expect e = {cases[i].c, cases[i].first, cases[i].step, cases[i].count};
        int mdd = strstr(cases[i].name, ".mdd") || strstr(cases[i].options, "mdd");
        if (mdd) check_mdd(path, &e);
        else check_pc2(path, &e);
    }
}

/* ---------------------------------------------------------------- threads */

static int same_bytes(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int same = fa && fb, ca, cb;
    while (same && ((ca = getc(fa)) != EOF) | ((cb = getc(fb)) != EOF)) same = ca == cb;
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

/* The files do not depend on the thread count. */
static void test_threads_do_not_change_files(void)
{
    static const char *const formats[] = {"ply", "vtk"};
    for (int f = 0; f < 2; f++) {
        char dirs[3][FM_PATH_MAX], args[3 * FM_PATH_MAX], name[64];
        for (int t = 0; t < 3; t++) {
            snprintf(name, sizeof name, "seq_threads%d", t + 1);
            snprintf(args, sizeof args, "--format %s -o '%s' --threads %d", formats[f], fresh_dir(dirs[t], name), t + 1);
            ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
        }
        for (int k = 0; k < FRAMES; k++) {
            char a[FM_PATH_MAX + 32], b[FM_PATH_MAX + 32];
            snprintf(a, sizeof a, "%s/seq_%05d.%s", dirs[0], k, f ? "vtu" : "ply");
            for (int t = 1; t < 3; t++) {
                snprintf(b, sizeof b, "%s/seq_%05d.%s", dirs[t], k, f ? "vtu" : "ply");
                ENSURE_MSG(same_bytes(a, b), "%s and %s differ", a, b);
            }
        }
    }
}

/* ---------------------------------------------------------------- errors */

/* Exit status `code`, a message holding both words, and nothing written into dir. */
static void expect_failure(const char *args, int code, const char *word1, const char *word2, const char *dir)
{
    int rc = export_cmd(args);
    ENSURE_MSG(rc == code, "export %s: exit %d, expected %d: %s", args, rc, code, g_err);
    ENSURE_MSG(strstr(g_err, word1) && strstr(g_err, word2), "export %s: message '%s' lacks '%s' or '%s'", args,
               g_err, word1, word2);
    char have[4096];
    list_dir(dir, have, sizeof have);
    ENSURE_MSG(!have[0], "export %s left '%s'", args, have);
}

static void test_usage_errors(void)
{
    /* options (%s: the output directory), and two words the message must hold */
    static const struct { const char *options, *word1, *word2; } cases[] = {
        {"--format ply --frames 5:2 -o '%s'", "--frames", FRAMES_TEXT},
        {"--format ply --frames 0:99 -o '%s'", "--frames", FRAMES_TEXT},
        {"--format ply --frames -10: -o '%s'", "--frames", FRAMES_TEXT},
        {"--format ply --frames 9 -o '%s'", "--frames", FRAMES_TEXT},
        {"--format ply --frames :-10 -o '%s'", "--frames", FRAMES_TEXT},
        {"-o '%s/x.ply' --frame 9", "--frame 9", FRAMES_TEXT},
        {"--format ply --frames abc -o '%s'", "--frames", "'abc'"},
        {"--format ply --frames 1:2:0 -o '%s'", "--frames", "'1:2:0'"},
        {"--format ply --frames 1:2:3:4 -o '%s'", "--frames", "'1:2:3:4'"},
        {"--format ply --frames 1:: -o '%s'", "--frames", "'1::'"},
        {"-o '%s/x.pc2' --frame 2", "--frame", "--frames A:B"},
        {"--format ply --name frames.ply -o '%s'", "--name", "'frames.ply'"},
        {"--format ply --name 'f%%d_%%d.ply' -o '%s'", "--name", "exactly one"},
        {"--format ply --name 'f%%s.ply' -o '%s'", "--name", "'f%s.ply'"},
        {"--format ply --name 'f%%5.2f.ply' -o '%s'", "--name", "integer"},
        {"--format ply --name 'a/f%%d.ply' -o '%s'", "--name", "'/'"},
        {"--name 'f%%d.ply' -o '%s/x.ply'", "--name", "sequence"},
        {"--format ply --start -1 -o '%s'", "--start", "'-1'"},
        {"-o '%s/x.ply' --start 5", "--start", "one file"},
        {"--format ply --up x -o '%s'", "--up", "'x'"},
        {"--format ply --pscale 0 -o '%s'", "--pscale", "'0'"},
        {"--format mdd --frames 3:1 -o '%s/x.mdd'", "--frames", FRAMES_TEXT},
        {"--format ply --frames 1-3 -o '%s'", "--frames", "'1-3'"},
        {"--format ply --frames '' -o '%s'", "--frames", "A:B"},
        {"--format ply --frames 1.5: -o '%s'", "--frames", "'1.5:'"},
        {"--format stl -o '%s'", "--format", "'stl'"},
        {"--frames 1:2 -o '%s'", "--frames 1:2", "--format"},
        {"--format ply --frame 2 -o '%s'", "--frame K", "--frames"},
        {"-o '%s/x.stl'", "-o", "extension"},
        {"--format vdb --voxel -1 -o '%s'", "--voxel", "'-1'"},
        {"--format ply --threads 0 -o '%s'", "--threads", "'0'"},
        {"--format ply --scale 0 -o '%s'", "--scale", "'0'"},
        {"--format ply --scale 1e7 -o '%s'", "--scale", "'1e7'"},
        {"--format ply --preset nuke -o '%s'", "--preset", "'nuke'"},
        {"--format ply --obstacles o.ply --no-obstacles -o '%s'", "--obstacles FILE", "--no-obstacles"},
    };
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    fresh_dir(dir, "seq_errors");
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(args, sizeof args, cases[i].options, dir);
        expect_failure(args, 1, cases[i].word1, cases[i].word2, dir);
    }
}

static void test_io_errors(void)
{
    char dir[FM_PATH_MAX], file[FM_PATH_MAX + 16], args[3 * FM_PATH_MAX];
    fresh_dir(dir, "seq_io");
    ENSURE(mkdir(dir, 0777) == 0);
    snprintf(file, sizeof file, "%s/plain", dir);
    export_write_raw(file, "x", 1, 0);
    /* the output "directory" is a file, or lies under one: the user's -o, exit 1 (docs/errors.md) */
    snprintf(args, sizeof args, "--format vtk -o '%s'", file);
    ENSURE_MSG(export_cmd(args) == 1 && strstr(g_err, "not a directory"), "exit and message: %s", g_err);
    snprintf(args, sizeof args, "--format vtk -o '%s/sub'", file);
    ENSURE_MSG(export_cmd(args) == 1 && strstr(g_err, "cannot create the output directory"), "%s", g_err);
    /* a frame's file cannot be written (a directory is in the way of its final name; one at the
     * .partial name is in nobody's way, the temporary file having a name of its own) */
    char blocker[FM_PATH_MAX + 64];
    snprintf(blocker, sizeof blocker, "%s/seq_00003.ply.partial", dir);
    ENSURE(mkdir(blocker, 0777) == 0);
    snprintf(args, sizeof args, "--format ply -o '%s' --threads 2", dir);
    ENSURE_MSG(export_cmd(args) == 0, "a directory at seq_00003.ply.partial is in the way: %s", g_err);
    snprintf(blocker, sizeof blocker, "%s/seq_00003.ply", dir);
    ENSURE(remove(blocker) == 0 && mkdir(blocker, 0777) == 0);
    ENSURE_MSG(export_cmd(args) == 3 && strstr(g_err, "seq_00003.ply"), "exit and message: %s", g_err);
    struct stat st;
    ENSURE_MSG(stat(blocker, &st) == 0 && S_ISDIR(st.st_mode) && rmdir(blocker) == 0, "%s was not left alone", blocker);
    /* an obstacle mesh that cannot be read: exit 2 naming it, before any frame is written */
    snprintf(args, sizeof args, "--format ply -o '%s/obst' --obstacles '%s/none.ply'", dir, dir);
    ENSURE_MSG(export_cmd(args) == 2 && strstr(g_err, "--obstacles") && strstr(g_err, "none.ply"), "exit and message: %s", g_err);
    snprintf(blocker, sizeof blocker, "%s/obst/seq_00000.ply", dir);
    ENSURE(!export_file_exists(blocker));
}

int main(void)
{
    make_caches();
    RUN_TEST(test_ply_sequence);
    RUN_TEST(test_obj_sequence);
    RUN_TEST(test_frame_ranges);
    RUN_TEST(test_vtk_sequence);
    RUN_TEST(test_strided_pvd);
    RUN_TEST(test_vdb_sequence);
    RUN_TEST(test_single_file);
    RUN_TEST(test_point_cache);
    RUN_TEST(test_point_cache_without_velocity);
    RUN_TEST(test_phases_in_vtk);
    RUN_TEST(test_flock_vtk);
    RUN_TEST(test_point_caches);
    RUN_TEST(test_houdini_ply_points);
    RUN_TEST(test_ply_points_with_groups);
    RUN_TEST(test_vdb_with_groups);
    RUN_TEST(test_up_y);
    RUN_TEST(test_tet_ply_ids_and_phases);
    RUN_TEST(test_houdini_vdb);
    RUN_TEST(test_obstacles_follow_the_frames);
    RUN_TEST(test_run_obstacles_in_the_chosen_axes);
    RUN_TEST(test_render_reads_run_obstacles_back);
    RUN_TEST(test_run_axes_errors);
    RUN_TEST(test_threads_do_not_change_files);
    RUN_TEST(test_usage_errors);
    RUN_TEST(test_io_errors);
    return test_result();
}
