/* libFuzzer target: the scene parser (fm_scene_parse), then fm_scene_validate and the path's key
 * points (fm_path_build, FM §5.1) on what it accepts. Meshes named by the scene are not loaded;
 * the path runs between two fixed centroids. */
#include "fuzz_check.h"
#include "morph.h"

#include <math.h>

#include <stdint.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Q_0 = C_S and Q_{m+1} = C_T exactly, m + 2 finite key points in between. */
static void check_path(const fm_scene_def *def)
{
    const double cs[3] = {-3, 0.5, 0}, ct[3] = {4, 1, -2};
    fm_path path = {0};
    fm_error err = {0};
    fm_status st = fm_path_build(def, cs, ct, &path, &err);
    fuzz_expect_clean(st, &err);
    if (st != FM_OK) return;
    FUZZ_ASSERT(path.count == def->path_key_points + 2);
    for (int32_t i = 0; i < 3 * path.count; i++) FUZZ_ASSERT(isfinite(path.q[i]));
    FUZZ_ASSERT(!memcmp(path.q, cs, sizeof cs) && !memcmp(path.q + 3 * (path.count - 1), ct, sizeof ct));
    fm_path_free(&path);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static fm_scene_def def; /* about 90 KB: not on the stack */
    fm_error err = {0};
    fm_status st = fm_scene_parse((const char *)data, size, "fuzz/scene.json", &def, &err);
    fuzz_expect_clean(st, &err);
    if (st != FM_OK) {
        FUZZ_ASSERT(st == FM_ERR_INPUT && strstr(err.message, "fuzz/scene.json") == err.message);
        return 0;
    }
    /* Whatever the loader accepts, the validator (which also checks definitions built in code)
     * must accept too: both walk the one parameter table. */
    fm_error verr = {0};
    st = fm_scene_validate(&def, &verr);
    if (st != FM_OK) fprintf(stderr, "fuzz: loaded but not valid: %s\n", verr.message);
    FUZZ_ASSERT(st == FM_OK);
    FUZZ_ASSERT(!strncmp(def.source.path, "fuzz/", 5) || def.source.path[0] == '/');
    check_path(&def);
    return 0;
}
