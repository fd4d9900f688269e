/* fm_scene_load and fm_scene_validate: values and defaults, mesh paths resolved against the
 * scene's directory, and errors that point at FILE:LINE:COL of the offending key or value.
 *
 * Scene texts mark the expected error position with '@'; the marker is removed before the text is
 * written, and the expected line and column are computed from where it was. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define MESHES "\"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"}"

static char *tmp_path(char *buf, const char *name)
{
    snprintf(buf, FM_PATH_MAX, "%s/scene_%s", FM_TEST_TMP, name);
    return buf;
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (!f) return;
    fputs(text, f);
    fclose(f);
}

/* Removes the '@' marker from marked into out and returns its 1-based line and column. */
static void strip_marker(const char *marked, char *out, int *line, int *col)
{
    *line = 0, *col = 0;
    int ln = 1, cl = 1;
    for (; *marked; marked++) {
        if (*marked == '@') {
            *line = ln, *col = cl;
            continue;
        }
        *out++ = *marked;
        if (*marked == '\n') ln++, cl = 1;
        else cl++;
    }
    *out = 0;
    ENSURE_MSG(*line > 0, "the scene text has no '@' marker");
}

/* Loads the marked scene and expects FM_ERR_INPUT, "FILE:LINE:COL: " at the marker, and `what`. */
static void expect_error_at(const char *name, const char *marked, const char *what)
{
    char path[FM_PATH_MAX], text[4096], prefix[FM_PATH_MAX + 64];
    int line, col;
    strip_marker(marked, text, &line, &col);
    write_text(tmp_path(path, name), text);
    fm_scene_def def;
    fm_error err = {0};
    fm_status st = fm_scene_load(path, &def, &err);
    ENSURE_MSG(st == FM_ERR_INPUT && err.status == FM_ERR_INPUT, "%s: status %d", name, (int)st);
    snprintf(prefix, sizeof prefix, "%s:%d:%d: ", path, line, col);
    ENSURE_MSG(strncmp(err.message, prefix, strlen(prefix)) == 0, "%s: expected '%s...', got '%s'",
               name, prefix, err.message);
    ENSURE_MSG(strstr(err.message, what) != NULL, "%s: '%s' not in '%s'", name, what, err.message);
}

/* Loads an unmarked scene text; returns the status. */
static fm_status load_text(const char *name, const char *text, fm_scene_def *def, fm_error *err)
{
    char path[FM_PATH_MAX];
    write_text(tmp_path(path, name), text);
    return fm_scene_load(path, def, err);
}

static int same_vec3(const double a[3], const double b[3])
{
    return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

/* ---------------------------------------------------------------- valid scenes */

static void test_valid_scene_fields(void)
{
    const char *text =
        "{\n"
        "  \"source\": {\"mesh\": \"a.obj\", \"translate\": [-1.5, 2, 300], \"scale\": 0.5,\n"
        "             \"rotate_deg\": [10, 20, 30]},\n"
        "  \"target\": {\"mesh\": \"/abs/dir/b.ply\", \"translate\": [4, 5, 6]},\n"
        "  \"n\": 1234,\n"
        "  \"tetgen\": {\"quality\": 1.5, \"max_volume\": 0.25},\n"
        "  \"speed0\": 7.5, \"omega1\": 0.5,\n"
        "  \"time\": {\"frame_rate\": 30, \"time_step\": 0.008333333333333333, \"frame_limit\": 500},\n"
        "  \"path\": {\"points\": [[1, 2, 3], [-4, -5.5, 6]], \"key_points\": 12, \"curve\": \"catmull_rom\"},\n"
        "  \"launch_rate\": 100,\n"
        "  \"morph\": {\"shrink\": 0.25, \"shrink_time\": 0.5, \"morph_fraction\": 0.6},\n"
        "  \"seed\": 9007199254740991,\n"
        "  \"output\": {\"cache\": \"run.fmc\", \"compression_level\": 19, \"delta\": false, \"key_interval\": 7,\n"
        "             \"quantum\": 0.001}\n"
        "}\n";
    char path[FM_PATH_MAX], expect[FM_PATH_MAX + 16];
    fm_scene_def d;
    fm_error err = {0};
    ENSURE_MSG(load_text("valid.json", text, &d, &err) == FM_OK, "%s", err.message);
    ENSURE(strcmp(d.scene_path, tmp_path(path, "valid.json")) == 0);
    snprintf(expect, sizeof expect, "%s/a.obj", FM_TEST_TMP);
    ENSURE_MSG(strcmp(d.source.path, expect) == 0, "source path '%s'", d.source.path);
    ENSURE_MSG(strcmp(d.target.path, "/abs/dir/b.ply") == 0, "target path '%s'", d.target.path);
    ENSURE(same_vec3(d.source.translate, (double[3]){-1.5, 2, 300}) && d.source.scale == 0.5);
    ENSURE(same_vec3(d.source.rotate_deg, (double[3]){10, 20, 30}));
    ENSURE(same_vec3(d.target.translate, (double[3]){4, 5, 6}) && d.target.scale == 1.0);
    ENSURE(same_vec3(d.target.rotate_deg, (double[3]){0, 0, 0}));
    ENSURE(d.n == 1234);
    ENSURE(d.tet_quality == 1.5 && d.tet_max_volume == 0.25);
    ENSURE(d.speed0 == 7.5 && d.omega1 == 0.5);
    ENSURE(d.frame_rate == 30 && d.time_step == 0.008333333333333333 && d.frame_limit == 500);
    ENSURE(d.path_point_count == 2 && same_vec3(d.path_points[0], (double[3]){1, 2, 3}));
    ENSURE(same_vec3(d.path_points[1], (double[3]){-4, -5.5, 6}));
    ENSURE(d.path_key_points == 12 && d.path_curve == FM_CURVE_CATMULL_ROM);
    ENSURE(d.launch_rate == 100);
    ENSURE(d.shrink == 0.25 && d.shrink_time == 0.5 && d.morph_fraction == 0.6);
    ENSURE(d.seed == 9007199254740991ull && d.seed == FM_SEED_MAX); /* 2^53 - 1, the largest */
    ENSURE(strcmp(d.cache_name, "run.fmc") == 0 && d.compression_level == 19);
    ENSURE(d.cache_delta == 0 && d.cache_key_interval == 7 && d.cache_quantum == 0.001);
}

static void test_defaults_for_left_out_keys(void)
{
    fm_scene_def d, e = fm_default_scene_def();
    fm_error err = {0};
    ENSURE_MSG(load_text("minimal.json", "{" MESHES "}", &d, &err) == FM_OK, "%s", err.message);
    ENSURE(same_vec3(d.source.translate, e.source.translate) && d.source.scale == 1.0);
    ENSURE(same_vec3(d.target.rotate_deg, e.target.rotate_deg) && d.target.scale == 1.0);
    ENSURE(d.n == e.n && d.tet_quality == e.tet_quality && d.tet_max_volume == e.tet_max_volume);
    ENSURE(d.speed0 == e.speed0 && d.omega1 == e.omega1);
    ENSURE(d.frame_rate == e.frame_rate && d.time_step == e.time_step && d.frame_limit == e.frame_limit);
    ENSURE(d.path_point_count == 0 && d.path_key_points == e.path_key_points);
    ENSURE(d.path_curve == FM_CURVE_POLYLINE && d.launch_rate == e.launch_rate);
    ENSURE(d.shrink == e.shrink && d.shrink_time == e.shrink_time && d.morph_fraction == e.morph_fraction);
    ENSURE(d.seed == e.seed && d.compression_level == e.compression_level);
    ENSURE(strcmp(d.cache_name, e.cache_name) == 0);
    /* the documented defaults themselves */
    ENSURE(e.speed0 == 10.0 && e.frame_rate == 24.0 && e.compression_level == 1 && e.shrink == 0.5);
    ENSURE(d.cache_delta == 1 && d.cache_key_interval == 16 && d.cache_quantum == 0);
}

static void test_boundary_values_accepted(void)
{
    fm_scene_def d;
    fm_error err = {0};
    const char *text = "{" MESHES ", \"morph\": {\"shrink\": 1, \"morph_fraction\": 0.999, \"shrink_time\": 0},"
                       " \"output\": {\"compression_level\": 1}, \"time\": {\"time_step\": 0.020833333333333332},"
                       " \"seed\": 0, \"n\": 0, \"tetgen\": {\"quality\": 1.1}}";
    ENSURE_MSG(load_text("bounds.json", text, &d, &err) == FM_OK, "%s", err.message);
    ENSURE(d.shrink == 1 && d.morph_fraction == 0.999 && d.shrink_time == 0 && d.compression_level == 1);
    ENSURE(d.seed == 0 && d.tet_quality == 1.1);
}

/* The bounds that keep a run from blowing up (issue 42; docs/scene.md, "Ranges") take their limits
 * themselves, and every bundled example, each group of a shot too, still loads with them. */
static void test_blow_up_bounds_accepted_at_their_limits(void)
{
    fm_scene_def d;
    fm_error err = {0};
    const char *text = "{" MESHES ", \"speed0\": 1e6, \"time\": {\"frame_rate\": 0.01}}";
    ENSURE_MSG(load_text("blow_up_bounds.json", text, &d, &err) == FM_OK, "%s", err.message);
    ENSURE(d.speed0 == 1e6 && d.frame_rate == 0.01);
    text = "{" MESHES ", \"mode\": \"shape_flock\", \"n\": 10, \"shape_flock\": {\"mass\": 1e-6}}";
    ENSURE_MSG(load_text("light_flock.json", text, &d, &err) == FM_OK, "%s", err.message);
    ENSURE(d.flock.mass == 1e-6);
}

static void test_every_example_loads(void)
{
    static const char *const scenes[] = {
        "castling/scene.json", "castling/rook.json", "creatures/scene.json", "flock_bird/scene.json",
        "flock_cylinder_sphere/scene.json", "flock_overlap/scene.json", "flock_sequence/scene.json",
        "flock_suzanne_torus/scene.json", "flock_tracking/scene.json", "flock_travel/scene.json", "moon/scene.json",
        "walking_suzanne/scene.json", "words/scene.json",
    };
    static fm_scene_def d, group;
    for (size_t i = 0; i < sizeof scenes / sizeof scenes[0]; i++) {
        char path[FM_PATH_MAX];
        fm_error err = {0};
        snprintf(path, sizeof path, "%s/examples/%s", FM_SOURCE_DIR, scenes[i]);
        ENSURE_MSG(fm_scene_load(path, &d, &err) == FM_OK, "%s: %s", path, err.message);
        for (int g = 0; g < d.group_count; g++)
            ENSURE_MSG(fm_scene_load_group(path, NULL, 0, g, &group, &err) == FM_OK, "%s group %d: %s", path, g, err.message);
    }
}

/* A scene given by a relative path: its meshes are relative to the scene's directory. */
static void test_relative_scene_path(void)
{
    char cwd[FM_PATH_MAX], path[FM_PATH_MAX];
    ENSURE(getcwd(cwd, sizeof cwd) != NULL);
    mkdir(tmp_path(path, "sub"), 0777);
    ENSURE(chdir(FM_TEST_TMP) == 0);
    write_text("scene_sub/rel.json", "{\"source\": {\"mesh\": \"m/a.obj\"}, \"target\": {\"mesh\": \"../b.obj\"}}");
    write_text("scene_plain.json", "{" MESHES "}");
    fm_scene_def d;
    fm_error err = {0};
    ENSURE_MSG(fm_scene_load("scene_sub/rel.json", &d, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(strcmp(d.source.path, "scene_sub/m/a.obj") == 0, "'%s'", d.source.path);
    ENSURE_MSG(strcmp(d.target.path, "scene_sub/../b.obj") == 0, "'%s'", d.target.path);
    ENSURE_MSG(fm_scene_load("scene_plain.json", &d, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(strcmp(d.source.path, "a.obj") == 0, "'%s'", d.source.path);
    ENSURE(chdir(cwd) == 0);
}

/* ---------------------------------------------------------------- errors with positions */

/* The velocity model's keys (FM §5.2-5.4): lists of fields and obstacles with per-type keys. */
static void test_velocity_model_keys(void)
{
    fm_scene_def def;
    fm_error err = {0};
    fm_status st = load_text("velocity.json",
        "{" MESHES ", \"style\": {\"omega2\": 0.3, \"grid\": [8, 9, 10], \"fields\": ["
        "{\"type\": \"wind\", \"speed\": 2, \"turbulence\": 0.5}, {\"type\": \"vortex\", \"strength\": -1}]},"
        " \"obstacles\": {\"meshes\": [{\"mesh\": \"k.obj\", \"scale\": 2}], \"k_a\": 0.5, \"in_phase2\": true},"
        " \"mde\": {\"d_min\": 0.1}, \"path\": {\"width\": 3}, \"phase2\": {\"switch\": \"distance\", \"switch_distance\": 0.2,"
        " \"blend_time\": 0.5}}",
        &def, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    ENSURE(def.omega2 == 0.3 && def.field_grid[0] == 8 && def.field_grid[2] == 10 && def.field_count == 2);
    ENSURE(def.fields[0].kind == FM_FIELD_WIND && def.fields[0].speed == 2 && def.fields[0].turbulence == 0.5);
    ENSURE(def.fields[0].direction[0] == 1 && def.fields[0].period == 1);    /* wind defaults */
    ENSURE(def.fields[1].kind == FM_FIELD_VORTEX && def.fields[1].strength == -1 && def.fields[1].axis[1] == 1);
    ENSURE(def.obstacle_count == 1 && def.obstacles[0].scale == 2 && strstr(def.obstacles[0].path, "k.obj"));
    ENSURE(def.k_a == 0.5 && def.avoid_in_phase2 == 1 && def.d_min == 0.1 && def.path_width == 3);
    ENSURE(def.phase_switch == FM_SWITCH_DISTANCE && def.switch_distance == 0.2 && def.blend_time == 0.5);
    ENSURE(def.path_route == 1 && def.detour_time == 0); /* issue 38's detour: on by default */
    st = load_text("detour.json", "{" MESHES ", \"obstacles\": {\"meshes\": [{\"mesh\": \"k.obj\"}], \"route\": false,"
                   " \"detour_time\": -1}}", &def, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    ENSURE(def.path_route == 0 && def.detour_time == -1);
    ENSURE(fm_default_scene_def().blend_time == 0.25); /* issue 38: the switch blend is on by default */
    expect_error_at("field_key.json", "{" MESHES ",\n \"style\": {\"fields\": [{\"type\": \"curl_noise\", @\"speed\": 1}]}}",
                    "style.fields[0].speed: does not apply");
    expect_error_at("field_type.json", "{" MESHES ",\n \"style\": {\"fields\": [{\"type\": @\"breeze\"}]}}", "\"wind\"");
    expect_error_at("field_untyped.json", "{" MESHES ",\n \"style\": {\"fields\": [@{\"gain\": 1}]}}", "needs a \"type\"");
    expect_error_at("obstacle_key.json", "{" MESHES ",\n \"obstacles\": {\"meshes\": [{\"mesh\": \"k.obj\", @\"sclae\": 2}]}}",
                    "obstacles.meshes[0].sclae");
    expect_error_at("obstacle_mesh.json", "{" MESHES ",\n \"obstacles\": {\"meshes\": [@{\"scale\": 2}]}}", "needs a \"mesh\"");
    expect_error_at("switch.json", "{" MESHES ",\n \"phase2\": {\"switch\": @\"box\"}}", "\"sphere\" or \"distance\"");
    expect_error_at("k_a.json", "{" MESHES ",\n \"obstacles\": {\"k_a\": @0}}", "obstacles.k_a");
}

static void test_unknown_key_top_level(void)
{
    expect_error_at("unknown_top.json",
                    "{\n  " MESHES ",\n  \"speed0\": 5,\n  @\"speeed0\": 5\n}\n", "speeed0");
    expect_error_at("unknown_top2.json", "{" MESHES ", \"n\": 10,   @\"colour\": \"red\"}", "colour");
    /* a top-level key spelled with a dot is not the nested parameter */
    expect_error_at("dotted.json", "{" MESHES ",\n  @\"time.frame_rate\": 30\n}", "time.frame_rate");
}

static void test_unknown_key_nested(void)
{
    /* "fram_rate" also appears earlier as a value: the position must be the key's. */
    expect_error_at("unknown_nested.json",
                    "{\n  " MESHES ",\n  \"output\": {\"cache\": \"fram_rate\"},\n"
                    "  \"time\": {\"frame_rate\": 24,\n\t    @\"fram_rate\": 24}\n}\n",
                    "time.fram_rate");
    expect_error_at("unknown_deep.json",
                    "{\"source\": {\"mesh\": \"a.obj\",\n \"translate\": {@\"x\": 1}}, \"target\": {\"mesh\": \"b.obj\"}}",
                    "source.translate.x");
}

/* Keys that are unusual but valid JSON must still be located: a \u escape, 300 bytes. */
static void test_unusual_keys_located(void)
{
    expect_error_at("escaped.json", "{" MESHES ",\n  @\"fr\\u0061me\": 1\n}", "frame");
    char text[600], key[301];
    memset(key, 'k', 300);
    key[300] = 0;
    snprintf(text, sizeof text, "{" MESHES ",\n @\"%s\": 1}", key);
    key[40] = 0; /* the message may shorten the key */
    expect_error_at("long_key.json", text, key);
}

static void test_wrong_types(void)
{
    expect_error_at("type_speed.json", "{" MESHES ",\n  \"speed0\": @\"fast\"\n}", "speed0");
    expect_error_at("type_limit.json", "{" MESHES ",\n  \"time\": {\"frame_rate\": 24,\n    \"frame_limit\": @2.5}}",
                    "time.frame_limit");
    expect_error_at("type_translate.json",
                    "{\"source\": {\"mesh\": \"a.obj\", \"translate\": @[1, 2]},\n \"target\": {\"mesh\": \"b.obj\"}}",
                    "source.translate");
    expect_error_at("type_point.json", "{" MESHES ",\n  \"path\": {\"points\": [[0, 0, 0],\n    [1, @\"y\", 2]]}}",
                    "path.points");
    expect_error_at("type_group.json", "{" MESHES ", \"time\": @24}", "time");
    expect_error_at("type_mesh.json", "{\"source\": {\"mesh\": @42}, \"target\": {\"mesh\": \"b.obj\"}}", "source.mesh");
    expect_error_at("type_n.json", "{" MESHES ", \"n\": @true}", "n");
    expect_error_at("type_curve.json", "{" MESHES ", \"path\": {\"curve\": @\"bezier\"}}", "path.curve");
}

static void test_out_of_range(void)
{
    expect_error_at("range_speed.json", "{" MESHES ",\n  \"speed0\": @0\n}", "speed0");
    expect_error_at("range_shrink.json", "{" MESHES ",\n  \"morph\": {\"shrink\": @-0.5}}", "morph.shrink");
    expect_error_at("range_level.json", "{" MESHES ",\n  \"output\": {\"compression_level\": @25}}",
                    "output.compression_level");
    expect_error_at("range_level_fast.json", "{" MESHES ",\n  \"output\": {\"compression_level\": @-8}}",
                    "output.compression_level: -8 is out of range: must be >= -7");
    expect_error_at("range_level_zero.json", "{" MESHES ",\n  \"output\": {\"compression_level\": @0}}",
                    "output.compression_level: 0 is not a level");
    expect_error_at("range_key.json", "{" MESHES ",\n  \"output\": {\"key_interval\": @0}}", "output.key_interval");
    expect_error_at("range_quantum.json", "{" MESHES ",\n  \"output\": {\"quantum\": @-1}}", "output.quantum");
    expect_error_at("range_piece.json", "{" MESHES ",\n  \"output\": {\"piece_agents\": @255}}",
                    "output.piece_agents: 255 is out of range: must be >= 256");
    expect_error_at("range_fraction.json", "{" MESHES ",\n  \"morph\": {\"morph_fraction\": @1.5}}",
                    "morph.morph_fraction");
    /* docs/scene.md: strictly between 0 and 1 */
    expect_error_at("range_fraction0.json", "{" MESHES ", \"morph\": {\"morph_fraction\": @0}}", "morph.morph_fraction");
    expect_error_at("range_fraction1.json", "{" MESHES ", \"morph\": {\"morph_fraction\": @1.0}}", "morph.morph_fraction");
    expect_error_at("range_rotate.json", "{\"source\": {\"mesh\": \"a.obj\", \"rotate_deg\": [0, @4000, 0]}, "
                    "\"target\": {\"mesh\": \"b.obj\"}}", "source.rotate_deg");
    expect_error_at("range_blend.json", "{" MESHES ", \"phase2\": {\"blend_time\": @-0.1}}",
                    "phase2.blend_time: -0.1 is out of range");
    expect_error_at("range_seed.json", "{" MESHES ", \"seed\": @-1}", "seed");
    /* 2^53 + 1 reads back as 2^53 in jq and JavaScript: refused, the message naming the key */
    expect_error_at("range_seed_53.json", "{" MESHES ", \"seed\": @9007199254740992}",
                    "seed: 9007199254740992 is out of range: must be <= 9007199254740991 (2^53 - 1");
    { /* a group's own seed too, read with its group */
        char path[FM_PATH_MAX];
        write_text(tmp_path(path, "range_seed_group.json"),
                   "{\"groups\": [{\"name\": \"a\", " MESHES ", \"seed\": 9223372036854775807}]}");
        fm_scene_def def;
        fm_error err = {0};
        ENSURE(fm_scene_load_group(path, NULL, 0, 0, &def, &err) == FM_ERR_INPUT);
        ENSURE_MSG(strstr(err.message, "groups[0].seed: 9223372036854775807 is out of range: must be <= "
                                       "9007199254740991") != NULL, "%s", err.message);
    }
    expect_error_at("range_cache.json", "{" MESHES ", \"output\": {\"cache\": @\"../x.fmc\"}}", "output.cache");
}

/* A travelling target (target.path.*, issue 37): off by default; read in the shape flock; refused in
 * the tetra morph, with one point, with its timing but no route, and with the static strategy's
 * curves (a travelling target runs the tracking ones). */
#define FLOCK_ROUTE "{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"},\n"
static void test_target_route(void)
{
    fm_scene_def d;
    fm_error err = {0};
    ENSURE_MSG(load_text("route_none.json", FLOCK_ROUTE "\"target\": {\"mesh\": \"b.obj\"}}", &d, &err) == FM_OK, "%s",
               err.message);
    ENSURE(d.flock.travel_point_count == 0 && d.flock.travel_start == -1 && d.flock.travel_speed == 0);
    ENSURE(d.flock.travel_ease == 1 && d.flock.travel_orient == 1);
    ENSURE_MSG(load_text("route.json", FLOCK_ROUTE "\"target\": {\"mesh\": \"b.obj\", \"path\": {\"points\": [[0, 0, 0], "
                         "[5, 1, 0], [9, 4, 2]], \"start\": 2.5, \"speed\": 4, \"ease\": 0.5, \"orient\": false}}}", &d, &err) == FM_OK,
               "%s", err.message);
    ENSURE(d.flock.travel_point_count == 3 && d.flock.travel_points[2][0] == 9 && d.flock.travel_points[2][2] == 2);
    ENSURE(d.flock.travel_start == 2.5 && d.flock.travel_speed == 4 && d.flock.travel_ease == 0.5 && !d.flock.travel_orient);
    expect_error_at("route_one.json", FLOCK_ROUTE "\"target\": {\"mesh\": \"b.obj\", \"path\": {\"points\": @[[0, 0, 0]]}}}",
                    "a route needs at least 2 points");
    expect_error_at("route_timing.json", FLOCK_ROUTE "\"target\": {\"mesh\": \"b.obj\", \"path\": {@\"speed\": 3}}}",
                    "target.path.speed: the target has no route");
    expect_error_at("route_tetra.json", "{\"source\": {\"mesh\": \"a.obj\"},\n\"target\": {\"mesh\": \"b.obj\", "
                    "\"path\": {@\"points\": [[0, 0, 0], [1, 0, 0]]}}}", "does not apply to mode \"tetra_morph\"");
    expect_error_at("route_static_curve.json", FLOCK_ROUTE "\"target\": {\"mesh\": \"b.obj\", \"path\": {\"points\": "
                    "[[0, 0, 0], [1, 0, 0]]}},\n\"shape_flock\": {\"fuzzy\": {@\"homing\": [[0, 1]]}}}",
                    "travels (target.path.points)");
}

/* `up` (issue 14): +Z by default, any non-zero direction, refused when zero or in a shape flock. */
static void test_up_direction(void)
{
    fm_scene_def d;
    fm_error err = {0};
    ENSURE_MSG(load_text("up_default.json", "{" MESHES "}", &d, &err) == FM_OK, "%s", err.message);
    ENSURE(d.up[0] == 0 && d.up[1] == 0 && d.up[2] == 1);
    ENSURE_MSG(load_text("up_y.json", "{" MESHES ", \"up\": [0, 2, 0]}", &d, &err) == FM_OK, "%s", err.message);
    ENSURE(d.up[0] == 0 && d.up[1] == 2 && d.up[2] == 0);
    expect_error_at("up_zero.json", "{" MESHES ",\n \"up\": @[0, 0, 0]}", "up: the up direction must not be zero");
    expect_error_at("up_flock.json", "{\"mode\": \"shape_flock\", \"n\": 10, " MESHES ",\n @\"up\": [0, 1, 0]}",
                    "does not apply to mode \"shape_flock\"");
}

static void test_time_step_must_divide_frame(void)
{
    expect_error_at("step_bad.json", "{" MESHES ",\n \"time\": {\"frame_rate\": 24, \"time_step\": @0.03}}",
                    "time.time_step");
    expect_error_at("step_long.json", "{" MESHES ",\n \"time\": {\"time_step\": @0.125}}", "time.time_step");
    fm_scene_def d;
    fm_error err = {0};
    ENSURE_MSG(load_text("step_ok.json", "{" MESHES ", \"time\": {\"frame_rate\": 25, \"time_step\": 0.01}}",
                         &d, &err) == FM_OK, "%s", err.message);
    ENSURE(d.time_step == 0.01);
}

/* jansson's own position for a syntax error, checked against the line we broke. */
static void expect_syntax_error(const char *name, const char *text, int broken_line)
{
    char path[FM_PATH_MAX], prefix[FM_PATH_MAX + 64];
    json_error_t jerr;
    json_t *root = json_loads(text, JSON_REJECT_DUPLICATES, &jerr);
    ENSURE(root == NULL);
    json_decref(root);
    ENSURE_MSG(jerr.line == broken_line, "%s: jansson says line %d", name, jerr.line);
    fm_scene_def d;
    fm_error err = {0};
    ENSURE(load_text(name, text, &d, &err) == FM_ERR_INPUT);
    snprintf(prefix, sizeof prefix, "%s:%d:%d: ", tmp_path(path, name), jerr.line, jerr.column);
    ENSURE_MSG(strncmp(err.message, prefix, strlen(prefix)) == 0, "expected '%s...', got '%s'", prefix, err.message);
    ENSURE_MSG(strstr(err.message, jerr.text) != NULL, "'%s' lacks jansson's '%s'", err.message, jerr.text);
}

static void test_syntax_error(void)
{
    expect_syntax_error("syntax_comma.json",
                        "{\n  \"source\": {\"mesh\": \"a.obj\"}\n  \"target\": {\"mesh\": \"b.obj\"}\n}\n", 3);
    expect_syntax_error("syntax_trailing.json", "{" MESHES ",\n  \"n\": 5,\n}\n", 3);
    expect_syntax_error("syntax_empty.json", "", 1);
}

static void test_duplicate_keys(void)
{
    expect_syntax_error("dup_top.json", "{" MESHES ",\n  \"speed0\": 1,\n  \"speed0\": 2\n}\n", 3);
    expect_syntax_error("dup_nested.json", "{" MESHES ",\n  \"time\": {\"frame_rate\": 24,\n  \"frame_rate\": 25}}", 3);
    fm_scene_def d;
    fm_error err = {0};
    ENSURE(load_text("dup_msg.json", "{" MESHES ", \"n\": 1, \"n\": 2}", &d, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "duplicate") != NULL, "'%s'", err.message);
}

static void test_missing_mesh(void)
{
    expect_error_at("no_source.json", "@{\"target\": {\"mesh\": \"b.obj\"}}", "source.mesh");
    expect_error_at("no_target.json", "\n  @{\"source\": {\"mesh\": \"a.obj\"}, \"target\": {}}", "target.mesh");
    expect_error_at("empty_mesh.json", "{\"source\": {\"mesh\": @\"\"}, \"target\": {\"mesh\": \"b.obj\"}}",
                    "source.mesh");
    expect_error_at("not_object.json", "@[1, 2, 3]", "object");
}

static void test_missing_scene_file(void)
{
    char path[FM_PATH_MAX];
    fm_scene_def d;
    fm_error err = {0};
    fm_status st = fm_scene_load(tmp_path(path, "does_not_exist.json"), &d, &err);
    ENSURE(st == FM_ERR_INPUT && err.status == st);
    ENSURE_MSG(strstr(err.message, path) && strstr(err.message, "cannot open"), "'%s'", err.message);
    /* a directory is not a scene file either */
    mkdir(tmp_path(path, "dir.json"), 0777);
    st = fm_scene_load(path, &d, &err);
    ENSURE(st != FM_OK && err.status == st);
    ENSURE_MSG(strstr(err.message, path) != NULL, "'%s'", err.message);
    /* no error struct: still a status, no crash */
    ENSURE(fm_scene_load(tmp_path(path, "does_not_exist.json"), &d, NULL) == FM_ERR_INPUT);
}

/* ---------------------------------------------------------------- fm_scene_validate */

static fm_scene_def def_with_meshes(void)
{
    fm_scene_def d = fm_default_scene_def();
    strcpy(d.source.path, "a.obj");
    strcpy(d.target.path, "b.obj");
    return d;
}

/* fm_scene_parse: a text in memory, not NUL-terminated, named "shots/s.json" in messages and
 * for resolving relative mesh paths; a NUL inside the text is a syntax error, not the text's end. */
static void test_parse_from_memory(void)
{
    const char text[] = "{" MESHES ", \"speed0\": 3}XXXX";
    fm_scene_def d;
    fm_error err = {0};
    ENSURE_MSG(fm_scene_parse(text, strlen(text) - 4, "shots/s.json", &d, &err) == FM_OK, "%s", err.message);
    ENSURE(!strcmp(d.source.path, "shots/a.obj") && !strcmp(d.scene_path, "shots/s.json") && d.speed0 == 3);
    const char bad[] = "{" MESHES ",\n \"speed0\": -1}";
    ENSURE(fm_scene_parse(bad, strlen(bad), "shots/s.json", &d, &err) == FM_ERR_INPUT);
    ENSURE_MSG(!strncmp(err.message, "shots/s.json:2:12: speed0:", 26), "%s", err.message);
    const char with_nul[] = "{" MESHES "}\0 garbage";
    ENSURE(fm_scene_parse(with_nul, sizeof with_nul - 1, "s.json", &d, &err) == FM_ERR_INPUT);
    ENSURE_MSG(!strncmp(err.message, "s.json:1:", 9), "%s", err.message);
}

static void expect_invalid(const fm_scene_def *d, const char *what)
{
    fm_error err = {0};
    fm_status st = fm_scene_validate(d, &err);
    ENSURE_MSG(st == FM_ERR_INPUT && err.status == FM_ERR_INPUT, "%s: status %d", what, (int)st);
    ENSURE_MSG(strstr(err.message, what) != NULL, "'%s' not in '%s'", what, err.message);
}

/* Applies `change` to a valid definition (called d_) and expects validation to name `what`. */
#define EXPECT_INVALID(change, what)                                                              \
    do {                                                                                          \
        fm_scene_def d_ = def_with_meshes();                                                      \
        change;                                                                                   \
        expect_invalid(&d_, what);                                                                \
    } while (0)

static void test_validate(void)
{
    fm_scene_def d = def_with_meshes();
    fm_error err = {0};
    ENSURE_MSG(fm_scene_validate(&d, &err) == FM_OK, "%s", err.message);
    EXPECT_INVALID(d_.speed0 = -1, "speed0");
    EXPECT_INVALID(d_.source.path[0] = 0, "source.mesh");
    EXPECT_INVALID(d_.omega1 = NAN, "omega1");
    EXPECT_INVALID(d_.time_step = 0.03, "time.time_step");
    EXPECT_INVALID(d_.target.translate[2] = 1e10, "target.translate");
    /* a cache name built in code gets the scene file's check: a plain, non-empty file name */
    EXPECT_INVALID(strcpy(d_.cache_name, "../escape.fmc"), "output.cache");
    EXPECT_INVALID(d_.cache_name[0] = 0, "output.cache");
    /* nor the name of another file of the run, or of a file being written */
    EXPECT_INVALID(strcpy(d_.cache_name, FM_OUTPUT_STATS), "output.cache");
    EXPECT_INVALID(strcpy(d_.cache_name, FM_OUTPUT_CHECKPOINT), "output.cache");
    EXPECT_INVALID(strcpy(d_.cache_name, "frames.fmc.partial"), "output.cache");
}

/* Issue 38: the tetra morph's moving target, its defaults, and the combinations it refuses. */
static void test_target_motion_keys(void)
{
    fm_scene_def def;
    fm_error err = {0};
    fm_status st = load_text("motion.json",
        "{" MESHES ", \"target_motion\": {\"sequence\": \"walk_%03d.obj\", \"frames\": 12, \"start\": 2,"
        " \"path\": [[1, 0, 0], [1, 2, 0]], \"speed\": 3}}",
        &def, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    const struct fm_target_motion_def *tm = &def.target_motion;
    ENSURE(strstr(tm->sequence, "/walk_%03d.obj") != NULL && tm->frames == 12 && tm->frame_rate == 24);
    ENSURE(tm->start == 2 && tm->path_count == 2 && tm->path[1][1] == 2 && tm->speed == 3);
    const fm_scene_def d = fm_default_scene_def(); /* no motion: the target stands still */
    ENSURE(!d.target_motion.sequence[0] && d.target_motion.path_count == 0 && d.target_motion.speed == 1);
    expect_error_at("motion_frames.json", "{" MESHES ",\n \"target_motion\": {\"frames\": @3}}",
                    "target_motion.frames: meshes of no sequence");
    expect_error_at("motion_pattern.json", "{" MESHES ",\n \"target_motion\": {\"sequence\": @\"walk.obj\", \"frames\": 3}}",
                    "not a file name pattern");
    expect_error_at("motion_none.json", "{" MESHES ",\n \"target_motion\": {\"sequence\": @\"w%d.obj\"}}",
                    "target_motion.frames: a sequence needs at least one mesh");
    expect_error_at("motion_speed.json", "{" MESHES ",\n \"target_motion\": {\"speed\": @0}}", "target_motion.speed");
    expect_error_at("motion_switch.json", "{" MESHES ",\n \"phase2\": {\"switch\": @\"distance\"},"
                    " \"target_motion\": {\"path\": [[1, 0, 0]]}}", "phase2.switch: \"distance\" reads");
    expect_error_at("motion_flock.json", "{\"mode\": \"shape_flock\", \"n\": 10, " MESHES ",\n \"target_motion\": {@\"start\": 1}}",
                    "target_motion.start: does not apply");
}

int main(void)
{
    RUN_TEST(test_valid_scene_fields);
    RUN_TEST(test_defaults_for_left_out_keys);
    RUN_TEST(test_boundary_values_accepted);
    RUN_TEST(test_blow_up_bounds_accepted_at_their_limits);
    RUN_TEST(test_every_example_loads);
    RUN_TEST(test_relative_scene_path);
    RUN_TEST(test_velocity_model_keys);
    RUN_TEST(test_target_motion_keys);
    RUN_TEST(test_unknown_key_top_level);
    RUN_TEST(test_unknown_key_nested);
    RUN_TEST(test_unusual_keys_located);
    RUN_TEST(test_wrong_types);
    RUN_TEST(test_out_of_range);
    RUN_TEST(test_time_step_must_divide_frame);
    RUN_TEST(test_up_direction);
    RUN_TEST(test_target_route);
    RUN_TEST(test_syntax_error);
    RUN_TEST(test_duplicate_keys);
    RUN_TEST(test_missing_mesh);
    RUN_TEST(test_missing_scene_file);
    RUN_TEST(test_validate);
    RUN_TEST(test_parse_from_memory);
    return test_result();
}
