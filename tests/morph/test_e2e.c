/* End to end: CASA -> 2014 through the public API. The last frame is the target
 * tetrahedralization, no tet inverts, the cache is the same for 1 and 2 threads and for the same
 * seed, agents launch in D1 order and targets are handed out in D2 order. */
#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <stdlib.h>
#include <string.h>

static fm_scene_def words_def(void)
{
    fm_scene_def def = fm_default_scene_def();
    snprintf(def.source.path, sizeof def.source.path, "%s/examples/words/casa.obj", FM_SOURCE_DIR);
    snprintf(def.target.path, sizeof def.target.path, "%s/examples/words/y2014.obj", FM_SOURCE_DIR);
    def.source.translate[0] = -10, def.target.translate[0] = 10;
    def.path_point_count = 1;
    def.path_points[0][2] = 8;
    def.launch_rate = 3000;
    def.frame_rate = 24, def.time_step = 1.0 / 48;
    return def;
}

static fm_morph_model *model;

static char *slurp(const char *path, long *len)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    *len = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)*len);
    if (buf && fread(buf, 1, (size_t)*len, f) != (size_t)*len) free(buf), buf = NULL;
    fclose(f);
    return buf;
}

static void run_to_cache(int threads, const char *path, fm_morph_run_stats *rs)
{
    fm_error err = {0};
    fm_morph_state *state = fm_morph_state_create(model, threads, &err);
    fm_cache_writer *w = fm_cache_writer_create(path, (uint64_t)fm_morph_model_get_info(model).agents, 24, 3, &err);
    ENSURE(state && w);
    ENSURE_MSG(fm_morph_run(model, state, w, NULL, NULL, rs, &err) == FM_OK, "%s", err.message);
    fm_morph_run_stats_free(rs);
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    fm_morph_state_destroy(state);
}

static int compare_vertices(const void *a, const void *b)
{
    const float *p = a, *q = b;
    for (int k = 0; k < 3; k++)
        if (p[k] != q[k]) return p[k] < q[k] ? -1 : 1;
    return 0;
}

static int compare_tets(const void *a, const void *b) { return memcmp(a, b, 12 * sizeof(float)); }

/* Sorts each tet's vertices, then the tets: equal sets of tets give equal arrays. */
static void canonical(float *tets, int64_t n)
{
    for (int64_t i = 0; i < n; i++) qsort(tets + 12 * i, 4, 3 * sizeof(float), compare_vertices);
    qsort(tets, (size_t)n, 12 * sizeof(float), compare_tets);
}

static void test_last_frame_is_the_target_and_threads_agree(void)
{
    fm_morph_run_stats r1, r2;
    const char *p1 = FM_TEST_TMP "/e2e_threads1.fmc", *p2 = FM_TEST_TMP "/e2e_threads2.fmc";
    run_to_cache(1, p1, &r1);
    run_to_cache(2, p2, &r2);
    ENSURE(r1.all_arrived && r2.all_arrived);
    ENSURE(r1.inverted_tet_frames == 0);
    ENSURE(r1.target_tets_filled_once);
    ENSURE_MSG(r1.final_max_vertex_error <= 1e-5, "%g", r1.final_max_vertex_error);
    long n1, n2;
    char *a = slurp(p1, &n1), *b = slurp(p2, &n2);
    ENSURE(a && b && n1 == n2 && memcmp(a, b, (size_t)n1) == 0); /* same bytes for 1 and 2 threads */
    free(a), free(b);

    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(p2, &err);
    ENSURE(r != NULL);
    int64_t n = (int64_t)fm_cache_agents(r);
    float *last = malloc(sizeof(float) * 12 * (size_t)n), *target = malloc(sizeof(float) * 12 * (size_t)n);
    ENSURE(fm_cache_read_frame(r, fm_cache_frames(r) - 1, last, &err) == FM_OK);
    for (int64_t j = 0; j < n; j++) memcpy(target + 12 * j, fm_morph_model_target_tet(model, j), 12 * sizeof(float));
    canonical(last, n), canonical(target, n);
    double worst = 0; /* every target tet is in the last frame, once */
    for (int64_t i = 0; i < 12 * n; i++) worst = fmax(worst, fabs((double)last[i] - target[i]));
    ENSURE_MSG(worst <= 1e-5, "last frame differs from the target tets by %g", worst);
    free(last), free(target);
    fm_cache_close(r);
}

static void test_same_seed_same_bytes(void)
{
    fm_morph_run_stats rs;
    const char *p1 = FM_TEST_TMP "/e2e_seed_a.fmc", *p2 = FM_TEST_TMP "/e2e_threads2.fmc";
    run_to_cache(2, p1, &rs);
    long n1, n2;
    char *a = slurp(p1, &n1), *b = slurp(p2, &n2);
    ENSURE(a && b && n1 == n2 && memcmp(a, b, (size_t)n1) == 0);
    free(a), free(b);
}

/* At every step the launched agents are a prefix of the D1 order (agent ids) and the target
 * slots handed out are a prefix of the D2 order, each taken once. */
static void test_launch_and_hand_out_orders(void)
{
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(model, 2, &err);
    int64_t n = fm_morph_model_get_info(model).agents, *targets = malloc(sizeof(int64_t) * (size_t)n);
    uint8_t *seen = malloc((size_t)n);
    int ok_launch = 1, ok_slots = 1;
    while (!fm_morph_get_info(s).all_arrived && fm_morph_get_info(s).run.step < 5000) {
        double t_before = fm_morph_get_info(s).run.time;
        fm_morph_step(model, s);
        fm_morph_info info = fm_morph_get_info(s);
        fm_morph_targets(s, targets);
        memset(seen, 0, (size_t)n);
        int64_t handed = 0;
        for (int64_t a = 0; a < n; a++)
            if (targets[a] >= 0) {
                ok_slots &= targets[a] < n && !seen[targets[a]];
                if (targets[a] < n) seen[targets[a]] = 1;
                handed++;
            }
        for (int64_t k = 0; k < handed; k++) ok_slots &= seen[k];
        ok_launch &= info.run.count[FM_PHASE_WAITING] == n - (int64_t)fmin((double)n, floor(3000.0 * t_before) + 1);
    }
    ENSURE(fm_morph_get_info(s).all_arrived);
    ENSURE(ok_slots);
    ENSURE(ok_launch);
    free(targets), free(seen);
    fm_morph_state_destroy(s);
}

/* Frame 0 is the source at rest: its tets' volume is the source volume. */
static void test_first_frame_is_the_source(void)
{
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(model, 2, &err);
    fm_morph_model_info mi = fm_morph_model_get_info(model);
    float *v = malloc(sizeof(float) * 12 * (size_t)mi.agents);
    fm_morph_tet_vertices(model, s, v);
    double vol = 0;
    for (int64_t i = 0; i < mi.agents; i++) {
        const float *t = v + 12 * i;
        double a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) a[k] = t[3 + k] - t[k], b[k] = t[6 + k] - t[k], c[k] = t[9 + k] - t[k];
        vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6;
    }
    ENSURE_NEAR(vol, mi.source_volume, 1e-4 * mi.source_volume);
    ENSURE(mi.agents == (mi.source_tets > mi.target_tets ? mi.source_tets : mi.target_tets));
    free(v);
    fm_morph_state_destroy(s);
}

int main(void)
{
    fm_error err = {0};
    fm_scene_def def = words_def();
    model = fm_morph_model_build(&def, NULL, NULL, &err);
    if (!model) {
        fprintf(stderr, "model: %s\n", err.message);
        return 1;
    }
    RUN_TEST(test_last_frame_is_the_target_and_threads_agree);
    RUN_TEST(test_same_seed_same_bytes);
    RUN_TEST(test_launch_and_hand_out_orders);
    RUN_TEST(test_first_frame_is_the_source);
    fm_morph_model_destroy(model);
    return test_result();
}
