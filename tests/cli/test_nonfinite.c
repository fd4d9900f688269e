/* Readers facing a cache whose values ran away (issue 15, item 11), as a cache written before the
 * engine stopped such runs, or by another writer, may hold: `inspect` counts the values that are
 * not finite and keeps them out of the bounds, `render` refuses a frame that holds any with exit 2
 * and says which, and a frame with huge but finite coordinates renders without a crash. */
#include "flockmorph/flockmorph.h"
#include "test_macros.h"
#include "test_cli_helpers.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

enum { AGENTS = 6, FRAMES = 3 };

static char g_cache[FM_PATH_MAX];

/* Frame 0 sane tets, frame 1 with a NaN and an inf in agents 2 and 4, frame 2 sane but 2.5e9 away. */
static void write_cache(const char *path)
{
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(path, AGENTS, 24, 1, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    static const float tet[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    float verts[AGENTS * 12];
    for (int f = 0; f < FRAMES; f++) {
        for (int a = 0; a < AGENTS; a++)
            for (int i = 0; i < 12; i++) verts[12 * a + i] = tet[i] + (float)(2 * a) + (f == 2 ? 2.5e9f : 0);
        if (f == 1) verts[12 * 2 + 4] = NAN, verts[12 * 4 + 9] = INFINITY;
        ENSURE_MSG(fm_cache_writer_add_frame(w, verts, &err) == FM_OK, "%s", err.message);
    }
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
}

static void test_inspect_counts_values_that_are_not_finite(void)
{
    const char *cache = g_cache;
    char args[2 * FM_PATH_MAX];
    snprintf(args, sizeof args, "inspect '%s' --json", cache);
    ENSURE_MSG(cli(args) == 0, "inspect: %s", g_err);
    json_error_t jerr;
    json_t *j = json_loads(g_out, 0, &jerr);
    ENSURE_MSG(j != NULL, "inspect --json: %s", jerr.text);
    const json_t *b = json_object_get(json_object_get(j, "bounds"), "tet_vertices");
    ENSURE(json_integer_value(json_object_get(b, "non_finite_values")) == 2);
    ENSURE(json_integer_value(json_object_get(b, "first_non_finite_frame")) == 1);
    ENSURE(json_real_value(json_array_get(json_object_get(b, "min"), 0)) == 0);
    ENSURE(json_real_value(json_array_get(json_object_get(b, "max"), 0)) == (double)(2.5e9f + 11)); /* inf left out */
    json_decref(j);
    snprintf(args, sizeof args, "inspect '%s'", cache);
    ENSURE_MSG(cli(args) == 0 && strstr(g_out, "2 values not finite, the first in frame 1"), "inspect: %s", g_out);
}

static void test_render_refuses_a_frame_that_is_not_finite(void)
{
    const char *cache = g_cache;
    char args[3 * FM_PATH_MAX], png[FM_PATH_MAX];
    snprintf(png, sizeof png, "%s/nonfinite.png", FM_TEST_TMP);
    remove(png);
    snprintf(args, sizeof args, "render '%s' --frame 1 -o '%s' --size 64x48", cache, png);
    int rc = cli(args);
    ENSURE_MSG(rc == 2 && strstr(g_err, "frame 1") && strstr(g_err, "not finite") && strstr(g_err, "agent 2"),
               "render of a frame with NaN: exit %d, %s", rc, g_err);
    FILE *f = fopen(png, "rb");
    ENSURE_MSG(f == NULL, "a PNG was written for a frame that is not finite");
    if (f) fclose(f);
    snprintf(args, sizeof args, "render '%s' --frame 2 -o '%s' --size 64x48", cache, png);
    rc = cli(args);
    ENSURE_MSG(rc == 0, "render of a frame 2.5e9 away: exit %d, %s", rc, g_err);
    snprintf(args, sizeof args, "render '%s' --frame 0 -o '%s' --size 64x48", cache, png);
    ENSURE_MSG(cli(args) == 0, "render of a sane frame: %s", g_err);
}

int main(void)
{
    (void)write_text, (void)write_octahedron; /* test_cli_helpers.h's, unused here */
    snprintf(g_cache, sizeof g_cache, "%s/nonfinite.fmc", FM_TEST_TMP);
    write_cache(g_cache);
    RUN_TEST(test_inspect_counts_values_that_are_not_finite);
    RUN_TEST(test_render_refuses_a_frame_that_is_not_finite);
    return test_result();
}
