/* The flockmorph command line (FM_CLI): exit statuses, messages, and one small end-to-end run of
 * an octahedron onto itself 20 units away, followed by export, render and info on its cache. */
#define _POSIX_C_SOURCE 200809L
#define _DEFAULT_SOURCE /* timegm */
#include "flockmorph/flockmorph.h"
#include "test_macros.h"
#include "test_cli_helpers.h"
#include "geom.h"

#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>

#define XXH_INLINE_ALL /* the scene file's hash, as stats.json records it */
#include <xxhash.h>

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

/* --version and -V print the CMake project's version (the generated flockmorph/version.h), and
 * 'help CMD' prints exactly what 'CMD --help' prints. */
static void test_version_and_help_command(void)
{
    char expected[64], text[sizeof g_out];
    snprintf(expected, sizeof expected, "flockmorph %s\n", FM_VERSION_STRING);
    ENSURE_EXIT("--version", 0);
    ENSURE_MSG(!strcmp(g_out, expected), "'%s', expected '%s'", g_out, expected);
    ENSURE_EXIT("-V", 0);
    ENSURE_MSG(!strcmp(g_out, expected), "'%s', expected '%s'", g_out, expected);
    snprintf(expected, sizeof expected, "%d.%d.%d", FM_VERSION_MAJOR, FM_VERSION_MINOR, FM_VERSION_PATCH);
    ENSURE_MSG(!strcmp(FM_VERSION_STRING, expected), "FM_VERSION_STRING %s, parts %s", FM_VERSION_STRING, expected);
    static const char *const commands[] = {"run", "export", "render", "inspect", "info"};
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++) {
        char args[64];
        snprintf(args, sizeof args, "%s --help", commands[i]);
        ENSURE_EXIT(args, 0);
        snprintf(text, sizeof text, "%s", g_out);
        snprintf(args, sizeof args, "help %s", commands[i]);
        ENSURE_EXIT(args, 0);
        ENSURE_MSG(text[0] && !strcmp(g_out, text), "'help %s' printed '%s', '%s --help' '%s'", commands[i], g_out,
                   commands[i], text);
    }
    ENSURE_EXIT("help", 0);
    ENSURE(strstr(g_out, "usage: flockmorph <command>") != NULL);
    ENSURE_EXIT("help frobnicate", 1);
    ENSURE_MSG(strstr(g_err, "unknown command 'frobnicate'") != NULL, "%s", g_err);
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
    /* one line and where to read more, not the whole usage text */
    static const struct { const char *args, *see; } one_line[] = {
        {"run --threads 0 s.json -o o", "see 'flockmorph help run'\n"},
        {"export c.fmc --format stl -o d", "see 'flockmorph help export'\n"},
        {"render c.fmc -o x.gif", "see 'flockmorph help render'\n"},
        {"inspect", "see 'flockmorph help inspect'\n"},
        {"frobnicate", "see 'flockmorph help'\n"},
    };
    for (size_t i = 0; i < sizeof one_line / sizeof one_line[0]; i++) {
        ENSURE_EXIT(one_line[i].args, 1);
        const char *nl = strchr(g_err, '\n');
        ENSURE_MSG(nl && !strcmp(nl + 1, one_line[i].see) && !strstr(g_err, "usage:"),
                   "flockmorph %s: stderr '%s'", one_line[i].args, g_err);
    }
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
    const char *version = json_string_value(json_object_get(j, "version"));
    ENSURE_MSG(version && !strcmp(version, FM_VERSION_STRING), "stats.json version %s", version ? version : "missing");
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

/* 1 if both files hold the same bytes. */
static int same_file(const char *a, const char *b)
{
    FILE *f = fopen(a, "rb"), *g = fopen(b, "rb");
    int same = f && g, c = EOF;
    while (same && (c = fgetc(f)) == fgetc(g))
        if (c == EOF) break;
    same = same && c == EOF;
    if (f) fclose(f);
    if (g) fclose(g);
    return same;
}

/* OMP_NUM_THREADS=100000 (nothing bounds it) must neither crash nor crawl: the engine caps its
 * default team at 4 threads a core (fm_threads). Both modes run to the end in the environment,
 * the tetra morph's cache equal byte for byte to the --threads 2 run's; export runs too. */
static void test_huge_omp_num_threads(void)
{
    char scene[FM_PATH_MAX], outdir[FM_PATH_MAX], cache[FM_PATH_MAX + 16], stats[FM_PATH_MAX + 16];
    char args[3 * FM_PATH_MAX];
    ENSURE(g_cache[0]);
    tmp_path(scene, "ok.json");
    snprintf(cache, sizeof cache, "%s/frames.fmc", tmp_path(outdir, "omp_out"));
    snprintf(stats, sizeof stats, "%s/stats.json", outdir);
    setenv("OMP_NUM_THREADS", "100000", 1);
    cli_env watched = {.seconds = 120};
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", scene, outdir);
    int rc = cli_with(&watched, args);
    ENSURE_MSG(rc == 0, "OMP_NUM_THREADS=100000: exit %d: %s", rc, g_err);
    ENSURE_MSG(same_file(cache, g_cache), "%s differs from %s", cache, g_cache);
    json_t *j = json_load_file(stats, 0, NULL);
    long threads = j ? (long)json_integer_value(json_object_get(j, "threads")) : -1;
    ENSURE_MSG(threads >= 1 && threads <= 4 * sysconf(_SC_NPROCESSORS_ONLN), "threads %ld", threads);
    json_decref(j);
    write_scene(tmp_path(scene, "omp_flock.json"), ",\n  \"mode\": \"shape_flock\"");
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", scene, tmp_path(outdir, "omp_flock_out"));
    rc = cli_with(&watched, args);
    ENSURE_MSG(rc == 0, "shape flock, OMP_NUM_THREADS=100000: exit %d: %s", rc, g_err);
    snprintf(args, sizeof args, "export '%s' --format ply -o '%s'", cache, tmp_path(outdir, "omp_ply"));
    rc = cli_with(&watched, args);
    ENSURE_MSG(rc == 0, "export, OMP_NUM_THREADS=100000: exit %d: %s", rc, g_err);
    unsetenv("OMP_NUM_THREADS");
}

/* docs/scene.md: reaching time.frame_limit is not an error; stats.json and a warning say so. */
/* Every key of a stats.json, nested objects' as PARENT.KEY, has a row "| `KEY`" (or a row listing
 * it among others) in docs/stats.md, and every key listed there for this mode is in the file. */
static void check_stats_keys_documented(const char *stats, const char *mode_section)
{
    char path[FM_PATH_MAX];
    static char doc[1 << 16];
    snprintf(path, sizeof path, "%s/docs/stats.md", FM_SOURCE_DIR);
    slurp(path, doc, sizeof doc);
    json_t *j = json_load_file(stats, 0, NULL);
    ENSURE_MSG(j && doc[0], "%s or %s missing", stats, path);
    if (!j) return;
    const char *key;
    json_t *v;
    json_object_foreach(j, key, v) {
        char want[160];
        int nested = json_is_object(v);
        const char *sub;
        json_t *w;
        if (!nested) {
            snprintf(want, sizeof want, "`%s`", key);
            ENSURE_MSG(strstr(doc, want), "%s: key %s is not in docs/stats.md", stats, key);
        }
        json_object_foreach(nested ? v : NULL, sub, w) {
            snprintf(want, sizeof want, "`%s.%s`", key, sub);
            ENSURE_MSG(strstr(doc, want), "%s: key %s.%s is not in docs/stats.md", stats, key, sub);
        }
    }
    /* the other way: each `key` in the first column of the common section and of this mode's */
    static const char *const sections[] = {"## Both modes", NULL};
    for (int s = 0; s < 2; s++) {
        const char *at = strstr(doc, s ? mode_section : sections[0]), *end = at ? strstr(at + 3, "\n## ") : NULL;
        for (const char *row = at ? strstr(at, "\n| `") : NULL; row && (!end || row < end); row = strstr(row + 1, "\n| `")) {
            const char *cell_end = strchr(row + 3, '|');
            for (const char *k = strchr(row, '`'); k && k < cell_end; k = strchr(strchr(k + 1, '`') + 1, '`')) {
                char name[96] = "", top[96];
                sscanf(k + 1, "%95[^`]", name);
                snprintf(top, sizeof top, "%s", name);
                char *dot = strchr(top, '.');
                if (dot) *dot = 0;
                json_t *value = json_object_get(j, top);
                ENSURE_MSG(value && (!dot || json_object_get(value, dot + 1)), "%s: docs/stats.md lists %s, which it lacks",
                           stats, name);
            }
        }
    }
    json_decref(j);
}

static json_t *inspect_json(const char *path, int expect_exit);

/* XXH64 (seed 0) of a file's bytes as 16 hex digits, as xxhsum prints it; "" if unreadable. */
static void file_hash(const char *path, char hex[17])
{
    static char bytes[1 << 20];
    size_t n = slurp(path, bytes, sizeof bytes);
    snprintf(hex, 17, "%016llx", n ? (unsigned long long)XXH64(bytes, n, 0) : 0ull);
    if (!n) hex[0] = 0;
}

/* stats.json's "meshes" entry for `key`: its path and xxh64 must be those of the file. */
static void check_mesh_entry(json_t *meshes, const char *key, const char *file)
{
    char absolute[PATH_MAX], hex[17];
    json_t *found = NULL, *m;
    size_t i;
    json_array_foreach(meshes, i, m) if (!strcmp(json_string_value(json_object_get(m, "key")), key)) found = m;
    ENSURE_MSG(found && realpath(file, absolute), "no meshes entry %s for %s", key, file);
    if (!found) return;
    file_hash(file, hex);
    ENSURE_MSG(!strcmp(json_string_value(json_object_get(found, "path")), absolute), "%s: path %s, expected %s", key,
               json_string_value(json_object_get(found, "path")), absolute);
    ENSURE_MSG(!strcmp(json_string_value(json_object_get(found, "xxh64")), hex), "%s: xxh64 %s, the file's %s", key,
               json_string_value(json_object_get(found, "xxh64")), hex);
}

/* The build's commit (40 hex digits, "-modified" when tracked files differed; "unknown" outside a
 * git checkout), the cache's absolute path, the working directory and the meshes with their hashes;
 * `inspect --json` of the cache gives the same. */
static void check_run_provenance(json_t *j, const char *outdir)
{
    const char *commit = json_string_value(json_object_get(j, "commit"));
    size_t hex = commit ? strspn(commit, "0123456789abcdef") : 0;
    ENSURE_MSG(commit && ((hex == 40 && (!commit[40] || !strcmp(commit + 40, "-modified"))) || !strcmp(commit, "unknown")),
               "commit %s", commit ? commit : "missing");
    char cache[FM_PATH_MAX + 16], absolute[PATH_MAX], cwd[PATH_MAX];
    snprintf(cache, sizeof cache, "%s/frames.fmc", outdir);
    ENSURE(realpath(cache, absolute) && getcwd(cwd, sizeof cwd));
    ENSURE(!strcmp(json_string_value(json_object_get(j, "cache_absolute")), absolute));
    ENSURE(!strcmp(json_string_value(json_object_get(j, "working_directory")), cwd));
    json_t *meshes = json_object_get(j, "meshes");
    char mesh[FM_PATH_MAX];
    ENSURE_MSG(json_array_size(meshes) == 1, "%zu meshes: source and target are one file", json_array_size(meshes));
    check_mesh_entry(meshes, "source.mesh", tmp_path(mesh, "octahedron.obj"));
    json_t *inspected = inspect_json(cache, 0), *from_stats = json_object_get(inspected, "provenance");
    static const char *const same[] = {"version", "commit", "meshes", "cache_absolute", "working_directory", "scene_xxh64"};
    for (size_t k = 0; k < sizeof same / sizeof same[0]; k++)
        ENSURE_MSG(json_equal(json_object_get(from_stats, same[k]), json_object_get(j, same[k])),
                   "inspect --json's provenance.%s differs from stats.json's", same[k]);
    ENSURE(!strcmp(json_string_value(json_object_get(inspected, "path_absolute")), absolute));
    json_decref(inspected);
}

/* stats.json's mesh hash follows the mesh: a byte changed in the file (a comment, the same shape)
 * changes its xxh64 to the new file's, and the scene's own hash stays. */
static void test_stats_mesh_hash_follows_the_mesh(void)
{
    char scene[FM_PATH_MAX], mesh[FM_PATH_MAX], args[3 * FM_PATH_MAX], stats[2][FM_PATH_MAX + 32], out[FM_PATH_MAX + 16];
    char base[FM_PATH_MAX];
    write_text(tmp_path(scene, "hashed.json"), "{\"source\": {\"mesh\": \"cli_hashed.obj\", \"translate\": [-4, 0, 0]},\n"
               " \"target\": {\"mesh\": \"cli_hashed.obj\", \"translate\": [4, 0, 0]}, \"n\": 8,\n"
               " \"time\": {\"frame_limit\": 2}}\n");
    write_octahedron(tmp_path(mesh, "hashed.obj"));
    json_t *run[2];
    for (int r = 0; r < 2; r++) {
        if (r) {
            FILE *f = fopen(mesh, "a");
            ENSURE(f && fputs("# the same shape, other bytes\n", f) >= 0);
            if (f) fclose(f);
        }
        snprintf(out, sizeof out, "%s_%d", tmp_path(base, "hashed_out"), r);
        snprintf(stats[r], sizeof stats[r], "%s/stats.json", out);
        remove(stats[r]);
        snprintf(args, sizeof args, "run '%s' -o '%s' --quiet --threads 1", scene, out);
        ENSURE_EXIT(args, 0);
        run[r] = json_load_file(stats[r], 0, NULL);
        ENSURE(run[r] != NULL);
        if (run[r]) check_mesh_entry(json_object_get(run[r], "meshes"), "source.mesh", mesh);
    }
    const char *hash[2];
    for (int r = 0; r < 2; r++) hash[r] = json_string_value(json_object_get(json_array_get(json_object_get(run[r], "meshes"), 0), "xxh64"));
    ENSURE_MSG(hash[0] && hash[1] && strcmp(hash[0], hash[1]) != 0, "the mesh changed, its hash stayed %s", hash[0] ? hash[0] : "missing");
    ENSURE(json_equal(json_object_get(run[0], "scene_xxh64"), json_object_get(run[1], "scene_xxh64")));
    json_decref(run[0]), json_decref(run[1]);
}

/* schema, scene and its hash, command line, start time, machine; mde_fraction_per_frame one
 * entry per frame, frame 0 null; every key documented both ways. */
static void test_stats_provenance(void)
{
    char stats[FM_PATH_MAX + 16], scene[FM_PATH_MAX];
    char outdir[FM_PATH_MAX];
    snprintf(stats, sizeof stats, "%s/stats.json", tmp_path(outdir, "ok_out"));
    tmp_path(scene, "ok.json");
    json_t *j = json_load_file(stats, 0, NULL);
    ENSURE(j != NULL);
    if (!j) return;
    ENSURE(json_integer_value(json_object_get(j, "schema")) == 1);
    ENSURE(!strcmp(json_string_value(json_object_get(j, "scene")), scene));
    char hex[17];
    file_hash(scene, hex);
    const char *have = json_string_value(json_object_get(j, "scene_xxh64"));
    ENSURE_MSG(have && !strcmp(have, hex), "scene_xxh64 %s, expected %s", have ? have : "missing", hex);
    json_t *cmd = json_object_get(j, "command_line");
    ENSURE(json_array_size(cmd) == 8 && !strcmp(json_string_value(json_array_get(cmd, 1)), "run") &&
           !strcmp(json_string_value(json_array_get(cmd, 2)), scene) && !strcmp(json_string_value(json_array_get(cmd, 7)), "2"));
    const char *start = json_string_value(json_object_get(j, "start_time"));
    struct tm tm = {0};
    char z = 0;
    int fields = start ? sscanf(start, "%4d-%2d-%2dT%2d:%2d:%2d%c", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour,
                                &tm.tm_min, &tm.tm_sec, &z) : 0;
    tm.tm_year -= 1900, tm.tm_mon -= 1;
    double age = fields == 7 && z == 'Z' && strlen(start) == 20 ? difftime(time(NULL), timegm(&tm)) : -1;
    ENSURE_MSG(age >= 0 && age < 3600, "start_time %s is %g s ago", start ? start : "missing", age);
    json_t *machine = json_object_get(j, "machine");
    ENSURE(json_integer_value(json_object_get(machine, "cores")) == sysconf(_SC_NPROCESSORS_ONLN));
    ENSURE(json_is_string(json_object_get(machine, "hostname")));
    json_t *mde = json_object_get(j, "mde_fraction_per_frame");
    ENSURE_MSG((long long)json_array_size(mde) == json_integer_value(json_object_get(j, "frames")) &&
               json_is_null(json_array_get(mde, 0)) && json_is_number(json_array_get(mde, 1)),
               "mde_fraction_per_frame: %zu entries for %lld frames", json_array_size(mde),
               (long long)json_integer_value(json_object_get(j, "frames")));
    check_run_provenance(j, outdir);
    json_decref(j);
    check_stats_keys_documented(stats, "## Tetra morph");
    snprintf(stats, sizeof stats, "%s/stats.json", tmp_path(outdir, "omp_flock_out"));
    check_stats_keys_documented(stats, "## Shape flock");
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* One segment of a shot run into `outdir` (--stop-after-frame `stop`, or to the end when `stop` < 0),
 * resuming the one before when `resume`; a resumed segment runs on one thread, the first on the
 * default. After a stop, the checkpoint of group 1 must be there. */
static void shot_segment(const char *scene, const char *outdir, int stop, int resume)
{
    char args[3 * FM_PATH_MAX], group[FM_PATH_MAX + 48], until[48] = "";
    if (stop >= 0) snprintf(until, sizeof until, " --stop-after-frame %d", stop);
    snprintf(args, sizeof args, "run '%s/%s' -o '%s' --quiet%s%s", FM_SOURCE_DIR, scene, outdir,
             resume ? " --resume --threads 1" : "", until);
    ENSURE_EXIT(args, 0);
    snprintf(group, sizeof group, "%s/checkpoint.fmck.f%d.g1", outdir, stop + 1);
    if (stop >= 0) ENSURE_MSG(file_exists(group), "%s: no checkpoint of group 1 after a stop at frame %d", outdir, stop);
}

/* The shot stopped at each of `stops` in turn (each segment resuming the last one's checkpoint) and
 * then resumed to its end in `outdir`: the cache of the run in `whole` byte for byte, and no
 * checkpoint file left, the groups' included. `refused_set`, when not NULL, is a --set that a resume
 * after the first stop must refuse (exit 2, `refused_why`), leaving that checkpoint to the next
 * segment. One chain of segments checks every stop's checkpoint as a stop-and-resume per stop did,
 * running the shot once instead of once per stop (CI's time, docs/testing.md). */
static void check_shot_resumes(const char *scene, const char *name, const int *stops, int count, const char *whole,
                               const char *refused_set, const char *refused_why)
{
    char outdir[FM_PATH_MAX], args[3 * FM_PATH_MAX], got[FM_PATH_MAX + 16], want[FM_PATH_MAX + 16], group[FM_PATH_MAX + 48];
    tmp_path(outdir, name);
    for (int k = 0; k < count; k++) {
        shot_segment(scene, outdir, stops[k], k > 0);
        if (k > 0 || !refused_set) continue;
        snprintf(args, sizeof args, "run '%s/%s' -o '%s' --quiet --resume --set %s", FM_SOURCE_DIR, scene, outdir,
                 refused_set);
        ENSURE_EXIT(args, 2);
        ENSURE_MSG(strstr(g_err, refused_why), "'%s'", g_err);
    }
    shot_segment(scene, outdir, -1, 1);
    snprintf(got, sizeof got, "%s/frames.fmc", outdir);
    snprintf(want, sizeof want, "%s/frames.fmc", whole);
    ENSURE_MSG(same_file(got, want), "%s: stopped and resumed, the cache differs from the whole run's", name);
    for (int k = 0; k < count; k++) {
        snprintf(group, sizeof group, "%s/checkpoint.fmck.f%d.g1", outdir, stops[k] + 1);
        ENSURE_MSG(!file_exists(group), "%s: %s left after the run finished", name, group);
    }
    snprintf(group, sizeof group, "%s/checkpoint.fmck", outdir);
    ENSURE(!file_exists(group));
}

/* Shots (examples/castling, two tetra-morph groups; examples/flock_sequence, two shape-flock groups):
 * their stats.json keys documented both ways; a shot stopped and resumed (before and after its
 * second group started) gives the whole run's cache; a resume with another group's parameters is
 * refused. */
#define WEDGE_FRAMES 12
static void test_shot_run(void)
{
    char outdir[FM_PATH_MAX], stats[FM_PATH_MAX + 16], args[3 * FM_PATH_MAX];
    tmp_path(outdir, "shot_out");
    snprintf(args, sizeof args, "run '%s/examples/castling/scene.json' -o '%s' --quiet --threads 2", FM_SOURCE_DIR, outdir);
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(strstr(g_out, "2 groups: king arrived, rook arrived") != NULL, "'%s'", g_out);
    snprintf(stats, sizeof stats, "%s/stats.json", outdir);
    check_stats_keys_documented(stats, "## Tetra-morph shot");
    tmp_path(outdir, "flock_shot_out");
    snprintf(args, sizeof args, "run '%s/examples/flock_sequence/scene.json' -o '%s' --quiet --threads 2", FM_SOURCE_DIR,
             outdir);
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(strstr(g_out, "2 groups: sphere bound, torus bound") != NULL, "'%s'", g_out);
    snprintf(stats, sizeof stats, "%s/stats.json", outdir);
    check_stats_keys_documented(stats, "## Shape-flock shot");
    char whole[FM_PATH_MAX];
    /* before the rook starts, then while it flies; a resume with another group's speed0 is refused */
    check_shot_resumes("examples/castling/scene.json", "shot_resume", (const int[]){20, 250}, 2,
                       tmp_path(whole, "shot_out"), "groups.1.speed0=7",
                       "checkpoint.fmck: written for a different model: the groups' scenes");
    check_shot_resumes("examples/flock_sequence/scene.json", "flock_shot_resume", (const int[]){200}, 1, outdir, NULL,
                       NULL); /* the torus flies */
    /* two wedges that change nothing else differ by their derived seed. The first
     * WEDGE_FRAMES frames of each show it (--set wins over the wedge file): frames cut short are a
     * prefix of the whole run's, so where two whole caches were the same these are too */
    char wedges[FM_PATH_MAX], one[FM_PATH_MAX], two[FM_PATH_MAX + 16], other[FM_PATH_MAX + 16];
    FILE *w = fopen(tmp_path(wedges, "shot_wedges.json"), "w");
    if (w) fputs("{\"wedges\": [{\"speed0\": 8.0}, {\"speed0\": 8.0}]}\n", w), fclose(w);
    for (int i = 0; i < 2; i++) {
        snprintf(args, sizeof args, "run '%s/examples/flock_sequence/scene.json' -o '%s/{wedge}' --quiet --wedge-file '%s' "
                 "--wedge %d --set time.frame_limit=%d", FM_SOURCE_DIR, tmp_path(one, "shot_wedge_out"), wedges, i,
                 WEDGE_FRAMES);
        ENSURE_EXIT(args, 0);
    }
    snprintf(two, sizeof two, "%s/0000/frames.fmc", one);
    snprintf(other, sizeof other, "%s/0001/frames.fmc", one);
    ENSURE_MSG(!same_file(two, other), "a shot's wedges 0 and 1 wrote the same cache: the derived seed did not reach its groups");
    /* --set reaches into a group, and an error in what it set names the override */
    snprintf(args, sizeof args, "run '%s/examples/castling/scene.json' -o '%s' --set groups.1.speed0=-6", FM_SOURCE_DIR,
             tmp_path(outdir, "shot_set_error"));
    ENSURE_EXIT(args, 2);
    ENSURE_MSG(strstr(g_err, "--set groups.1.speed0=-6: speed0: -6 is out of range"), "'%s'", g_err);
}

/* A scene with an obstacle writes OUTDIR/obstacles.ply, which reads back as the obstacle placed in
 * the world (the octahedron scaled by 2, turned 45 degrees about z, moved to y = 3); a run of a
 * scene without obstacles into the same directory removes it, so render does not draw a stale one;
 * and the cache may not take its name. */
static void test_run_writes_obstacles(void)
{
    char scene[FM_PATH_MAX], outdir[FM_PATH_MAX], ply[FM_PATH_MAX + 32], partial[FM_PATH_MAX + 48], args[3 * FM_PATH_MAX];
    write_scene(tmp_path(scene, "obstacle.json"), ",\n  \"time\": {\"frame_limit\": 3},\n"
                "  \"obstacles\": {\"meshes\": [{\"mesh\": \"cli_octahedron.obj\", \"translate\": [0, 3, 0], "
                "\"scale\": 2, \"rotate_deg\": [0, 0, 45]}], \"k_a\": 1.0, \"voxel\": 0.15}");
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", scene, tmp_path(outdir, "obstacle_out"));
    snprintf(ply, sizeof ply, "%s/obstacles.ply", outdir);
    snprintf(partial, sizeof partial, "%s.partial", ply);
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(strstr(g_out, "obstacles: ") && strstr(g_out, ply), "%s", g_out);
    ENSURE(!file_exists(partial));
    fm_mesh m = {0};
    fm_error err = {0};
    ENSURE_MSG(fm_mesh_load(ply, &m, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(m.nv == 6 && m.nt == 8, "%lld vertices, %lld triangles", (long long)m.nv, (long long)m.nt);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int64_t i = 0; i < m.nv; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], m.v[3 * i + k]), hi[k] = fmax(hi[k], m.v[3 * i + k]);
    const double r = sqrt(2.0), want_lo[3] = {-r, 3 - r, -2}, want_hi[3] = {r, 3 + r, 2};
    for (int k = 0; k < 3; k++) {
        ENSURE_NEAR(lo[k], want_lo[k], 1e-5);
        ENSURE_NEAR(hi[k], want_hi[k], 1e-5);
    }
    ENSURE(fm_mesh_check_closed(&m, ply, &err) == FM_OK);
    fm_mesh_free(&m);

    write_scene(scene, ",\n  \"time\": {\"frame_limit\": 3}");
    ENSURE_EXIT(args, 1); /* the folder holds the first run's results */
    ENSURE_MSG(strstr(g_err, "holds the results of an earlier run") && strstr(g_err, "--overwrite"), "%s", g_err);
    strcat(args, " --overwrite");
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(!file_exists(ply), "%s of the scene before is still there", ply);
    write_scene(scene, ",\n  \"output\": {\"cache\": \"obstacles.ply\"}");
    ENSURE_EXIT(args, 2);
    ENSURE_MSG(strstr(g_err, "'obstacles.ply' is the name of another file the run writes"), "%s", g_err);
}

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
    /* it names its stragglers (issue 38): how many, in which phase, the first by id and how far out */
    ENSURE_MSG(strstr(g_err, "agents not yet arrived (") && strstr(g_err, "first by id: 0 ") &&
               strstr(g_err, "from the switch sphere"), "%s", g_err);
    json_t *st = json_object_get(j, "stragglers"), *first = json_object_get(st, "first");
    const json_int_t agents = json_integer_value(json_object_get(j, "agents"));
    const json_int_t count = json_integer_value(json_object_get(st, "count"));
    ENSURE_MSG(count > 0 && count <= agents, "stragglers.count %lld of %lld", (long long)count, (long long)agents);
    ENSURE(count == json_integer_value(json_object_get(st, "waiting")) + json_integer_value(json_object_get(st, "flying")) +
                        json_integer_value(json_object_get(st, "homing")));
    ENSURE(json_array_size(first) == (size_t)(count < 8 ? count : 8));
    for (size_t i = 0; i < json_array_size(first); i++) {
        json_t *e = json_array_get(first, i);
        const char *phase = json_string_value(json_object_get(e, "phase"));
        ENSURE(json_integer_value(json_object_get(e, "id")) >= (json_int_t)i); /* ascending, distinct */
        ENSURE(i == 0 || json_integer_value(json_object_get(e, "id")) >
                             json_integer_value(json_object_get(json_array_get(first, i - 1), "id")));
        ENSURE(phase && (!strcmp(phase, "waiting") || !strcmp(phase, "flying") || !strcmp(phase, "homing")));
        ENSURE(json_is_real(json_object_get(e, "sphere_distance")));
    }
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
    /* a run's cache has ids and phases: each vertex x y z, its velocity and its own int id; each
     * face its tet's int agent_id and uchar phase */
    ENSURE_MSG(strstr(ply, "property float z\nproperty float vx\nproperty float vy\nproperty float vz\nproperty int id\n"
                           "element face") &&
                   strstr(ply, "property list uchar int vertex_indices\nproperty int agent_id\nproperty uchar phase\n"
                               "end_header\n"),
               "PLY header: %.600s", ply);
    if (end) ENSURE(len == (size_t)(end + 11 - ply) + 4 * AGENTS * 28 + 4 * AGENTS * 18);
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
    /* a size past 32 bits (a 16x16 image, once) and trailing junk are refused, naming --size */
    static const char *const bad_sizes[] = {"4294967312x4294967312", "64x64junk", "64x", "x64", "64x4294967360"};
    for (size_t i = 0; i < sizeof bad_sizes / sizeof *bad_sizes; i++) {
        snprintf(args, sizeof args, "render '%s' -o '%s' --size %s", g_cache, out, bad_sizes[i]);
        ENSURE_EXIT(args, 1);
        ENSURE_MSG(strstr(g_err, "--size wants WIDTHxHEIGHT") && strstr(g_err, bad_sizes[i]), "%s", g_err);
    }
}

/* -o NAME.%04d.png: one PNG per frame of --frames (a stride here), named by the cache's frame
 * number, each the image `render -o FILE.png --frame K` draws; bad patterns are usage errors. */
static void test_render_png_sequence(void)
{
    char dir[FM_PATH_MAX], args[3 * FM_PATH_MAX], path[FM_PATH_MAX + 32], one[FM_PATH_MAX];
    ENSURE(g_cache[0] && g_frames > 4);
    if (!g_cache[0] || g_frames <= 4) return;
    snprintf(args, sizeof args, "rm -rf '%s' && mkdir '%s'", tmp_path(dir, "png_seq"), dir);
    ENSURE(system(args) == 0);
    snprintf(args, sizeof args, "render '%s' -o '%s/f.%%04d.png' --frames 1::3 --size 32x24", g_cache, dir);
    ENSURE_EXIT(args, 0);
    int count = 0;
    for (int k = 0; k < (int)g_frames + 2; k++) {
        snprintf(path, sizeof path, "%s/f.%04d.png", dir, k);
        struct stat st;
        int want = k >= 1 && (k - 1) % 3 == 0 && k < (int)g_frames, have = stat(path, &st) == 0;
        ENSURE_MSG(want == have, "%s: %s", path, have ? "written" : "missing");
        if (!have || count++ >= 2) continue; /* compare the first two with the one-file form */
        snprintf(args, sizeof args, "render '%s' -o '%s' --frame %d --size 32x24", g_cache, tmp_path(one, "png_one.png"), k);
        ENSURE_EXIT(args, 0);
        ENSURE_MSG(same_file(path, one), "%s differs from the one-file render of frame %d", path, k);
    }
    static const char *const bad[] = {"f%%%%.png", "f.%%.png", "f.%%d.%%d.png", "f.%%s.png", "f.%%.2f.png", "f.%%123d.png"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char name[64];
        snprintf(name, sizeof name, bad[i]);
        snprintf(args, sizeof args, "render '%s' -o '%s/%s' --size 32x24", g_cache, dir, name);
        ENSURE_EXIT(args, 1);
        ENSURE_MSG(strstr(g_err, "integer conversion"), "%s: %s", name, g_err);
    }
    snprintf(args, sizeof args, "render '%s' -o '%s/f.%%d.png' --frame 2", g_cache, dir);
    ENSURE_EXIT(args, 1);
    snprintf(args, sizeof args, "render '%s' -o '%s/x.mp4' --frames 0:4:0", g_cache, dir);
    ENSURE_EXIT(args, 1);
}

/* Progress when stderr is not a terminal (a farm's log): plain lines, every --log-every seconds
 * (0: every frame), with the frame, the limit, the percentage done and an ETA; one line at the
 * default interval for a run this short, and a line at each checkpoint; none with --quiet. */
static void test_run_progress_in_a_log(void)
{
    char scene[FM_PATH_MAX], outdir[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    write_scene(tmp_path(scene, "progress.json"), "");
    snprintf(args, sizeof args, "run '%s' -o '%s' --threads 1 --log-every 0", scene, tmp_path(outdir, "progress_out"));
    ENSURE_EXIT(args, 0);
    int lines = 0;
    double last_done = -1;
    for (const char *l = strstr(g_err, "flockmorph: progress: frame "); l; l = strstr(l + 1, "flockmorph: progress: frame ")) {
        long long frame, limit;
        double done;
        const char *d = strstr(l, "done ");
        ENSURE_MSG(sscanf(l, "flockmorph: progress: frame %lld of at most %lld", &frame, &limit) == 2 && d &&
                   sscanf(d, "done %lf%%", &done) == 1 && strstr(l, "eta "), "line '%.200s'", l);
        ENSURE_MSG(frame == lines + 1 && limit > 0 && done >= last_done && done <= 100.0, "line '%.200s'", l);
        last_done = done, lines++;
    }
    ENSURE_MSG(lines == (int)g_frames - 1 && last_done == 100.0, "%d progress lines for %lld frames, last %.1f%%: %s",
               lines, (long long)g_frames, last_done, g_err);
    snprintf(args, sizeof args, "run '%s' -o '%s' --threads 1 --overwrite", scene, outdir);
    ENSURE_EXIT(args, 0);
    const char *first = strstr(g_err, "flockmorph: progress: frame 1 ");
    ENSURE_MSG(first && !strstr(first + 1, "flockmorph: progress:"), "default interval: %s", g_err);
    snprintf(args, sizeof args, "run '%s' -o '%s' --threads 1 --checkpoint-every 2 --overwrite", scene, outdir);
    ENSURE_EXIT(args, 0);
    double seconds = -1;
    const char *ck = strstr(g_err, "flockmorph: checkpoint at frame 1 written ("); /* frames 0 and 1 written */
    ENSURE_MSG(ck && sscanf(ck, "flockmorph: checkpoint at frame 1 written (%lf s)", &seconds) == 1 && seconds >= 0 &&
               strstr(ck, "flockmorph: checkpoint at frame 3 written (") && !strstr(g_err, "checkpoint at frame 2 "),
               "checkpoints in the log: %s", g_err);
    snprintf(args, sizeof args, "run '%s' -o '%s' --threads 1 --quiet --checkpoint-every 2 --overwrite", scene, outdir);
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(!strstr(g_err, "progress") && !strstr(g_err, "checkpoint at"), "--quiet: %s", g_err);
    snprintf(args, sizeof args, "run '%s' -o '%s' --log-every -1", scene, outdir);
    ENSURE_EXIT(args, 1);
    snprintf(args, sizeof args, "run '%s' -o '%s' --stop-after-frame -2", scene, outdir);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, "--stop-after-frame wants a frame number >= 0, not '-2'"), "'%s'", g_err);
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

/* ---------------------------------------------------------------- inspect */

/* Runs `inspect --json` on path and parses its output; NULL (and a failed check) otherwise. */
static json_t *inspect_json(const char *path, int expect_exit)
{
    char args[FM_PATH_MAX + 64];
    snprintf(args, sizeof args, "inspect '%s' --json", path);
    ENSURE_EXIT(args, expect_exit);
    json_error_t jerr;
    json_t *j = json_loads(g_out, 0, &jerr);
    ENSURE_MSG(j != NULL, "inspect output is not JSON (%s): %s", jerr.text, g_out);
    return j;
}

static double jnum(json_t *j, const char *key) { return json_number_value(json_object_get(j, key)); }

/* Bounds of the tet vertices over all frames, read through the C API. */
static void cache_bounds(fm_cache_reader *r, double lo[3], double hi[3])
{
    size_t n = 12 * (size_t)fm_cache_agents(r);
    float *v = malloc(sizeof(float) * n);
    fm_error err = {0};
    for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (uint32_t f = 0; f < fm_cache_frames(r); f++) {
        ENSURE(fm_cache_read_frame(r, f, v, &err) == FM_OK);
        for (size_t i = 0; i < n; i++) lo[i % 3] = fmin(lo[i % 3], v[i]), hi[i % 3] = fmax(hi[i % 3], v[i]);
    }
    free(v);
}

/* Every value inspect reports, checked against the cache read through the C API. */
static void test_inspect_json(void)
{
    ENSURE(g_cache[0]);
    if (!g_cache[0]) return;
    json_t *j = inspect_json(g_cache, 0);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(g_cache, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!j || !r) return json_decref(j), fm_cache_close(r);
    uint32_t frames = fm_cache_frames(r);
    ENSURE(jnum(j, "format_version") == 4 && jnum(j, "agents") == AGENTS && jnum(j, "frames") == frames && frames == g_frames);
    ENSURE(jnum(j, "header_frames") == frames && fm_cache_header_frames(r) == frames);
    ENSURE(jnum(j, "frame_rate") == 24 && fabs(jnum(j, "duration_seconds") - (frames - 1) / 24.0) < 1e-9);
    json_t *attrs = json_object_get(j, "attributes");
    ENSURE(json_array_size(attrs) == 3 && fm_cache_attr_count(r) == 3);
    ENSURE(!strcmp(json_string_value(json_object_get(json_array_get(attrs, 0), "name")), "tet_vertices"));
    ENSURE(jnum(json_array_get(attrs, 0), "components") == 12);
    ENSURE(!strcmp(json_string_value(json_object_get(json_array_get(attrs, 1), "name")), "id"));
    ENSURE(!strcmp(json_string_value(json_object_get(json_array_get(attrs, 1), "type")), "u32"));
    ENSURE(!strcmp(json_string_value(json_object_get(json_array_get(attrs, 2), "name")), "phase"));
    ENSURE(!strcmp(json_string_value(json_object_get(json_array_get(attrs, 2), "type")), "u8"));
    json_t *o = json_object_get(j, "options");
    ENSURE(jnum(o, "compression_level") == 1 && json_is_true(json_object_get(o, "delta")) && jnum(o, "key_interval") == 16 && jnum(o, "quantum") == 0);
    struct stat st;
    ENSURE(stat(g_cache, &st) == 0 && jnum(j, "file_bytes") == (double)st.st_size);
    ENSURE(jnum(j, "raw_bytes") == (double)frames * AGENTS * (48 + 4 + 1) && jnum(j, "raw_bytes") == fm_cache_raw_bytes(r));
    ENSURE(jnum(j, "compressed_bytes") == fm_cache_compressed_bytes(r));
    ENSURE(fabs(jnum(j, "compression_ratio") - jnum(j, "raw_bytes") / jnum(j, "compressed_bytes")) < 1e-6);
    uint64_t lo = UINT64_MAX, hi = 0, sum = 0;
    for (uint32_t f = 0; f < frames; f++) {
        uint64_t b = fm_cache_frame_bytes(r, f);
        lo = b < lo ? b : lo, hi = b > hi ? b : hi, sum += b;
    }
    json_t *fb = json_object_get(j, "frame_bytes");
    ENSURE(jnum(fb, "min") == lo && jnum(fb, "max") == hi && fabs(jnum(fb, "mean") - (double)sum / frames) < 1e-6);
    ENSURE(sum + 72 + 3 * 16 + 16 + 16 * frames + 16 == (uint64_t)st.st_size);
    double blo[3], bhi[3];
    cache_bounds(r, blo, bhi);
    json_t *b = json_object_get(json_object_get(j, "bounds"), "tet_vertices");
    for (int k = 0; k < 3; k++) {
        ENSURE_NEAR(json_number_value(json_array_get(json_object_get(b, "min"), k)), blo[k], 1e-6 * (1 + fabs(blo[k])));
        ENSURE_NEAR(json_number_value(json_array_get(json_object_get(b, "max"), k)), bhi[k], 1e-6 * (1 + fabs(bhi[k])));
    }
    ENSURE(bhi[0] - blo[0] > 20); /* the flock crossed from -10 to +10 */
    ENSURE(json_is_true(json_object_get(j, "complete")) && json_is_null(json_object_get(j, "warning")));
    fm_cache_close(r);
    json_decref(j);
}

/* The text form says the same; a cache cut short is reported as recovered, with the warning. */
static void test_inspect_text_and_recovered(void)
{
    char args[3 * FM_PATH_MAX], cut[FM_PATH_MAX], buf[1 << 16];
    ENSURE(g_cache[0]);
    if (!g_cache[0]) return;
    snprintf(args, sizeof args, "inspect '%s'", g_cache);
    ENSURE_EXIT(args, 0);
    snprintf(buf, sizeof buf, "frames        %lld (the header states %lld)\n", g_frames, g_frames);
    ENSURE_MSG(strstr(g_out, "format        4\n") && strstr(g_out, "status        complete\n") && strstr(g_out, buf) &&
               strstr(g_out, "attributes    tet_vertices (12 x f32), id (1 x u32), phase (1 x u8)\n") && strstr(g_out, "ratio ") &&
               strstr(g_out, "bounds        tet_vertices: ["), "%s", g_out);
    FILE *in = fopen(g_cache, "rb"), *out = fopen(tmp_path(cut, "cut.fmc"), "wb");
    ENSURE(in && out);
    if (!in || !out) return;
    size_t n = fread(buf, 1, 3000, in); /* the header and the first chunks */
    fwrite(buf, 1, n, out);
    fclose(in), fclose(out);
    json_t *j = inspect_json(cut, 0);
    ENSURE_MSG(strstr(g_err, "warning: ") && strstr(g_err, "recovered"), "%s", g_err);
    ENSURE(j && json_is_false(json_object_get(j, "complete")) && strstr(json_string_value(json_object_get(j, "warning")), "recovered"));
    ENSURE(j && jnum(j, "frames") >= 1 && jnum(j, "frames") < g_frames && jnum(j, "file_bytes") == 3000);
    ENSURE(j && jnum(j, "header_frames") == g_frames); /* a finished cache cut short: its header is intact */
    json_decref(j);
    snprintf(args, sizeof args, "inspect '%s'", cut);
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(strstr(g_out, "status        recovered"), "%s", g_out);
}

/* docs/cache-format.md's "Inspecting a cache" table lists exactly the keys inspect --json prints,
 * in the same order. */
static void test_inspect_keys_are_documented(void)
{
    static char doc[1 << 17];
    ENSURE(g_cache[0] && slurp(FM_SOURCE_DIR "/docs/cache-format.md", doc, sizeof doc) > 0);
    json_t *j = g_cache[0] ? inspect_json(g_cache, 0) : NULL;
    const char *at = strstr(doc, "## Inspecting a cache"), *end = at ? strstr(at + 3, "\n## ") : NULL;
    ENSURE_MSG(j && at && end, "%s", "no inspect output or no 'Inspecting a cache' section");
    if (!j || !at || !end) return json_decref(j);
    size_t documented = 0;
    void *iter = json_object_iter(j); /* jansson keeps the keys in the order they were read */
    for (const char *row = strstr(at, "\n| `"); row && row < end; row = strstr(row + 1, "\n| `")) {
        char name[64] = "";
        sscanf(row, "\n| `%63[^`]`", name);
        const char *key = iter ? json_object_iter_key(iter) : "(none)";
        ENSURE_MSG(!strcmp(name, key), "documented key %zu is '%s', inspect prints '%s'", documented, name, key);
        iter = iter ? json_object_iter_next(j, iter) : NULL;
        documented++;
    }
    ENSURE_MSG(documented == json_object_size(j), "%zu keys documented, inspect prints %zu", documented, json_object_size(j));
    json_decref(j);
}

static void test_inspect_errors(void)
{
    char args[3 * FM_PATH_MAX], path[FM_PATH_MAX];
    ENSURE_EXIT("inspect", 1);
    ENSURE_EXIT("inspect --yaml x.fmc", 1);
    snprintf(args, sizeof args, "inspect '%s'", tmp_path(path, "no_such.fmc"));
    ENSURE_EXIT(args, 2);
    write_text(tmp_path(path, "not_a_cache.fmc"), "{\"agents\": 1}\n");
    snprintf(args, sizeof args, "inspect '%s' --json", path);
    ENSURE_EXIT(args, 2);
    ENSURE_MSG(strstr(g_err, "not a flockmorph cache"), "%s", g_err);
}

/* The phase attribute the run writes: everyone waits in frame 0, everyone has arrived in the last. */
static void test_run_writes_phases(void)
{
    fm_error err = {0};
    fm_cache_reader *r = g_cache[0] ? fm_cache_open(g_cache, &err) : NULL;
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    uint8_t first[AGENTS], last[AGENTS], mid[AGENTS];
    ENSURE(fm_cache_read_attr(r, 0, FM_ATTR_PHASE, first, &err) == FM_OK);
    ENSURE(fm_cache_read_attr(r, fm_cache_frames(r) - 1, FM_ATTR_PHASE, last, &err) == FM_OK);
    ENSURE(fm_cache_read_attr(r, fm_cache_frames(r) / 2, FM_ATTR_PHASE, mid, &err) == FM_OK);
    int flying = 0;
    for (int a = 0; a < AGENTS; a++) {
        ENSURE(first[a] == FM_PHASE_WAITING && last[a] == FM_PHASE_ARRIVED && mid[a] <= FM_PHASE_ARRIVED);
        flying += mid[a] == FM_PHASE_FLYING || mid[a] == FM_PHASE_HOMING;
    }
    ENSURE(flying > 0);
    fm_cache_close(r);
}

/* output.delta / key_interval / quantum reach the cache: inspect shows them, and the frames are
 * the lossless run's within quantum / 2 (same scene and seed, so the same simulation). */
static void test_run_cache_options(void)
{
    char scene[FM_PATH_MAX], outdir[FM_PATH_MAX], args[3 * FM_PATH_MAX], cache[FM_PATH_MAX + 16];
    ENSURE(g_cache[0]);
    if (!g_cache[0]) return;
    write_scene(tmp_path(scene, "options.json"), ",\n  \"output\": {\"delta\": true, \"key_interval\": 5, \"quantum\": 0.0001}");
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", scene, tmp_path(outdir, "options_out"));
    ENSURE_EXIT(args, 0);
    snprintf(cache, sizeof cache, "%s/frames.fmc", outdir);
    json_t *j = inspect_json(cache, 0), *o = json_object_get(j, "options");
    ENSURE(json_is_true(json_object_get(o, "delta")) && jnum(o, "key_interval") == 5 && jnum(o, "quantum") == 0.0001);
    json_decref(j);
    fm_error err = {0};
    fm_cache_reader *a = fm_cache_open(g_cache, &err), *b = fm_cache_open(cache, &err);
    ENSURE(a && b && fm_cache_frames(a) == fm_cache_frames(b));
    float va[12 * AGENTS], vb[12 * AGENTS];
    double worst = 0;
    for (uint32_t f = 0; a && b && f < fm_cache_frames(a); f++) {
        ENSURE(fm_cache_read_frame(a, f, va, &err) == FM_OK && fm_cache_read_frame(b, f, vb, &err) == FM_OK);
        for (int i = 0; i < 12 * AGENTS; i++) worst = fmax(worst, fabs((double)va[i] - vb[i]));
    }
    ENSURE_MSG(worst <= 0.00005 + 1e-6 && worst > 0.00002, "largest difference %g for quantum 1e-4", worst);
    fm_cache_close(a), fm_cache_close(b);
}

int main(void)
{
    RUN_TEST(test_help);
    RUN_TEST(test_version_and_help_command);
    RUN_TEST(test_usage_errors);
    RUN_TEST(test_run_unknown_key);
    RUN_TEST(test_shot_run);
    RUN_TEST(test_run_missing_mesh);
    RUN_TEST(test_successful_run);
    RUN_TEST(test_huge_omp_num_threads);
    RUN_TEST(test_run_stops_at_frame_limit);
    RUN_TEST(test_run_writes_obstacles);
    RUN_TEST(test_stats_provenance);
    RUN_TEST(test_stats_mesh_hash_follows_the_mesh);
    RUN_TEST(test_export);
    RUN_TEST(test_export_errors);
    RUN_TEST(test_render);
    RUN_TEST(test_render_png_sequence);
    RUN_TEST(test_run_progress_in_a_log);
    RUN_TEST(test_info);
    RUN_TEST(test_inspect_json);
    RUN_TEST(test_inspect_text_and_recovered);
    RUN_TEST(test_inspect_errors);
    RUN_TEST(test_inspect_keys_are_documented);
    RUN_TEST(test_run_writes_phases);
    RUN_TEST(test_run_cache_options);
    return test_result();
}
