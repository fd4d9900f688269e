/* libFuzzer target: the scene parser (fm_scene_parse) and fm_scene_validate on what it accepts.
 * Meshes named by the scene are not loaded. */
#include "fuzz_check.h"

#include <stdint.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

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
    return 0;
}
