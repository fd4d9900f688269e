/* Bad input through the CLI (docs/errors.md): every mistake a user can make in a scene, a mesh, a
 * parameter or an output directory ends with exit status 1 (usage) or 2 (input) and a message that
 * names the file, line and column, key or mesh element; disk full and file-size limits end with
 * exit status 3, nothing under the final cache name and a partial cache readable up to its last
 * complete frame. The bad meshes are written here (under the test's scratch directory). */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "cache_format.h"
#include "fm_internal.h"
#include "modes.h"
#include "morph.h"
#include "test_macros.h"
#include "test_cli_helpers.h"
#include "full_disk.h"

#include <jansson.h>
#include <malloc.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#if defined(__SANITIZE_ADDRESS__)
size_t __sanitizer_get_current_allocated_bytes(void); /* libasan's (gcc installs no header for it) */
#endif

#define LEFT "\"translate\": [-10, 0, 0]"
#define RIGHT "\"translate\": [10, 0, 0]"
#define OCTAHEDRON "bad_octahedron.obj"
#define FLOCK ",\n  \"mode\": \"shape_flock\"" /* the member that makes a scene a shape flock */

static char *tmp_path(char *buf, const char *name)
{
    snprintf(buf, FM_PATH_MAX, "%s/bad_%s", FM_TEST_TMP, name);
    return buf;
}

static char g_scene[FM_PATH_MAX];  /* the last scene written */
static char g_scene_text[8192];    /* and its text */

/* Writes scene `name`: `source` (a file in the scratch directory) with source_keys, morphing into
 * the octahedron with target_keys, plus `extra` members. Returns its path. */
static const char *scene(const char *name, const char *source, const char *source_keys, const char *target_keys,
                         const char *extra)
{
    char oct[FM_PATH_MAX];
    write_octahedron(tmp_path(oct, "octahedron.obj"));
    snprintf(g_scene_text, sizeof g_scene_text,
             "{\n  \"source\": {\"mesh\": \"%s\", %s},\n  \"target\": {\"mesh\": \"" OCTAHEDRON "\", %s}%s\n}\n",
             source, source_keys, target_keys, extra);
    write_text(tmp_path(g_scene, name), g_scene_text);
    return g_scene;
}

/* The octahedron 20 units apart from itself, with `extra` members. */
static const char *plain_scene(const char *name, const char *extra)
{
    return scene(name, OCTAHEDRON, LEFT, RIGHT, extra);
}

/* "SCENE:LINE:COL" of the first `needle` in the last scene's text. */
static const char *scene_position(const char *needle, char *out, size_t size)
{
    const char *hit = strstr(g_scene_text, needle);
    ENSURE_MSG(hit != NULL, "'%s' is not in the scene", needle);
    int line = 1, col = 1;
    for (const char *c = g_scene_text; hit && c < hit; c++) {
        if (*c == '\n') line++, col = 1;
        else col++;
    }
    snprintf(out, size, "%s:%d:%d: ", g_scene, line, col);
    return out;
}

static char g_outdir[FM_PATH_MAX];

/* Runs the scene into a fresh output directory; returns the exit status. */
static int run_scene(const cli_env *env, const char *scene_path, const char *outdir_name)
{
    char args[3 * FM_PATH_MAX];
    tmp_path(g_outdir, outdir_name);
    snprintf(args, sizeof args, "rm -rf '%s'", g_outdir);
    ENSURE(system(args) == 0);
    if (env && env->unprivileged) mkdir(g_outdir, 0777), chmod(g_outdir, 0777); /* nobody may write it */
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", scene_path, g_outdir);
    return cli_with(env, args);
}

/* Expects exit status `code` and every one of the NULL-terminated `parts` on stderr. */
static void expect_output(int rc, int code, const char *what, const char *const *parts)
{
    ENSURE_MSG(rc == code, "%s: exit %d, expected %d\nstderr: %s", what, rc, code, g_err);
    for (int i = 0; parts[i]; i++) ENSURE_MSG(strstr(g_err, parts[i]) != NULL, "%s: '%s' not in stderr: %s", what, parts[i], g_err);
}

#define EXPECT_RUN(scene_path, code, ...)                                                              \
    expect_output(run_scene(NULL, (scene_path), "out"), (code), (scene_path), (const char *const[]){__VA_ARGS__, NULL})

/* Runs as an unprivileged user (nobody) when the test is root, so that permissions apply. */
#define EXPECT_RUN_UNPRIVILEGED(scene_path, outdir, code, ...)                                               \
    do {                                                                                                     \
        cli_env env_ = {.unprivileged = 1};                                                                  \
        int rc_ = run_scene(&env_, (scene_path), (outdir));                                                  \
        if (rc_ == CLI_NOT_RUN) printf("  (skipped: cannot run as an unprivileged user)\n");                  \
        else expect_output(rc_, (code), (scene_path), (const char *const[]){__VA_ARGS__, NULL});            \
    } while (0)

static int exists(const char *path)
{
    struct stat st;
    return lstat(path, &st) == 0;
}

/* ---------------------------------------------------------------- the scene file */

static void test_scene_file_unreadable(void)
{
    char path[FM_PATH_MAX], dir[FM_PATH_MAX];
    remove(tmp_path(path, "no_such_scene.json"));
    EXPECT_RUN(path, 2, path, "cannot open the scene file", "No such file");
    mkdir(tmp_path(dir, "scene_dir.json"), 0755);
    EXPECT_RUN(dir, 2, dir, "cannot open the scene file: it is a directory");
    const char *locked = plain_scene("locked.json", "");
    chmod(locked, 0);
    EXPECT_RUN_UNPRIVILEGED(locked, "out", 2, locked, "cannot open the scene file: Permission denied");
    chmod(locked, 0644);
}

/* JSON has no NaN or infinity; a number too large for a double is jansson's syntax error. */
static void test_scene_numbers_not_finite(void)
{
    static const char *const cases[][3] = {{"inf.json", "1e999", "real number overflow"},
                                           {"nan.json", "NaN", "invalid token"},
                                           {"minus_inf.json", "-Infinity", "invalid token"}};
    for (int i = 0; i < 3; i++) {
        char extra[64], where[FM_PATH_MAX + 32];
        snprintf(extra, sizeof extra, ",\n  \"speed0\": %s", cases[i][1]);
        const char *path = plain_scene(cases[i][0], extra);
        snprintf(where, sizeof where, "%s:4:", path); /* jansson's line; its column is where it stopped */
        EXPECT_RUN(path, 2, where, cases[i][2]);
    }
}

/* Every numeric key with a lower bound, at a value below it: "@" marks where the value goes. */
typedef struct bound_case {
    const char *member; /* JSON member(s) with '@' for the value */
    const char *key;    /* as the message names it */
    int positive;       /* 1: must be > 0 (0 is tested too); 0: must be >= 0 */
} bound_case;

static const bound_case BOUND_CASES[] = {
    {"\"n\": @", "n", 0},
    {"\"speed0\": @", "speed0", 1},
    {"\"omega1\": @", "omega1", 1},
    {"\"launch_rate\": @", "launch_rate", 0},
    {"\"seed\": @", "seed", 0},
    {"\"tetgen\": {\"quality\": @}", "tetgen.quality", 1},
    {"\"tetgen\": {\"max_volume\": @}", "tetgen.max_volume", 0},
    {"\"time\": {\"frame_rate\": @}", "time.frame_rate", 1},
    {"\"time\": {\"time_step\": @}", "time.time_step", 0},
    {"\"time\": {\"frame_limit\": @}", "time.frame_limit", 1},
    {"\"path\": {\"key_points\": @}", "path.key_points", 1},
    {"\"path\": {\"width\": @}", "path.width", 0},
    {"\"path\": {\"attraction\": @}", "path.attraction", 0},
    {"\"morph\": {\"shrink\": @}", "morph.shrink", 1},
    {"\"morph\": {\"shrink_time\": @}", "morph.shrink_time", 0},
    {"\"morph\": {\"morph_fraction\": @}", "morph.morph_fraction", 1},
    {"\"style\": {\"omega2\": @}", "style.omega2", 0},
    {"\"style\": {\"grid\": [4, @, 4]}", "style.grid", 0},
    {"\"style\": {\"fields\": [{\"type\": \"curl_noise\", \"gain\": @}]}", "style.fields[0].gain", 0},
    {"\"style\": {\"fields\": [{\"type\": \"curl_noise\", \"scale\": @}]}", "style.fields[0].scale", 1},
    {"\"style\": {\"fields\": [{\"type\": \"wind\", \"speed\": @}]}", "style.fields[0].speed", 0},
    {"\"style\": {\"fields\": [{\"type\": \"wind\", \"turbulence\": @}]}", "style.fields[0].turbulence", 0},
    {"\"style\": {\"fields\": [{\"type\": \"wind\", \"scale\": @}]}", "style.fields[0].scale", 1},
    {"\"style\": {\"fields\": [{\"type\": \"wind\", \"period\": @}]}", "style.fields[0].period", 0},
    {"\"style\": {\"fields\": [{\"type\": \"gravity\", \"speed\": @}]}", "style.fields[0].speed", 0},
    {"\"obstacles\": {\"k_a\": @}", "obstacles.k_a", 1},
    {"\"obstacles\": {\"voxel\": @}", "obstacles.voxel", 0},
    {"\"obstacles\": {\"meshes\": [{\"mesh\": \"" OCTAHEDRON "\", \"scale\": @}]}", "obstacles.meshes[0].scale", 1},
    {"\"mde\": {\"d_min\": @}", "mde.d_min", 0},
    {"\"mde\": {\"speed\": @}", "mde.speed", 0},
};

/* `text` with its '@' replaced by `value`, into out. */
static const char *put_value(const char *text, const char *value, char *out, size_t size)
{
    const char *at = strchr(text, '@');
    snprintf(out, size, "%.*s%s%s", (int)(at - text), text, value, at + 1);
    return out;
}

/* Writes the case's scene with `value` at the '@'. */
static const char *write_bound_case(const bound_case *c, const char *value, int source_member)
{
    char member[512], extra[600];
    put_value(c->member, value, member, sizeof member);
    snprintf(extra, sizeof extra, ",\n  %s", member);
    return source_member ? scene("bound.json", OCTAHEDRON, member, RIGHT, "") : plain_scene("bound.json", extra);
}

/* Expects exit 2, the value's FILE:LINE:COL (where '@' was) and the key. */
static void expect_below_bound(const bound_case *c, const char *value, int source_member)
{
    char where[FM_PATH_MAX + 32], expect[FM_PATH_MAX + 96];
    write_bound_case(c, "@", source_member);
    scene_position("@", where, sizeof where);
    snprintf(expect, sizeof expect, "%s%s: ", where, c->key);
    const char *path = write_bound_case(c, value, source_member);
    EXPECT_RUN(path, 2, expect, "must be >");
}

static void test_numeric_keys_out_of_range(void)
{
    for (size_t i = 0; i < sizeof BOUND_CASES / sizeof BOUND_CASES[0]; i++) {
        expect_below_bound(&BOUND_CASES[i], "-1", 0);
        if (BOUND_CASES[i].positive) expect_below_bound(&BOUND_CASES[i], "0", 0);
    }
    const bound_case source_scale = {"\"scale\": @", "source.scale", 1};
    expect_below_bound(&source_scale, "0", 1);
    expect_below_bound(&source_scale, "-2", 1);
}

/* A bad value of a shape-flock key: `member` (inside "shape_flock") with '@' where `value` goes. */
typedef struct flock_value_case {
    const char *member, *value;
    const char *key;  /* as the message names it */
    const char *what; /* the rest of the message */
} flock_value_case;

static const flock_value_case FLOCK_VALUE_CASES[] = {
    {"\"kalman\": {\"q\": @}", "-1", "shape_flock.kalman.q", "-1 is out of range: must be >= 0"},
    {"\"kalman\": {\"r_position\": @}", "0", "shape_flock.kalman.r_position", "0 is out of range: must be > 0"},
    {"\"kalman\": {\"r_velocity\": @}", "-2", "shape_flock.kalman.r_velocity", "-2 is out of range: must be > 0"},
    {"\"kalman\": {\"q\": @}", "\"big\"", "shape_flock.kalman.q", "expected a number, got a string"},
    {"\"separation\": {\"radius_j\": @}", "-1", "shape_flock.separation.radius_j", "-1 is out of range: must be >= 0"},
    {"\"cohesion\": {\"radius_j\": [2, @]}", "-3", "shape_flock.cohesion.radius_j", "-3 is out of range: must be >= 0"},
    {"\"alignment\": {\"angle\": @}", "0", "shape_flock.alignment.angle", "0 is out of range: must be > 0"},
    {"\"separation\": {\"angle\": [90, @]}", "361", "shape_flock.separation.angle", "361 is out of range: must be <= 360"},
    {"\"cohesion\": {\"angle\": @}", "720", "shape_flock.cohesion.angle", "720 is out of range: must be <= 360"},
    {"\"alignment\": {\"weight\": @}", "-0.5", "shape_flock.alignment.weight", "-0.5 is out of range: must be >= 0"},
    {"\"max_speed\": @", "0", "shape_flock.max_speed", "0 is out of range: must be > 0"},
    {"\"max_speed\": @", "[12, 8]", "shape_flock.max_speed", "the range [12, 8] runs backwards"},
    {"\"max_force\": @", "-1", "shape_flock.max_force", "-1 is out of range: must be >= 0"},
    {"\"mass\": @", "0", "shape_flock.mass", "0 is out of range: must be >= 1e-06"},
    {"\"damping\": @", "-1", "shape_flock.damping", "-1 is out of range: must be >= 0"},
    {"\"external_gain\": @", "-1", "shape_flock.external_gain", "-1 is out of range: must be >= 0"},
    {"\"path_time\": @", "-1", "shape_flock.path_time", "-1 is out of range: must be >= 0"},
    {"\"fuzzy\": {\"homing\": [[0, 1], [2, @]]}", "-1", "shape_flock.fuzzy.homing", "-1 is out of range: must be >= 0"},
    {"\"arrival\": {\"radius\": @}", "-1", "shape_flock.arrival.radius", "-1 is out of range: must be >= 0"},
    {"\"arrival\": {\"time\": @}", "0", "shape_flock.arrival.time", "0 is out of range: must be > 0"},
    {"\"arrival\": {\"turn_rate\": @}", "0", "shape_flock.arrival.turn_rate", "0 is out of range: must be > 0"},
    {"\"arrival\": {\"bind_distance\": @}", "-1", "shape_flock.arrival.bind_distance", "-1 is out of range: must be >= 0"},
    {"\"arrival\": {\"float_period\": @}", "0", "shape_flock.arrival.float_period", "0 is out of range: must be > 0"},
    {"\"arrival\": {\"mode\": @}", "\"hover\"", "shape_flock.arrival.mode", "expected \"bind\" or \"float\""},
    {"\"sampling\": @", "\"poisson\"", "shape_flock.sampling", "expected \"random\", \"mosaic\" or \"stratified\""},
    {"\"deform\": {\"type\": \"wave\", \"period\": @}", "0", "shape_flock.deform.period", "0 is out of range: must be > 0"},
    {"\"deform\": {\"type\": \"wave\", \"wavelength\": @}", "-4", "shape_flock.deform.wavelength", "-4 is out of range: must be > 0"},
    {"\"kalman\": {\"r_scale\": {\"over\": @}}", "\"time\"", "shape_flock.kalman.r_scale.over",
     "expected \"none\", \"distance\" or \"leader_speed\""},
    {"\"kalman\": {\"r_scale\": {\"over\": \"distance\", \"points\": [[0, 1], [2, @]]}}", "0",
     "shape_flock.kalman.r_scale.points", "0 is out of range: must be > 0"},
    {"\"kalman\": {\"r_scale\": {\"over\": \"none\", @: [[0, 2]]}}", "\"points\"", "shape_flock.kalman.r_scale.points",
     "set shape_flock.kalman.r_scale.over to \"distance\" or \"leader_speed\": the curve's x is one of them"},
    {"\"kalman\": {\"r_scale\": {\"over\": @}}", "\"leader_speed\"", "shape_flock.kalman.r_scale.over",
     "\"leader_speed\" needs shape_flock.kalman.r_scale.points: the default points are distances"},
    {"\"fuzzy\": {\"strategy\": @}", "\"dynamic\"", "shape_flock.fuzzy.strategy", "expected \"auto\", \"static\" or \"tracking\""},
    {"\"separation\": {\"radius\": [1, 2], @: [20, 40]}", "\"radius_j\"", "shape_flock.separation.radius_j",
     "give shape_flock.separation.radius (in spacings) or shape_flock.separation.radius_j (SCF's J), not both"},
    {"\"kalman\": {@: 1}", "\"qq\"", "shape_flock.kalman.qq", "unknown key"}, /* '@' at the key */
};

/* Each bad flock value: exit 2, the '@''s FILE:LINE:COL, the key and what is wrong. */
static void test_flock_values_out_of_range(void)
{
    for (size_t i = 0; i < sizeof FLOCK_VALUE_CASES / sizeof FLOCK_VALUE_CASES[0]; i++) {
        const flock_value_case *c = &FLOCK_VALUE_CASES[i];
        char extra[600], filled[640], where[FM_PATH_MAX + 32], expect[FM_PATH_MAX + 96];
        snprintf(extra, sizeof extra, FLOCK ",\n  \"shape_flock\": {%s}", c->member);
        plain_scene("flock_value.json", extra);
        scene_position("@", where, sizeof where);
        snprintf(expect, sizeof expect, "%s%s: %s", where, c->key, c->what);
        EXPECT_RUN(plain_scene("flock_value.json", put_value(extra, c->value, filled, sizeof filled)), 2, expect);
    }
}

/* The octahedron scene with `extra`: exit 2, the position of `at` in the text, the key, `what`. */
static void expect_scene_error(const char *name, const char *extra, const char *at, const char *key, const char *what)
{
    char where[FM_PATH_MAX + 32];
    const char *path = plain_scene(name, extra);
    EXPECT_RUN(path, 2, scene_position(at, where, sizeof where), key, what);
}

/* Values each fine alone that do not fit together. */
static void test_scene_consistency(void)
{
    expect_scene_error("grid.json", ",\n  \"style\": {\"grid\": [8, 0, 8]}", "[8, 0, 8]", "style.grid", "give all three");
    expect_scene_error("huge_grid.json", ",\n  \"style\": {\"grid\": [2048, 2048, 2048]}", "[2048", "style.grid",
                       "more than the 2^28 supported");
    expect_scene_error("gravity.json", ",\n  \"style\": {\"fields\": [{\"type\": \"gravity\", \"direction\": [0, 0, 0]}]}",
                       "[0, 0, 0]", "style.fields[0].direction", "must not be [0, 0, 0]");
    expect_scene_error("vortex.json", ",\n  \"style\": {\"fields\": [{\"type\": \"vortex\", \"axis\": [0, 0, 0]}]}",
                       "[0, 0, 0]", "style.fields[0].axis", "must not be [0, 0, 0]");
    expect_scene_error("tiny_step.json", ",\n  \"time\": {\"frame_rate\": 25, \"time_step\": 1e-9}", "1e-9",
                       "time.time_step", "steps per frame");
}

static void test_output_cache_name(void)
{
    expect_scene_error("cache_slash.json", ",\n  \"output\": {\"cache\": \"sub/frames.fmc\"}", "\"sub/", "output.cache",
                       "not a plain file name");
    expect_scene_error("cache_empty.json", ",\n  \"output\": {\"cache\": \"\"}", "\"\"", "output.cache",
                       "not a plain file name");
}

/* A cache named like another file of the run (stats.json, the checkpoint, the lock) or like a file
 * being written (*.partial) is refused before anything in the output directory is touched. */
static void test_output_cache_name_taken(void)
{
    static const char *const cases[][2] = {{"stats.json", "another file the run writes"},
                                           {"checkpoint.fmck", "another file the run writes"},
                                           {".flockmorph.lock", "another file the run writes"},
                                           {"frames.fmc.partial", "ends in .partial"},
                                           {"stats.json.partial", "ends in .partial"}};
    char outdir[FM_PATH_MAX], stats[FM_PATH_MAX + 16], args[3 * FM_PATH_MAX], kept[64];
    mkdir(tmp_path(outdir, "taken_out"), 0755);
    snprintf(stats, sizeof stats, "%s/stats.json", outdir);
    for (int i = 0; i < 5; i++) {
        char extra[128], at[64], where[FM_PATH_MAX + 32];
        snprintf(extra, sizeof extra, ",\n  \"output\": {\"cache\": \"%s\"}", cases[i][0]);
        snprintf(at, sizeof at, "\"%s\"}", cases[i][0]);
        const char *path = plain_scene("cache_taken.json", extra);
        scene_position(at, where, sizeof where);
        write_text(stats, "{\"an older run\": true}");
        snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", path, outdir);
        expect_output(cli(args), 2, cases[i][0], (const char *const[]){where, "output.cache", cases[i][1], NULL});
        slurp(stats, kept, sizeof kept);
        ENSURE_MSG(!strcmp(kept, "{\"an older run\": true}"), "%s: stats.json changed to '%s'", cases[i][0], kept);
    }
}

/* ---------------------------------------------------------------- meshes */

/* A scene whose source is `mesh_name` (in the scratch directory); `where` gets the position of the
 * source.mesh value. */
static const char *mesh_scene(const char *mesh_name, char *where, size_t size)
{
    char file[FM_PATH_MAX], quoted[FM_PATH_MAX + 2];
    snprintf(file, sizeof file, "bad_%s", mesh_name);
    const char *path = scene("mesh.json", file, LEFT, RIGHT, "");
    snprintf(quoted, sizeof quoted, "\"%s\"", file);
    scene_position(quoted, where, size);
    strncat(where, "source.mesh: ", size - strlen(where) - 1);
    return path;
}

/* Runs a scene with the bad mesh as its source; expects exit 2, the scene position, the mesh's
 * path and `what`. */
static void expect_bad_mesh(const char *mesh_name, const char *what)
{
    char where[FM_PATH_MAX + 64], mesh[FM_PATH_MAX];
    const char *path = mesh_scene(mesh_name, where, sizeof where);
    EXPECT_RUN(path, 2, where, tmp_path(mesh, mesh_name), what);
}

static void write_mesh(const char *name, const char *text)
{
    char path[FM_PATH_MAX];
    write_text(tmp_path(path, name), text);
}

static void test_mesh_file_unreadable(void)
{
    char mesh[FM_PATH_MAX];
    remove(tmp_path(mesh, "missing.obj"));
    expect_bad_mesh("missing.obj", "cannot open the mesh: No such file");
    mkdir(tmp_path(mesh, "folder.obj"), 0755);
    expect_bad_mesh("folder.obj", "cannot open the mesh: it is a directory");
    write_octahedron(tmp_path(mesh, "locked.obj"));
    chmod(mesh, 0);
    char where[FM_PATH_MAX + 64];
    const char *path = mesh_scene("locked.obj", where, sizeof where);
    EXPECT_RUN_UNPRIVILEGED(path, "locked_out", 2, where, mesh, "cannot open the mesh: Permission denied");
    chmod(mesh, 0644);
}

static void write_binary(const char *name, const void *bytes, size_t len)
{
    char path[FM_PATH_MAX];
    FILE *f = fopen(tmp_path(path, name), "wb");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (f) fwrite(bytes, 1, len, f), fclose(f);
}

/* Tiny files whose headers claim two billion elements: refused as damaged from the file's size,
 * before assimp allocates for the count (the run's address space is limited to 2 GiB, so a
 * regression fails here rather than exhausting the machine). */
static void test_mesh_counts_beyond_file(void)
{
    write_mesh("huge_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 2000000000\nproperty float x\nproperty float y\n"
               "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n");
    write_mesh("huge_binary.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
               "property float y\nproperty float z\nelement face 2000000000\nproperty list uchar int vertex_indices\n"
               "end_header\nVERTEX 1 x y zVERTEX 2 x y zVERTEX 3 x y z"); /* 36 bytes: 3 vertices */
    write_mesh("huge.off", "OFF\n# a comment\n2000000000 1 0\n0 0 0\n");
    unsigned char stl[84 + 50] = {0};
    stl[80] = 0x00, stl[81] = 0x94, stl[82] = 0x35, stl[83] = 0x77; /* 2e9 triangles, one present */
    write_binary("huge.stl", stl, sizeof stl);
    static const char *const cases[][2] = {{"huge_ascii.ply", "2000000000 'vertex' elements"}, {"huge_binary.ply", "2000000000 'face' elements"},
                                           {"huge.off", "2000000000 vertices"}, {"huge.stl", "2000000000 triangles"}};
    for (int i = 0; i < 4; i++) {
        char where[FM_PATH_MAX + 64], mesh[FM_PATH_MAX];
        const char *path = mesh_scene(cases[i][0], where, sizeof where);
        cli_env limited = {.memory_limit = 2LL << 30};
        expect_output(run_scene(&limited, path, "out"), 2, cases[i][0],
                      (const char *const[]){where, tmp_path(mesh, cases[i][0]), cases[i][1], "damaged or cut short", NULL});
    }
}

/* A PLY face whose list of indices is empty (count 0): assimp's triangulation asserted on it and
 * aborted the process (found by fuzz_ply_binary; tests/fuzz/regressions/ply_binary). Now exit 2
 * naming the file and the face, in the binary and the ASCII form. */
static void test_mesh_face_without_indices(void)
{
    static const char head[] = "ply\nformat %s 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                               "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n";
    static const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    static const int32_t f[3][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}};
    unsigned char bin[512];
    size_t len = (size_t)snprintf((char *)bin, sizeof bin, head, "binary_little_endian"); /* the test runs on x86 */
    memcpy(bin + len, v, sizeof v), len += sizeof v;
    for (int k = 0; k < 3; k++) bin[len++] = 3, memcpy(bin + len, f[k], sizeof f[k]), len += sizeof f[k];
    bin[len++] = 0; /* the fourth face: no indices */
    write_binary("face_without_indices.ply", bin, len);
    char text[512];
    snprintf(text, sizeof text, head, "ascii");
    strncat(text, "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n0\n", sizeof text - strlen(text) - 1);
    write_mesh("face_without_indices_ascii.ply", text);
    expect_bad_mesh("face_without_indices.ply", "face 4 (of mesh 1 in the file) has no vertex indices: the file is damaged");
    expect_bad_mesh("face_without_indices_ascii.ply", "face 4 (of mesh 1 in the file) has no vertex indices");
}

/* A binary PLY face whose list count (uint) says 4294967280 entries, with 12 bytes after it: assimp
 * sized the list from the count (34 GB) before reading it; a 300-byte file took 2.2 GB this way.
 * Refused from the file's size, under a 2 GiB address space like the counts above. */
static void test_mesh_list_longer_than_file(void)
{
    static const char head[] = "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty "
                               "float y\nproperty float z\nelement face 4\nproperty list uint int vertex_indices\nend_header\n";
    static const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    static const uint32_t f[4][4] = {{3, 0, 2, 1}, {3, 0, 1, 3}, {3, 0, 3, 2}, {4294967280u, 1, 2, 3}};
    unsigned char bin[512];
    size_t len = sizeof head - 1;
    memcpy(bin, head, len);
    memcpy(bin + len, v, sizeof v), len += sizeof v; /* little-endian: the test runs on x86 */
    memcpy(bin + len, f, sizeof f), len += sizeof f;
    write_binary("list_too_long.ply", bin, len);
    char where[FM_PATH_MAX + 64], mesh[FM_PATH_MAX];
    const char *path = mesh_scene("list_too_long.ply", where, sizeof where);
    cli_env limited = {.memory_limit = 2LL << 30};
    expect_output(run_scene(&limited, path, "out"), 2, "list_too_long.ply",
                  (const char *const[]){where, tmp_path(mesh, "list_too_long.ply"), "'face' element 4: the list "
                                        "'vertex_indices' declares 4294967280 entries of 4 bytes, but 12 bytes are left "
                                        "in the file: it is damaged or cut short", NULL});
}

/* The same in an ASCII PLY: a face line whose count says 3·10^8 (assimp sized the list from it:
 * 4.7 GB for a 200-byte file). */
static void test_mesh_ascii_list_longer_than_file(void)
{
    write_mesh("ascii_list_too_long.ply",
               "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
               "element face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
               "3 0 2 1\n3 0 1 3\n3 0 3 2\n300000000 1 2 3\n");
    char where[FM_PATH_MAX + 64], mesh[FM_PATH_MAX];
    const char *path = mesh_scene("ascii_list_too_long.ply", where, sizeof where);
    cli_env limited = {.memory_limit = 2LL << 30};
    expect_output(run_scene(&limited, path, "out"), 2, "ascii_list_too_long.ply",
                  (const char *const[]){where, tmp_path(mesh, "ascii_list_too_long.ply"), "'face' element 4: the list "
                                        "'vertex_indices' declares 300000000 entries, but 6 bytes are left in the file",
                                        NULL});
    /* a well-formed ASCII PLY still imports (the walk refuses nothing that fits) */
    write_mesh("ascii_ok.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
               "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n"
               "1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3");
    path = mesh_scene("ascii_ok.ply", where, sizeof where);
    int rc = run_scene(NULL, path, "out_ok");
    ENSURE_MSG(!strstr(g_err, "declares") && !strstr(g_err, "ascii_ok.ply"),
               "a valid ASCII PLY (no newline at the end) was refused (exit %d): %s", rc, g_err);
}

static void test_mesh_empty_or_not_a_mesh(void)
{
    write_mesh("empty.obj", "");
    expect_bad_mesh("empty.obj", "cannot read the mesh");
    write_mesh("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n");
    expect_bad_mesh("points.obj", "cannot read the mesh");
    write_mesh("mesh.xyz", "solid nonsense\n 1 2 3\n");
    expect_bad_mesh("mesh.xyz", "supported: OBJ, PLY, STL, OFF, glTF");
    write_mesh("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    expect_bad_mesh("nan.obj", "non-finite");
}

/* Random bytes under each known extension: an error naming the file, never a crash. */
static void test_mesh_garbage_bytes(void)
{
    static const char *names[] = {"garbage.obj", "garbage.ply", "garbage.stl", "garbage.off", "garbage.gltf", "garbage.glb"};
    uint64_t rng = 7;
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        char path[FM_PATH_MAX];
        FILE *f = fopen(tmp_path(path, names[i]), "wb");
        ENSURE(f != NULL);
        if (!f) return;
        for (int k = 0; k < 4000; k++) fputc((int)(test_next_u64(&rng) & 0xFF), f);
        fclose(f);
        expect_bad_mesh(names[i], names[i]);
    }
}

/* The octahedron without its last triangle: three edges have one triangle each. */
static void test_mesh_open(void)
{
    char path[FM_PATH_MAX], text[1024];
    write_octahedron(tmp_path(path, "open.obj"));
    slurp(path, text, sizeof text);
    *strrchr(text, 'f') = 0;
    write_mesh("open.obj", text);
    expect_bad_mesh("open.obj", "has no neighbour: the surface has a hole there");
}

/* Octahedra centred at the origin and at (1, 1, 0) share the edge (1, 0, 0)-(0, 1, 0) and
 * nothing else: four triangles meet at it. */
static void test_mesh_non_manifold(void)
{
    char path[FM_PATH_MAX];
    write_octahedra(tmp_path(path, "shared_edge.obj"), (const double[][3]){{0, 0, 0}, {1, 1, 0}}, 2);
    expect_bad_mesh("shared_edge.obj", "is shared by more than two triangles");
}

/* Octahedra centred at the origin and at (1, 0, 0): the first one's four +x triangles (1, 3, 5,
 * 7) cross the second one's four -x triangles (8 + 2, 4, 6, 8); no other pair meets. TetGen's
 * detection names them. */
static void test_mesh_self_intersecting(void)
{
    char path[FM_PATH_MAX];
    write_octahedra(tmp_path(path, "crossing.obj"), (const double[][3]){{0, 0, 0}, {1, 0, 0}}, 2);
    expect_bad_mesh("crossing.obj", "the surface intersects itself: TetGen finds triangles 1, 3, 5, 7, 10, 12, 14, 16 crossing");
}

static void test_mesh_degenerate(void)
{
    /* a tetrahedron whose bottom edge (0,0,0)-(2,0,0) is split at (1,0,0) on one side only, closed
     * by the zero-area triangle 3 along that edge */
    write_mesh("zero_area.obj", "v 0 0 0\nv 2 0 0\nv 0 2 0\nv 0 0 2\nv 1 0 0\n"
                                "f 1 3 5\nf 5 3 2\nf 1 5 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    expect_bad_mesh("zero_area.obj", "triangle 3 (corner (0, 0, 0)) is degenerate: zero area");
    /* two triangles back to back: closed and manifold, but flat (TetGen used to abort on it) */
    write_mesh("flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n");
    expect_bad_mesh("flat.obj", "the mesh encloses no volume");
    /* the same, tilted out of the axis planes */
    write_mesh("tilted.obj", "v 0 0 0\nv 1 1 0\nv 0 1 1\nf 1 2 3\nf 1 3 2\n");
    expect_bad_mesh("tilted.obj", "the mesh encloses no volume");
}

/* The octahedron with its first triangle wound the other way: closed and manifold, but that
 * triangle faces inward, so each of its edges runs the same way in it and in its neighbour. */
static void test_mesh_flipped_triangle(void)
{
    char path[FM_PATH_MAX], text[1024];
    write_octahedron(tmp_path(path, "flipped.obj"));
    slurp(path, text, sizeof text);
    char *face = strstr(text, "\nf ") + 1;
    int a, b, c, len;
    ENSURE(sscanf(face, "f %d %d %d%n", &a, &b, &c, &len) == 3);
    char flipped[64];
    snprintf(flipped, sizeof flipped, "f %d %d %d", a, c, b); /* same length: indices below 10 */
    memcpy(face, flipped, (size_t)len);
    write_mesh("flipped.obj", text);
    expect_bad_mesh("flipped.obj", "of triangle 1 runs the same way in both of its triangles: their orientations disagree");
}

/* A ninth triangle whose first two corners are the same point given twice (vertex 7 repeats vertex
 * 1; the import welds equal positions). */
static void test_mesh_repeated_corner(void)
{
    char path[FM_PATH_MAX], text[1024];
    write_octahedron(tmp_path(path, "repeated_corner.obj"));
    slurp(path, text, sizeof text);
    strncat(text, "v 1 0 0\nf 1 7 3\n", sizeof text - strlen(text) - 1);
    write_mesh("repeated_corner.obj", text);
    expect_bad_mesh("repeated_corner.obj", "triangle 9 is degenerate (two corners at the same position)");
}

/* An OBJ of lines only: assimp reads it, but there is no surface. */
static void test_mesh_lines_only(void)
{
    write_mesh("lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nl 1 2\nl 2 3\nl 3 4\nl 4 1\n");
    expect_bad_mesh("lines.obj", "the mesh has no triangles");
}

/* A scale allowed by its range (> 0) that leaves the placed mesh too small for float32 (and, at
 * translate -10, rounds every vertex to one point, on which TetGen used to assert and abort): exit 2
 * at the mesh's key, in both modes, for the source, the target and an obstacle. */
static void test_mesh_too_small_when_placed(void)
{
    static const char *const cases[][3] = {
        {"tiny_far.json", "\"translate\": [-10, 0, 0], \"scale\": 1e-30", RIGHT},
        {"tiny_origin.json", "\"scale\": 1e-30", RIGHT},
        {"tiny_relative.json", "\"translate\": [-10, 0, 0], \"scale\": 1e-6", RIGHT},
        {"tiny_target.json", LEFT, "\"translate\": [10, 0, 0], \"scale\": 1e-30"}};
    for (int i = 0; i < 4; i++)
        for (int flock = 0; flock < 2; flock++) {
            char where[FM_PATH_MAX + 64];
            const char *path = scene(cases[i][0], OCTAHEDRON, cases[i][1], cases[i][2], flock ? FLOCK ",\n  \"n\": 50" : "");
            scene_position(i == 3 ? "\"" OCTAHEDRON "\", \"translate\": [10" : "\"" OCTAHEDRON "\"", where, sizeof where);
            strncat(where, i == 3 ? "target.mesh: " : "source.mesh: ", sizeof where - strlen(where) - 1);
            cli_env watched = {.seconds = 60};
            expect_output(run_scene(&watched, path, "out"), 2, cases[i][0],
                          (const char *const[]){where, "placed in the world", "float32 precision", NULL});
        }
    const char *path = plain_scene("tiny_obstacle.json", ",\n  \"obstacles\": {\"meshes\": [{\"mesh\": \"" OCTAHEDRON
                                   "\", \"translate\": [0, 5, 0], \"scale\": 1e-30}]}");
    EXPECT_RUN(path, 2, "obstacles.meshes[0]", "placed in the world");
}

/* ---------------------------------------------------------------- n */

static void test_n_too_small(void)
{
    char where[FM_PATH_MAX + 32];
    const char *path = plain_scene("n_small.json", ",\n  \"n\": 2");
    EXPECT_RUN(path, 2, scene_position("2\n", where, sizeof where), "n: 2 is smaller than the", "tets TetGen made for");
}

/* Bytes allocated on the heap now (glibc's accounting, or ASan's under the sanitizer build). */
static double allocated_bytes(void)
{
#if defined(__SANITIZE_ADDRESS__)
    return (double)__sanitizer_get_current_allocated_bytes();
#else
    struct mallinfo2 mi = mallinfo2();
    return (double)mi.uordblks + (double)mi.hblkhd;
#endif
}

/* The octahedron 20 units from itself with 200000 agents, in `mode`. */
static fm_scene_def estimate_scene(fm_mode mode)
{
    char mesh[FM_PATH_MAX];
    write_octahedron(tmp_path(mesh, "octahedron.obj"));
    fm_scene_def def = fm_default_scene_def();
    def.mode = mode;
    snprintf(def.source.path, sizeof def.source.path, "%s", mesh);
    snprintf(def.target.path, sizeof def.target.path, "%s", mesh);
    def.source.translate[0] = -10, def.target.translate[0] = 10;
    def.n = 200000;
    return def;
}

/* The bytes allocated since `before` are within 5 % of the estimate e's part for n agents: `per_agent`
 * × n and the cache encoder's scratch, the part of e.fixed past the grids and libraries (a block a
 * thread, allocated with the first frame). */
static void expect_estimate(const fm_scene_def *def, double before, const fm_memory_estimate *e, double per_agent,
                            const char *parts)
{
    const double scratch = e->fixed - fm_memory_fixed_bytes(def), n = (double)def->n;
    double used = allocated_bytes() - before, estimated = per_agent * n + scratch;
    ENSURE_MSG(used > 0.95 * estimated && used < 1.05 * estimated, "allocated %.0f bytes, estimated %.0f (%.1f vs %.1f per agent)",
               used, estimated, used / n, estimated / n);
    printf("  allocated %.1f bytes per agent, estimated %.1f: %.1f per agent and %.1f MB of encoder scratch%s\n", used / n,
           estimated / n, per_agent, scratch / 1e6, parts);
}

/* Hands the writer its first frame, with which it makes its frame buffers, and waits until the frame
 * is written. Returns what zstd's compressors hold for their work then: fixed, not per agent (the
 * estimate's fixed part counts it), so left out of the comparison. Asked of zstd, not measured
 * around the flush: the writer's thread may have started compressing (and allocating) before the
 * frame was handed over. */
static double first_frame(fm_cache_writer *w, const void *const *data)
{
    fm_error err = {0};
    ENSURE_MSG(fm_cache_writer_add_frame_attrs(w, data, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(fm_cache_writer_flush(w, &err) == FM_OK, "%s", err.message);
    return (double)fm_cache_writer_zstd_bytes(w);
}

/* The estimate follows the real allocations: model, agent store, the run's frame and the cache
 * writer's buffers (made with its first frame, handed over here) for 200000 agents, measured by
 * the allocator. */
static void test_memory_estimate_matches_allocations(void)
{
    char cache[FM_PATH_MAX];
    fm_scene_def def = estimate_scene(FM_MODE_TETRA_MORPH);
    fm_error err = {0};
    double before = allocated_bytes();
    fm_morph_model *model = fm_morph_model_build(&def, NULL, NULL, &err);
    fm_morph_state *state = model ? fm_morph_state_create(model, 1, &err) : NULL;
    float *frame = malloc(sizeof(float) * 12 * (size_t)def.n);
    uint8_t *phases = malloc((size_t)def.n);
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_ID, FM_ATTR_PHASE}; /* as tools/cli_run.c */
    fm_cache_writer *w = state ? fm_cache_writer_create_attrs(tmp_path(cache, "estimate.fmc"), (uint64_t)def.n, 24, attrs, 3,
                                                              NULL, &err)
                               : NULL;
    ENSURE_MSG(w != NULL && frame != NULL && phases != NULL, "%s", err.message);
    fm_morph_tet_vertices(model, state, frame); /* the writer makes its frame buffers with its first frame */
    fm_morph_phases(state, phases);
    const void *data[] = {frame, fm_cache_writer_ids(w), phases};
    before += first_frame(w, data);
    fm_memory_estimate e = fm_morph_memory_estimate(&def, def.n);
    expect_estimate(&def, before, &e, e.model + e.state + e.frames, "");
    fm_cache_writer_abort(w);
    free(frame), free(phases);
    fm_morph_state_destroy(state);
    fm_morph_model_destroy(model);
}

/* The same for the shape flock: model, agent store (with its neighbour grid), the run's frame
 * (position, velocity, orientation, phase) and the cache writer. */
static void test_flock_memory_estimate_matches_allocations(void)
{
    char cache[FM_PATH_MAX], parts[128];
    fm_scene_def def = estimate_scene(FM_MODE_SHAPE_FLOCK);
    fm_error err = {0};
    double before = allocated_bytes();
    fm_flock_model *model = fm_flock_model_build(&def, NULL, NULL, &err);
    fm_flock_state *state = model ? fm_flock_state_create(model, 1, &err) : NULL;
    void *frame = malloc((sizeof(float) * 10 + 1) * (size_t)def.n);
    fm_cache_writer *w = state ? fm_flock_cache_create(tmp_path(cache, "flock_estimate.fmc"), model, NULL, &err) : NULL;
    ENSURE_MSG(w != NULL && frame != NULL, "%s", err.message);
    float *position = frame, *velocity = position + 3 * def.n, *orientation = velocity + 3 * def.n;
    uint8_t *phase = (uint8_t *)(orientation + 4 * def.n);
    fm_flock_frame(state, position, velocity, orientation, phase); /* the writer's buffers come with its first frame */
    const void *data[] = {position, velocity, orientation, fm_cache_writer_ids(w), phase};
    before += first_frame(w, data);
    fm_memory_estimate e = fm_memory_estimate_for(&def, def.n);
    snprintf(parts, sizeof parts, " (model %.1f, store %.1f, frames %.1f, grid %.1f)", e.model, e.state, e.frames, e.grid);
    expect_estimate(&def, before, &e, e.per_agent, parts);
    fm_cache_writer_abort(w);
    free(frame);
    fm_flock_state_destroy(state);
    fm_flock_model_destroy(model);
}

/* n beyond physical memory is refused before anything is built, with the estimate of the scene's
 * mode (`mode_member` selects it). */
static void expect_n_too_large(const char *name, fm_mode mode, const char *mode_member)
{
    fm_scene_def def = fm_default_scene_def();
    def.mode = mode;
    double physical = fm_physical_memory(), per_agent = fm_memory_estimate_for(&def, 1000).per_agent;
    long long n = (long long)(1.25 * physical / per_agent);
    if (physical <= 0 || n > 1000000000) {
        printf("  (skipped: this machine's memory fits the largest n a scene accepts)\n");
        return;
    }
    char extra[96], where[FM_PATH_MAX + 32], need[96];
    snprintf(extra, sizeof extra, "%s,\n  \"n\": %lld", mode_member, n);
    const char *path = plain_scene(name, extra);
    snprintf(extra, sizeof extra, "%lld", n);
    fm_memory_estimate e = fm_memory_estimate_for(&def, n);
    snprintf(need, sizeof need, "n: %lld agents need about %.1f GiB (%.0f bytes per agent", n, e.total / 1073741824.0, e.per_agent);
    EXPECT_RUN(path, 2, scene_position(extra, where, sizeof where), need, "physical memory", "docs/limits.md");
}

static void test_n_too_large_for_memory(void) { expect_n_too_large("n_large.json", FM_MODE_TETRA_MORPH, ""); }

/* The shape flock's own estimate (fm_flock_memory_estimate), checked before its per-agent arrays. */
static void test_flock_n_too_large_for_memory(void)
{
    expect_n_too_large("flock_n_large.json", FM_MODE_SHAPE_FLOCK, FLOCK);
}

/* A shot whose groups each fit the machine but not together is refused before any is built, naming
 * the groups (fm_memory_check_shot); `mode_member` selects the mode. */
static void expect_shot_too_large(const char *name, fm_mode mode, const char *mode_member)
{
    fm_scene_def def = fm_default_scene_def();
    def.mode = mode;
    double physical = fm_physical_memory(), per_agent = fm_memory_estimate_for(&def, 1000).per_agent;
    long long n = (long long)(0.7 * physical / per_agent); /* one group fits, two side by side do not */
    if (physical <= 0 || n > 1000000000) {
        printf("  (skipped: this machine's memory fits the largest n a scene accepts)\n");
        return;
    }
    char oct[FM_PATH_MAX], expected[64];
    write_octahedron(tmp_path(oct, "octahedron.obj"));
    snprintf(g_scene_text, sizeof g_scene_text,
             "{\n  \"n\": %lld%s,\n  \"groups\": [\n"
             "    {\"name\": \"a\", \"source\": {\"mesh\": \"" OCTAHEDRON "\", " LEFT "}, "
             "\"target\": {\"mesh\": \"" OCTAHEDRON "\", " RIGHT "}},\n"
             "    {\"name\": \"b\", \"after\": \"a\", \"source\": {\"mesh\": \"" OCTAHEDRON "\", " RIGHT "}, "
             "\"target\": {\"mesh\": \"" OCTAHEDRON "\", " LEFT "}}\n  ]\n}\n", n, mode_member);
    write_text(tmp_path(g_scene, name), g_scene_text);
    snprintf(expected, sizeof expected, "the shot's 2 groups (a %.3g, b %.3g agents)", (double)n, (double)n);
    EXPECT_RUN(g_scene, 2, expected, "together", "physical memory", "lower the groups' n");
}

static void test_shot_too_large_for_memory(void) { expect_shot_too_large("shot_large.json", FM_MODE_TETRA_MORPH, ""); }
static void test_flock_shot_too_large_for_memory(void)
{
    expect_shot_too_large("flock_shot_large.json", FM_MODE_SHAPE_FLOCK, FLOCK);
}

/* ---------------------------------------------------------------- the path and obstacles */

static void test_path_too_short(void)
{
    char where[FM_PATH_MAX + 32];
    const char *path = scene("path_short.json", OCTAHEDRON, "\"translate\": [3, 0, 0]", "\"translate\": [3, 0, 0]", "");
    EXPECT_RUN(path, 2, scene_position("[3, 0, 0]}\n}", where, sizeof where), "target.translate",
               "fewer than two distinct points");
}

#define OBSTACLE_AT(where) ",\n  \"obstacles\": {\"meshes\": [{\"mesh\": \"" OCTAHEDRON "\", " where "}]}"
/* The same with the voxel of a coarse distance grid, for scenes that run to their end: the default
 * (1/160 of the extent) took 2 s of a run's 2.8 s of CPU (Release) to build the grid, and 8 s under
 * the sanitizers. What is refused, and why, does not depend on the grid (the refusals above). */
#define COARSE_OBSTACLE_AT(where) ",\n  \"obstacles\": {\"voxel\": 0.15, \"meshes\": [{\"mesh\": \"" OCTAHEDRON "\", " where "}]}"

static void test_path_end_inside_obstacle(void)
{
    char where[FM_PATH_MAX + 32];
    const char *path = plain_scene("path_last.json", ",\n  \"path\": {\"points\": [[0, 6, 0], [0.2, 0, 0]]}"
                                   OBSTACLE_AT("\"translate\": [0, 0, 0]"));
    EXPECT_RUN(path, 2, scene_position("[0.2, 0, 0]", where, sizeof where), "path.points[1]: the last path point (0.2, 0, 0) lies inside obstacles.meshes[0]");
    path = plain_scene("path_first.json", ",\n  \"path\": {\"points\": [[0.2, 0, 0], [0, 6, 0]]}"
                       OBSTACLE_AT("\"translate\": [0, 0, 0]"));
    EXPECT_RUN(path, 2, scene_position("[0.2, 0, 0]", where, sizeof where), "path.points[0]: the first path point (0.2, 0, 0) lies inside obstacles.meshes[0]");
    /* a source of two octahedra 6 apart has its centroid C_S between them, in the obstacle there */
    char mesh[FM_PATH_MAX];
    write_octahedra(tmp_path(mesh, "pair.obj"), (const double[][3]){{-3, 0, 0}, {3, 0, 0}}, 2);
    path = scene("centroid.json", "bad_pair.obj", LEFT, "\"translate\": [20, 0, 0]",
                 OBSTACLE_AT("\"translate\": [-10, 0, 0], \"scale\": 0.5"));
    EXPECT_RUN(path, 2, scene_position("{\"mesh\": \"" OCTAHEDRON "\", \"translate\": [-10", where, sizeof where),
               "the source centroid C_S (where the path starts) (-10, 0, 0) lies inside obstacles.meshes[0]");
}

/* An obstacle crossing the source, around the target, inside the source: exit 2 naming the
 * obstacle and how it overlaps; `mode_member` selects the mode, `agents` what the message calls them. */
static void expect_obstacle_overlaps(const char *mode_member, const char *agents)
{
    char where[FM_PATH_MAX + 32], extra[512], would[64];
    snprintf(would, sizeof would, "; %s would start or end inside it", agents);
    snprintf(extra, sizeof extra, "%s" OBSTACLE_AT("\"translate\": [-9, 0, 0]"), mode_member);
    const char *path = plain_scene("obstacle_cross.json", extra);
    EXPECT_RUN(path, 2, scene_position("{\"mesh\": \"" OCTAHEDRON "\", \"translate\": [-9", where, sizeof where),
               "obstacles.meshes[0]: the obstacle overlaps the source: their surfaces intersect", would);
    snprintf(extra, sizeof extra, "%s" OBSTACLE_AT("\"translate\": [10, 0, 0], \"scale\": 3"), mode_member);
    path = plain_scene("obstacle_around.json", extra);
    EXPECT_RUN(path, 2, "the obstacle overlaps the target: the target lies inside obstacles.meshes[0]", would);
    snprintf(extra, sizeof extra, "%s" OBSTACLE_AT("\"translate\": [-10, 0, 0], \"scale\": 0.3"), mode_member);
    path = plain_scene("obstacle_inside.json", extra);
    EXPECT_RUN(path, 2, "the obstacle overlaps the source: obstacles.meshes[0] lies inside the source", would);
}

static void test_obstacle_overlaps_source_or_target(void) { expect_obstacle_overlaps("", "tets"); }

/* The shape flock refuses the same obstacles: its agents start and end on the two surfaces. */
static void test_flock_obstacle_overlaps_source_or_target(void)
{
    expect_obstacle_overlaps(FLOCK ",\n  \"n\": 200", "agents");
}

/* What the shape flock does not refuse (docs/errors.md says why): a path point inside an obstacle
 * (no agent has to reach it: each follows its own copy of the path from its start to its
 * destination, SCF eq 12), and an obstacle in the hollow of an open surface (it has no inside). */
static void test_flock_obstacle_allowed(void)
{
    const char *path = plain_scene("flock_obstacle_path.json", FLOCK ",\n  \"n\": 200,\n  \"path\": {\"points\": [[0.2, 0, 0]]}"
                                   COARSE_OBSTACLE_AT("\"translate\": [0, 0, 0]"));
    EXPECT_RUN(path, 0, "");
    /* the octahedron's lower half (the four triangles at vertex 6, -z): an open bowl */
    char bowl[FM_PATH_MAX], text[1024], open_text[1024] = "";
    write_octahedron(tmp_path(bowl, "bowl.obj"));
    slurp(bowl, text, sizeof text);
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        int a, b, c;
        if (line[0] == 'f' && (sscanf(line, "f %d %d %d", &a, &b, &c) != 3 || (a != 6 && b != 6 && c != 6))) continue;
        strncat(open_text, line, sizeof open_text - strlen(open_text) - 2), strcat(open_text, "\n");
    }
    write_mesh("bowl.obj", open_text);
    path = scene("flock_bowl.json", "bad_bowl.obj", LEFT ", \"scale\": 3", RIGHT,
                 FLOCK ",\n  \"n\": 200" COARSE_OBSTACLE_AT("\"translate\": [-9.7, 0, -1], \"scale\": 0.3"));
    EXPECT_RUN(path, 0, "");
}

/* FM assumes source and target apart; overlapping ones run, with a warning on stderr and in
 * stats.json. */
static void test_source_target_overlap_warns(void)
{
    char where[FM_PATH_MAX + 32], stats[FM_PATH_MAX + 16];
    const char *path = scene("overlap.json", OCTAHEDRON, "\"translate\": [0, 0, 0]", "\"translate\": [0.5, 0, 0]", "");
    scene_position("[0.5, 0, 0]", where, sizeof where);
    EXPECT_RUN(path, 0, "flockmorph: warning: ", where, "target.translate: the source and target overlap");
    snprintf(stats, sizeof stats, "%s/stats.json", g_outdir);
    json_t *j = json_load_file(stats, 0, NULL);
    json_t *w = json_object_get(j, "warnings");
    ENSURE_MSG(json_is_array(w) && json_array_size(w) == 1, "%s: warnings", stats);
    const char *text = json_string_value(json_array_get(w, 0));
    ENSURE_MSG(text && strstr(text, where) && strstr(text, "overlap"), "warning '%s'", text ? text : "");
    ENSURE(json_is_true(json_object_get(j, "all_arrived")));
    json_decref(j);
    /* apart: no warning */
    path = plain_scene("apart.json", "");
    EXPECT_RUN(path, 0, "");
    ENSURE_MSG(strstr(g_err, "warning") == NULL, "%s", g_err);
    j = json_load_file(stats, 0, NULL);
    ENSURE(json_is_array(json_object_get(j, "warnings")) && json_array_size(json_object_get(j, "warnings")) == 0);
    json_decref(j);
}

/* ---------------------------------------------------------------- files that are not regular files */

/* A FIFO (which would block a read until a writer comes, here never), /dev/zero (which never ends)
 * and a directory, as the scene, a mesh, a cache and a checkpoint: refused at once (exit 2, the run
 * given 30 s before SIGALRM would end it), naming the file and what it is. */
static void test_not_regular_files(void)
{
    char fifo[FM_PATH_MAX], dir[FM_PATH_MAX], where[FM_PATH_MAX + 64], args[3 * FM_PATH_MAX];
    remove(tmp_path(fifo, "fifo.obj"));
    ENSURE(mkfifo(fifo, 0644) == 0);
    mkdir(tmp_path(dir, "dir.fmc"), 0755);
    cli_env watched = {.seconds = 30};
    expect_output(run_scene(&watched, fifo, "out"), 2, "FIFO scene",
                  (const char *const[]){fifo, "cannot open the scene file: it is a FIFO (named pipe)", NULL});
    expect_output(run_scene(&watched, "/dev/zero", "out"), 2, "/dev/zero scene",
                  (const char *const[]){"/dev/zero: cannot open the scene file: it is a device", NULL});
    const char *path = mesh_scene("fifo.obj", where, sizeof where);
    expect_output(run_scene(&watched, path, "out"), 2, "FIFO mesh",
                  (const char *const[]){where, fifo, "cannot open the mesh: it is a FIFO", NULL});
    const char *const caches[][2] = {{fifo, "it is a FIFO"}, {"/dev/zero", "it is a device"}, {dir, "it is a directory"}};
    for (int i = 0; i < 3; i++) {
        snprintf(args, sizeof args, "inspect '%s'", caches[i][0]);
        expect_output(cli_with(&watched, args), 2, caches[i][0],
                      (const char *const[]){caches[i][0], "cannot open the cache", caches[i][1], NULL});
    }
    /* a FIFO where --resume reads the checkpoint */
    char outdir[FM_PATH_MAX], ckpt[FM_PATH_MAX + 32];
    path = plain_scene("fifo_resume.json", "");
    mkdir(tmp_path(outdir, "fifo_out"), 0755);
    snprintf(ckpt, sizeof ckpt, "%s/checkpoint.fmck", outdir);
    remove(ckpt);
    ENSURE(mkfifo(ckpt, 0644) == 0);
    snprintf(args, sizeof args, "run '%s' -o '%s' --resume --quiet", path, outdir);
    expect_output(cli_with(&watched, args), 2, "FIFO checkpoint",
                  (const char *const[]){ckpt, "cannot open the checkpoint: it is a FIFO", NULL});
    remove(ckpt), remove(fifo);
    /* a regular file far larger than any scene is not read to its end */
    char big[FM_PATH_MAX];
    FILE *f = fopen(tmp_path(big, "big.json"), "w");
    ENSURE(f && ftruncate(fileno(f), 65 << 20) == 0); /* sparse: no disk used */
    if (f) fclose(f);
    expect_output(run_scene(&watched, big, "out"), 2, "big scene",
                  (const char *const[]){big, "the scene file is larger than 64 MiB", NULL});
    remove(big);
}

/* ---------------------------------------------------------------- the output directory */

static void test_output_directory(void)
{
    char args[3 * FM_PATH_MAX], parent[FM_PATH_MAX], out[FM_PATH_MAX + 16];
    const char *path = plain_scene("outdir.json", "");
    /* a parent that is a regular file cannot hold directories */
    write_text(tmp_path(parent, "plain_file"), "x");
    snprintf(args, sizeof args, "run '%s' -o '%s/sub/out' --quiet", path, parent);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, "cannot create the output directory") && strstr(g_err, "Not a directory"), "%s", g_err);
    /* an output name taken by a directory would fail only after the whole run */
    snprintf(out, sizeof out, "%s/frames.fmc", tmp_path(parent, "taken"));
    mkdir(parent, 0755), mkdir(out, 0755);
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", path, parent);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, out) && strstr(g_err, "a directory of that name is in the way"), "%s", g_err);
    /* permissions: a read-only directory, and a missing one under it */
    mkdir(tmp_path(parent, "read_only"), 0755);
    chmod(parent, 0555);
    cli_env env = {.unprivileged = 1};
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", path, parent);
    int rc = cli_with(&env, args);
    if (rc == CLI_NOT_RUN) printf("  (skipped: cannot run as an unprivileged user)\n");
    else expect_output(rc, 1, parent, (const char *const[]){"cannot write to the output directory", "Permission denied", NULL});
    snprintf(args, sizeof args, "run '%s' -o '%s/new' --quiet", path, parent);
    rc = cli_with(&env, args);
    if (rc != CLI_NOT_RUN)
        expect_output(rc, 1, parent, (const char *const[]){"cannot create the output directory", "Permission denied", NULL});
    chmod(parent, 0755);
}

/* ---------------------------------------------------------------- resource limits */

/* Reads attribute `attr` (`floats` per agent) of every frame of a cache into one array. */
static float *read_attr_frames(const char *path, fm_cache_attr attr, int floats, uint32_t *frames, uint64_t *agents,
                               char *warning, size_t size)
{
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return NULL;
    *frames = fm_cache_frames(r), *agents = fm_cache_agents(r);
    snprintf(warning, size, "%s", fm_cache_warning(r));
    size_t per_frame = (size_t)floats * (size_t)*agents;
    float *all = malloc(sizeof(float) * per_frame * (*frames ? *frames : 1));
    for (uint32_t f = 0; all && f < *frames; f++)
        ENSURE_MSG(fm_cache_read_attr(r, f, attr, all + per_frame * f, &err) == FM_OK, "%s", err.message);
    fm_cache_close(r);
    return all;
}

/* Every frame's tet vertices (frames × agents × 12 floats). */
static float *read_frames(const char *path, uint32_t *frames, uint64_t *agents, char *warning, size_t size)
{
    return read_attr_frames(path, FM_ATTR_TET_VERTICES, 12, frames, agents, warning, size);
}

/* The file-size limit stops the cache of `scene_path` midway: exit 3 naming the file and the
 * reason, nothing under the final name, no stats.json (not even the last run's), and the partial
 * cache holds complete frames whose `attr` (`floats` per agent) equals the unlimited run's. */
static void expect_file_size_limit(const char *scene_path, const char *outdir, fm_cache_attr attr, int floats)
{
    char cache[FM_PATH_MAX + 16], partial[FM_PATH_MAX + 32], stats[FM_PATH_MAX + 16], warning[FM_PATH_MAX + 200];
    char cut_dir[64];
    snprintf(cut_dir, sizeof cut_dir, "%.50s_cut", outdir);
    ENSURE(run_scene(NULL, scene_path, outdir) == 0);
    snprintf(cache, sizeof cache, "%s/frames.fmc", g_outdir);
    struct stat st;
    ENSURE(stat(cache, &st) == 0);
    uint32_t frames = 0, got = 0;
    uint64_t agents = 0, got_agents = 0;
    float *full = read_attr_frames(cache, attr, floats, &frames, &agents, warning, sizeof warning);
    ENSURE(full != NULL && frames > 4);

    tmp_path(g_outdir, cut_dir);
    mkdir(g_outdir, 0755);
    snprintf(cache, sizeof cache, "%s/frames.fmc", g_outdir);
    snprintf(partial, sizeof partial, "%s.partial", cache);
    snprintf(stats, sizeof stats, "%s/stats.json", g_outdir);
    write_text(cache, "an older run's cache"), write_text(stats, "{\"all_arrived\": true}");
    remove(partial);
    char args[3 * FM_PATH_MAX];
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet --overwrite", scene_path, g_outdir); /* the older run's go */
    cli_env limited = {.file_size_limit = (long long)st.st_size / 2};
    int rc = cli_with(&limited, args);
    expect_output(rc, 3, "file-size limit", (const char *const[]){partial, "File too large", "ulimit -f",
                  "complete frames written before the error are in", "no stats.json", NULL});
    ENSURE_MSG(!exists(cache) && !exists(stats), "a final cache or stats.json is left in %s", g_outdir);
    float *cut = read_attr_frames(partial, attr, floats, &got, &got_agents, warning, sizeof warning);
    ENSURE_MSG(got >= 1 && got < frames && got_agents == agents, "%u of %u frames recovered", got, frames);
    ENSURE_MSG(strstr(warning, "incomplete cache") != NULL, "warning '%s'", warning);
    if (full && cut) ENSURE(memcmp(full, cut, sizeof(float) * (size_t)floats * (size_t)agents * got) == 0);
    char said[64];
    snprintf(said, sizeof said, "the %u complete frames", got);
    ENSURE_MSG(strstr(g_err, said) != NULL, "'%s' not in %s", said, g_err);
    free(full), free(cut);
    remove(partial);
}

static void test_file_size_limit(void)
{
    expect_file_size_limit(plain_scene("limit.json", ",\n  \"n\": 300"), "limit", FM_ATTR_TET_VERTICES, 12);
}

/* The shape flock's cache under the same limit: its positions up to the last complete frame. */
static void test_flock_file_size_limit(void)
{
    expect_file_size_limit(plain_scene("flock_limit.json", FLOCK ",\n  \"n\": 300"), "flock_limit", FM_ATTR_POSITION, 3);
}

/* export under the file-size limit: exit 3 with the reason (not death by SIGXFSZ), and nothing
 * under the final name. */
static void test_export_file_size_limit(void)
{
    char cache[FM_PATH_MAX + 16], ply[FM_PATH_MAX], args[4 * FM_PATH_MAX];
    ENSURE(run_scene(NULL, plain_scene("export_limit.json", ",\n  \"n\": 300"), "export_limit") == 0);
    snprintf(cache, sizeof cache, "%s/frames.fmc", g_outdir);
    remove(tmp_path(ply, "export_limit.ply"));
    snprintf(args, sizeof args, "export '%s' -o '%s'", cache, ply);
    cli_env limited = {.file_size_limit = 4096};
    expect_output(cli_with(&limited, args), 3, "export under a file-size limit",
                  (const char *const[]){ply, "File too large", "ulimit -f", NULL});
    ENSURE_MSG(!exists(ply), "%s is left", ply);
}

/* Rewrites the header of the cache at path to claim `agents`, its crc32 made to match. */
static void claim_agents(const char *path, uint64_t agents)
{
    FILE *f = fopen(path, "r+b");
    unsigned char h[CACHE_MAX_HEADER];
    ENSURE(f && fread(h, 1, 64, f) == 64);
    if (!f) return;
    uint32_t header_bytes = get_u32(h + 12);
    ENSURE(header_bytes <= sizeof h && fseek(f, 0, SEEK_SET) == 0 && fread(h, 1, header_bytes, f) == header_bytes);
    put_u64(h + 16, agents);
    put_u32(h + 52, 0); /* the crc32 is computed with its own field 0 */
    put_u32(h + 52, cache_crc32(0, h, header_bytes));
    ENSURE(fseek(f, 0, SEEK_SET) == 0 && fwrite(h, 1, header_bytes, f) == header_bytes);
    fclose(f);
}

/* A cache of `frames` frames of `agents` tets whose coordinates are random (incompressible). */
static void write_random_cache(const char *path, int agents, int frames)
{
    float *frame = malloc(sizeof(float) * 12 * (size_t)agents);
    uint64_t rng = 5;
    fm_error err = {0};
    fm_cache_writer *w = frame ? fm_cache_writer_create(path, (uint64_t)agents, 24, 1, &err) : NULL;
    fm_status st = w ? FM_OK : FM_ERR_INTERNAL;
    for (int k = 0; k < frames && st == FM_OK; k++) {
        for (int i = 0; i < 12 * agents; i++) frame[i] = (float)test_uniform(&rng);
        st = fm_cache_writer_add_frame(w, frame, &err);
    }
    ENSURE_MSG(st == FM_OK && fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    free(frame);
}

/* A cache of `frames` frames of `tets` random tets, its header claiming `agents`, under a memory
 * limit of `limit` bytes: inspect, then `command` (export or render into PATH.EXT), each exit 2
 * naming the cache and what it says. */
static void expect_lying_header(const char *name, uint64_t agents, int tets, int frames, long long limit,
                                const char *command, const char *ext, const char *says)
{
    char path[FM_PATH_MAX], args[3 * FM_PATH_MAX];
    write_random_cache(tmp_path(path, name), tets, frames);
    claim_agents(path, agents);
    cli_env limited = {.memory_limit = limit};
    snprintf(args, sizeof args, "inspect '%s'", path);
    expect_output(cli_with(&limited, args), 2, "inspect", (const char *const[]){path, says, NULL});
    snprintf(args, sizeof args, "%s '%s' -o '%s.%s'", command, path, path, ext);
    expect_output(cli_with(&limited, args), 2, command, (const char *const[]){path, "damaged header", NULL});
}

/* A small cache whose header claims 2^38 agents (its crc32 made to match) is refused as damaged by
 * inspect and export from the file's size, before anything is allocated for that many agents. */
static void test_cache_agents_beyond_file(void)
{
    expect_lying_header("huge_agents.fmc", (uint64_t)1 << 38, 50, 1, 2LL << 30, "export", "ply",
                        "274877906944 agents cannot come from a file of");
}

/* A header claiming 2^24 agents on a cache of 2 frames of 400 random tets (38 KB): the file's size
 * could hold them at zstd's best ratio, so only the first frame tells the lie (issue 42). inspect
 * and render under a memory limit that the buffers for 2^24 agents (800 MB a frame) pass refuse it
 * as damaged input (exit 2), where they ended out of memory (exit 4). */
static void test_cache_header_lies_within_the_file(void)
{
    expect_lying_header("lying_agents.fmc", (uint64_t)1 << 24, 400, 2, 1LL << 29, "render", "png",
                        "damaged header: the block table that 16777216 agents make");
}

/* The library alone: a writer whose file hits the file-size limit (this process's, lowered for the
 * test; a program using the library ignores SIGXFSZ as the CLI does) fails in fm_cache_writer_finish with FM_ERR_IO, leaves nothing under the final name, and
 * its PATH.partial holds the frames that fitted, bit for bit. */
static void test_cache_writer_keeps_partial(void)
{
    enum { AGENTS = 2000, FRAMES = 8 };
    char path[FM_PATH_MAX], partial[FM_PATH_MAX + 16], warning[FM_PATH_MAX + 200];
    snprintf(partial, sizeof partial, "%s.partial", tmp_path(path, "writer.fmc"));
    remove(path), remove(partial);
    float *frames = malloc(sizeof(float) * 12 * AGENTS * FRAMES);
    uint64_t rng = 11;
    for (size_t i = 0; frames && i < 12 * (size_t)AGENTS * FRAMES; i++) frames[i] = (float)test_uniform(&rng);
    ENSURE(frames != NULL);
    if (!frames) return;
    struct rlimit old, lowered;
    getrlimit(RLIMIT_FSIZE, &old);
    lowered = old;
    lowered.rlim_cur = 64 + 3 * (24 + 12 * AGENTS * 4) + 12 * AGENTS * 2; /* random floats barely compress */
    void (*previous)(int) = signal(SIGXFSZ, SIG_IGN);
    ENSURE(setrlimit(RLIMIT_FSIZE, &lowered) == 0);
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(path, AGENTS, 24, 1, &err);
    fm_status st = FM_OK;
    for (int f = 0; w && f < FRAMES && st == FM_OK; f++) st = fm_cache_writer_add_frame(w, frames + 12 * AGENTS * f, &err);
    fm_status finished = w ? fm_cache_writer_finish(w, &err) : FM_ERR_INTERNAL;
    setrlimit(RLIMIT_FSIZE, &old);
    signal(SIGXFSZ, previous);
    ENSURE_MSG(finished == FM_ERR_IO && strstr(err.message, "File too large"), "status %d: %s", (int)finished, err.message);
    ENSURE(!exists(path));
    uint32_t got = 0;
    uint64_t agents = 0;
    float *read = read_frames(partial, &got, &agents, warning, sizeof warning);
    ENSURE_MSG(got >= 2 && got < FRAMES && agents == AGENTS, "%u frames recovered", got);
    if (read) ENSURE(memcmp(read, frames, sizeof(float) * 12 * AGENTS * got) == 0);
    free(read), free(frames);
    remove(partial);
}

/* Values that can only blow a run up are refused when the scene loads (issue 42), at their key's
 * line and column, before any mesh is read: speed0 10^9, a frame rate of 10^-9, a flock mass of
 * 10^-300 each used to run until the state ran away (test_scene loads every example with the bounds). */
static void test_ranges_that_blow_up(void)
{
    expect_scene_error("fast.json", ",\n  \"speed0\": 1e9", "1e9", "speed0",
                       "speed0: 1000000000 is out of range: must be <= 1000000");
    expect_scene_error("slow_frames.json", ",\n  \"time\": {\"frame_rate\": 1e-9}", "1e-9", "time.frame_rate",
                       "time.frame_rate: 1e-09 is out of range: must be >= 0.01");
    expect_scene_error("light.json", ",\n  \"mode\": \"shape_flock\", \"n\": 40,\n  \"shape_flock\": {\"mass\": 1e-300}",
                       "1e-300", "shape_flock.mass", "shape_flock.mass: 1e-300 is out of range: must be >= 1e-06");
    ENSURE_MSG(!strstr(g_err, "ran away"), "%s", g_err);
}

/* A state that runs away stops the run with exit 2 and the parameters that set the speeds (issue
 * 15): the largest speed0 flies the tets out of this small scene in one frame, and a flock as fast
 * as max_speed allows leaves it as fast. No stats.json, no cache under its final name; the frames
 * before the runaway stay readable in the .partial. */
static void test_runaway_state_is_an_error(void)
{
    char cache[FM_PATH_MAX + 32];
    EXPECT_RUN(plain_scene("runaway.json", ",\n  \"n\": 40, \"speed0\": 1e6"), 2, "frame 1: agent",
               "flew over 1000 scene sizes out of the scene", "the simulation ran away", "speed0");
    snprintf(cache, sizeof cache, "%s/frames.fmc", g_outdir);
    ENSURE(!exists(cache) && exists(strcat(cache, ".partial")));
    snprintf(cache, sizeof cache, "%s/stats.json", g_outdir);
    ENSURE(!exists(cache));
    EXPECT_RUN(plain_scene("runaway_flock.json", ",\n  \"mode\": \"shape_flock\", \"n\": 40, \"speed0\": 1e6,\n"
                                                 "  \"shape_flock\": {\"mass\": 1e-6, \"max_speed\": 1e9, \"max_force\": 1e12}"),
               2, "the simulation ran away", "shape_flock.mass");
}

/* A full disk (a tmpfs, tests/helpers/full_disk.h), first for the cache (no space at all), then for
 * stats.json after a complete cache (a disk of exactly the cache's pages, learnt from a run
 * elsewhere: results are the same bytes on every run). */
static void test_disk_full(void)
{
    char outdir[FM_PATH_MAX], cache[2 * FM_PATH_MAX], partial[2 * FM_PATH_MAX + 16], stats[FM_PATH_MAX + 16];
    char args[3 * FM_PATH_MAX];
    const char *path = plain_scene("full.json", "");
    if (full_disk_mount(tmp_path(outdir, "full_out"), 0) != 0) return;
    snprintf(cache, sizeof cache, "%s/frames.fmc", outdir);
    snprintf(partial, sizeof partial, "%s.partial", cache);
    snprintf(stats, sizeof stats, "%s/stats.json", outdir);
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", path, outdir);
    int rc = cli(args);
    expect_output(rc, 3, "disk full (cache)", (const char *const[]){partial, "No space left on device", "the disk is full", NULL});
    ENSURE(!exists(cache) && !exists(stats));
    full_disk_unmount(outdir);

    struct stat st;
    ENSURE(run_scene(NULL, path, "full_sizes") == 0);
    snprintf(cache, sizeof cache, "%s/frames.fmc", g_outdir);
    ENSURE(stat(cache, &st) == 0);
    if (full_disk_mount(outdir, (size_t)st.st_size) != 0) return;
    snprintf(cache, sizeof cache, "%s/frames.fmc", outdir);
    rc = cli(args);
    expect_output(rc, 3, "disk full (stats)", (const char *const[]){stats, "No space left on device", NULL});
    ENSURE_MSG(!exists(stats), "stats.json written");
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(cache, &err); /* the cache itself was complete */
    ENSURE_MSG(r != NULL && !fm_cache_warning(r)[0], "%s", err.message);
    fm_cache_close(r);
    ENSURE_MSG(files_in(outdir) == 1, "%s holds more than the cache", outdir);
    full_disk_unmount(outdir);
}

/* ---------------------------------------------------------------- work without bound (issue 15, item 9) */

/* Runs the scene under a 30 s alarm and expects exit 2 with `parts` within `seconds`. */
static void expect_quick_refusal(const char *path, double seconds, const char *const *parts)
{
    cli_env env = {.seconds = 30};
    double t0 = fm_seconds();
    int rc = run_scene(&env, path, "out");
    double took = fm_seconds() - t0;
    expect_output(rc, 2, path, parts);
    ENSURE_MSG(took < seconds, "%s: refused after %.1f s, not at once", path, took);
}

/* A volume bound whose tets could not fit in any machine's memory is refused before TetGen runs
 * (it ran for over 500 s): 1.5 x (4/3) / 1e-12 = 2e12 tets at about 700 B each. */
static void test_tetgen_volume_bound_too_fine(void)
{
    char where[FM_PATH_MAX + 32];
    const char *path = plain_scene("tet_bound.json", ",\n  \"tetgen\": {\"max_volume\": 1e-12}");
    scene_position("1e-12", where, sizeof where);
    expect_quick_refusal(path, 10, (const char *const[]){where, "tetgen.max_volume: 1e-12 over the volume 1.33333 of "
                         "source.mesh", "implies at least 2e+12 tets", "physical memory", "use a tetgen.max_volume of at "
                         "least", NULL});
    /* a bound that fits still runs */
    EXPECT_RUN(plain_scene("tet_bound_ok.json", ",\n  \"tetgen\": {\"max_volume\": 0.05},\n  \"time\": {\"frame_limit\": 2}"),
               0, "");
}

/* A shape flock of n agents over the octahedra, one frame, with the shape_flock group given. */
static const char *flock_sampling_scene(const char *name, int n, const char *shape_flock)
{
    char extra[512];
    snprintf(extra, sizeof extra, FLOCK ",\n  \"n\": %d,\n  \"time\": {\"frame_limit\": 1},\n  \"shape_flock\": %s", n,
             shape_flock);
    return plain_scene(name, extra);
}

/* A flock of n agents whose sampling group `too_much` is refused at once, at the position of `needle`
 * in the scene, with every one of `parts`; with `fits` instead, the run goes. */
static void expect_sampling_work_refused(const char *name, int n, const char *too_much, const char *needle,
                                         const char *const *parts, const char *fits)
{
    char where[FM_PATH_MAX + 32];
    const char *path = flock_sampling_scene(name, n, too_much);
    scene_position(needle, where, sizeof where);
    expect_quick_refusal(path, 5, parts);
    ENSURE_MSG(strstr(g_err, where) != NULL, "%s: '%s' not in stderr: %s", name, where, g_err);
    EXPECT_RUN(flock_sampling_scene("sampling_fits.json", n, fits), 0, "");
}

/* lambda 100, oversample 16 for 300 agents ran for over 400 s; now refused at load, naming the keys.
 * lambda 4 passes at any n (the same keys with a large n fail only later, on memory). */
static void test_stratified_work_too_large(void)
{
    expect_sampling_work_refused("strat.json", 300, "{\"sampling\": \"stratified\", \"stratified\": {\"lambda\": 100, "
                                 "\"oversample\": 16}}", "100", (const char *const[]){"shape_flock.stratified.lambda: 100 "
                                 "with shape_flock.stratified.oversample 16 and n 300", "3.84e+08 triangle pieces per surface",
                                 "4800 voxels", "more than the limit of 2.68e+08", "lambda of at most 83.6", NULL},
                                 "{\"sampling\": \"stratified\", \"stratified\": {\"lambda\": 4, \"oversample\": 16}}");
}

/* k 16 and 10^5 mosaic iterations for 2000 agents would sample each surface for about 40 CPU
 * minutes; refused before the first iteration at the sampling key, naming the iterations that fit.
 * k 16 itself is allowed: 10 iterations run. */
static void test_mosaic_work_too_large(void)
{
    expect_sampling_work_refused("mosaic.json", 2000, "{\"sampling\": \"mosaic\", \"mosaic\": {\"k\": 16, \"iterations\": "
                                 "100000}}", "\"mosaic\"", (const char *const[]){"shape_flock.sampling: mosaic sampling: 100000 "
                                 "iterations over 2000 points with k 16", "more than the limit of 300 CPU s", "use at most", NULL},
                                 "{\"sampling\": \"mosaic\", \"mosaic\": {\"k\": 16, \"iterations\": 10}}");
}

/* ---------------------------------------------------------------- messages that help (issue 15, item 13) */

static void test_messages_name_what_decides(void)
{
    /* every digit that decides, not 1e+07 twice */
    expect_scene_error("frame_limit.json", ",\n  \"time\": {\"frame_limit\": 10000001}", "10000001", "time.frame_limit",
                       "10000001 is out of range: must be <= 10000000");
    expect_scene_error("speed0.json", ",\n  \"speed0\": 1000000.0000000001", "1000000.0000000001", "speed0",
                       "1000000.0000000001 is out of range: must be <= 1000000");
    /* the distance switch's grid is the target's: no obstacles in the wording */
    const char *path = plain_scene("switch.json", ",\n  \"phase2\": {\"switch\": \"distance\", \"switch_distance\": 1e9}");
    char where[FM_PATH_MAX + 32];
    EXPECT_RUN(path, 2, scene_position("1e9", where, sizeof where), "phase2.switch_distance: 1000000000 is too far for "
               "the target's distance grid", "use a switch distance of at most");
    ENSURE_MSG(!strstr(g_err, "obstacle"), "a scene without obstacles reads of obstacles: %s", g_err);
    /* the quantum's failure names output.quantum where the scene sets it */
    path = plain_scene("quantum.json", ",\n  \"output\": {\"quantum\": 1e-9}");
    EXPECT_RUN(path, 2, scene_position("1e-9", where, sizeof where), "output.quantum: ", "not a finite multiple of "
               "quantum 1e-09", "raise output.quantum");
}

/* A UTF-8 byte-order mark at the start of a scene is skipped (RFC 8259 allows it); positions
 * after it are the same as without it. */
static void test_scene_byte_order_mark(void)
{
    char bom_path[FM_PATH_MAX], text[sizeof g_scene_text + 4], where[FM_PATH_MAX + 32], expect[FM_PATH_MAX + 64];
    plain_scene("bom.json", ",\n  \"time\": {\"frame_limit\": 2}");
    snprintf(text, sizeof text, "\xEF\xBB\xBF%s", g_scene_text);
    write_text(tmp_path(bom_path, "bom_marked.json"), text);
    EXPECT_RUN(bom_path, 0, "");
    plain_scene("bom_bad.json", ",\n  \"sped0\": 1");
    snprintf(text, sizeof text, "\xEF\xBB\xBF%s", g_scene_text);
    write_text(tmp_path(bom_path, "bom_bad_marked.json"), text);
    scene_position("\"sped0\"", where, sizeof where);
    snprintf(expect, sizeof expect, "%s:%s", bom_path, strchr(where + strlen(g_scene), ':') + 1);
    EXPECT_RUN(bom_path, 2, expect, "sped0: unknown key");
}

/* The shape flock's mesh errors carry the scene's FILE:LINE:COL like every other. */
static void test_flock_mesh_errors_located(void)
{
    char where[FM_PATH_MAX + 32];
    const char *path = plain_scene("seq.json", FLOCK ",\n  \"n\": 50,\n  \"shape_flock\": {\"deform\": {\"type\": "
                                   "\"sequence\", \"sequence\": \"bad_no_such_%d.obj\", \"frames\": 2}}");
    EXPECT_RUN(path, 2, scene_position("\"bad_no_such", where, sizeof where), "shape_flock.deform.sequence: mesh 0: ",
               "cannot open the mesh");
    path = scene("flock_missing.json", "bad_missing.obj", LEFT, RIGHT, FLOCK ",\n  \"n\": 50");
    EXPECT_RUN(path, 2, scene_position("\"bad_missing.obj\"", where, sizeof where), "source.mesh: ", "cannot open the mesh");
}

/* ---------------------------------------------------------------- output paths (issue 15, items 12, 14) */

/* FM_TEST_TMP/bad_NAME/ddd.../ddd, `length` bytes in all (out holds FM_PATH_MAX + 64), in folders of
 * at most 200 bytes. */
static void long_path(char *out, const char *name, int length)
{
    char base[FM_PATH_MAX], part[201];
    memset(part, 'd', 200), part[200] = 0;
    int n = snprintf(out, FM_PATH_MAX + 64, "%s", tmp_path(base, name));
    while (n < length) n += snprintf(out + n, FM_PATH_MAX + 64 - (size_t)n, "/%.*s", FM_MIN(length - n - 1, 200), part);
}

static void expect_outdir_refused(const char *scene_path, const char *outdir, const char *what)
{
    char args[8 * FM_PATH_MAX];
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", scene_path, outdir);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, what) != NULL, "-o %.80s: '%s' not in stderr: %s", outdir, what, g_err);
}

static void test_output_paths_refused_up_front(void)
{
    const char *path = plain_scene("outpaths.json", "");
    struct stat st;
    if (stat("/proc/self", &st) == 0) expect_outdir_refused(path, "/proc", "-o /proc: cannot create the lock file");
    if (stat("/sys/kernel", &st) == 0) expect_outdir_refused(path, "/sys/kernel", "-o /sys/kernel: cannot create the lock file");
    char longest[FM_PATH_MAX + 64];
    long_path(longest, "long", 4080);
    ENSURE(strlen(longest) == 4080);
    expect_outdir_refused(path, longest, "the path is too long");
    /* a long cache name in a long directory: the .partial would not fit in a path */
    char name[256];
    memset(name, 'c', 250), name[250] = 0;
    char extra[400];
    snprintf(extra, sizeof extra, ",\n  \"output\": {\"cache\": \"%s\"}", name);
    path = plain_scene("long_cache.json", extra);
    longest[3900] = 0;
    expect_outdir_refused(path, longest, ".partial, which the run writes there, would be 4159 bytes, more than the 4095");
    /* stats.json records -o as JSON text, which is UTF-8 */
    char bad[FM_PATH_MAX];
    snprintf(bad, sizeof bad, "%s/bad_out_\xFE", FM_TEST_TMP);
    expect_outdir_refused(plain_scene("outpaths.json", ""), bad, "the path is not UTF-8 text");
}

/* ---------------------------------------------------------------- outputs that cannot be hijacked (issue 42) */

static int same_text(const char *path, const char *text)
{
    static char got[256];
    slurp(path, got, sizeof got);
    return !strcmp(got, text);
}

static int regular_file(const char *path)
{
    struct stat st;
    return lstat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* Links planted at the temporary names a run (cache, stats.json, manifest, checkpoint), an export
 * and a render write through point at a file outside the folder: each writes its own file, and
 * the file pointed at keeps its bytes. */
static void test_partial_links_not_followed(void)
{
    char outdir[FM_PATH_MAX], victim[FM_PATH_MAX], link[FM_PATH_MAX + 64], file[FM_PATH_MAX + 64], args[4 * FM_PATH_MAX];
    const char *path = plain_scene("links.json", "");
    write_text(tmp_path(victim, "victim.txt"), "victim\n");
    snprintf(args, sizeof args, "rm -rf '%s' && mkdir '%s'", tmp_path(outdir, "links_out"), outdir);
    ENSURE(system(args) == 0);
    static const char *const names[] = {"frames.fmc.partial", "stats.json.partial", "wedge.json.partial",
                                        "checkpoint.fmck.partial", "frame.ply.partial", "frame.png.partial"};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        snprintf(link, sizeof link, "%s/%s", outdir, names[i]);
        ENSURE(symlink(victim, link) == 0);
    }
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet --set seed=3 --stop-after-frame 3", path, outdir);
    ENSURE_EXIT(args, 0);
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet --set seed=3 --resume", path, outdir);
    ENSURE_EXIT(args, 0);
    snprintf(args, sizeof args, "export '%s/frames.fmc' --frame 0 -o '%s/frame.ply'", outdir, outdir);
    ENSURE_EXIT(args, 0);
    snprintf(args, sizeof args, "render '%s/frames.fmc' --size 32x32 -o '%s/frame.png'", outdir, outdir);
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(same_text(victim, "victim\n"), "the file the links point at was written: %.200s", g_err);
    static const char *const written[] = {"frames.fmc", "stats.json", "wedge.json", "frame.ply", "frame.png"};
    for (size_t i = 0; i < sizeof written / sizeof *written; i++) {
        snprintf(file, sizeof file, "%s/%s", outdir, written[i]);
        ENSURE_MSG(regular_file(file), "%s is not a file of its own", file);
    }
}

/* Two writers of one final name (two renders to one PNG) never share a temporary file: each
 * commit puts its own whole bytes under the name, and no temporary file is left. */
static void test_two_writers_of_one_name(void)
{
    char dir[FM_PATH_MAX], path[FM_PATH_MAX + 16], args[3 * FM_PATH_MAX];
    snprintf(args, sizeof args, "rm -rf '%s' && mkdir '%s'", tmp_path(dir, "two_writers"), dir);
    ENSURE(system(args) == 0);
    snprintf(path, sizeof path, "%s/image.png", dir);
    fm_output_file a, b;
    fm_error err = {0};
    ENSURE_MSG(fm_output_open(&a, path, &err) == FM_OK && fm_output_open(&b, path, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(strcmp(a.partial, b.partial) != 0, "both write %s", a.partial);
    fputs("first writer\n", a.f), fputs("second\n", b.f);
    ENSURE(fm_output_commit(&a, NULL, &err) == FM_OK && same_text(path, "first writer\n"));
    ENSURE(fm_output_commit(&b, NULL, &err) == FM_OK && same_text(path, "second\n"));
    ENSURE_MSG(files_in(dir) == 1, "a temporary file was left in %s", dir);
}

/* A folder that holds a finished run's results is refused (exit 1, naming --overwrite) and keeps
 * them; --overwrite replaces them; the lock file goes with the run. */
static void test_finished_folder_refused(void)
{
    char outdir[FM_PATH_MAX], cache[FM_PATH_MAX + 16], lock[FM_PATH_MAX + 32], args[3 * FM_PATH_MAX];
    static char before[1 << 16], after[1 << 16];
    const char *path = plain_scene("again.json", "");
    ENSURE(run_scene(NULL, path, "again_out") == 0);
    snprintf(cache, sizeof cache, "%s/frames.fmc", tmp_path(outdir, "again_out"));
    snprintf(lock, sizeof lock, "%s/" FM_OUTPUT_LOCK, outdir);
    ENSURE_MSG(!exists(lock), "%s is left after the run", lock);
    struct stat first, now;
    ENSURE(stat(cache, &first) == 0);
    size_t n = slurp(cache, before, sizeof before);
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet --set time.frame_limit=3", path, outdir);
    ENSURE_EXIT(args, 1);
    ENSURE_MSG(strstr(g_err, "holds the results of an earlier run") && strstr(g_err, "--overwrite"), "%s", g_err);
    ENSURE_MSG(stat(cache, &now) == 0 && now.st_size == first.st_size && slurp(cache, after, sizeof after) == n &&
               !memcmp(before, after, n), "the refused run changed %s", cache);
    strcat(args, " --overwrite");
    ENSURE_EXIT(args, 0);
    ENSURE_MSG(stat(cache, &now) == 0 && now.st_size < first.st_size, "--overwrite kept the old cache");
    strcat(args, " --resume");
    ENSURE_EXIT(args, 1);
}

/* With stdout and stderr closed, the first files the run opens would get descriptors 1 and 2 and
 * its progress lines would land in the cache: it opens /dev/null there first. */
static void test_closed_standard_streams(void)
{
    char outdir[FM_PATH_MAX], cache[FM_PATH_MAX + 16], args[3 * FM_PATH_MAX];
    const char *path = plain_scene("closed.json", "");
    snprintf(args, sizeof args, "rm -rf '%s'", tmp_path(outdir, "closed_out"));
    ENSURE(system(args) == 0);
    snprintf(args, sizeof args, "run '%s' -o '%s' --log-every 0 >&- 2>&-", path, outdir);
    ENSURE_EXIT(args, 0);
    snprintf(cache, sizeof cache, "%s/frames.fmc", outdir);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(cache, &err);
    ENSURE_MSG(r && !fm_cache_warning(r)[0] && fm_cache_frames(r) > 2, "%s%s", err.message, r ? fm_cache_warning(r) : "");
    fm_cache_close(r);
}

/* ---------------------------------------------------------------- smaller items (issue 42) */

/* A NUL byte between JSON tokens is refused at its line and column (jansson took it for the end). */
static void test_nul_byte_between_tokens(void)
{
    char path[FM_PATH_MAX];
    plain_scene("nul.json", "");
    FILE *f = fopen(tmp_path(path, "nul.json"), "wb");
    ENSURE(f != NULL);
    if (!f) return;
    const char *second_line = strchr(g_scene_text, '\n') + 1;
    fwrite(g_scene_text, 1, (size_t)(second_line - g_scene_text), f);
    fputs("  ", f), fputc(0, f), fputs(second_line + 2, f); /* line 2, column 3 */
    fclose(f);
    EXPECT_RUN(path, 2, "bad_nul.json:2:3: a NUL byte, which JSON text may not hold");
}

/* A sequence pattern of a huge width is refused at once, by its key, without 2 KB of blanks. */
static void test_sequence_pattern_width(void)
{
    const char *path = plain_scene("wide.json", ",\n  \"target_motion\": {\"sequence\": \"walk_%999999999d.obj\", \"frames\": 2}");
    expect_quick_refusal(path, 5, (const char *const[]){"target_motion.sequence: '", "walk_%999999999d.obj' is not a "
                                                        "file name pattern", "a width of at most 2 digits", NULL});
    ENSURE_MSG(strlen(g_err) < 512, "%zu bytes of message", strlen(g_err));
}

/* An -o under PATH_MAX whose files fit (4069 bytes) is taken; an error about a path of several KB
 * keeps its reason, the path cut in its middle. */
static void test_long_paths(void)
{
    char dir[FM_PATH_MAX + 64], args[3 * FM_PATH_MAX], base[FM_PATH_MAX];
    long_path(dir, "long4069", 4069);
    ENSURE(strlen(dir) == 4069);
    tmp_path(base, "long4069");
    snprintf(args, sizeof args, "rm -rf '%s'", base);
    ENSURE(system(args) == 0);
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", plain_scene("long.json", ",\n  \"time\": {\"frame_limit\": 2}"), dir);
    ENSURE_EXIT(args, 0);
    dir[3000] = 0; /* a scene 3000 bytes deep that is not there */
    snprintf(args, sizeof args, "run '%s/none.json' -o '%s' --quiet", dir, tmp_path(base, "long_out"));
    ENSURE_EXIT(args, 2);
    ENSURE_MSG(strstr(g_err, "...") && strstr(g_err, "none.json: cannot open the scene file: No such file or directory"),
               "%.300s", g_err + (strlen(g_err) > 300 ? strlen(g_err) - 300 : 0));
}

/* A scene path that is not UTF-8 stays in stats.json's warnings, each bad byte as \xNN. */
static void test_stats_keep_text_that_is_not_utf8(void)
{
    char odd[FM_PATH_MAX], args[3 * FM_PATH_MAX], stats[FM_PATH_MAX + 16];
    scene("utf8.json", OCTAHEDRON, "\"translate\": [0, 0, 0]", "\"translate\": [0.5, 0, 0]",
          ",\n  \"time\": {\"frame_limit\": 2}"); /* the overlap's warning names the scene */
    snprintf(odd, sizeof odd, "%s/bad_scene_\xFE.json", FM_TEST_TMP);
    write_text(odd, g_scene_text);
    snprintf(args, sizeof args, "run '%s' -o '%s' --quiet", odd, tmp_path(g_outdir, "utf8_out"));
    ENSURE_EXIT(args, 0);
    snprintf(stats, sizeof stats, "%s/stats.json", g_outdir);
    json_t *j = json_load_file(stats, 0, NULL);
    ENSURE_MSG(j != NULL, "%s does not parse", stats);
    ENSURE(j && json_is_string(json_object_get(j, "cache")));
    json_t *warnings = j ? json_object_get(j, "warnings") : NULL;
    int kept = 0;
    for (size_t i = 0; i < json_array_size(warnings); i++)
        kept |= strstr(json_string_value(json_array_get(warnings, i)), "bad_scene_\\xFE.json:") != NULL;
    ENSURE_MSG(kept, "no warning names bad_scene_\\xFE.json: %zu warnings", json_array_size(warnings));
    json_decref(j);
}

int main(void)
{
    RUN_TEST(test_scene_file_unreadable);
    RUN_TEST(test_scene_numbers_not_finite);
    RUN_TEST(test_numeric_keys_out_of_range);
    RUN_TEST(test_scene_consistency);
    RUN_TEST(test_output_cache_name);
    RUN_TEST(test_output_cache_name_taken);
    RUN_TEST(test_flock_values_out_of_range);
    RUN_TEST(test_mesh_file_unreadable);
    RUN_TEST(test_mesh_empty_or_not_a_mesh);
    RUN_TEST(test_mesh_counts_beyond_file);
    RUN_TEST(test_mesh_face_without_indices);
    RUN_TEST(test_mesh_list_longer_than_file);
    RUN_TEST(test_mesh_ascii_list_longer_than_file);
    RUN_TEST(test_mesh_garbage_bytes);
    RUN_TEST(test_mesh_open);
    RUN_TEST(test_mesh_non_manifold);
    RUN_TEST(test_mesh_self_intersecting);
    RUN_TEST(test_mesh_degenerate);
    RUN_TEST(test_mesh_flipped_triangle);
    RUN_TEST(test_mesh_repeated_corner);
    RUN_TEST(test_mesh_lines_only);
    RUN_TEST(test_mesh_too_small_when_placed);
    RUN_TEST(test_n_too_small);
    RUN_TEST(test_memory_estimate_matches_allocations);
    RUN_TEST(test_flock_memory_estimate_matches_allocations);
    RUN_TEST(test_n_too_large_for_memory);
    RUN_TEST(test_flock_n_too_large_for_memory);
    RUN_TEST(test_shot_too_large_for_memory);
    RUN_TEST(test_flock_shot_too_large_for_memory);
    RUN_TEST(test_path_too_short);
    RUN_TEST(test_path_end_inside_obstacle);
    RUN_TEST(test_obstacle_overlaps_source_or_target);
    RUN_TEST(test_flock_obstacle_overlaps_source_or_target);
    RUN_TEST(test_flock_obstacle_allowed);
    RUN_TEST(test_source_target_overlap_warns);
    RUN_TEST(test_not_regular_files);
    RUN_TEST(test_output_directory);
    RUN_TEST(test_file_size_limit);
    RUN_TEST(test_flock_file_size_limit);
    RUN_TEST(test_export_file_size_limit);
    RUN_TEST(test_cache_writer_keeps_partial);
    RUN_TEST(test_cache_agents_beyond_file);
    RUN_TEST(test_cache_header_lies_within_the_file);
    RUN_TEST(test_disk_full);
    RUN_TEST(test_ranges_that_blow_up);
    RUN_TEST(test_runaway_state_is_an_error);
    RUN_TEST(test_tetgen_volume_bound_too_fine);
    RUN_TEST(test_stratified_work_too_large);
    RUN_TEST(test_mosaic_work_too_large);
    RUN_TEST(test_messages_name_what_decides);
    RUN_TEST(test_scene_byte_order_mark);
    RUN_TEST(test_flock_mesh_errors_located);
    RUN_TEST(test_output_paths_refused_up_front);
    RUN_TEST(test_stats_keep_text_that_is_not_utf8);
    RUN_TEST(test_partial_links_not_followed);
    RUN_TEST(test_two_writers_of_one_name);
    RUN_TEST(test_finished_folder_refused);
    RUN_TEST(test_closed_standard_streams);
    RUN_TEST(test_nul_byte_between_tokens);
    RUN_TEST(test_sequence_pattern_width);
    RUN_TEST(test_long_paths);
    return test_result();
}
