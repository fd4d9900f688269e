/* Shot tests' helpers (tests/morph/test_shot.c, tests/flock/test_flock_shot.c): a scene's groups
 * loaded as flockmorph run loads them, and a byte comparison of two files. */
#ifndef FM_TEST_SHOT_HELPERS_H
#define FM_TEST_SHOT_HELPERS_H

#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <stdio.h>

/* Every group of the scene at path into defs (FM_MAX_GROUPS of them); 0 on success. */
static inline int load_groups(const char *path, fm_scene_def *defs, int *count)
{
    fm_error err = {0};
    static fm_scene_def top; /* 120 KiB */
    ENSURE_MSG(fm_scene_load(path, &top, &err) == FM_OK, "%s", err.message);
    if (err.status != FM_OK) return -1;
    *count = top.group_count;
    for (int g = 0; g < *count; g++) {
        ENSURE_MSG(fm_scene_load_group(path, NULL, 0, g, &defs[g], &err) == FM_OK, "%s", err.message);
        if (err.status != FM_OK) return -1;
    }
    return 0;
}

/* 1 if both files hold the same bytes. */
static inline int same_file(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int same = fa && fb;
    while (same) {
        int x = fgetc(fa), y = fgetc(fb);
        same = x == y;
        if (x == EOF || y == EOF) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

#endif
