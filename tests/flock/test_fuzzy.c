/* Fuzzy weight curves (SCF Figure 6): continuous (sampled densely, no step larger than the steepest
 * piece allows), through their points, flat beyond their ends; bad curves are refused; the scene
 * defaults are valid curves. */
#include "flock_fuzzy.h"
#include "test_macros.h"

#include <string.h>

static fm_fuzzy_def curve(int count, const double (*pts)[2])
{
    fm_fuzzy_def def = {.count = count};
    for (int i = 0; i < count; i++) def.d[i] = pts[i][0], def.w[i] = pts[i][1];
    return def;
}

/* The largest jump between samples h apart over [lo, hi], against the bound the slopes allow. */
static void ensure_continuous(const fm_fuzzy *c, float lo, float hi, const char *name)
{
    float steepest = 0;
    for (int i = 0; i < c->count; i++) steepest = fmaxf(steepest, fabsf(c->slope[i]));
    const float h = 1e-3f;
    float worst = 0, prev = fm_fuzzy_eval(c, lo);
    for (float d = lo + h; d <= hi; d += h) {
        float w = fm_fuzzy_eval(c, d);
        worst = fmaxf(worst, fabsf(w - prev) - steepest * h);
        prev = w;
    }
    ENSURE_MSG(worst <= 1e-5f, "%s: a jump of %g beyond what its slopes allow", name, worst);
}

static void test_curve_is_continuous_and_through_its_points(void)
{
    const double pts[5][2] = {{0.5, 1}, {1, 0.2}, {1.001, 0.9}, {4, 0.9}, {9, 0}};
    fm_fuzzy_def def = curve(5, pts);
    fm_fuzzy c;
    ENSURE(fm_fuzzy_init(&c, &def, "test", NULL) == FM_OK);
    for (int i = 0; i < 5; i++) ENSURE_NEAR(fm_fuzzy_eval(&c, (float)pts[i][0]), pts[i][1], 1e-6);
    ENSURE_NEAR(fm_fuzzy_eval(&c, 0.75f), 0.6, 1e-6);      /* halfway along the first piece */
    ENSURE(fm_fuzzy_eval(&c, 0) == 1 && fm_fuzzy_eval(&c, 100) == 0 && fm_fuzzy_eval(&c, NAN) == 1);
    ensure_continuous(&c, -1, 12, "five points");
}

/* A steep piece (700 per unit) is still continuous: the check is against its slope, and a real
 * jump (a step function sampled the same way) would be caught. */
static void test_a_step_would_be_caught(void)
{
    const double pts[2][2] = {{1, 0}, {1.001, 0.7}};
    fm_fuzzy_def def = curve(2, pts);
    fm_fuzzy c;
    ENSURE(fm_fuzzy_init(&c, &def, "steep", NULL) == FM_OK);
    ensure_continuous(&c, 0, 2, "steep");
    fm_fuzzy step = c;                 /* the same curve with its slope forgotten: a jump of 0.7 */
    step.slope[0] = 0;
    float worst = 0, prev = fm_fuzzy_eval(&step, 0);
    for (float d = 1e-3f; d <= 2; d += 1e-3f) worst = fmaxf(worst, fabsf(fm_fuzzy_eval(&step, d) - prev)), prev = fm_fuzzy_eval(&step, d);
    ENSURE(worst > 0.5f);
}

static void test_bad_curves_are_refused(void)
{
    fm_fuzzy c;
    fm_error err = {0};
    const double down[3][2] = {{0, 1}, {2, 1}, {2, 0}}, negative[2][2] = {{0, 1}, {1, -0.5}};
    fm_fuzzy_def def = curve(3, down);
    ENSURE(fm_fuzzy_init(&c, &def, "shape_flock.fuzzy.homing", &err) == FM_ERR_INPUT);
    ENSURE(strstr(err.message, "shape_flock.fuzzy.homing[2]") && strstr(err.message, "increase"));
    def = curve(2, negative);
    ENSURE(fm_fuzzy_init(&c, &def, "w", &err) == FM_ERR_INPUT);
    def = curve(0, negative);
    ENSURE(fm_fuzzy_init(&c, &def, "w", &err) == FM_ERR_INPUT);
}

static void test_scene_defaults_are_valid_continuous_curves(void)
{
    fm_scene_def def = fm_default_scene_def();
    static const char *const names[FM_FUZZY_FORCES] = {"steering", "homing", "damping", "external"};
    for (int f = 0; f < FM_FUZZY_FORCES; f++) {
        fm_fuzzy c;
        fm_error err = {0};
        ENSURE_MSG(fm_fuzzy_init(&c, &def.flock.fuzzy[f], names[f], &err) == FM_OK, "%s", err.message);
        ensure_continuous(&c, 0, 50, names[f]);
    }
}

int main(void)
{
    RUN_TEST(test_curve_is_continuous_and_through_its_points);
    RUN_TEST(test_a_step_would_be_caught);
    RUN_TEST(test_bad_curves_are_refused);
    RUN_TEST(test_scene_defaults_are_valid_continuous_curves);
    return test_result();
}
