/* A program outside flockmorph that uses the engine through the installed package: loads SCENE,
 * builds the tetra morph's model (assimp, TetGen, the obstacle field's OpenVDB and Embree code are
 * linked through it), takes 10 steps on 2 OpenMP threads, checks that every tet vertex is finite
 * and renders the state to PNG (Embree, libpng). Linked statically it shows that the package's
 * link interface (find_package, pkg-config --static) names every library the engine needs.
 *   run_scene SCENE AGENTS PNG */
#include <flockmorph/flockmorph.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv)
{
    if (argc != 4) return fprintf(stderr, "usage: run_scene SCENE AGENTS PNG\n"), 2;
    fm_error err = {0};
    fm_scene_def def;
    if (fm_scene_load(argv[1], &def, &err) != FM_OK) return fprintf(stderr, "run_scene: %s\n", err.message), 1;
    fm_morph_model *model = fm_morph_model_build(&def, NULL, NULL, &err);
    if (!model) return fprintf(stderr, "run_scene: %s\n", err.message), 1;
    int64_t agents = fm_morph_model_get_info(model).agents;
    fm_morph_state *state = fm_morph_state_create(model, 2, &err);
    float *v = malloc((size_t)agents * 12 * sizeof *v);
    int bad = agents != strtoll(argv[2], NULL, 10);
    if (!state || !v) return fprintf(stderr, "run_scene: %s\n", state ? "out of memory" : err.message), 1;
    for (int s = 0; s < 10; s++) fm_morph_step(model, state);
    fm_morph_tet_vertices(model, state, v);
    for (int64_t i = 0; i < agents * 12; i++) bad += !isfinite(v[i]);
    fm_render_opts opts = fm_default_render_opts();
    opts.width = opts.height = 64;
    fm_status st = fm_render_tets_png(v, (size_t)agents, &opts, argv[3], &err);
    if (st != FM_OK) fprintf(stderr, "run_scene: %s\n", err.message);
    if (bad) fprintf(stderr, "run_scene: %lld agents (expected %s) or non-finite vertices\n", (long long)agents, argv[2]);
    else if (st == FM_OK) printf("run_scene: %lld agents after 10 steps, %s written\n", (long long)agents, argv[3]);
    free(v);
    fm_morph_state_destroy(state);
    fm_morph_model_destroy(model);
    return st == FM_OK && !bad ? 0 : 1;
}
