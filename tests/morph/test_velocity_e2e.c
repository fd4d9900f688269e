/* The full velocity model end to end (FM §5): style fields baked on a grid, an obstacle in the
 * path, MDE and a path width, on CASA -> 2014. Same cache for 1 and 2 threads; everyone arrives;
 * no tet's bounding sphere enters the obstacle; the §8 options (distance switch, avoidance in
 * phase 2) also complete. */
#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <stdlib.h>
#include <string.h>

static fm_scene_def scene(void)
{
    fm_scene_def d = fm_default_scene_def();
    snprintf(d.source.path, sizeof d.source.path, "%s/examples/words/casa.obj", FM_SOURCE_DIR);
    snprintf(d.target.path, sizeof d.target.path, "%s/examples/words/y2014.obj", FM_SOURCE_DIR);
    d.source.translate[0] = -12, d.target.translate[0] = 12;
    d.launch_rate = 3000;
    d.frame_rate = 24, d.time_step = 1.0 / 48;
    d.omega1 = 0.8, d.omega2 = 0.2;
    d.field_count = 2;
    d.fields[0] = fm_default_field_def(FM_FIELD_CURL_NOISE);
    d.fields[0].gain = 4, d.fields[0].scale = 3;
    d.fields[1] = fm_default_field_def(FM_FIELD_VORTEX);
    d.fields[1].axis[0] = 1, d.fields[1].axis[1] = 0, d.fields[1].strength = 0.5;
    d.field_grid[0] = d.field_grid[1] = d.field_grid[2] = 24;
    d.obstacle_count = 1; /* a small king standing on the straight path */
    snprintf(d.obstacles[0].path, sizeof d.obstacles[0].path, "%s/examples/castling/king.obj", FM_SOURCE_DIR);
    d.obstacles[0].scale = 0.3;
    d.obstacles[0].translate[1] = 0.5;
    d.k_a = 1.0;
    d.d_min = 0.05;
    d.path_width = 6, d.path_attraction = 1;
    return d;
}

static int run(const fm_scene_def *d, int threads, const char *cache, fm_morph_run_stats *rs)
{
    fm_error err = {0};
    fm_morph_model *m = fm_morph_model_build(d, NULL, NULL, &err);
    ENSURE_MSG(m != NULL, "%s", err.message);
    if (!m) return -1;
    fm_morph_state *s = fm_morph_state_create(m, threads, &err);
    fm_cache_writer *w = cache ? fm_cache_writer_create(cache, (uint64_t)fm_morph_model_get_info(m).agents, 24, 1, &err) : NULL;
    ENSURE(s && (w || !cache));
    ENSURE_MSG(fm_morph_run(m, s, w, NULL, NULL, rs, &err) == FM_OK, "%s", err.message);
    if (w) ENSURE(fm_cache_writer_finish(w, &err) == FM_OK);
    fm_morph_state_destroy(s);
    fm_morph_model_destroy(m);
    return 0;
}

static int same_file(const char *a, const char *b)
{
    FILE *f = fopen(a, "rb"), *g = fopen(b, "rb");
    int same = f && g;
    while (same) {
        int x = fgetc(f), y = fgetc(g);
        same = x == y;
        if (x == EOF || y == EOF) break;
    }
    if (f) fclose(f);
    if (g) fclose(g);
    return same;
}

static void test_full_model_threads_agree_and_everyone_arrives(void)
{
    fm_scene_def d = scene();
    fm_morph_run_stats r1, r2;
    const char *c1 = FM_TEST_TMP "/velocity_t1.fmc", *c2 = FM_TEST_TMP "/velocity_t2.fmc";
    if (run(&d, 1, c1, &r1) || run(&d, 2, c2, &r2)) return;
    ENSURE(r1.all_arrived && r2.all_arrived);
    ENSURE(r1.inverted_tet_frames == 0 && r1.target_tets_filled_once);
    ENSURE_MSG(r1.final_max_vertex_error <= 1e-5, "%g", r1.final_max_vertex_error);
    ENSURE_MSG(r1.min_obstacle_clearance >= 0, "a tet entered the obstacle: clearance %g", r1.min_obstacle_clearance);
    ENSURE_MSG(r1.min_obstacle_clearance < 0.5, "the obstacle was never approached (%g)", r1.min_obstacle_clearance);
    ENSURE_MSG(r1.mde_fraction_mean > 0, "MDE never acted");
    ENSURE(same_file(c1, c2)); /* bitwise the same for 1 and 2 threads */
    fm_morph_run_stats_free(&r1), fm_morph_run_stats_free(&r2);
}

static void test_beyond_the_paper_options_complete(void)
{
    fm_scene_def d = scene();
    d.phase_switch = FM_SWITCH_DISTANCE;
    d.switch_distance = 1.0;
    d.avoid_in_phase2 = 1;
    fm_morph_run_stats rs;
    if (run(&d, 2, NULL, &rs)) return;
    ENSURE(rs.all_arrived);
    ENSURE(rs.inverted_tet_frames == 0 && rs.target_tets_filled_once);
    ENSURE_MSG(rs.final_max_vertex_error <= 1e-5, "%g", rs.final_max_vertex_error);
    fm_morph_run_stats_free(&rs);
}

int main(void)
{
    RUN_TEST(test_full_model_threads_agree_and_everyone_arrives);
    RUN_TEST(test_beyond_the_paper_options_complete);
    return test_result();
}
