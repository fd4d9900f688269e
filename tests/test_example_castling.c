/* The bundled castling example (FM Figure 8 bottom), run as a user runs it: the rook's tets fly
 * past the king standing in their path; every agent arrives, and no tet's bounding sphere ever
 * enters the king (min_obstacle_clearance >= 0). */
#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <jansson.h>
#include <stdlib.h>
#include <sys/wait.h>

static void test_castling_example_completes(void)
{
    const char *out = FM_TEST_TMP "/example_castling";
    char cmd[4 * FM_PATH_MAX];
    snprintf(cmd, sizeof cmd, "'%s' run '%s/examples/castling/scene.json' -o '%s' --threads 2 --quiet > '%s.log' 2>&1",
             FM_CLI, FM_SOURCE_DIR, out, out);
    int rc = system(cmd);
    ENSURE_MSG(WIFEXITED(rc) && WEXITSTATUS(rc) == 0, "exit status %d (see %s.log)", WEXITSTATUS(rc), out);
    char stats_path[FM_PATH_MAX];
    snprintf(stats_path, sizeof stats_path, "%s/stats.json", out);
    json_error_t jerr;
    json_t *stats = json_load_file(stats_path, 0, &jerr);
    ENSURE_MSG(stats != NULL, "%s: %s", stats_path, jerr.text);
    if (!stats) return;
    double clearance = json_number_value(json_object_get(stats, "min_obstacle_clearance"));
    ENSURE_MSG(json_is_number(json_object_get(stats, "min_obstacle_clearance")) && clearance >= 0,
               "a tet entered the king: clearance %g", clearance);
    ENSURE_MSG(clearance < 0.3, "the flock never came near the king (clearance %g)", clearance);
    ENSURE(json_number_value(json_object_get(stats, "mde_fraction_mean")) > 0);
    ENSURE(json_is_true(json_object_get(stats, "all_arrived")));
    ENSURE(json_is_true(json_object_get(stats, "target_tets_filled_once")));
    ENSURE(json_integer_value(json_object_get(stats, "inverted_tet_frames")) == 0);
    double error = json_number_value(json_object_get(stats, "final_max_vertex_error"));
    ENSURE_MSG(json_is_number(json_object_get(stats, "final_max_vertex_error")) && error <= 1e-5, "error %g", error);
    ENSURE(json_integer_value(json_object_get(stats, "frames")) > 10);
    ENSURE(json_number_value(json_object_get(stats, "agent_steps_per_second")) > 0);
    json_decref(stats);

    char cache[FM_PATH_MAX];
    snprintf(cache, sizeof cache, "%s/frames.fmc", out);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(cache, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (r) ENSURE(fm_cache_frames(r) > 10);
    fm_cache_close(r);
}

int main(void)
{
    RUN_TEST(test_castling_example_completes);
    return test_result();
}
