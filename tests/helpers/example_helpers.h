/* Loads a bundled example's scene (examples/NAME/scene.json) for tests that change its parameters. */
#ifndef FM_EXAMPLE_HELPERS_H
#define FM_EXAMPLE_HELPERS_H

#include "flockmorph/flockmorph.h"
#include "test_macros.h"

static inline fm_scene_def load_example(const char *name)
{
    fm_scene_def def;
    fm_error err = {0};
    char scene[FM_PATH_MAX];
    snprintf(scene, sizeof scene, "%s/examples/%s/scene.json", FM_SOURCE_DIR, name);
    ENSURE_MSG(fm_scene_load(scene, &def, &err) == FM_OK, "%s", err.message);
    return def;
}

#endif
