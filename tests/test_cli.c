/* The flockmorph command line (FM_CLI): exit statuses, messages, and one small end-to-end run of
 * an octahedron onto itself 20 units away, followed by export, render and info on its cache. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "test_macros.h"
#include "test_cli_helpers.h"

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>

#define AGENTS 200

static char g_cache[FM_PATH_MAX + 16];       /* the successful run's cache, "" until it exists */
static long long g_frames = -1;              /* frames according to its stats.json */

static char *tmp_path(char *buf, const char *name)
{
    snprintf(buf, FM_PATH_MAX, "%s/cli_%s", FM_TEST_TMP, name);
    return buf;
}

static char g_scene_text[4096]; /* the last scene write_scene wrote */

/* A scene of the octahedron at -10 and +10 on x with `extra` JSON members appended. */
static void write_scene(const char *path, const char *extra)
{
    char mesh[FM_PATH_MAX], *text = g_scene_text;
    write_octahedron(tmp_path(mesh, "octahedron.obj"));
    snprintf(text, sizeof g_scene_text,
             "{\n  \"source\": {\"mesh\": \"cli_octahedron.obj\", \"translate\": [-10, 0, 0]},\n"
             "  \"target\": {\"mesh\": \"cli_octahedron.obj\", \"translate\": [10, 0, 0]},\n"
             "  \"n\": %d%s\n}\n", AGENTS, extra);
    write_text(path, text);
}

/* ---------------------------------------------------------------- usage */

static void test_help(void)
{
    ENSURE_EXIT("--help", 0);
    ENSURE_MSG(strstr(g_out, "usage: flockmorph <command>") != NULL, "%s", g_out);
    ENSURE_EXIT("run --help", 0);
    ENSURE_MSG(strstr(g_out, "usage: flockmorph run") && strstr(g_out, "--output"), "%s", g_out);
    ENSURE_EXIT("export --help", 0);
    ENSURE(strstr(g_out, "usage: flockmorph export") != NULL);
    ENSURE_EXIT("info -h", 0);
    ENSURE(strstr(g_out, "usage: flockmorph info") != NULL);
}

static void test_usage_errors(void)
{
    char scene[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    ENSURE_EXIT("", 1);
    ENSURE(strstr(g_err, "usage:") != NULL);
    ENSURE_EXIT("frobnicate", 1);
    ENSURE_MSG(strstr(g_err, "unknown command 'frobnicate'") != NULL, "%s", g_err);
    write_scene(tmp_path(scene, "usage.json"), "");
    snprintf(args, sizeof args, "run '%s'", scene);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, "-o") != NULL, "%s", g_err);
    snprintf(args, sizeof args, "run '%s' -o '%s/cli_usage_out' --threads 0", scene, FM_TEST_TMP);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, "--threads") != NULL, "%s", g_err);
    snprintf(args, sizeof args, "run '%s' -o '%s/cli_usage_out' --threads", scene, FM_TEST_TMP);
    ENSURE_EXIT(args, 1);
    ENSURE_EXIT("run", 1);
}

/* ---------------------------------------------------------------- bad scenes */

static void test_run_unknown_key(void)
{
    char scene[FM_PATH_MAX], args[3 * FM_PATH_MAX], where[FM_PATH_MAX + 32];
    write_scene(tmp_path(scene, "unknown_key.json"), ",\n  \"speed\": 3");
    snprintf(args, sizeof args, "run '%s' -o '%s/cli_unknown_out' --quiet", scene, FM_TEST_TMP);
    ENSURE_EXIT(args, 2);
    int line = 1, col = 1; /* where the key "speed" sits in the text */
    for (const char *c = g_scene_text; c < strstr(g_scene_text, "\"speed\""); c++) {
        if (*c == '\n') line++, col = 1;
        else col++;
    }
    snprintf(where, sizeof where, "%s:%d:%d: ", scene, line, col);
    ENSURE_MSG(strstr(g_err, where) && strstr(g_err, "speed"), "'%s' not in '%s'", where, g_err);
}

static void test_run_missing_mesh(void)
{
    char scene[FM_PATH_MAX], mesh[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    tmp_path(mesh, "no_such_mesh.obj");
    remove(mesh);
    snprintf(args, sizeof args, "{\"source\": {\"mesh\": \"cli_no_such_mesh.obj\"}, \"target\": {\"mesh\": \"%s\"}}",
             mesh);
    write_text(tmp_path(scene, "missing_mesh.json"), args);
    snprintf(args, sizeof args, "run '%s' -o '%s/cli_missing_out' --quiet", scene, FM_TEST_TMP);
    int rc = cli(args);
    ENSURE_MSG(rc == 2 || rc == 3, "exit %d: %s", rc, g_err);
    ENSURE_MSG(strstr(g_err, mesh) != NULL, "'%s' not in '%s'", mesh, g_err);
}

/* ---------------------------------------------------------------- a real run */

static void test_successful_run(void)
{
    char scene[FM_PATH_MAX], outdir[FM_PATH_MAX], stats[FM_PATH_MAX + 16], args[3 * FM_PATH_MAX], line[FM_PATH_MAX + 64];
    write_scene(tmp_path(scene, "ok.json"), "");
    tmp_path(outdir, "ok_out");
    snprintf(stats, sizeof stats, "%s/stats.json", outdir);
    remove(stats);
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet --threads 2", scene, outdir);
    ENSURE_EXIT(args, 0);
    snprintf(line, sizeof line, "cache: %s/frames.fmc\n", outdir);
    ENSURE_MSG(strstr(g_out, line) != NULL, "'%s' not in '%s'", line, g_out);
    snprintf(line, sizeof line, "stats: %s\n", stats);
    ENSURE_MSG(strstr(g_out, line) != NULL, "'%s' not in '%s'", line, g_out);

    json_error_t jerr;
    json_t *j = json_load_file(stats, 0, &jerr);
    ENSURE_MSG(j != NULL, "%s: %s", stats, jerr.text);
    if (!j) return;
    ENSURE(json_integer_value(json_object_get(j, "agents")) == AGENTS);
    ENSURE(json_is_true(json_object_get(j, "all_arrived")));
    ENSURE(json_is_integer(json_object_get(j, "inverted_tet_frames")) &&
           json_integer_value(json_object_get(j, "inverted_tet_frames")) == 0);
    ENSURE(json_is_true(json_object_get(j, "target_tets_filled_once")));
    json_t *e = json_object_get(j, "final_max_vertex_error");
    ENSURE_MSG(json_is_number(e) && json_number_value(e) >= 0 && json_number_value(e) <= 1e-5, "error %g",
               json_number_value(e));
    g_frames = json_integer_value(json_object_get(j, "frames"));
    ENSURE(g_frames > 1);
    json_decref(j);
    snprintf(g_cache, sizeof g_cache, "%s/frames.fmc", outdir);
}

/* docs/scene.md: reaching time.frame_limit is not an error; stats.json and a warning say so. */
static void test_run_stops_at_frame_limit(void)
{
    char scene[FM_PATH_MAX], outdir[FM_PATH_MAX], stats[FM_PATH_MAX + 16], args[3 * FM_PATH_MAX];
    write_scene(tmp_path(scene, "limit.json"), ",\n  \"time\": {\"frame_limit\": 3}");
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", scene, tmp_path(outdir, "limit_out"));
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(strstr(g_err, "warning: stopped at the frame limit (3 frames)") != NULL, "%s", g_err);
    snprintf(stats, sizeof stats, "%s/stats.json", outdir);
    json_t *j = json_load_file(stats, 0, NULL);
    ENSURE(j != NULL);
    if (!j) return;
    ENSURE(json_integer_value(json_object_get(j, "frames")) == 3);
    ENSURE(json_is_false(json_object_get(j, "all_arrived")) && json_is_true(json_object_get(j, "stopped_at_frame_limit")));
    ENSURE(json_is_null(json_object_get(j, "final_max_vertex_error")));
    const char *warning = json_string_value(json_array_get(json_object_get(j, "warnings"), 0));
    ENSURE_MSG(warning && strstr(warning, "stopped at the frame limit (3 frames)"), "stats.json warnings: %s", warning ? warning : "none");
    json_decref(j);
    /* an output "directory" that is a regular file is a usage error (docs/errors.md) */
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", scene, stats);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, "not a directory") != NULL, "%s", g_err);
}

/* Parses an exported OBJ: counts v and f lines; returns the largest |x - cx| + |y| + |z|. */
static double obj_extent(const char *path, double cx, long *nv, long *nf)
{
    FILE *f = fopen(path, "r");
    char line[256];
    double worst = -1;
    *nv = *nf = 0;
    if (!f) return worst;
    while (fgets(line, sizeof line, f)) {
        double x, y, z;
        if (sscanf(line, "v %lf %lf %lf", &x, &y, &z) == 3) {
            double d = fabs(x - cx) + fabs(y) + fabs(z);
            worst = d > worst ? d : worst;
            (*nv)++;
        } else if (line[0] == 'f' && line[1] == ' ') (*nf)++;
    }
    fclose(f);
    return worst;
}

static void test_export(void)
{
    char out[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    ENSURE(g_cache[0]);
    if (!g_cache[0]) return;
    long nv, nf;
    remove(tmp_path(out, "last.ply"));
    remove(tmp_path(out, "last.obj"));
    snprintf(args, sizeof args, "export '%s' -o '%s'", g_cache, out);
    ENSURE_EXIT(args, 0);
    double extent = obj_extent(out, 10.0, &nv, &nf); /* the last frame is the target octahedron */
    ENSURE_MSG(nv == 4 * AGENTS && nf == 4 * AGENTS, "%ld vertices, %ld faces", nv, nf);
    ENSURE_MSG(extent >= 0 && extent <= 1 + 1e-4, "a vertex lies %g from the target's centre", extent);
    snprintf(args, sizeof args, "export '%s' -o '%s' --frame 0", g_cache, out);
    ENSURE_EXIT(args, 0);
    extent = obj_extent(out, -10.0, &nv, &nf); /* frame 0 is the source at rest */
    ENSURE_MSG(extent >= 0 && extent <= 1 + 1e-4, "a vertex lies %g from the source's centre", extent);

    snprintf(args, sizeof args, "export '%s' -o '%s'", g_cache, tmp_path(out, "last.ply"));
    ENSURE_EXIT(args, 0);
    static char ply[1 << 16];
    struct stat st;
    size_t len = stat(out, &st) == 0 ? (size_t)st.st_size : 0;
    slurp(out, ply, sizeof ply);
    char face[64];
    snprintf(face, sizeof face, "\nelement face %d\n", 4 * AGENTS);
    ENSURE_MSG(strncmp(ply, "ply\n", 4) == 0 && strstr(ply, face), "PLY header: %.200s", ply);
    const char *end = strstr(ply, "end_header\n");
    ENSURE(end != NULL);
    if (end) ENSURE(len == (size_t)(end + 11 - ply) + 4 * AGENTS * 12 + 4 * AGENTS * 13);
}

static void test_export_errors(void)
{
    char out[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    ENSURE(g_cache[0]);
    if (!g_cache[0]) return;
    remove(tmp_path(out, "bad_frame.obj"));
    snprintf(args, sizeof args, "export '%s' -o '%s' --frame 99999", g_cache, out);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, "99999") != NULL, "%s", g_err);
    struct stat st;
    ENSURE(stat(out, &st) != 0);
    snprintf(args, sizeof args, "export '%s/cli_no_such.fmc' -o '%s'", FM_TEST_TMP, out);
    ENSURE_EXIT(args, 2);
    ENSURE_MSG(strstr(g_err, "cli_no_such.fmc") != NULL, "%s", g_err);
}

static void test_render(void)
{
    char out[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    ENSURE(g_cache[0]);
    if (!g_cache[0]) return;
    remove(tmp_path(out, "last.png"));
    snprintf(args, sizeof args, "render '%s' -o '%s' --size 64x48 --view top", g_cache, out);
    ENSURE_EXIT(args, 0);
    unsigned char png[32] = {0};
    FILE *f = fopen(out, "rb");
    ENSURE(f != NULL && fread(png, 1, sizeof png, f) == sizeof png);
    if (f) fclose(f);
    ENSURE(memcmp(png, "\x89PNG\r\n\x1a\n", 8) == 0);
    ENSURE(memcmp(png + 12, "IHDR", 4) == 0);
    ENSURE(png[16] == 0 && png[17] == 0 && png[18] == 0 && png[19] == 64);  /* width */
    ENSURE(png[20] == 0 && png[21] == 0 && png[22] == 0 && png[23] == 48);  /* height */
    snprintf(args, sizeof args, "render '%s' -o '%s' --view diagonal", g_cache, out);
    ENSURE_EXIT(args, 1);
}

static void test_info(void)
{
    char args[3 * FM_PATH_MAX], want[64];
    ENSURE(g_cache[0]);
    if (!g_cache[0]) return;
    snprintf(args, sizeof args, "info '%s'", g_cache);
    ENSURE_EXIT(args, 0);
    snprintf(want, sizeof want, "\"agents\": %d,", AGENTS);
    ENSURE_MSG(strstr(g_out, want) != NULL, "%s", g_out);
    snprintf(want, sizeof want, "\"frames\": %lld,", g_frames);
    ENSURE_MSG(strstr(g_out, want) != NULL, "'%s' not in %s", want, g_out);
}

int main(void)
{
    RUN_TEST(test_help);
    RUN_TEST(test_usage_errors);
    RUN_TEST(test_run_unknown_key);
    RUN_TEST(test_run_missing_mesh);
    RUN_TEST(test_successful_run);
    RUN_TEST(test_run_stops_at_frame_limit);
    RUN_TEST(test_export);
    RUN_TEST(test_export_errors);
    RUN_TEST(test_render);
    RUN_TEST(test_info);
    return test_result();
}
