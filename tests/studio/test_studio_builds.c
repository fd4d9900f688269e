/* The studio's model builds (docs/studio.md, "An edit and the model"; issue 39). A build the studio
 * cancels stops at its next stage boundary with FM_STOPPED, in either mode: here the keep's cancel
 * flag is set by the build's own progress report at a stage, as an edit sets it from the studio's
 * server thread. The keep it leaves holds nothing half-made: a build from it gives, byte for byte,
 * the model a build without a keep gives (the tetra morph's tets, key points and obstacle grid; the
 * shape flock's start and destination points, obstacle grid and path R, routed round the obstacle),
 * and a build cancelled before it starts leaves every kept part to the next (tets or samples, grid
 * and route kept). The mosaic sampler stops between its iterations. */
#include "flock.h"
#include "morph.h"
#include "sample.h"
#include "test_macros.h"

#include <stdlib.h>
#include <string.h>

/* The progress report that sets the flag when the build reaches `at` (NULL: never). */
typedef struct canceller {
    const char *at;
    volatile sig_atomic_t flag;
} canceller;

static void cancel_at(const char *stage, double fraction, void *user)
{
    (void)fraction;
    canceller *c = user;
    if (c->at && !strcmp(stage, c->at)) c->flag = 1;
}

static void example_mesh(fm_mesh_ref *ref, const char *name, double x)
{
    snprintf(ref->path, sizeof ref->path, "%s/examples/flock_cylinder_sphere/%s", FM_SOURCE_DIR, name);
    ref->translate[0] = x;
}

/* The cylinder to the sphere past a small sphere on the path's way (docs/studio.md's server test). */
static fm_scene_def scene(fm_mode mode, int64_t n)
{
    fm_scene_def def = fm_default_scene_def();
    def.mode = mode, def.n = n, def.seed = 9, def.speed0 = 8;
    example_mesh(&def.source, "cylinder.obj", -15), example_mesh(&def.target, "sphere.obj", 15);
    def.path_point_count = 1;
    def.path_points[0][1] = -6, def.path_points[0][2] = 7;
    def.obstacle_count = 1, def.k_a = 1.0, def.obstacle_voxel = 0.5;
    example_mesh(&def.obstacles[0], "sphere.obj", 0);
    def.obstacles[0].scale = 0.3, def.obstacles[0].translate[1] = -3, def.obstacles[0].translate[2] = 3.5;
    def.detour_time = -1;                                           /* no navigation function: 1 to 3 s a build */
    def.flock.sampling = FM_FLOCK_SAMPLE_MOSAIC, def.flock.mosaic_iterations = 10; /* iterations to stop between */
    return def;
}

static int same_floats(const float *a, const float *b, size_t count) { return !memcmp(a, b, sizeof(float) * count); }

/* The obstacles' distance grids, node for node. */
static int same_grid(const fm_obstacles *a, const fm_obstacles *b)
{
    const fm_sdf_view x = fm_obstacles_sdf(a), y = fm_obstacles_sdf(b);
    const size_t nodes = (size_t)x.n[0] * (size_t)x.n[1] * (size_t)x.n[2];
    return !memcmp(x.n, y.n, sizeof x.n) && same_floats(x.origin, y.origin, 3) && x.voxel == y.voxel &&
           same_floats(x.d, y.d, nodes);
}

static int same_morph(const fm_morph_model *a, const fm_morph_model *b)
{
    const size_t n = (size_t)a->n;
    int same = a->n == b->n && a->key_count == b->key_count && same_floats(a->src_rel, b->src_rel, 12 * n) &&
               same_floats(a->tgt_f, b->tgt_f, 12 * n) && same_grid(a->obstacles, b->obstacles);
    for (int k = 0; same && k < 3; k++) same = same_floats(a->key_q[k], b->key_q[k], (size_t)a->key_count);
    return same;
}

/* A mode's keeping build (fm_morph_model_build_keeping, fm_flock_model_build_keeping). */
typedef struct mode_ops {
    const char *name;
    void *(*build)(const fm_scene_def *def, void *keep, fm_progress_fn progress, void *user, fm_error *err);
    void (*destroy)(void *model);
} mode_ops;

static void *build_morph(const fm_scene_def *def, void *keep, fm_progress_fn progress, void *user, fm_error *err)
{
    return fm_morph_model_build_keeping(def, keep, progress, user, err);
}
static void destroy_morph(void *m) { fm_morph_model_destroy(m); }
static void *build_flock(const fm_scene_def *def, void *keep, fm_progress_fn progress, void *user, fm_error *err)
{
    return fm_flock_model_build_keeping(def, keep, progress, user, err);
}
static void destroy_flock(void *m) { fm_flock_model_destroy(m); }
static const mode_ops MORPH = {"tetra morph", build_morph, destroy_morph}, FLOCK = {"shape flock", build_flock, destroy_flock};

/* A keeping build whose flag (*cancel, the keep's) is set at stage `at` (NULL: before it starts)
 * stops there: NULL, FM_STOPPED. */
static void expect_cancelled(const mode_ops *mode, const fm_scene_def *def, void *keep,
                             const volatile sig_atomic_t **cancel, const char *at)
{
    canceller c = {at, at ? 0 : 1};
    fm_error err = {0};
    *cancel = &c.flag;
    void *m = mode->build(def, keep, cancel_at, &c, &err);
    ENSURE_MSG(m == NULL && err.status == FM_STOPPED, "a %s build cancelled at %s: status %d (%s)", mode->name,
               at ? at : "its start", (int)err.status, err.message);
    mode->destroy(m);
    *cancel = NULL;
}

static void test_morph_build_cancelled_keeps_nothing_half_made(void)
{
    const fm_scene_def def = scene(FM_MODE_TETRA_MORPH, 0);
    fm_error err = {0};
    fm_morph_model *plain = fm_morph_model_build(&def, NULL, NULL, &err);
    ENSURE_MSG(plain != NULL, "%s", err.message);
    fm_morph_keep keep = {0};
    expect_cancelled(&MORPH, &def, &keep, &keep.cancel, "tetrahedralize target"); /* the source's TetGen kept */
    expect_cancelled(&MORPH, &def, &keep, &keep.cancel, "order");                 /* the tets and the grid kept */
    fm_morph_model *kept = fm_morph_model_build_keeping(&def, &keep, NULL, NULL, &err);
    ENSURE_MSG(kept != NULL, "%s", err.message);
    ENSURE_MSG(kept && keep.grid_reused && !keep.route_reused, "after a cancel at the route: grid %d, route %d kept",
               keep.grid_reused, keep.route_reused);
    ENSURE_MSG(kept && plain && same_morph(kept, plain), "the build after two cancelled ones differs from a plain build");
    expect_cancelled(&MORPH, &def, &keep, &keep.cancel, NULL); /* before TetGen: a shot's next group */
    fm_morph_model *again = fm_morph_model_build_keeping(&def, &keep, NULL, NULL, &err);
    ENSURE_MSG(again && keep.reused && keep.grid_reused && keep.route_reused,
               "a build cancelled at its start left the keep whole: tets %d, grid %d, route %d kept", keep.reused,
               keep.grid_reused, keep.route_reused);
    ENSURE_MSG(again && plain && same_morph(again, plain), "the kept build differs from a plain build");
    fm_morph_model_destroy(again), fm_morph_model_destroy(kept), fm_morph_model_destroy(plain);
    fm_morph_keep_clear(&keep);
}

static int same_flock(const fm_flock_model *a, const fm_flock_model *b)
{
    const size_t n = (size_t)a->n;
    float *p = malloc(sizeof(float) * 12 * n);
    int same = p && a->n == b->n && a->path.count == b->path.count && same_grid(a->obstacles, b->obstacles) &&
               !memcmp(a->path.ctrl, b->path.ctrl, sizeof(double) * 3 * (size_t)(a->path.count + 2));
    if (same) {
        fm_flock_model_endpoints(a, p, p + 3 * n);
        fm_flock_model_endpoints(b, p + 6 * n, p + 9 * n);
        same = same_floats(p, p + 6 * n, 6 * n);
    }
    free(p);
    return same;
}

static void test_flock_build_cancelled_keeps_nothing_half_made(void)
{
    const fm_scene_def def = scene(FM_MODE_SHAPE_FLOCK, 200);
    fm_error err = {0};
    fm_flock_model *plain = fm_flock_model_build(&def, NULL, NULL, &err);
    ENSURE_MSG(plain != NULL, "%s", err.message);
    fm_flock_keep keep = {0};
    expect_cancelled(&FLOCK, &def, &keep, &keep.cancel, "sample target"); /* between the samplings */
    expect_cancelled(&FLOCK, &def, &keep, &keep.cancel, "match");         /* both sampled, not matched */
    ENSURE_MSG(!keep.has, "a shape flock build cancelled before its match kept samples");
    fm_flock_model *kept = fm_flock_model_build_keeping(&def, &keep, NULL, NULL, &err);
    ENSURE_MSG(kept != NULL && !keep.reused, "%s", err.message);
    ENSURE_MSG(kept && plain && same_flock(kept, plain), "the build after two cancelled ones differs from a plain build");
    ENSURE_MSG(plain && plain->path.count > 3, "R was routed round the sphere (%d points)", plain ? plain->path.count : 0);
    expect_cancelled(&FLOCK, &def, &keep, &keep.cancel, NULL);
    fm_flock_model *again = fm_flock_model_build_keeping(&def, &keep, NULL, NULL, &err);
    ENSURE_MSG(again && keep.reused && keep.grid_reused && keep.route_reused,
               "a build cancelled at its start left the keep whole: samples %d, grid %d, route %d kept", keep.reused,
               keep.grid_reused, keep.route_reused);
    ENSURE_MSG(again && plain && same_flock(again, plain), "the kept build differs from a plain build");
    fm_flock_model_destroy(again), fm_flock_model_destroy(kept), fm_flock_model_destroy(plain);
    fm_flock_keep_clear(&keep);
}

/* The mosaic checks the flag before each iteration: set, it samples nothing. */
static void test_mosaic_stops_between_iterations(void)
{
    fm_mesh mesh = {0};
    fm_error err = {0};
    char path[FM_PATH_MAX];
    snprintf(path, sizeof path, "%s/examples/flock_cylinder_sphere/sphere.obj", FM_SOURCE_DIR);
    ENSURE_MSG(fm_mesh_load(path, &mesh, &err) == FM_OK, "%s", err.message);
    volatile sig_atomic_t flag = 1;
    fm_sample_opts opts = fm_default_sample_opts();
    opts.method = FM_SAMPLE_MOSAIC, opts.cancel = &flag;
    fm_samples out = {0};
    ENSURE(fm_sample_surface(&mesh, 300, &opts, &out, &err) == FM_STOPPED && out.p == NULL);
    flag = 0;
    ENSURE(fm_sample_surface(&mesh, 300, &opts, &out, &err) == FM_OK && out.n == 300);
    fm_samples_free(&out);
    fm_mesh_free(&mesh);
}

int main(void)
{
    RUN_TEST(test_morph_build_cancelled_keeps_nothing_half_made);
    RUN_TEST(test_flock_build_cancelled_keeps_nothing_half_made);
    RUN_TEST(test_mosaic_stops_between_iterations);
    return test_result();
}
