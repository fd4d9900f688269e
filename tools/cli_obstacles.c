/* The obstacles that go with a cache: the mesh `render` draws and `export` writes beside the frames
 * in their axes and units (docs/render.md, docs/export.md). A file flockmorph wrote names its axes
 * and scale in its header (`run --up y` writes obstacles.ply Y-up), and is read back into the
 * cache's, where the frames are. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "geom.h"

#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

/* The mesh at path from the convention its header names into the cache's axes and units; 0, or
 * the input error when that line is malformed (printed, naming the file). */
static int into_cache_axes(const char *path, fm_mesh *m)
{
    cli_axes axes;
    char line[512];
    int named = cli_axes_of_file(path, &axes, line, sizeof line);
    if (named > 0) cli_axes_mesh_from(&axes, m);
    if (named >= 0) return 0;
    fprintf(stderr, "flockmorph: error: %s: its header line '%s' does not say 'up y' or 'up z' and a scale from "
            "1e-6 to 1e6 ('flockmorph axes: up y, scale 2.5'), so the obstacles cannot be put where the frames are\n",
            path, line);
    fm_mesh_free(m);
    return FM_ERR_INPUT;
}

int cli_cache_obstacles(const char *cache, const char *given, fm_mesh *out, char path[FM_PATH_MAX + 32])
{
    memset(out, 0, sizeof *out);
    const char *slash = strrchr(cache, '/');
    snprintf(path, FM_PATH_MAX + 32, "%.*s" FM_OUTPUT_OBSTACLES, slash ? (int)(slash - cache + 1) : 0, cache);
    struct stat st;
    if (given) snprintf(path, FM_PATH_MAX + 32, "%s", given);
    else if (stat(path, &st) != 0) return path[0] = 0, 0; /* a run without obstacles writes none */
    fm_error err = {0};
    if (fm_mesh_load(path, out, &err) == FM_OK) return into_cache_axes(path, out);
    fprintf(stderr, "flockmorph: error: %s: %s%s\n", given ? "--obstacles" : "the obstacles beside the cache",
            err.message, given ? "" : " (--no-obstacles leaves them out)");
    return err.status ? (int)err.status : FM_ERR_INPUT;
}
