/* The obstacles that go with a cache: the mesh `render` draws and `export` writes beside the frames
 * in their axes and units (docs/render.md, docs/export.md). */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "geom.h"

#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

int cli_cache_obstacles(const char *cache, const char *given, fm_mesh *out, char path[FM_PATH_MAX + 32])
{
    memset(out, 0, sizeof *out);
    const char *slash = strrchr(cache, '/');
    snprintf(path, FM_PATH_MAX + 32, "%.*s" FM_OUTPUT_OBSTACLES, slash ? (int)(slash - cache + 1) : 0, cache);
    struct stat st;
    if (given) snprintf(path, FM_PATH_MAX + 32, "%s", given);
    else if (stat(path, &st) != 0) return path[0] = 0, 0; /* a run without obstacles writes none */
    fm_error err = {0};
    if (fm_mesh_load(path, out, &err) == FM_OK) return 0;
    fprintf(stderr, "flockmorph: error: %s: %s%s\n", given ? "--obstacles" : "the obstacles beside the cache",
            err.message, given ? "" : " (--no-obstacles leaves them out)");
    return err.status ? (int)err.status : FM_ERR_INPUT;
}
