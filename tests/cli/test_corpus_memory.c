/* No input file under 1 MB makes a command use more than 1 GiB (issue 15): every file of the fuzz
 * corpus and regressions (tests/fuzz/) goes through the CLI command that reads it, under
 * RLIMIT_AS = 1 GiB and a 60 s alarm: caches through inspect, export and render, meshes as a
 * scene's source through run, scenes through run. Each command must exit with a documented status
 * (0 to 5, docs/errors.md), never by a signal (a crash, an abort, or the alarm of a hang). A mesh
 * or a cache must not end with exit 4 either: what the readers allocate is bounded by the file's
 * size (docs/errors.md, "Counts the file cannot hold"), so a small file that runs out of 1 GiB is
 * a bug; a scene may ask for more agents than 1 GiB holds, so exit 4 is allowed for scenes.
 * Files are taken in name order, at most MAX_PER_SET of each set, so the test stays short (about
 * ten seconds) and always runs the same files. Skipped under a sanitizer, whose shadow memory
 * needs more address space than the limit. */
#define _POSIX_C_SOURCE 200809L
#define _DEFAULT_SOURCE
#include "test_macros.h"
#include "test_cli_helpers.h"
#include "../fuzz/fuzz_mesh_files.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define GIB (1024LL * 1024 * 1024)
#define MAX_INPUT_BYTES (1 << 20)
#define MAX_PER_SET 16

static const cli_env LIMITED = {.memory_limit = GIB, .seconds = 60};
static int g_commands;

static char *tmp(char *buf, const char *name)
{
    snprintf(buf, FM_PATH_MAX, "%s/corpus_memory_%s", FM_TEST_TMP, name);
    return buf;
}

/* Runs `flockmorph ARGS` under the limits and checks how it ended. */
static void expect_bounded(const char *input, const char *args, int allow_memory_error)
{
    int rc = cli_with(&LIMITED, args);
    g_commands++;
    ENSURE_MSG(rc >= 0 && rc <= 5, "%s: flockmorph %s: %s (stderr: %.400s)", input, args,
               rc < 0 ? "ended by a signal (crash, abort or the 60 s alarm)" : "undocumented exit status", g_err);
    ENSURE_MSG(rc != 4 || allow_memory_error, "%s: flockmorph %s ran out of 1 GiB (stderr: %.400s)", input, args, g_err);
}

static void check_cache(const char *path)
{
    char args[4 * FM_PATH_MAX], out[FM_PATH_MAX];
    snprintf(args, sizeof args, "inspect '%s'", path);
    expect_bounded(path, args, 0);
    snprintf(args, sizeof args, "export '%s' -o '%s' --threads 2", path, tmp(out, "frame.ply"));
    expect_bounded(path, args, 0);
    snprintf(args, sizeof args, "render '%s' -o '%s' --size 64x48 --threads 2", path, tmp(out, "frame.png"));
    expect_bounded(path, args, 0);
}

/* The mesh the input stands for (fuzz_mesh_files.h) as the source of a short morph into an
 * octahedron. */
static void check_mesh(const char *set, const char *path, const uint8_t *data, size_t size)
{
    size_t len;
    const char *ext;
    uint8_t *file = fuzz_mesh_file(set, data, size, &len, &ext);
    if (!file) return;
    char mesh[FM_PATH_MAX], name[64], scene[FM_PATH_MAX], oct[FM_PATH_MAX], out[FM_PATH_MAX];
    snprintf(name, sizeof name, "mesh.%s", ext);
    FILE *f = fopen(tmp(mesh, name), "wb");
    ENSURE(f && fwrite(file, 1, len, f) == len);
    if (f) fclose(f);
    free(file);
    write_octahedron(tmp(oct, "octahedron.obj"));
    char text[3 * FM_PATH_MAX];
    snprintf(text, sizeof text, "{\"source\": {\"mesh\": \"%s\", \"translate\": [-10, 0, 0]},\n \"target\": {\"mesh\": "
             "\"%s\", \"translate\": [10, 0, 0]},\n \"time\": {\"frame_limit\": 2}}\n", mesh, oct);
    write_text(tmp(scene, "mesh_scene.json"), text);
    char args[4 * FM_PATH_MAX];
    snprintf(args, sizeof args, "run '%s' -o '%s' --threads 2 --quiet", scene, tmp(out, "mesh_out"));
    expect_bounded(path, args, 0);
}

/* A scene as it is (its meshes are looked for beside it), cut to two frames. */
static void check_scene(const char *path)
{
    char args[4 * FM_PATH_MAX], out[FM_PATH_MAX];
    snprintf(args, sizeof args, "run '%s' -o '%s' --threads 2 --quiet --set time.frame_limit=2", path,
             tmp(out, "scene_out"));
    expect_bounded(path, args, 1);
}

static uint8_t *read_input(const char *path, size_t *size)
{
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISREG(st.st_mode) || st.st_size >= MAX_INPUT_BYTES) return NULL;
    uint8_t *data = malloc((size_t)st.st_size + 1);
    FILE *f = fopen(path, "rb");
    *size = f && data ? fread(data, 1, (size_t)st.st_size, f) : 0;
    if (f) fclose(f);
    return data;
}

static int not_hidden(const struct dirent *e) { return e->d_name[0] != '.'; }

/* The first MAX_PER_SET inputs of tests/fuzz/KIND/SET in name order; returns how many ran. */
static int check_set(const char *kind, const char *set)
{
    char dir[FM_PATH_MAX], path[2 * FM_PATH_MAX];
    snprintf(dir, sizeof dir, "%s/tests/fuzz/%s/%s", FM_SOURCE_DIR, kind, set);
    struct dirent **names;
    int count = scandir(dir, &names, not_hidden, alphasort), done = 0;
    for (int i = 0; i < count; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[i]->d_name);
        size_t size = 0;
        uint8_t *data = done < MAX_PER_SET ? read_input(path, &size) : NULL;
        if (data && !strcmp(set, "cache")) check_cache(path);
        else if (data && !strcmp(set, "scene")) check_scene(path);
        else if (data) check_mesh(set, path, data, size);
        done += data != NULL;
        free(data), free(names[i]);
    }
    if (count >= 0) free(names);
    return done;
}

static void test_corpus_under_one_gib(void)
{
    static const char *const sets[] = {"cache", "mesh", "ply_binary", "stl_binary", "scene"};
    ENSURE_MSG(cli("--version") == 0, "the CLI does not run at all: %s", g_err);
    int inputs = 0;
    for (int i = 0; i < 5; i++) {
        inputs += check_set("corpus", sets[i]);
        inputs += check_set("regressions", sets[i]);
    }
    printf("  %d inputs, %d commands under RLIMIT_AS = 1 GiB\n", inputs, g_commands);
    /* the limit bites: 3e6 agents (about 2 GiB, which the machine's memory passes) end with exit 4 */
    char oct[FM_PATH_MAX], scene[FM_PATH_MAX], out[FM_PATH_MAX], text[3 * FM_PATH_MAX], args[4 * FM_PATH_MAX];
    write_octahedron(tmp(oct, "octahedron.obj"));
    snprintf(text, sizeof text, "{\"source\": {\"mesh\": \"%s\", \"translate\": [-10, 0, 0]}, \"target\": {\"mesh\": "
             "\"%s\", \"translate\": [10, 0, 0]}, \"n\": 3000000, \"time\": {\"frame_limit\": 2}}\n", oct, oct);
    write_text(tmp(scene, "big_scene.json"), text);
    snprintf(args, sizeof args, "run '%s' -o '%s' --threads 2 --quiet", scene, tmp(out, "big_out"));
    int rc = cli_with(&LIMITED, args);
    ENSURE_MSG(rc == 4 || (rc == 2 && strstr(g_err, "physical memory")), "3e6 agents under 1 GiB: exit %d, stderr %s", rc, g_err);
    ENSURE_MSG(inputs >= 30, "only %d corpus inputs found under %s/tests/fuzz", inputs, FM_SOURCE_DIR);
}

int main(void)
{
#if defined(CLI_SANITIZED)
    (void)test_corpus_under_one_gib;
    printf("skipped: a sanitizer's shadow memory needs more address space than RLIMIT_AS allows\n");
    return 0;
#else
    RUN_TEST(test_corpus_under_one_gib);
    return test_result();
#endif
}
