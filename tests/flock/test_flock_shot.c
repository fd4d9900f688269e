/* Shape-flock shots (docs/scene.md, "Groups"): SCF's flock that "transforms among different static
 * shapes" in one run. examples/flock_sequence: cylinder -> sphere -> torus, the torus group taking
 * over the sphere group's agents. Checked on the cache, independently of the engine's figures:
 *   - the rows are the one flock's (3000, not 6000), the group attribute turns from 0 to 1 once;
 *   - the hand-over is unbroken: no agent moves further across it than any agent moves in any
 *     other frame;
 *   - the frame before the hand-over lies on the sphere, the last frame on the torus (brute-force
 *     point-triangle distances to the placed meshes);
 *   - 1 and 2 threads give the same bytes;
 * and the refusals of what a flock's groups cannot do. */
#include "flockmorph/flockmorph.h"
#include "geom.h"
#include "inside_test.h"
#include "shot_helpers.h"
#include "test_macros.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int run_shot(const fm_scene_def *defs, int count, int threads, const char *cache, fm_flock_shot_stats *stats)
{
    fm_error err = {0};
    fm_flock_shot *shot = fm_flock_shot_build(defs, count, NULL, NULL, &err);
    ENSURE_MSG(shot != NULL, "%s", err.message);
    if (!shot) return -1;
    fm_flock_shot_set_threads(shot, threads);
    const fm_cache_attr attrs[] = {FM_ATTR_POSITION, FM_ATTR_ID, FM_ATTR_PHASE, FM_ATTR_GROUP};
    fm_cache_options opts = fm_default_cache_options();
    fm_cache_writer *w = fm_cache_writer_create_attrs(cache, (uint64_t)fm_flock_shot_rows(shot), defs[0].frame_rate,
                                                      attrs, 4, &opts, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    fm_run_control c = fm_default_run_control();
    fm_status st = w ? fm_flock_shot_run(shot, w, &c, stats, &err) : FM_ERR_IO;
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    if (w) ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    fm_flock_shot_destroy(shot);
    return st == FM_OK ? 0 : -1;
}

/* The largest distance from any of n points to the placed mesh (brute force over its triangles). */
static double farthest_from(const fm_mesh_ref *ref, const float *p, uint64_t n)
{
    fm_error err = {0};
    fm_mesh mesh = {0};
    ENSURE_MSG(fm_mesh_load(ref->path, &mesh, &err) == FM_OK, "%s", err.message);
    if (err.status != FM_OK) return INFINITY;
    fm_mesh_place(&mesh, ref);
    double worst = 0;
    for (uint64_t a = 0; a < n; a++) {
        const double q[3] = {p[3 * a], p[3 * a + 1], p[3 * a + 2]};
        double best = INFINITY;
        for (int64_t t = 0; t < mesh.nt; t++) {
            const int32_t *i = mesh.tri + 3 * t;
            best = fmin(best, inside_tri_dist2(q, mesh.v + 3 * i[0], mesh.v + 3 * i[1], mesh.v + 3 * i[2]));
        }
        worst = fmax(worst, sqrt(best));
    }
    fm_mesh_free(&mesh);
    return worst;
}

static double largest_move(const float *x, const float *y, uint64_t n)
{
    double most = 0;
    for (uint64_t a = 0; a < n; a++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += ((double)x[3 * a + k] - y[3 * a + k]) * ((double)x[3 * a + k] - y[3 * a + k]);
        most = fmax(most, sqrt(d2));
    }
    return most;
}

static void test_sequence_of_shapes(void)
{
    char path[FM_PATH_MAX], one[FM_PATH_MAX], two[FM_PATH_MAX];
    snprintf(path, sizeof path, "%s/examples/flock_sequence/scene.json", FM_SOURCE_DIR);
    snprintf(one, sizeof one, "%s/flock_shot_1.fmc", FM_TEST_TMP);
    snprintf(two, sizeof two, "%s/flock_shot_2.fmc", FM_TEST_TMP);
    static fm_scene_def defs[FM_MAX_GROUPS];
    int count = 0;
    if (load_groups(path, defs, &count) != 0) return;
    ENSURE(count == 2 && defs[1].group.source_group == 0);
    fm_flock_shot_stats s1 = {0}, s2 = {0};
    const int failed = run_shot(defs, count, 1, one, &s1) || run_shot(defs, count, 2, two, &s2);
    const int64_t rows = s1.rows;
    const int all_bound = s1.all_bound && s1.group[0].all_bound && s1.group[1].all_bound;
    const int waited = s1.group[1].start_time >= s1.group[0].bound_time + 0.5 - 1e-9;
    fm_flock_shot_stats_free(&s1), fm_flock_shot_stats_free(&s2); /* their per-frame measures */
    if (failed) return;
    ENSURE_MSG(same_file(one, two), "the flock shot's cache differs between 1 and 2 threads");
    ENSURE_MSG(rows == defs[0].n, "%lld rows for a flock of %lld", (long long)rows, (long long)defs[0].n);
    ENSURE(all_bound);
    ENSURE(waited);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(one, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    const uint64_t n = fm_cache_agents(r);
    float *prev = malloc(sizeof(float) * 3 * n), *cur = malloc(sizeof(float) * 3 * n), *before = malloc(sizeof(float) * 3 * n);
    uint8_t *group = malloc(n);
    int handovers = 0, last_group = 0;
    double across = 0, elsewhere = 0;
    for (uint32_t f = 0; prev && cur && before && group && f < fm_cache_frames(r); f++) {
        ENSURE(fm_cache_read_attr(r, f, FM_ATTR_POSITION, cur, &err) == FM_OK);
        ENSURE(fm_cache_read_attr(r, f, FM_ATTR_GROUP, group, &err) == FM_OK);
        for (uint64_t a = 1; a < n; a++) ENSURE_MSG(group[a] == group[0], "frame %u: the rows belong to two groups", f);
        if (f > 0 && group[0] != last_group) handovers++, across = largest_move(prev, cur, n), memcpy(before, prev, 12 * n);
        else if (f > 0) elsewhere = fmax(elsewhere, largest_move(prev, cur, n));
        last_group = group[0];
        float *t = prev;
        prev = cur, cur = t;
    }
    double on_sphere = handovers ? farthest_from(&defs[0].target, before, n) : INFINITY;
    double on_torus = farthest_from(&defs[1].target, prev, n);
    printf("  sequence: %u frames, %d hand-over; largest move across it %.4g, in any other frame %.4g; the flock "
           "before it within %.2g of the sphere, at the end within %.2g of the torus\n",
           fm_cache_frames(r), handovers, across, elsewhere, on_sphere, on_torus);
    ENSURE(handovers == 1 && last_group == 1);
    ENSURE_MSG(across <= elsewhere, "the hand-over moved an agent %g, more than any frame's flight (%g)", across, elsewhere);
    ENSURE_MSG(on_sphere < 1e-4 && on_torus < 1e-4, "sphere %g, torus %g", on_sphere, on_torus);
    free(prev), free(cur), free(before), free(group);
    fm_cache_close(r);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (f) fputs(text, f), fclose(f);
}

/* A flock scene of two groups with the second item given, and the error it must give. */
static void expect_refusal(const char *name, const char *first, const char *second, const char *contains)
{
    char scene[FM_PATH_MAX], text[4096];
    snprintf(scene, sizeof scene, "%s/flock_shot_bad_%s.json", FM_TEST_TMP, name);
    snprintf(text, sizeof text,
             "{\n  \"mode\": \"shape_flock\", \"n\": 200,\n  \"groups\": [\n"
             "    { \"name\": \"a\", \"source\": { \"mesh\": \"%s/examples/flock_cylinder_sphere/cylinder.obj\" },"
             " \"target\": { \"mesh\": \"%s/examples/flock_cylinder_sphere/sphere.obj\", \"translate\": [15, 0, 0] }%s },\n"
             "%s\n  ]\n}\n", FM_SOURCE_DIR, FM_SOURCE_DIR, first, second);
    write_text(scene, text);
    fm_error err = {0};
    static fm_scene_def def, defs[FM_MAX_GROUPS];
    fm_status st = fm_scene_load(scene, &def, &err);
    for (int g = 0; st == FM_OK && g < def.group_count; g++) st = fm_scene_load_group(scene, NULL, 0, g, &defs[g], &err);
    if (st == FM_OK) {
        fm_flock_shot *shot = fm_flock_shot_build(defs, def.group_count, NULL, NULL, &err);
        st = shot ? FM_OK : err.status;
        fm_flock_shot_destroy(shot);
    }
    ENSURE_MSG(st == FM_ERR_INPUT && strstr(err.message, contains), "%s: status %d, message '%s' (expected '%s')", name, st,
               err.message, contains);
}

static void test_flock_group_refusals(void)
{
    char sphere[FM_PATH_MAX + 64];
    snprintf(sphere, sizeof sphere, "%s/examples/flock_cylinder_sphere/sphere.obj", FM_SOURCE_DIR);
    char second[2 * FM_PATH_MAX];
    snprintf(second, sizeof second, "    { \"name\": \"b\", \"source\": { \"group\": \"a\" }, \"avoid\": [\"a\"], "
             "\"target\": { \"mesh\": \"%s\", \"translate\": [30, 0, 0] } }", sphere);
    expect_refusal("avoid", "", second, "groups[1].avoid: the shape flock's groups take no avoid in this version");
    snprintf(second, sizeof second, "    { \"name\": \"b\", \"source\": { \"group\": \"a\" }, "
             "\"target\": { \"mesh\": \"%s\", \"translate\": [30, 0, 0] } }", sphere);
    expect_refusal("floating", ", \"shape_flock\": { \"arrival\": { \"mode\": \"float\" } }", second,
                   "\"a\" never holds a formed shape to start from: its target lets its agents float");
}

int main(void)
{
    RUN_TEST(test_flock_group_refusals);
    RUN_TEST(test_sequence_of_shapes);
    return test_result();
}
