/* `flockmorph export` on a cache made here (agents on known quadratic paths): file names and
 * counts for every --frames form, PLY/OBJ sequences re-imported with assimp, VTK checked with
 * Python's xml module (tests/check_vtk.py), VDB read back with its finite-difference velocities,
 * byte-identical files for any thread count, and the usage and I/O errors. */
#define _POSIX_C_SOURCE 200809L
#include "export.h" /* fm_vdb_points_read */
#include "test_export_helpers.h"

#include <dirent.h>
#include <stdint.h>
#include <unistd.h>

enum { AGENTS = 30, FRAMES = 9 };
#define FRAMES_TEXT "9 frames" /* as the error messages count them */
#define RATE 12.0

static char g_cache[FM_PATH_MAX];
static float g_frames[FRAMES][12 * AGENTS];
static char g_err[1 << 14]; /* the last command's stderr */

/* ---------------------------------------------------------------- the cache */

/* Agent i's centroid at time t: c0 + v t + a t^2 / 2, so the central difference at an inner
 * frame is exactly v + a t there, and the one-sided ones are off by a dt / 2. */
static void motion(int i, double c0[3], double v[3], double a[3])
{
    for (int k = 0; k < 3; k++) {
        c0[k] = 3.0 * (i % 5) - 6 + k + 0.25 * (i / 5);
        v[k] = 0.5 * ((i * 7 + k * 3) % 11) - 2.5;
        a[k] = 0.2 * ((i * 5 + k) % 7) - 0.6;
    }
}

static void make_cache(void)
{
    static const double shape[12] = {0, 0, 0, 0.4, 0, 0, 0, 0.4, 0, 0, 0, 0.4}; /* positive volume */
    for (int f = 0; f < FRAMES; f++) {
        double t = f / RATE;
        for (int i = 0; i < AGENTS; i++) {
            double c0[3], v[3], a[3];
            motion(i, c0, v, a);
            for (int j = 0; j < 12; j++)
                g_frames[f][12 * i + j] = (float)(c0[j % 3] + v[j % 3] * t + 0.5 * a[j % 3] * t * t + shape[j] - 0.1);
        }
    }
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(export_tmp(g_cache, "seq.fmc"), AGENTS, RATE, 1, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    for (int f = 0; w && f < FRAMES; f++) ENSURE(fm_cache_writer_add_frame(w, g_frames[f], &err) == FM_OK);
    if (w) ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
}

/* ---------------------------------------------------------------- running the CLI */

/* Runs `flockmorph export CACHE ARGS` (stdout discarded); returns its exit status. */
static int export_cmd(const char *args)
{
    char err_path[FM_PATH_MAX], cmd[4 * FM_PATH_MAX];
    export_tmp(err_path, "seq_stderr.txt");
    snprintf(cmd, sizeof cmd, "'%s' export '%s' %s >/dev/null 2>'%s'", FM_CLI, g_cache, args, err_path);
    int status = system(cmd);
    FILE *f = fopen(err_path, "r");
    size_t n = f ? fread(g_err, 1, sizeof g_err - 1, f) : 0;
    g_err[n] = 0;
    if (f) fclose(f);
    return status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

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

/* seq_<first>.ext .. seq_<last>.ext (and seq.pvd, listed first as the sort puts it), joined. */
static void expected_names(int first, int last, const char *ext, int pvd, char *out, size_t size)
{
    snprintf(out, size, "%s", pvd ? "seq.pvd" : "");
    for (int k = first; k <= last; k++)
        snprintf(out + strlen(out), size - strlen(out), "%sseq_%05d.%s", out[0] ? " " : "", k, ext);
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
    static const struct { const char *spec; int first, last; } cases[] = {
        {"3:", 3, FRAMES - 1}, {":2", 0, 2}, {"4", 4, 4}, {"-3:", FRAMES - 3, FRAMES - 1}, {"-3:-2", FRAMES - 3, FRAMES - 2},
        {":", 0, FRAMES - 1}, {"-1", FRAMES - 1, FRAMES - 1}, {"0:0", 0, 0}, {NULL, 0, FRAMES - 1}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], want[4096], frames[64] = "";
        fresh_dir(dir, "seq_range");
        if (cases[i].spec) snprintf(frames, sizeof frames, "--frames %s", cases[i].spec);
        snprintf(args, sizeof args, "--format obj %s -o '%s' --quiet", frames, dir);
        ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
        list_dir(dir, have, sizeof have);
        expected_names(cases[i].first, cases[i].last, "obj", 0, want, sizeof want);
        ENSURE_MSG(!strcmp(have, want), "--frames %s: files '%s', expected '%s'", cases[i].spec ? cases[i].spec : "(none)",
                   have, want);
    }
}

static void test_vtk_sequence(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], have[4096], want[4096], expected[FM_PATH_MAX];
    char path[FM_PATH_MAX + 32];
    snprintf(args, sizeof args, "--format vtk --frames 1:-2 -o '%s'", fresh_dir(dir, "seq_vtk"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    list_dir(dir, have, sizeof have);
    expected_names(1, FRAMES - 2, "vtu", 1, want, sizeof want);
    ENSURE_MSG(!strcmp(have, want), "files '%s', expected '%s'", have, want);
    uint32_t ids[AGENTS];
    for (uint32_t i = 0; i < AGENTS; i++) ids[i] = i;
    for (int k = 1; k <= FRAMES - 2; k++) {
        export_write_raw(export_tmp(expected, "seq_vtk.expected"), g_frames[k], sizeof g_frames[k], 0);
        export_write_raw(expected, ids, sizeof ids, 1);
        snprintf(path, sizeof path, "%s/seq_%05d.vtu", dir, k);
        snprintf(args, sizeof args, "vtu '%s' '%s' tets", path, expected);
        ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    }
    snprintf(args, sizeof args, "pvd '%s/seq.pvd' %.17g", dir, RATE);
    for (int k = 1; k <= FRAMES - 2; k++) snprintf(args + strlen(args), sizeof args - strlen(args), " %d", k);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
}

/* ---------------------------------------------------------------- VDB and velocities */

static void centroids(int frame, double c[AGENTS][3])
{
    for (int i = 0; i < AGENTS; i++)
        for (int k = 0; k < 3; k++) {
            const float *v = g_frames[frame] + 12 * i + k;
            c[i][k] = 0.25 * ((double)v[0] + v[3] + v[6] + v[9]);
        }
}

/* Reads DIR/seq_<k>.vdb and checks positions (centroids), ids and velocities: the central
 * difference of the cache's centroids inside, one-sided at frames 0 and FRAMES - 1, and near
 * the motion's own velocity (v + a t inside; a dt / 2 off at the ends). */
static void check_vdb_frame(const char *path, int k)
{
    size_t n;
    float *p, *v;
    int32_t *id;
    double voxel;
    fm_error err = {0};
    fm_status st = fm_vdb_points_read(path, &n, &p, &v, &id, &voxel, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    if (st != FM_OK) return;
    ENSURE_MSG(n == AGENTS, "%s: %zu points", path, n);
    int before = k > 0 ? k - 1 : k, after = k < FRAMES - 1 ? k + 1 : k;
    static double c[AGENTS][3], cb[AGENTS][3], ca[AGENTS][3];
    centroids(k, c), centroids(before, cb), centroids(after, ca);
    double t = k / RATE, worst_p = 0, worst_fd = 0, worst_motion = 0;
    for (size_t j = 0; j < n && n == AGENTS; j++) {
        int i = id[j];
        ENSURE_MSG(i >= 0 && i < AGENTS, "%s: id %d", path, i);
        if (i < 0 || i >= AGENTS) continue;
        double c0[3], mv[3], ma[3];
        motion(i, c0, mv, ma);
        for (int d = 0; d < 3; d++) {
            double fd = (ca[i][d] - cb[i][d]) * RATE / (after - before);
            double exact = mv[d] + ma[d] * t + (before == k ? 0.5 : after == k ? -0.5 : 0.0) * ma[d] / RATE;
            worst_p = fmax(worst_p, fabs(p[3 * j + d] - c[i][d]));
            /* the exporter's centroids are floats: each off by up to half an ulp (2^-24 relative) */
            double fd_tol = (fabs(ca[i][d]) + fabs(cb[i][d])) * 0x1p-24 * RATE / (after - before) + fabs(fd) * 1e-6;
            worst_fd = fmax(worst_fd, fabs(v[3 * j + d] - fd) / fd_tol);
            worst_motion = fmax(worst_motion, fabs(v[3 * j + d] - exact));
        }
    }
    /* centroids are rounded to float (|c| < 16: 1e-6) and then stored by OpenVDB relative to a voxel */
    ENSURE_MSG(worst_p <= 2e-6 + voxel * 1e-6, "%s: a position is %g from its centroid", path, worst_p);
    ENSURE_MSG(worst_fd <= 1, "%s: a velocity is %g times the tolerance from the finite difference", path, worst_fd);
    /* float vertices (ulp 1e-6 at |x| < 16) over 2 dt = 1/6 s: at most ~2e-5 */
    ENSURE_MSG(worst_motion <= 1e-4, "%s: a velocity is %g from the motion's", path, worst_motion);
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
        check_vdb_frame(path, k);
    }
    /* one frame alone has the same velocities (the difference spans the cache, not the range) */
    snprintf(args, sizeof args, "--format vdb --frames 4 -o '%s' --voxel 0.5", fresh_dir(dir, "seq_vdb1"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    snprintf(path, sizeof path, "%s/seq_00004.vdb", dir);
    check_vdb_frame(path, 4);
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
    char path[FM_PATH_MAX], args[3 * FM_PATH_MAX], expected[FM_PATH_MAX];
    snprintf(args, sizeof args, "-o '%s'", export_tmp(path, "seq_last.ply"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    export_check_assimp_tets(path, g_frames[FRAMES - 1], AGENTS, 0);
    snprintf(args, sizeof args, "-o '%s' --frame 3", export_tmp(path, "seq_three.vtu"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    uint32_t ids[AGENTS];
    for (uint32_t i = 0; i < AGENTS; i++) ids[i] = i;
    export_write_raw(export_tmp(expected, "seq_three.expected"), g_frames[3], sizeof g_frames[3], 0);
    export_write_raw(expected, ids, sizeof ids, 1);
    snprintf(args, sizeof args, "vtu '%s' '%s' tets", path, expected);
    ENSURE_MSG(export_run_check_vtk(args, 0) == 0, "check_vtk.py %s failed", args);
    snprintf(args, sizeof args, "-o '%s' --frame 0", export_tmp(path, "seq_first.vdb"));
    ENSURE_MSG(export_cmd(args) == 0, "%s: %s", args, g_err);
    check_vdb_frame(path, 0);
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
        {"--format ply --frames 1:2:3 -o '%s'", "--frames", "'1:2:3'"},
        {"--format ply --frames 1-3 -o '%s'", "--frames", "'1-3'"},
        {"--format ply --frames '' -o '%s'", "--frames", "A:B"},
        {"--format ply --frames 1.5: -o '%s'", "--frames", "'1.5:'"},
        {"--format stl -o '%s'", "--format", "'stl'"},
        {"--frames 1:2 -o '%s'", "--frames 1:2", "--format"},
        {"--format ply --frame 2 -o '%s'", "--frame K", "--frames"},
        {"-o '%s/x.stl'", "-o", "extension"},
        {"--format vdb --voxel -1 -o '%s'", "--voxel", "'-1'"},
        {"--format ply --threads 0 -o '%s'", "--threads", "'0'"},
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
    /* the output "directory" is a file, or lies under one */
    snprintf(args, sizeof args, "--format vtk -o '%s'", file);
    ENSURE_MSG(export_cmd(args) == 3 && strstr(g_err, "not a directory"), "exit and message: %s", g_err);
    snprintf(args, sizeof args, "--format vtk -o '%s/sub'", file);
    ENSURE_MSG(export_cmd(args) == 3 && strstr(g_err, "cannot create the output directory"), "%s", g_err);
    /* a frame's file cannot be written (a directory is in the way of its partial file) */
    char blocker[FM_PATH_MAX + 64];
    snprintf(blocker, sizeof blocker, "%s/seq_00003.ply.partial", dir);
    ENSURE(mkdir(blocker, 0777) == 0);
    snprintf(args, sizeof args, "--format ply -o '%s' --threads 2", dir);
    ENSURE_MSG(export_cmd(args) == 3 && strstr(g_err, "seq_00003.ply"), "exit and message: %s", g_err);
    snprintf(blocker, sizeof blocker, "%s/seq_00003.ply", dir);
    ENSURE(!export_file_exists(blocker));
}

int main(void)
{
    make_cache();
    RUN_TEST(test_ply_sequence);
    RUN_TEST(test_obj_sequence);
    RUN_TEST(test_frame_ranges);
    RUN_TEST(test_vtk_sequence);
    RUN_TEST(test_vdb_sequence);
    RUN_TEST(test_single_file);
    RUN_TEST(test_threads_do_not_change_files);
    RUN_TEST(test_usage_errors);
    RUN_TEST(test_io_errors);
    return test_result();
}
