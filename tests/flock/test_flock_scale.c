/* The 10^5-agent scenario, examples/flock_suzanne_torus, built from its scene file through
 * the public API: the model has 100,000 agents; every start lies on the placed source surface and
 * every destination on the placed target surface (Embree closest point, within 1e-5 of the
 * bounding-box diagonal, as tests/sample/test_sample.c); and after a few frames 1 and 2 threads hold the
 * same bits (positions, velocities, orientations, phases). The whole run (164 frames, about 6 s of
 * preprocessing and 45 s of steps) is measured in docs/shape-flock.md; here only its first frames
 * are stepped, to stay under ~20 s on two cores. */
#include "closest.h"
#include "flockmorph/flockmorph.h"
#include "test_macros.h"
#include "test_mesh_helpers.h"

#include <stdlib.h>
#include <string.h>

enum { AGENTS = 100000, FRAMES = 3 };

/* Every point (3 floats each) within 1e-5 of the diagonal of the mesh `ref` places, by Embree. */
static void check_on_surface(const fm_mesh_ref *ref, const float *p, int64_t n, const char *what)
{
    fm_mesh mesh = {0};
    fm_error err = {0};
    ENSURE_MSG(fm_mesh_load(ref->path, &mesh, &err) == FM_OK, "%s", err.message);
    fm_mesh_place(&mesh, ref);
    fm_closest *surface = fm_closest_build(&mesh, 1, what, 0, &err);
    ENSURE_MSG(surface != NULL, "%s", err.message);
    if (surface) {
        const double tol = 1e-5 * bbox_diagonal(&mesh);
        double worst = 0;
        for (int64_t i = 0; i < n; i++) {
            const double q[3] = {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
            worst = fmax(worst, fm_closest_point(surface, q, INFINITY, NULL, NULL));
        }
        printf("  %-7s %lld points, farthest from the surface %.2e (limit %.2e)\n", what, (long long)n, worst, tol);
        ENSURE_MSG(worst <= tol, "%s: a point %.3g from the surface (limit %.3g)", what, worst, tol);
    }
    fm_closest_destroy(surface);
    fm_mesh_free(&mesh);
}

typedef struct frame {
    float *p, *v, *q;
    uint8_t *phase;
} frame;

static frame frame_of(const fm_flock_state *s)
{
    frame f = {malloc(sizeof(float) * 3 * AGENTS), malloc(sizeof(float) * 3 * AGENTS), malloc(sizeof(float) * 4 * AGENTS),
               malloc(AGENTS)};
    fm_flock_frame(s, f.p, f.v, f.q, f.phase);
    return f;
}

static void frame_free(frame *f) { free(f->p), free(f->v), free(f->q), free(f->phase); }

/* Steps FRAMES frames on `threads` threads and returns the last one. */
static frame run_frames(const fm_flock_model *m, int threads)
{
    fm_error err = {0};
    fm_flock_state *s = fm_flock_state_create(m, threads, &err);
    ENSURE_MSG(s != NULL, "%s", err.message);
    frame f = {0};
    if (!s) return f;
    const int64_t steps = (int64_t)FRAMES * fm_flock_model_get_info(m).steps_per_frame;
    double t0 = fm_seconds();
    for (int64_t k = 0; k < steps; k++) fm_flock_step(m, s);
    printf("  %d thread(s): %lld steps in %.2f s\n", threads, (long long)steps, fm_seconds() - t0);
    ENSURE(fm_flock_get_info(s).step == steps);
    f = frame_of(s);
    fm_flock_state_destroy(s);
    return f;
}

static void test_hundred_thousand_agents(void)
{
    char scene[FM_PATH_MAX];
    snprintf(scene, sizeof scene, "%s/examples/flock_suzanne_torus/scene.json", FM_SOURCE_DIR);
    fm_scene_def def;
    fm_error err = {0};
    ENSURE_MSG(fm_scene_load(scene, &def, &err) == FM_OK, "%s", err.message);
    double t0 = fm_seconds();
    fm_flock_model *m = fm_flock_model_build(&def, NULL, NULL, &err);
    ENSURE_MSG(m != NULL, "%s", err.message);
    if (!m) return;
    printf("  model built in %.2f s\n", fm_seconds() - t0);
    ENSURE(def.n == AGENTS && fm_flock_model_get_info(m).agents == AGENTS);

    float *c1 = malloc(sizeof(float) * 3 * AGENTS), *c2 = malloc(sizeof(float) * 3 * AGENTS);
    fm_flock_model_endpoints(m, c1, c2);
    check_on_surface(&def.source, c1, AGENTS, "source");
    check_on_surface(&def.target, c2, AGENTS, "target");

    frame one = run_frames(m, 1), two = run_frames(m, 2);
    if (one.p && two.p) {
        ENSURE_MSG(!memcmp(one.p, two.p, sizeof(float) * 3 * AGENTS), "1 and 2 threads: positions differ");
        ENSURE_MSG(!memcmp(one.v, two.v, sizeof(float) * 3 * AGENTS), "1 and 2 threads: velocities differ");
        ENSURE_MSG(!memcmp(one.q, two.q, sizeof(float) * 4 * AGENTS), "1 and 2 threads: orientations differ");
        ENSURE_MSG(!memcmp(one.phase, two.phase, AGENTS), "1 and 2 threads: phases differ");
        /* the flock has left the source: the comparison is of a state that the steps changed */
        int64_t moved = 0;
        for (int64_t i = 0; i < 3 * AGENTS; i++) moved += one.p[i] != c1[i];
        ENSURE_MSG(moved > AGENTS, "only %lld coordinates moved in %d frames", (long long)moved, FRAMES);
    }
    frame_free(&one), frame_free(&two);
    free(c1), free(c2);
    fm_flock_model_destroy(m);
}

int main(void)
{
    RUN_TEST(test_hundred_thousand_agents);
    return test_result();
}
