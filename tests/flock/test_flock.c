/* The shape-constrained flock end to end through the public API: a static target ends with every
 * agent bound exactly on its destination (or floating within its amplitude); the run is the same
 * for 1 and 2 threads and for the same seed; orientations follow the velocity; destinations follow
 * a deforming target (procedural and mesh sequence) and the flock tracks it; scene keys of the
 * other mode are refused; the store re-sorted in space is a permutation that carries every agent's
 * parameters and changes no frame, measure or checkpoint. */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include "flockmorph/flockmorph.h"
#include "flock.h"  /* the store's layout: the re-sort's test reads its slots */
#include "sample.h" /* the sampler's defaults and fm_points_nn_stats */
#include "flock.h"   /* fm_flock_update_orientation */
#include "fm_math.h" /* fm_quat_from_rotation */
#include "test_macros.h"

#include <stdlib.h>
#include <string.h>

static fm_scene_def flock_def(int64_t n)
{
    fm_scene_def def = fm_default_scene_def();
    def.mode = FM_MODE_SHAPE_FLOCK;
    snprintf(def.source.path, sizeof def.source.path, "%s/examples/flock_cylinder_sphere/cylinder.obj", FM_SOURCE_DIR);
    snprintf(def.target.path, sizeof def.target.path, "%s/examples/flock_cylinder_sphere/sphere.obj", FM_SOURCE_DIR);
    def.source.translate[0] = -12, def.target.translate[0] = 12;
    def.path_point_count = 1;
    def.path_points[0][1] = -5, def.path_points[0][2] = 5;
    def.n = n;
    def.frame_rate = 24, def.time_step = 1.0 / 48, def.frame_limit = 600;
    def.speed0 = 8;
    def.flock.sampling = FM_FLOCK_SAMPLE_RANDOM;
    /* perception radii of 0.2 .. 0.6 units (r = J / sqrt(n)): the paper's J would have every agent
     * of a test-sized flock see all the others, which is slow and proves nothing more */
    const double root_n = sqrt((double)n);
    def.flock.separation.radius_j[0] = 0.3 * root_n, def.flock.separation.radius_j[1] = 0.6 * root_n;
    def.flock.cohesion.radius_j[0] = 0.2 * root_n, def.flock.cohesion.radius_j[1] = 0.6 * root_n;
    def.flock.alignment.radius_j[0] = 0.2 * root_n, def.flock.alignment.radius_j[1] = 0.4 * root_n;
    return def;
}

typedef struct frame {
    int64_t n;
    float *p, *v, *q;
    uint8_t *phase;
} frame;

static frame frame_of(const fm_flock_state *s, int64_t n)
{
    frame f = {n, malloc(sizeof(float) * 3 * (size_t)n), malloc(sizeof(float) * 3 * (size_t)n),
               malloc(sizeof(float) * 4 * (size_t)n), malloc((size_t)n)};
    fm_flock_frame(s, f.p, f.v, f.q, f.phase);
    return f;
}

static void frame_free(frame *f) { free(f->p), free(f->v), free(f->q), free(f->phase); }

static int frames_equal(const frame *a, const frame *b)
{
    size_t n = (size_t)a->n;
    return a->n == b->n && !memcmp(a->p, b->p, 12 * n) && !memcmp(a->v, b->v, 12 * n) && !memcmp(a->q, b->q, 16 * n) &&
           !memcmp(a->phase, b->phase, n);
}

/* Steps until every agent is in FM_PHASE_ARRIVED or `steps` steps; returns the steps taken. */
static int64_t run(const fm_flock_model *m, fm_flock_state *s, int64_t steps)
{
    int64_t k = 0;
    for (; k < steps && fm_flock_get_info(s).count[FM_PHASE_ARRIVED] < fm_flock_model_get_info(m).agents; k++)
        fm_flock_step(m, s);
    return k;
}

static fm_flock_model *build(const fm_scene_def *def)
{
    fm_error err = {0};
    fm_flock_model *m = fm_flock_model_build(def, NULL, NULL, &err);
    ENSURE_MSG(m != NULL, "%s", err.message);
    return m;
}

/* SCF Figure 9's static case: every agent ends bound exactly on its destination. */
static void test_static_target_every_agent_binds(void)
{
    fm_scene_def def = flock_def(600);
    fm_flock_model *m = build(&def);
    if (!m) return;
    fm_flock_state *s = fm_flock_state_create(m, 2, NULL);
    int64_t steps = run(m, s, 48 * 20);
    fm_run_info info = fm_flock_get_info(s);
    ENSURE_MSG(info.count[FM_PHASE_ARRIVED] == 600, "after %lld steps %lld agents are bound", (long long)steps,
               (long long)info.count[FM_PHASE_ARRIVED]);
    double mean, max;
    fm_flock_distance(s, &mean, &max);
    ENSURE_MSG(max == 0, "a bound agent is %g from its destination", max);
    float *dest = malloc(sizeof(float) * 3 * 600), *c2 = malloc(sizeof(float) * 3 * 600);
    fm_flock_destinations(s, dest);
    fm_flock_model_endpoints(m, NULL, c2);
    ENSURE(memcmp(dest, c2, sizeof(float) * 3 * 600) == 0); /* a static target's destinations stay put */
    /* it took the path: longer than the leaders' path time, but not much longer */
    double path_time = fm_flock_model_get_info(m).path_time;
    ENSURE_MSG(steps * (1.0 / 48) > path_time && steps * (1.0 / 48) < path_time + 6, "bound after %.2f s, path time %.2f s",
               steps / 48.0, path_time);
    free(dest), free(c2);
    fm_flock_state_destroy(s);
    fm_flock_model_destroy(m);
}

/* Floating instead of binding: agents stay within float_amplitude of their destinations. */
static void test_floating_agents_stay_near(void)
{
    fm_scene_def def = flock_def(300);
    def.flock.arrival_mode = FM_ARRIVAL_FLOAT;
    def.flock.float_amplitude = 0.1;
    fm_flock_model *m = build(&def);
    if (!m) return;
    fm_flock_state *s = fm_flock_state_create(m, 2, NULL);
    run(m, s, 48 * 20);
    ENSURE(fm_flock_get_info(s).count[FM_PHASE_ARRIVED] == 300);
    for (int k = 0; k < 96; k++) fm_flock_step(m, s); /* two more seconds of floating */
    double mean, max;
    fm_flock_distance(s, &mean, &max);
    ENSURE_MSG(max <= 0.1 * sqrt(3) * (1 + 1e-5), "a floating agent is %g away (amplitude 0.1 per axis)", max);
    ENSURE_MSG(mean > 0.01, "the agents do not float (mean offset %g)", mean);
    fm_flock_state_destroy(s);
    fm_flock_model_destroy(m);
}

/* 1 and 2 threads give the same bits at every stage of the run, with more than one block of agents
 * and the style fields on; a different seed gives a different flock, the same seed the same. */
static void test_threads_and_seeds_agree(void)
{
    fm_scene_def def = flock_def(5000); /* two blocks of 4096 */
    def.field_count = 1;
    def.fields[0] = fm_default_field_def(FM_FIELD_VORTEX);
    def.fields[0].center[0] = 0, def.fields[0].strength = 0.5;
    fm_flock_model *m = build(&def);
    def.seed = 99;
    fm_flock_model *other = build(&def);
    if (!m || !other) return;
    fm_flock_state *s1 = fm_flock_state_create(m, 1, NULL), *s2 = fm_flock_state_create(m, 2, NULL);
    fm_flock_state *again = fm_flock_state_create(m, 2, NULL), *s3 = fm_flock_state_create(other, 2, NULL);
    for (int chunk = 0; chunk < 4; chunk++) {
        for (int k = 0; k < 60; k++) fm_flock_step(m, s1), fm_flock_step(m, s2), fm_flock_step(m, again), fm_flock_step(other, s3);
        frame a = frame_of(s1, 5000), b = frame_of(s2, 5000), c = frame_of(again, 5000), d = frame_of(s3, 5000);
        ENSURE_MSG(frames_equal(&a, &b), "1 and 2 threads differ after %d steps", 60 * (chunk + 1));
        ENSURE_MSG(frames_equal(&b, &c), "two runs differ after %d steps", 60 * (chunk + 1));
        ENSURE_MSG(!frames_equal(&b, &d), "seeds 1 and 99 give the same flock");
        frame_free(&a), frame_free(&b), frame_free(&c), frame_free(&d);
    }
    fm_flock_state_destroy(s1), fm_flock_state_destroy(s2), fm_flock_state_destroy(again), fm_flock_state_destroy(s3);
    fm_flock_model_destroy(m), fm_flock_model_destroy(other);
}

static char *slurp(const char *path, long *len)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    *len = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)*len + 1);
    if (buf && fread(buf, 1, (size_t)*len, f) != (size_t)*len) free(buf), buf = NULL;
    fclose(f);
    return buf;
}

/* The whole run through fm_flock_run into a cache; returns its stats. */
static fm_flock_run_stats run_to_cache(const fm_flock_model *m, int threads, const char *path)
{
    fm_error err = {0};
    fm_flock_run_stats rs;
    memset(&rs, 0, sizeof rs);
    fm_flock_state *s = fm_flock_state_create(m, threads, &err);
    fm_cache_writer *w = fm_flock_cache_create(path, m, NULL, &err);
    ENSURE_MSG(s && w, "%s", err.message);
    if (!s || !w) return fm_flock_state_destroy(s), rs;
    ENSURE_MSG(fm_flock_run(m, s, w, NULL, NULL, &rs, &err) == FM_OK, "%s", err.message);
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    fm_flock_state_destroy(s);
    return rs;
}

/* The cache of a whole run: the same bytes for 1 and 2 threads and for a second run; the run stops
 * when every agent is bound, and the cache's last frame has every agent on its destination. */
static void test_caches_are_identical_for_threads_and_runs(void)
{
    fm_scene_def def = flock_def(1500);
    fm_flock_model *m = build(&def);
    if (!m) return;
    const char *p1 = FM_TEST_TMP "/flock_threads1.fmc", *p2 = FM_TEST_TMP "/flock_threads2.fmc", *p3 = FM_TEST_TMP "/flock_again.fmc";
    fm_flock_run_stats r1 = run_to_cache(m, 1, p1), r2 = run_to_cache(m, 2, p2), r3 = run_to_cache(m, 2, p3);
    ENSURE(r1.all_bound && !r1.stopped_at_frame_limit && r1.bound_fraction == 1 && r1.final_max_distance == 0);
    ENSURE(r1.run.frames == r2.run.frames && r2.run.frames == r3.run.frames && r1.run.steps == r2.run.steps && isnan(r1.tracking_lag));
    ENSURE(r1.measures && r2.measures && !memcmp(r1.measures, r2.measures, sizeof(double) * FM_FLOCK_MEASURES * (size_t)(r1.run.frames - 1)));
    ENSURE(!memcmp(r1.measures_mean, r2.measures_mean, sizeof r1.measures_mean));
    long n1 = 0, n2 = 0, n3 = 0;
    char *a = slurp(p1, &n1), *b = slurp(p2, &n2), *c = slurp(p3, &n3);
    ENSURE_MSG(a && b && n1 == n2 && !memcmp(a, b, (size_t)n1), "1 and 2 threads give different caches");
    ENSURE_MSG(b && c && n2 == n3 && !memcmp(b, c, (size_t)n2), "two runs give different caches");
    free(a), free(b), free(c);

    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(p1, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (r) {
        ENSURE(fm_cache_frames(r) == (uint32_t)r1.run.frames && fm_cache_agents(r) == 1500);
        float *pos = malloc(sizeof(float) * 3 * 1500), *c2 = malloc(sizeof(float) * 3 * 1500);
        ENSURE(fm_cache_read_attr(r, fm_cache_frames(r) - 1, FM_ATTR_POSITION, pos, &err) == FM_OK);
        fm_flock_model_endpoints(m, NULL, c2);
        ENSURE(!memcmp(pos, c2, sizeof(float) * 3 * 1500));
        ENSURE(fm_cache_read_attr(r, 0, FM_ATTR_POSITION, pos, &err) == FM_OK);
        fm_flock_model_endpoints(m, c2, NULL);
        ENSURE(!memcmp(pos, c2, sizeof(float) * 3 * 1500)); /* frame 0: every agent on its source sample */
        free(pos), free(c2);
        fm_cache_close(r);
    }
    fm_flock_model_destroy(m);
    fm_flock_run_stats_free(&r1), fm_flock_run_stats_free(&r2), fm_flock_run_stats_free(&r3);
}

/* A state with the re-sort every `every` steps (FM_FLOCK_RESORT, read when the state is made). */
static fm_flock_state *state_resorted_every(const fm_flock_model *m, int every)
{
    char value[16];
    snprintf(value, sizeof value, "%d", every);
    setenv("FM_FLOCK_RESORT", value, 1);
    fm_flock_state *s = fm_flock_state_create(m, 2, NULL);
    unsetenv("FM_FLOCK_RESORT");
    ENSURE(s != NULL && s->resort_every == every);
    return s;
}

/* FM_FLOCK_RESORT that is no interval: the state is refused, naming the variable (docs/errors.md). */
static void test_resort_switch_is_checked(void)
{
    fm_scene_def def = flock_def(200);
    fm_flock_model *m = build(&def);
    if (!m) return;
    fm_error err = {0};
    setenv("FM_FLOCK_RESORT", "8x", 1);
    fm_flock_state *s = fm_flock_state_create(m, 1, &err);
    unsetenv("FM_FLOCK_RESORT");
    ENSURE(s == NULL && err.status == FM_ERR_INPUT && strstr(err.message, "FM_FLOCK_RESORT=8x") != NULL);
    fm_flock_state_destroy(s);
    fm_flock_model_destroy(m);
}

/* id[] holds every agent once, slot_by_id is its inverse, and every slot's parameters are the model's
 * for its agent; returns whether the slots are out of id order. */
static int check_slots(const fm_flock_model *m, const fm_flock_state *s)
{
    const int64_t n = s->n;
    int32_t *seen = calloc((size_t)n, sizeof *seen);
    int moved = 0, ok = 1;
    for (int64_t a = 0; a < n; a++) {
        const int64_t id = s->id[a];
        ok &= id >= 0 && id < n && s->slot_by_id[id] == a;
        if (!(id >= 0 && id < n)) continue;
        seen[id]++, moved |= id != a;
        for (int r = 0; r < FM_BOIDS_RULES; r++)
            ok &= s->prm.radius[r][a] == m->radius[r][id] && s->prm.cos_half[r][a] == m->cos_half[r][id] &&
                  s->prm.weight[r][a] == m->weight[r][id];
        for (int k = 0; k < 3; k++) ok &= s->prm.start[k][a] == m->start[k][id];
        ok &= s->prm.max_speed[a] == m->max_speed[id] && s->prm.max_force[a] == m->max_force[id] &&
              s->prm.max_accel[a] == m->max_accel[id];
    }
    for (int64_t id = 0; id < n; id++) ok &= seen[id] == 1;
    ENSURE_MSG(ok, "the re-sorted store is not a permutation of the agents with their parameters (step %lld)",
               (long long)s->step);
    free(seen);
    return moved;
}

/* Right after a re-sort: the agents in the grid by their cell's slot in the next build (computed
 * here from grid.h's placement), the bound ones after them. */
static void check_sorted_in_space(const fm_flock_model *m, fm_flock_state *s)
{
    fm_flock_state_resort(m, s);
    const fm_grid g = fm_grid_placement(&s->grid, (const float *const *)s->p, s->member, s->slots, m->max_radius, 1);
    int ok = 1, bound_seen = 0;
    uint32_t last = 0;
    for (int64_t a = 0; a < s->slots; a++) {
        if (s->phase[a] == FM_PHASE_ARRIVED) {
            bound_seen = 1;
            continue;
        }
        const uint32_t slot = fm_grid_slot_of(&g, s->p[0][a], s->p[1][a], s->p[2][a]);
        ok &= !bound_seen && slot >= last;
        last = slot;
    }
    ENSURE_MSG(ok, "the store is not in grid-slot order with the bound agents last (step %lld)", (long long)s->step);
}

/* The store re-sorted in space every 8 steps (issue 40) against one left in id order, the boids on
 * (their per-neighbour sums are exact, kernel_boids.h, so the order changes no bit): a permutation of the agents carrying
 * their parameters, and the same frames, destinations, distances and measures until 95 % are bound,
 * sorted by grid slot with the bound last while some are bound and others fly; a checkpoint of either is the same bytes,
 * and a run resumed from it continues as the uninterrupted one. */
static void test_resorted_store_changes_no_frame(void)
{
    const int64_t n = 4200; /* two blocks of 4096 */
    fm_scene_def def = flock_def(n);
    def.source.translate[0] = -6, def.target.translate[0] = 6, def.speed0 = 16; /* a shorter flight */
    fm_flock_model *m = build(&def);
    if (!m) return;
    fm_flock_state *sorted = state_resorted_every(m, 8), *plain = state_resorted_every(m, 0);
    fm_flock_state *resumed = fm_flock_state_create(m, 1, NULL);
    ENSURE(plain->id == NULL && plain->prm.radius[0] == m->radius[0]); /* the switch leaves the old store */
    int moved = 0, mixed = 0, resumed_at = 0;
    float *d1 = malloc(sizeof(float) * 3 * (size_t)n), *d2 = malloc(sizeof(float) * 3 * (size_t)n);
    for (int chunk = 0; chunk < 200 && plain->count[FM_PHASE_ARRIVED] < n - n / 20; chunk++) {
        for (int k = 0; k < 12; k++) fm_flock_step(m, sorted), fm_flock_step(m, plain);
        moved |= check_slots(m, sorted);
        frame a = frame_of(sorted, n), b = frame_of(plain, n);
        ENSURE_MSG(frames_equal(&a, &b), "the re-sort changes the frame after %lld steps", (long long)plain->step);
        frame_free(&a), frame_free(&b);
        double ma[FM_FLOCK_MEASURES], mb[FM_FLOCK_MEASURES], mean[2], max[2];
        fm_flock_measure_frame(m, sorted, ma), fm_flock_measure_frame(m, plain, mb);
        ENSURE_MSG(!memcmp(ma, mb, sizeof ma), "the re-sort changes the measures after %lld steps", (long long)plain->step);
        fm_flock_distance(sorted, &mean[0], &max[0]), fm_flock_distance(plain, &mean[1], &max[1]);
        ENSURE(mean[0] == mean[1] && max[0] == max[1]);
        fm_flock_destinations(sorted, d1), fm_flock_destinations(plain, d2);
        ENSURE(!memcmp(d1, d2, sizeof(float) * 3 * (size_t)n));
        if (!mixed && sorted->count[FM_PHASE_ARRIVED] > n / 10 && sorted->count[FM_PHASE_ARRIVED] < n - n / 10)
            mixed = 1, check_sorted_in_space(m, sorted);
        if (chunk == 10) { /* the checkpoint: the same file from either store; resumed into a fresh state */
            const char *p1 = FM_TEST_TMP "/flock_sorted.fmck", *p2 = FM_TEST_TMP "/flock_plain.fmck";
            fm_flock_run_stats stats = {.run = {.frames = 1}}, got;
            fm_error err = {0};
            ENSURE_MSG(sorted->sorted, "the store is in id order before the checkpoint");
            int32_t *order = malloc(sizeof(int32_t) * (size_t)n);
            memcpy(order, sorted->id, sizeof(int32_t) * (size_t)n);
            ENSURE(fm_flock_checkpoint_save(p1, m, sorted, &stats, &err) == FM_OK);
            ENSURE_MSG(sorted->sorted && !memcmp(order, sorted->id, sizeof(int32_t) * (size_t)n),
                       "the save changed the store's order");
            free(order);
            ENSURE(fm_flock_checkpoint_save(p2, m, plain, &stats, &err) == FM_OK);
            long n1 = 0, n2 = 0;
            char *f1 = slurp(p1, &n1), *f2 = slurp(p2, &n2);
            ENSURE_MSG(f1 && f2 && n1 == n2 && !memcmp(f1, f2, (size_t)n1), "the checkpoints of the two stores differ");
            free(f1), free(f2);
            ENSURE_MSG(fm_flock_checkpoint_load(p1, m, resumed, &got, &err) == FM_OK, "%s", err.message);
            fm_flock_run_stats_free(&got);
            resumed_at = 1;
        } else if (resumed_at && resumed_at++ <= 3) { /* three chunks on: the re-sort went on in both */
            for (int k = 0; k < 12; k++) fm_flock_step(m, resumed);
            frame a2 = frame_of(sorted, n), c = frame_of(resumed, n);
            ENSURE_MSG(frames_equal(&a2, &c), "the resumed run differs after %lld steps", (long long)resumed->step);
            frame_free(&a2), frame_free(&c);
        }
    }
    ENSURE_MSG(moved, "the re-sort never moved an agent");
    ENSURE_MSG(mixed, "no frame had both bound and flying agents");
    ENSURE(plain->count[FM_PHASE_ARRIVED] >= n - n / 20 && sorted->count[FM_PHASE_ARRIVED] == plain->count[FM_PHASE_ARRIVED]);
    free(d1), free(d2);
    fm_flock_state_destroy(sorted), fm_flock_state_destroy(plain), fm_flock_state_destroy(resumed);
    fm_flock_model_destroy(m);
}

/* Each flying agent's frame has its x axis along its velocity and stays upright (z has no part
 * pointing down unless it flies steeply); quaternions are unit. */
static void test_orientation_follows_velocity(void)
{
    fm_scene_def def = flock_def(400);
    fm_flock_model *m = build(&def);
    if (!m) return;
    fm_flock_state *s = fm_flock_state_create(m, 2, NULL);
    for (int k = 0; k < 60; k++) fm_flock_step(m, s);
    frame f = frame_of(s, 400);
    int checked = 0;
    for (int64_t a = 0; a < 400; a++) {
        const float *q = f.q + 4 * a, *v = f.v + 3 * a;
        double w = q[0], i = q[1], j = q[2], k = q[3];
        ENSURE_NEAR(w * w + i * i + j * j + k * k, 1, 1e-5);
        const double x[3] = {1 - 2 * (j * j + k * k), 2 * (i * j + w * k), 2 * (i * k - w * j)}; /* R e_x */
        double vlen = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
        if (vlen < 1e-3) continue;
        ENSURE_NEAR((x[0] * v[0] + x[1] * v[1] + x[2] * v[2]) / vlen, 1, 1e-5);
        checked++;
    }
    ENSURE(checked > 300);
    frame_free(&f);
    fm_flock_state_destroy(s);
    fm_flock_model_destroy(m);
}


/* The frame's closed form (fm_flock_update_orientation) is the rotation with columns x = unit(v),
 * y = unit(Z x x), z = x cross y, as Shepperd's conversion of that matrix gives it (w >= 0), in every
 * direction that is not within 0.06 degrees of vertical; y stays horizontal (the agent upright). */
static void test_orientation_is_the_upright_frame(void)
{
    uint64_t seed = 11;
    double worst = 0;
    for (int trial = 0; trial < 20000; trial++) {
        float v[3];
        for (int k = 0; k < 3; k++) v[k] = (float)(20 * test_uniform(&seed) - 10);
        if (trial < 8) v[0] = (float)(trial & 1 ? -3 : 3), v[1] = trial & 2 ? -0.0f : 0.0f, v[2] = (float)(trial & 4 ? 2 : -2); /* psi 0 or pi */
        const double len = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
        const double x[3] = {v[0] / len, v[1] / len, v[2] / len}, h = sqrt(x[0] * x[0] + x[1] * x[1]);
        if (h < 1e-3) continue;
        const double y[3] = {-x[1] / h, x[0] / h, 0};
        const double z[3] = {x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
        fm_mat3 r;
        for (int c = 0; c < 3; c++) r.m[c][0] = x[c], r.m[c][1] = y[c], r.m[c][2] = z[c];
        double want[4];
        fm_quat_from_rotation(r, want);
        float q[4] = {1, 0, 0, 0};
        fm_flock_update_orientation(q, v);
        const double sign = want[0] == 0 && (want[1] * q[1] + want[2] * q[2] + want[3] * q[3]) < 0 ? -1 : 1; /* w = 0: q or -q */
        for (int c = 0; c < 4; c++) worst = fmax(worst, fabs(sign * want[c] - q[c]));
    }
    ENSURE_MSG(worst < 3e-7, "closed form and Shepperd differ by %g", worst);
}

/* The frames of a block in lanes (fm_kernel_orient_along) are the scalar function's, bit for bit,
 * at every SIMD level: random headings, agents at rest, vertical and near-vertical ones (the scalar
 * fallback, from their previous frame), a tail shorter than the lanes, and skipped agents left as
 * they were. */
static void test_orientation_lanes_are_the_scalar_frames(void)
{
    enum { N = 4099 };
    float *v[3], *q0 = malloc(sizeof(float) * 4 * N), *want = malloc(sizeof(float) * 4 * N), *got = malloc(sizeof(float) * 4 * N);
    uint8_t *phase = malloc(N);
    uint64_t seed = 29;
    for (int k = 0; k < 3; k++) v[k] = malloc(sizeof(float) * N);
    for (int a = 0; a < N; a++) {
        for (int k = 0; k < 3; k++) v[k][a] = (float)(20 * test_uniform(&seed) - 10);
        if (a % 17 == 3) v[0][a] = v[1][a] = v[2][a] = 0;                   /* at rest */
        if (a % 19 == 4) v[0][a] = v[1][a] = 0;                             /* vertical */
        if (a % 23 == 5) v[0][a] = 1e-4f, v[1][a] = -2e-4f, v[2][a] = -3.0f; /* within 1e-3 of it */
        phase[a] = a % 13 == 7 ? 0xFF : 1;
        for (int c = 0; c < 4; c++) q0[4 * a + c] = (float)(test_uniform(&seed) - 0.5);
    }
    memcpy(want, q0, sizeof(float) * 4 * N);
    for (int a = 0; a < N; a++)
        if (phase[a] != 0xFF) {
            const float va[3] = {v[0][a], v[1][a], v[2][a]};
            fm_flock_update_orientation(want + 4 * a, va);
        }
    const fm_simd best = fm_simd_set_level(FM_SIMD_BEST);
    for (int level = FM_SIMD_SCALAR; level <= (int)best; level++) {
        fm_simd_set_level((fm_simd)level);
        memcpy(got, q0, sizeof(float) * 4 * N);
        fm_kernel_orient_along(got, (const float *const *)v, phase, 0xFF, 0, 1000);
        fm_kernel_orient_along(got, (const float *const *)v, phase, 0xFF, 1000, N);
        ENSURE_MSG(memcmp(got, want, sizeof(float) * 4 * N) == 0, "level %s: frames differ", fm_simd_name((fm_simd)level));
    }
    fm_simd_set_level(best);
    for (int k = 0; k < 3; k++) free(v[k]);
    free(q0), free(want), free(got), free(phase);
}

/* The flock's step at every SIMD level gives the scalar code's bytes (the leaders', the forces',
 * Kalman's, the boids' and the frames' lanes), through the ease's ramps and delays, the cruise and
 * the arrivals; with R over the distance, and with the layout's reform, a field and R over the
 * leader's speed. */
/* Agents whose leader has not started at time t (the ease's delay), and those on its path. */
static void leaders_started(const fm_flock_model *m, const fm_flock_state *s, double t, int64_t *waiting, int64_t *flying)
{
    for (int64_t a = 0; a < s->slots; a++) {
        double f;
        const double u = fm_flock_leader(m, (const float *const *)s->prm.start, a, t, &f);
        *waiting += u == 0, *flying += u > 0 && u < 1;
    }
}

static int64_t leaders_on_destination(const fm_flock_state *s)
{
    int64_t n = 0;
    for (int64_t a = 0; a < s->slots; a++)
        n += s->leader[0][a] == s->dest[0][a] && s->leader[1][a] == s->dest[1][a] && s->leader[2][a] == s->dest[2][a];
    return n;
}

static void test_simd_levels_give_the_same_flock(void)
{
    for (int reform = 0; reform < 2; reform++) {
        fm_scene_def def = flock_def(400);
        def.flock.ease_in = 0.4, def.flock.ease_out = 0.5, def.flock.ease_spread = 0.6;
        def.flock.reform = reform ? 0.3 : 0;
        def.speed0 = 20; /* the leaders' path in about a second: every leader arrives within the run */
        if (reform) { /* the external fields' forces too, and R over the leader's speed */
            def.field_count = 1;
            def.fields[0] = fm_default_field_def(FM_FIELD_VORTEX);
            def.fields[0].center[0] = 0, def.fields[0].strength = 0.5;
            def.flock.kalman_r_over = FM_KALMAN_R_OVER_LEADER_SPEED;
        }
        fm_flock_model *m = build(&def);
        if (!m) return;
        const fm_simd best = fm_simd_set_level(FM_SIMD_BEST);
        frame want[3] = {{0}};
        for (int level = FM_SIMD_SCALAR; level <= (int)best; level++) {
            fm_simd_set_level((fm_simd)level);
            fm_flock_state *s = fm_flock_state_create(m, 1, NULL);
            int64_t waiting = 0, flying = 0;
            leaders_started(m, s, 8 * m->dt, &waiting, &flying);
            for (int chunk = 0; chunk < 3; chunk++) {
                for (int k = 0; k < 80; k++) fm_flock_step(m, s);
                frame got = frame_of(s, 400);
                if (level == FM_SIMD_SCALAR) {
                    want[chunk] = got;
                    continue;
                }
                ENSURE_MSG(frames_equal(&got, &want[chunk]), "reform %d, level %s: the flock differs after %d steps", reform,
                           fm_simd_name((fm_simd)level), 80 * (chunk + 1));
                frame_free(&got);
            }
            if (level == FM_SIMD_SCALAR) {
                const int64_t done = leaders_on_destination(s);
                const fm_run_info info = fm_flock_get_info(s);
                printf("  reform %d: at step 8 %lld leaders waiting and %lld on their way; at the end %lld on their destination,"
                       " %lld agents flying, %lld homing, %lld bound\n", reform, (long long)waiting, (long long)flying, (long long)done,
                       (long long)info.count[FM_PHASE_FLYING], (long long)info.count[FM_PHASE_HOMING],
                       (long long)info.count[FM_PHASE_ARRIVED]);
                ENSURE(waiting > 0 && flying > 0 && done == 400);
                ENSURE(info.count[FM_PHASE_HOMING] + info.count[FM_PHASE_ARRIVED] > 0);
            }
            fm_flock_state_destroy(s);
        }
        fm_simd_set_level(best);
        for (int c = 0; c < 3; c++) frame_free(&want[c]);
        fm_flock_model_destroy(m);
    }
}

/* A pulsing target: destinations breathe with it (each one's distance to the centre scales by
 * 1 + A sin(2 pi t / period)), and once the path is done the flock stays close (the Kalman homing
 * tracks the moving leaders), closer with a small R (position variance) than with a large one. */
static double tracking_lag(double r)
{
    fm_scene_def def = flock_def(400);
    def.flock.deform = FM_DEFORM_PULSE;
    def.flock.deform_amplitude = 0.2, def.flock.deform_period = 1.5;
    def.flock.arrival_radius = 0; /* no binding: forces all the way */
    def.flock.damping = 0;        /* homing alone holds them */
    def.flock.kalman_r_position = r, def.flock.kalman_r_velocity = 1;
    fm_flock_model *m = build(&def);
    if (!m) return NAN;
    fm_flock_state *s = fm_flock_state_create(m, 2, NULL);
    double path_time = fm_flock_model_get_info(m).path_time, lag = 0;
    int samples = 0;
    for (int k = 0; k < 48 * 12; k++) {
        fm_flock_step(m, s);
        if (fm_flock_get_info(s).time < path_time + 1) continue;
        double mean, max;
        fm_flock_distance(s, &mean, &max);
        lag += mean, samples++;
    }
    fm_flock_state_destroy(s);
    fm_flock_model_destroy(m);
    return lag / samples;
}

static void test_deforming_target_is_tracked(void)
{
    fm_scene_def def = flock_def(200);
    def.flock.deform = FM_DEFORM_PULSE;
    def.flock.deform_amplitude = 0.2, def.flock.deform_period = 1.5;
    fm_flock_model *m = build(&def);
    if (!m) return;
    fm_flock_state *s = fm_flock_state_create(m, 1, NULL);
    float *c2 = malloc(sizeof(float) * 600), *dest = malloc(sizeof(float) * 600);
    fm_flock_model_endpoints(m, NULL, c2);
    const double center[3] = {12, 0, 0}; /* the sphere's vertices average to its centre */
    for (int k = 0; k < 30; k++) fm_flock_step(m, s);
    fm_flock_destinations(s, dest);
    double t = fm_flock_get_info(s).time, scale = 1 + 0.2 * sin(2 * 3.14159265358979 * t / 1.5), worst = 0;
    for (int a = 0; a < 200; a++)
        for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(dest[3 * a + k] - (center[k] + (c2[3 * a + k] - center[k]) * scale)));
    ENSURE_MSG(worst < 1e-3, "destinations are %g off the pulsing sphere", worst);
    free(c2), free(dest);
    fm_flock_state_destroy(s);
    fm_flock_model_destroy(m);

    double tight = tracking_lag(0.01), loose = tracking_lag(10);
    printf("  tracking lag on a pulsing sphere: R = 0.01 %.4f, R = 10 %.4f\n", tight, loose);
    ENSURE_MSG(tight < 0.25, "the flock does not keep up: mean lag %g", tight);
    ENSURE_MSG(2 * tight < loose, "a smaller R does not track more closely: %g vs %g", tight, loose);
}

/* A sequence of meshes: a sphere moving 1 unit along +z per mesh at 12 meshes a second.
 * Destinations interpolate between the meshes and loop. */
static void write_moved_sphere(const char *path, double dz, double xy_sign)
{
    char src[FM_PATH_MAX];
    snprintf(src, sizeof src, "%s/examples/flock_cylinder_sphere/sphere.obj", FM_SOURCE_DIR);
    FILE *in = fopen(src, "r"), *out = fopen(path, "w");
    char line[256];
    while (in && out && fgets(line, sizeof line, in)) {
        double x, y, z;
        if (sscanf(line, "v %lf %lf %lf", &x, &y, &z) == 3) fprintf(out, "v %.9g %.9g %.9g\n", xy_sign * x, xy_sign * y, z + dz);
        else fputs(line, out);
    }
    if (in) fclose(in);
    if (out) fclose(out);
}

static void test_mesh_sequence_moves_the_destinations(void)
{
    char pattern[FM_PATH_MAX];
    for (int i = 0; i < 3; i++) {
        snprintf(pattern, sizeof pattern, "%s/seq_%02d.obj", FM_TEST_TMP, i);
        write_moved_sphere(pattern, i, 1);
    }
    fm_scene_def def = flock_def(100);
    snprintf(def.target.path, sizeof def.target.path, "%s/seq_00.obj", FM_TEST_TMP);
    def.flock.deform = FM_DEFORM_SEQUENCE;
    snprintf(def.flock.deform_sequence, sizeof def.flock.deform_sequence, "%s/seq_%%02d.obj", FM_TEST_TMP);
    def.flock.deform_frames = 3, def.flock.deform_frame_rate = 12;
    fm_flock_model *m = build(&def);
    if (!m) return;
    fm_flock_state *s = fm_flock_state_create(m, 2, NULL);
    float *c2 = malloc(sizeof(float) * 300), *dest = malloc(sizeof(float) * 300);
    fm_flock_model_endpoints(m, NULL, c2);
    const double expect_dz[3] = {0.5, 2 - 2 * 0.5, 0}; /* t = 1/24: halfway to mesh 1; t = 5/24: mesh 2 -> 0; t = 1/4 */
    const int steps[3] = {2, 8, 2};
    for (int check = 0; check < 3; check++) {
        for (int k = 0; k < steps[check]; k++) fm_flock_step(m, s);
        fm_flock_destinations(s, dest);
        double worst = 0;
        for (int a = 0; a < 100; a++)
            worst = fmax(worst, fabs(dest[3 * a] - c2[3 * a]) + fabs(dest[3 * a + 1] - c2[3 * a + 1]) +
                                    fabs(dest[3 * a + 2] - (c2[3 * a + 2] + expect_dz[check])));
        ENSURE_MSG(worst < 1e-4, "check %d (t = %g): destinations %g off", check, fm_flock_get_info(s).time, worst);
    }
    free(c2), free(dest);
    fm_flock_state_destroy(s);
    fm_flock_model_destroy(m);

    /* a mesh with other connectivity is refused, naming it */
    snprintf(pattern, sizeof pattern, "%s/seq_01.obj", FM_TEST_TMP);
    FILE *f = fopen(pattern, "w");
    if (f) fputs("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n", f), fclose(f);
    fm_error err = {0};
    ENSURE(fm_flock_model_build(&def, NULL, NULL, &err) == NULL && err.status == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "seq_01.obj") && strstr(err.message, "connectivity"), "%s", err.message);
}

/* A sequence whose mesh 1 is the sphere turned half a turn about z: every vertex moves, and the
 * order of the positions (which welding sorts by) changes; the vertices still match the target's
 * one for one as the file lists them, so each destination turns with its triangle. */
static void test_mesh_sequence_matches_vertices_as_listed(void)
{
    char pattern[FM_PATH_MAX];
    for (int i = 0; i < 2; i++) {
        snprintf(pattern, sizeof pattern, "%s/turn_%02d.obj", FM_TEST_TMP, i);
        write_moved_sphere(pattern, 0, i ? -1 : 1);
    }
    fm_scene_def def = flock_def(100);
    snprintf(def.target.path, sizeof def.target.path, "%s/turn_00.obj", FM_TEST_TMP);
    def.flock.deform = FM_DEFORM_SEQUENCE;
    snprintf(def.flock.deform_sequence, sizeof def.flock.deform_sequence, "%s/turn_%%02d.obj", FM_TEST_TMP);
    def.flock.deform_frames = 2, def.flock.deform_frame_rate = 12;
    fm_flock_model *m = build(&def);
    if (!m) return;
    fm_flock_state *s = fm_flock_state_create(m, 1, NULL);
    float *c2 = malloc(sizeof(float) * 300), *dest = malloc(sizeof(float) * 300);
    fm_flock_model_endpoints(m, NULL, c2);
    for (int k = 0; k < 4; k++) fm_flock_step(m, s); /* t = 1/12: mesh 1 */
    fm_flock_destinations(s, dest);
    double worst = 0;
    for (int a = 0; a < 100; a++) /* the target is placed at x + 12 */
        worst = fmax(worst, fabs(dest[3 * a] - (24 - c2[3 * a])) + fabs(dest[3 * a + 1] + c2[3 * a + 1]) +
                                fabs(dest[3 * a + 2] - c2[3 * a + 2]));
    ENSURE_MSG(worst < 1e-4, "destinations %g off the turned sphere", worst);
    free(c2), free(dest);
    fm_flock_state_destroy(s);
    fm_flock_model_destroy(m);
}

#define MESHES "\"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"}"

static fm_status load_text(const char *text, fm_scene_def *def, fm_error *err)
{
    char path[FM_PATH_MAX];
    snprintf(path, sizeof path, "%s/flock_scene.json", FM_TEST_TMP);
    FILE *f = fopen(path, "w");
    if (!f) return FM_ERR_IO;
    fputs(text, f);
    fclose(f);
    return fm_scene_load(path, def, err);
}

static void test_scene_keys_belong_to_their_mode(void)
{
    fm_scene_def def;
    fm_error err = {0};
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"n\": 100, \"shape_flock\": {\"max_speed\": [5, 9], \"fuzzy\": {\"homing\": [[0, 1], [3, 0.5]]},\n"
                     " \"separation\": {\"angle\": 270}, \"arrival\": {\"mode\": \"float\"}}}",
                     &def, &err) == FM_OK);
    ENSURE_MSG(err.status == FM_OK, "%s", err.message);
    ENSURE(def.mode == FM_MODE_SHAPE_FLOCK && def.flock.max_speed[0] == 5 && def.flock.max_speed[1] == 9);
    ENSURE(def.flock.fuzzy[FM_FUZZY_HOMING].count == 2 && def.flock.fuzzy[FM_FUZZY_HOMING].w[1] == 0.5);
    ENSURE(def.flock.separation.angle_deg[0] == 270 && def.flock.separation.angle_deg[1] == 270);
    ENSURE(def.flock.arrival_mode == FM_ARRIVAL_FLOAT);

    ENSURE(load_text("{\"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n \"shape_flock\": {\"mass\": 2}}",
                     &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, ":2:18: shape_flock.mass: does not apply to mode \"tetra_morph\""), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"mde\": {\"d_min\": 0.1}}", &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "mde.d_min: does not apply to mode \"shape_flock\""), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"}}",
                     &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "n: the shape flock needs"), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"fuzzy\": {\"damping\": [[0, 1], [2, 0.5], [1, 0]]}}}", &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, ":2:58: shape_flock.fuzzy.damping: point 2: the distances must increase"), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"max_force\": [9, 3]}}", &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "shape_flock.max_force: the range [9, 3] runs backwards"), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"deform\": {\"type\": \"sequence\", \"sequence\": \"w_%s.obj\", \"frames\": 3}}}",
                     &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "shape_flock.deform.sequence") && strstr(err.message, "one integer"), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"deform\": {\"type\": \"wave\", \"direction\": [0, 0, 0]}}}", &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "shape_flock.deform.direction: a wave needs a non-zero direction"), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flok\", \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"}}",
                     &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "mode: expected \"tetra_morph\" or \"shape_flock\""), "%s", err.message);
}

/* SCF's two fuzzy strategies: shape_flock.fuzzy.* for a static target, shape_flock.fuzzy.tracking.*
 * for a deforming one, each read into its own set; a curve of the strategy the target does not use
 * is refused naming its key and the one that applies (a scene written before the two strategies
 * with fuzzy.* on a deforming target does not run silently with other curves). */
static void test_fuzzy_strategy_keys(void)
{
    fm_scene_def def;
    fm_error err = {0};
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"deform\": {\"type\": \"pulse\"}, \"fuzzy\": {\"tracking\": {\"homing\": [[0, 1], [4, 0.1]]}}}}",
                     &def, &err) == FM_OK);
    ENSURE_MSG(err.status == FM_OK, "%s", err.message);
    ENSURE(def.flock.fuzzy_tracking[FM_FUZZY_HOMING].count == 2 && def.flock.fuzzy_tracking[FM_FUZZY_HOMING].w[1] == 0.1);
    ENSURE(def.flock.fuzzy[FM_FUZZY_HOMING].count == fm_default_scene_def().flock.fuzzy[FM_FUZZY_HOMING].count);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"deform\": {\"type\": \"wave\"}, \"fuzzy\": {\"homing\": [[0, 1], [3, 0.5]]}}}",
                     &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, ":2:56: shape_flock.fuzzy.homing: the target deforms, so the tracking strategy's curve "
                                   "shape_flock.fuzzy.tracking.homing applies"), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"fuzzy\": {\"tracking\": {\"damping\": [[0, 1]]}}}}", &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "shape_flock.fuzzy.tracking.damping: the target is static, so the static strategy's curve "
                                   "shape_flock.fuzzy.damping applies"), "%s", err.message);
    /* shape_flock.fuzzy.strategy chooses against the target: a static target may track */
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"fuzzy\": {\"strategy\": \"tracking\", \"tracking\": {\"damping\": [[0, 1]]}}}}", &def,
                     &err) == FM_OK);
    ENSURE(def.flock.fuzzy_strategy == FM_FUZZY_TRACKING && def.flock.fuzzy_tracking[FM_FUZZY_DAMPING].count == 1);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"fuzzy\": {\"strategy\": \"tracking\", \"damping\": [[0, 1]]}}}", &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "shape_flock.fuzzy.damping: the strategy is chosen by shape_flock.fuzzy.strategy, so the "
                                   "tracking strategy's curve shape_flock.fuzzy.tracking.damping applies"), "%s", err.message);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, \"source\": {\"mesh\": \"a.obj\"}, \"target\": {\"mesh\": \"b.obj\"},\n"
                     " \"shape_flock\": {\"fuzzy\": {\"strategy\": \"dynamic\"}}}", &def, &err) == FM_ERR_INPUT);
    ENSURE_MSG(strstr(err.message, "shape_flock.fuzzy.strategy"), "%s", err.message);
    /* defaults: Figure 6, far from the destination the steering, near it homing; the tracking
     * strategy lowers steering below the static one's near the destination */
    const fm_flock_def f = fm_default_scene_def().flock;
    ENSURE(f.fuzzy[FM_FUZZY_STEERING].w[0] < f.fuzzy[FM_FUZZY_STEERING].w[f.fuzzy[FM_FUZZY_STEERING].count - 1]);
    ENSURE(f.fuzzy[FM_FUZZY_HOMING].w[0] > f.fuzzy[FM_FUZZY_HOMING].w[f.fuzzy[FM_FUZZY_HOMING].count - 1]);
    ENSURE(f.fuzzy_tracking[FM_FUZZY_STEERING].w[0] < f.fuzzy[FM_FUZZY_STEERING].w[0]);
    ENSURE(f.fuzzy_tracking[FM_FUZZY_EXTERNAL].w[0] < f.fuzzy[FM_FUZZY_EXTERNAL].w[0]);
}

/* The sampling groups: values reach fm_flock_def, the defaults are the sampler's own, bad values
 * and keys of the other method are refused at their line and column. */
static void test_sampling_keys_are_read_and_checked(void)
{
    fm_scene_def def = fm_default_scene_def();
    ENSURE(def.flock.mosaic_iterations == FM_SAMPLE_MOSAIC_ITERATIONS && def.flock.mosaic_k == FM_SAMPLE_MOSAIC_K);
    ENSURE(def.flock.mosaic_w == FM_SAMPLE_MOSAIC_W && def.flock.mosaic_step == FM_SAMPLE_MOSAIC_STEP);
    ENSURE(def.flock.mosaic_distance == FM_MOSAIC_EUCLIDEAN && def.flock.stratified_lambda == FM_SAMPLE_LAMBDA);
    ENSURE(def.flock.stratified_oversample == FM_SAMPLE_OVERSAMPLE);
    fm_error err = {0};
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, " MESHES ",\n \"shape_flock\": {\"mosaic\": {\"iterations\": 0, "
                     "\"distance\": \"manhattan\", \"k\": 3, \"w\": 0.5, \"step\": 0.1}}}", &def, &err) == FM_OK);
    ENSURE_MSG(err.status == FM_OK, "%s", err.message);
    ENSURE(def.flock.mosaic_iterations == 0 && def.flock.mosaic_distance == FM_MOSAIC_MANHATTAN);
    ENSURE(def.flock.mosaic_k == 3 && def.flock.mosaic_w == 0.5 && def.flock.mosaic_step == 0.1);
    ENSURE(load_text("{\"mode\": \"shape_flock\", \"n\": 10, " MESHES ",\n \"shape_flock\": {\"sampling\": \"stratified\", "
                     "\"stratified\": {\"lambda\": 2, \"oversample\": 3}}}", &def, &err) == FM_OK);
    ENSURE(def.flock.stratified_lambda == 2 && def.flock.stratified_oversample == 3);

    /* line 2 is ` "shape_flock": {GROUP}}`: GROUP starts at column 18 */
    static const struct { const char *group, *want; } bad[] = {
        {"\"mosaic\": {\"iterations\": -1}", ":2:43: shape_flock.mosaic.iterations: -1 is out of range: must be >= 0"},
        {"\"mosaic\": {\"iterations\": 2.5}", ":2:43: shape_flock.mosaic.iterations: expected an integer"},
        {"\"mosaic\": {\"k\": 0}", ":2:34: shape_flock.mosaic.k: 0 is out of range: must be > 0"},
        {"\"mosaic\": {\"w\": -0.9}", ":2:34: shape_flock.mosaic.w: -0.9 is out of range"},
        {"\"mosaic\": {\"step\": 5}", ":2:37: shape_flock.mosaic.step: 5 is out of range: must be <= 4"},
        {"\"mosaic\": {\"distance\": \"chebyshev\"}", ":2:41: shape_flock.mosaic.distance: expected \"euclidean\" or \"manhattan\""},
        {"\"mosaic\": {\"sigma\": 1}", ":2:29: shape_flock.mosaic.sigma: unknown key"},
        {"\"sampling\": \"stratified\", \"stratified\": {\"oversample\": 0.5}",
         ":2:73: shape_flock.stratified.oversample: 0.5 is out of range: must be >= 1"},
        {"\"sampling\": \"stratified\", \"mosaic\": {\"k\": 3}",
         ":2:55: shape_flock.mosaic.k: applies only with shape_flock.sampling \"mosaic\" (this scene's is \"stratified\")"},
        {"\"stratified\": {\"lambda\": 2}",
         ":2:33: shape_flock.stratified.lambda: applies only with shape_flock.sampling \"stratified\" (this scene's is \"mosaic\")"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char text[512];
        snprintf(text, sizeof text, "{\"mode\": \"shape_flock\", \"n\": 10, " MESHES ",\n \"shape_flock\": {%s}}", bad[i].group);
        ENSURE(load_text(text, &def, &err) == FM_ERR_INPUT);
        ENSURE_MSG(strstr(err.message, bad[i].want), "%s: want '%s', got '%s'", bad[i].group, bad[i].want, err.message);
    }
}

/* The nearest-neighbour CV of the destinations of a 2000-agent flock sampled as given. */
static double destination_cv(fm_flock_sampling sampling, int iterations, fm_mosaic_distance distance)
{
    fm_scene_def def = flock_def(2000);
    def.flock.sampling = sampling, def.flock.mosaic_iterations = iterations, def.flock.mosaic_distance = distance;
    fm_flock_model *m = build(&def);
    if (!m) return NAN;
    float *c2 = malloc(sizeof(float) * 3 * 2000);
    fm_flock_model_endpoints(m, NULL, c2);
    double mean = 0, cv = NAN;
    fm_error err = {0};
    ENSURE_MSG(fm_points_nn_stats(c2, 2000, 0, &mean, &cv, &err) == FM_OK, "%s", err.message);
    free(c2);
    fm_flock_model_destroy(m);
    return cv;
}

/* The scene's mosaic settings reach the sampler: no iterations leave the random start (the same
 * points as random sampling, so the same CV), 30 make the spacing far more even (docs/sampling.md:
 * about a tenth of random's CV), and the Manhattan distance gives another, less even, arrangement. */
static void test_sampling_keys_reach_the_sampler(void)
{
    const double random = destination_cv(FM_FLOCK_SAMPLE_RANDOM, 0, FM_MOSAIC_EUCLIDEAN);
    const double none = destination_cv(FM_FLOCK_SAMPLE_MOSAIC, 0, FM_MOSAIC_EUCLIDEAN);
    const double relaxed = destination_cv(FM_FLOCK_SAMPLE_MOSAIC, 30, FM_MOSAIC_EUCLIDEAN);
    const double manhattan = destination_cv(FM_FLOCK_SAMPLE_MOSAIC, 30, FM_MOSAIC_MANHATTAN);
    printf("  nearest-neighbour CV: random %.3f, mosaic 0 iterations %.3f, 30 %.3f, 30 Manhattan %.3f\n", random, none,
           relaxed, manhattan);
    ENSURE_NEAR(none, random, 1e-9);
    ENSURE_MSG(none > 0.4, "the random start has a CV of %g (uniform random points: about 0.52)", none);
    ENSURE_MSG(relaxed < 0.4 * none, "30 iterations: CV %g against %g for none", relaxed, none);
    ENSURE_MSG(manhattan > relaxed && manhattan < 0.6 * none, "Manhattan: CV %g (Euclidean %g, none %g)", manhattan, relaxed, none);
}

int main(void)
{
    RUN_TEST(test_static_target_every_agent_binds);
    RUN_TEST(test_floating_agents_stay_near);
    RUN_TEST(test_threads_and_seeds_agree);
    RUN_TEST(test_caches_are_identical_for_threads_and_runs);
    RUN_TEST(test_resorted_store_changes_no_frame);
    RUN_TEST(test_resort_switch_is_checked);
    RUN_TEST(test_orientation_follows_velocity);
    RUN_TEST(test_orientation_is_the_upright_frame);
    RUN_TEST(test_orientation_lanes_are_the_scalar_frames);
    RUN_TEST(test_simd_levels_give_the_same_flock);
    RUN_TEST(test_deforming_target_is_tracked);
    RUN_TEST(test_mesh_sequence_moves_the_destinations);
    RUN_TEST(test_mesh_sequence_matches_vertices_as_listed);
    RUN_TEST(test_scene_keys_belong_to_their_mode);
    RUN_TEST(test_fuzzy_strategy_keys);
    RUN_TEST(test_sampling_keys_are_read_and_checked);
    RUN_TEST(test_sampling_keys_reach_the_sampler);
    return test_result();
}
