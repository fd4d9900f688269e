/* The spatial re-sort of the store (src/morph/morph_resort.c) and the scheduler's determinism: the re-sort
 * keeps every agent's id and state and the frame; the active range is laid out as morph.h says; and a
 * scenario with MDE and an obstacle gives the same cache bytes for 1, 2 and 3 threads and for every
 * SIMD level. */
#include "flockmorph/flockmorph.h"
#include "morph.h"
#include "simd.h"
#include "test_macros.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static fm_morph_model *model;

/* examples/castling at its own n, cut to a few seconds: path, baked curl noise, the king as an
 * obstacle, MDE. */
static fm_morph_model *castling(void)
{
    fm_scene_def def;
    fm_error err = {0};
    char path[4096];
    snprintf(path, sizeof path, "%s/examples/castling/rook.json", FM_SOURCE_DIR);
    ENSURE_MSG(fm_scene_load(path, &def, &err) == FM_OK, "%s", err.message);
    def.frame_limit = 60;
    fm_morph_model *m = fm_morph_model_build(&def, NULL, NULL, &err);
    ENSURE_MSG(m, "%s", err.message);
    return m;
}

typedef struct agent_record {
    float p[3], v[3], p2[3], t2, tf, morph[FM_MORPH_FLOATS];
    int64_t target;
    uint8_t phase, perm, safe;
} agent_record;

static void snapshot(const fm_morph_state *s, agent_record *by_id)
{
    memset(by_id, 0, sizeof *by_id * (size_t)s->n);
    for (int64_t a = 0; a < s->n; a++) {
        agent_record *r = by_id + s->id[a];
        for (int k = 0; k < 3; k++) r->p[k] = s->p[k][a], r->v[k] = s->v[k][a], r->p2[k] = s->p2[k][a];
        r->t2 = s->t2[a], r->tf = s->tf[a], r->target = s->target[a];
        memcpy(r->morph, s->morph + FM_MORPH_FLOATS * a, sizeof r->morph);
        r->phase = s->phase[a], r->perm = s->perm[a], r->safe = s->morph_safe[a];
    }
}

static void test_resort_keeps_ids_state_and_frame(void)
{
    fm_error err = {0};
    const double rate = model->launch_rate;
    model->launch_rate = 1000; /* slower launches: some agents arrive while others still wait */
    fm_morph_state *s = fm_morph_state_create(model, 2, &err);
    ENSURE(s);
    for (int i = 0; i < 75 * FM_RESORT_INTERVAL + 3; i++) fm_morph_step(model, s);
    const int64_t n = s->n;
    agent_record *before = malloc(sizeof *before * (size_t)n), *after = malloc(sizeof *after * (size_t)n);
    float *frame0 = malloc(sizeof(float) * 12 * (size_t)n), *frame1 = malloc(sizeof(float) * 12 * (size_t)n);
    uint8_t *seen = calloc((size_t)n, 1);
    snapshot(s, before);
    fm_morph_tet_vertices(model, s, frame0);
    fm_morph_state_resort(model, s);
    snapshot(s, after);
    fm_morph_tet_vertices(model, s, frame1);
    int64_t bad_ids = 0;
    for (int64_t a = 0; a < n; a++) bad_ids += s->id[a] < 0 || s->id[a] >= n || seen[s->id[a]]++;
    ENSURE_MSG(bad_ids == 0, "%lld slots with a bad or repeated id", (long long)bad_ids);
    int64_t stale_rest = 0; /* the store-order copies of the rest tet moved with their agents */
    for (int64_t a = 0; a < n; a++) {
        const int32_t i = s->id[a];
        stale_rest += s->rest_radius[a] != model->src_radius[i];
        for (int j = 0; j < 12; j++) stale_rest += s->rest_rel[j][a] != model->src_rel[12 * (size_t)i + (size_t)j];
    }
    ENSURE_MSG(stale_rest == 0, "%lld rest values not those of the slot's agent", (long long)stale_rest);
    ENSURE_MSG(memcmp(before, after, sizeof *before * (size_t)n) == 0, "an agent's state changed in the re-sort");
    ENSURE_MSG(memcmp(frame0, frame1, sizeof(float) * 12 * (size_t)n) == 0, "the frame changed in the re-sort");
    /* layout: arrived, then in flight, then waiting in id order */
    int64_t misplaced = 0;
    for (int64_t a = 0; a < s->active_begin; a++) misplaced += s->phase[a] != FM_PHASE_ARRIVED;
    for (int64_t a = s->active_begin; a < s->active_end; a++)
        misplaced += s->phase[a] == FM_PHASE_ARRIVED || s->phase[a] == FM_PHASE_WAITING;
    for (int64_t a = s->active_end; a < n; a++)
        misplaced += s->phase[a] != FM_PHASE_WAITING || (a > s->active_end && s->id[a] != s->id[a - 1] + 1);
    ENSURE_MSG(misplaced == 0, "%lld agents outside their range", (long long)misplaced);
    ENSURE_MSG(s->active_begin > 0 && s->active_end > s->active_begin && s->active_end < n,
               "the test wants all three ranges non-empty: %lld %lld %lld", (long long)s->active_begin,
               (long long)s->active_end, (long long)n);
    free(before), free(after), free(frame0), free(frame1), free(seen);
    fm_morph_state_destroy(s);
    model->launch_rate = rate;
}

/* Mean distance between agents next to each other in the store: the re-sort's purpose. */
static double neighbour_gap(const fm_morph_state *s)
{
    double sum = 0;
    for (int64_t a = s->active_begin + 1; a < s->active_end; a++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (double)(s->p[k][a] - s->p[k][a - 1]) * (s->p[k][a] - s->p[k][a - 1]);
        sum += sqrt(d2);
    }
    return sum / (double)(s->active_end - s->active_begin - 1);
}

/* Without MDE the key is the Morton code of the position (with MDE, the MDE grid's slot: the test
 * below). Every agent launched at the first step, in launch order (D1, FM eq 4). */
static void test_resort_brings_neighbours_together(void)
{
    fm_error err = {0};
    const double d_min = model->def.d_min, rate = model->launch_rate;
    model->def.d_min = 0, model->launch_rate = 1e12;
    fm_morph_state *s = fm_morph_state_create(model, 1, &err);
    fm_morph_step(model, s), fm_morph_step(model, s); /* agent 0 at t = 0, the others at the next step */
    double gap_before = neighbour_gap(s);
    fm_morph_state_resort(model, s);
    double gap_after = neighbour_gap(s);
    printf("  mean gap between store neighbours: %.4f before, %.4f after the re-sort\n", gap_before, gap_after);
    ENSURE(gap_after < 0.5 * gap_before);
    fm_morph_state_destroy(s);
    model->def.d_min = d_min, model->launch_rate = rate;
}

/* A launch of many agents at once is re-sorted at the next step, not up to FM_RESORT_INTERVAL - 1
 * steps later; after that, every FM_RESORT_INTERVAL steps. */
static void test_a_large_launch_is_resorted_at_the_next_step(void)
{
    fm_error err = {0};
    const double rate = model->launch_rate;
    model->launch_rate = 1e12;
    fm_morph_state *s = fm_morph_state_create(model, 1, &err);
    fm_morph_step(model, s); /* step 0 launches agent 0 (at t = 0), step 1 everyone else */
    fm_morph_step(model, s);
    ENSURE(s->active_end == s->n && s->sorted_end <= 1);
    fm_morph_step(model, s);
    ENSURE_MSG(s->sorted_end == s->n, "step 2 did not re-sort the launch: sorted_end %lld", (long long)s->sorted_end);
    fm_morph_state_destroy(s);
    model->launch_rate = rate;
}

/* Entries of the MDE grid whose agent comes before the previous entry's in the store. */
static int64_t grid_descents(const fm_grid *g)
{
    int64_t descents = 0;
    for (int64_t k = 1; k < g->count; k++) descents += g->quad[k >> 2].i[k & 3] < g->quad[(k - 1) >> 2].i[(k - 1) & 3];
    return descents;
}

/* Issue 40: the re-sort orders the store by MDE grid slot, so the build that follows it lists the
 * flying agents in store order (the walk then reads the table and the entries in step with the
 * store), and most of that order holds until the next re-sort (entries in a random order would
 * descend half the time). */
static void test_grid_lists_agents_in_store_order_after_a_resort(void)
{
    fm_error err = {0};
    const double rate = model->launch_rate;
    model->launch_rate = 1e12; /* everyone launched at the first step, as in bench_suite */
    fm_morph_state *s = fm_morph_state_create(model, 2, &err);
    ENSURE(s);
    for (int i = 0; i < 3 * FM_RESORT_INTERVAL; i++) fm_morph_step(model, s);
    int64_t stale = grid_descents(&s->grid); /* built FM_RESORT_INTERVAL - 1 steps after a re-sort */
    fm_morph_step(model, s);                 /* re-sorts, then builds */
    ENSURE(s->grid.count > 1000);
    int64_t fresh = grid_descents(&s->grid);
    printf("  grid entries out of store order: %lld of %lld right after a re-sort, %lld seven steps later\n",
           (long long)fresh, (long long)s->grid.count, (long long)stale);
    ENSURE_MSG(fresh == 0, "%lld entries out of store order right after a re-sort", (long long)fresh);
    ENSURE_MSG(stale < s->grid.count / 3, "%lld of %lld entries out of store order before the re-sort", (long long)stale,
               (long long)s->grid.count);
    fm_morph_state_destroy(s);
    model->launch_rate = rate;
}

static size_t run_cache(int threads, const char *path)
{
    fm_error err = {0};
    fm_morph_state *s = fm_morph_state_create(model, threads, &err);
    fm_cache_writer *w = fm_cache_writer_create(path, (uint64_t)s->n, 24, 1, &err);
    fm_morph_run_stats rs;
    ENSURE_MSG(fm_morph_run(model, s, w, NULL, NULL, &rs, &err) == FM_OK, "%s", err.message);
    ENSURE(rs.mde_fraction_mean > 0); /* MDE did push agents */
    fm_morph_run_stats_free(&rs);
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    fm_morph_state_destroy(s);
    FILE *f = fopen(path, "rb");
    fseek(f, 0, SEEK_END);
    size_t size = (size_t)ftell(f);
    fclose(f);
    return size;
}

static int same_file(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int same = fa && fb;
    while (same) {
        int ca = fgetc(fa), cb = fgetc(fb);
        same = ca == cb;
        if (ca == EOF) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

static void test_threads_and_simd_levels_give_the_same_cache(void)
{
    char ref[512], other[512];
    snprintf(ref, sizeof ref, "%s/resort_t1.fmc", FM_TEST_TMP);
    ENSURE(run_cache(1, ref) > 0);
    for (int threads = 2; threads <= 3; threads++) {
        snprintf(other, sizeof other, "%s/resort_t%d.fmc", FM_TEST_TMP, threads);
        run_cache(threads, other);
        ENSURE_MSG(same_file(ref, other), "%d threads gave another cache than 1", threads);
    }
    fm_simd best = fm_simd_level();
    for (int level = FM_SIMD_SCALAR; level < (int)best; level++) {
        fm_simd_set_level((fm_simd)level);
        snprintf(other, sizeof other, "%s/resort_%s.fmc", FM_TEST_TMP, fm_simd_name((fm_simd)level));
        run_cache(2, other);
        ENSURE_MSG(same_file(ref, other), "SIMD level %s gave another cache", fm_simd_name((fm_simd)level));
    }
    fm_simd_set_level(best);
}

/* fm_copy_parallel, the re-sorts' copy back: every byte of every size (under and over its one-thread
 * threshold, off whole lines), for thread counts that split it unevenly, and nothing past the end. */
static void test_parallel_copy_is_memcpy(void)
{
    const size_t sizes[] = {0, 1, 65535, 65536 + 13, (1u << 20) + 7};
    const int threads[] = {1, 2, 3, 7};
    const size_t most = (1u << 20) + 7 + 64;
    unsigned char *src = malloc(most), *dst = malloc(most);
    ENSURE(src && dst);
    for (size_t k = 0; k < most; k++) src[k] = (unsigned char)(k * 2654435761u >> 13);
    for (size_t i = 0; i < sizeof sizes / sizeof *sizes; i++)
        for (size_t t = 0; t < sizeof threads / sizeof *threads; t++) {
            memset(dst, 0xA5, most);
            fm_copy_parallel(dst, src, sizes[i], threads[t]);
            ENSURE_MSG(memcmp(dst, src, sizes[i]) == 0, "%zu bytes on %d threads differ", sizes[i], threads[t]);
            for (size_t k = sizes[i]; k < sizes[i] + 64; k++)
                ENSURE_MSG(dst[k] == 0xA5, "%zu bytes on %d threads wrote byte %zu", sizes[i], threads[t], k);
        }
    free(src), free(dst);
}

int main(void)
{
    model = castling();
    if (!model) return 1;
    RUN_TEST(test_parallel_copy_is_memcpy);
    RUN_TEST(test_resort_keeps_ids_state_and_frame);
    RUN_TEST(test_resort_brings_neighbours_together);
    RUN_TEST(test_a_large_launch_is_resorted_at_the_next_step);
    RUN_TEST(test_grid_lists_agents_in_store_order_after_a_resort);
    RUN_TEST(test_threads_and_simd_levels_give_the_same_cache);
    fm_morph_model_destroy(model);
    return fm_test_failures != 0;
}
