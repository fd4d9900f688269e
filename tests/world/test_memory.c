/* The memory estimate of a machine (src/world/memory.c, docs/limits.md): on P ranks either mode's
 * model is once per machine (fm_morph_model_build_shared, fm_flock_model_build_shared), so a
 * machine of 4 ranks needs less than 4 one-rank machines' worth; the agents it says fit are the
 * largest n it accepts; a shot's groups share theirs the same way; one process holds its own. */
#include "memory.h"
#include "modes.h"
#include "flockmorph/scene.h"
#include "test_macros.h"

#include <math.h>
#include <stdio.h>

static fm_scene_def scene(fm_mode mode, int group_index)
{
    fm_scene_def def = fm_default_scene_def();
    def.mode = mode;
    def.d_min = 0.01; /* the tetra morph with MDE's grid */
    def.group_index = group_index;
    return def;
}

/* n = fm_memory_agents_that_fit is the largest n that fm_memory_fits: a little less fits, a little
 * more does not (the machine's total and the solver agree). */
static void check_fit_edge(const fm_scene_def *def)
{
    double fits = 1e6;
    for (int i = 0; i < 3; i++) { /* a few per-agent terms vary with n (the grid's, the encoder's) */
        const fm_memory_estimate e = fm_memory_estimate_for(def, (int64_t)fits);
        fits = fm_memory_agents_that_fit(&e);
    }
    ENSURE(fits > 1e5);
    fm_memory_estimate below = fm_memory_estimate_for(def, (int64_t)(0.99 * fits));
    fm_memory_estimate above = fm_memory_estimate_for(def, (int64_t)(1.01 * fits));
    ENSURE_MSG(fm_memory_fits(&below), "%.4g agents (0.99 of %.4g) need %.4g bytes", 0.99 * fits, fits, below.total);
    ENSURE_MSG(!fm_memory_fits(&above), "%.4g agents (1.01 of %.4g) need %.4g bytes", 1.01 * fits, fits, above.total);
}

static void check_mode(fm_mode mode)
{
    const int64_t n = 10000000;
    const fm_scene_def plain = scene(mode, -1), group = scene(mode, 0);
    fm_memory_set_ranks(4, 1); /* 4 machines of one rank: each holds a model and prepares one */
    const fm_memory_estimate alone = fm_memory_estimate_for(&plain, n);
    ENSURE(alone.shared > 0 && alone.model == 0 && alone.preparations_here == 1);
    check_fit_edge(&plain);

    fm_memory_set_ranks(4, 4); /* one machine of 4 ranks */
    const fm_memory_estimate machine = fm_memory_estimate_for(&plain, n);
    ENSURE(machine.ranks_here == 4 && machine.preparations_here == 1);
    /* one model and one preparation instead of four: less than four machines' worth, more than one */
    ENSURE_MSG(machine.total < 4 * alone.total - 2.5 * alone.shared * (double)n, "%.4g against 4 x %.4g", machine.total,
               alone.total);
    ENSURE(machine.total > alone.total);
    check_fit_edge(&plain);

    /* a shot's group: one model a machine too */
    const fm_memory_estimate shot = fm_memory_estimate_for(&group, n);
    ENSURE(shot.shared == machine.shared && shot.model == 0 && shot.preparations_here == 1);
    fm_memory_set_ranks(1, 1); /* one process holds its model and prepares it */
    const fm_memory_estimate one = fm_memory_estimate_for(&plain, n);
    ENSURE(one.shared == 0 && one.model == machine.shared && one.preparations_here == 1);
    ENSURE_NEAR(one.total, fmax(one.run, one.preprocess), 1e-6 * one.total);
    check_fit_edge(&plain);
    fm_memory_set_ranks(1, 1);
}

static void test_a_machine_shares_its_model(void)
{
    if (fm_physical_memory() <= 0) {
        printf("  (skipped: physical memory unknown)\n");
        return;
    }
    check_mode(FM_MODE_TETRA_MORPH);
    check_mode(FM_MODE_SHAPE_FLOCK);
}

int main(void)
{
    RUN_TEST(test_a_machine_shares_its_model);
    return test_result();
}
