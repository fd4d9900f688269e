/* flockmorph export: one frame of a cache as PLY or OBJ. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"

#include <stdio.h>
#include <stdlib.h>

static const char *const USAGE_EXPORT =
    "usage: flockmorph export CACHE -o FILE.ply|FILE.obj [--frame K]\n"
    "\n"
    "Writes frame K (default: the last; negative counts from the end) as a triangle mesh with\n"
    "four triangles per tet.\n";


int cli_export(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_EXPORT), 0;
    cli_frame_options o;
    int rc = cli_parse_frame_options(argc, argv, USAGE_EXPORT, 0, &o);
    if (rc) return rc;
    fm_cache_reader *r;
    float *verts;
    uint32_t frame;
    if ((rc = cli_load_frame(&o, &r, &verts, &frame))) return rc;
    fm_error err = {0};
    if (fm_export_tets(verts, fm_cache_agents(r), o.out, &err) != FM_OK) rc = cli_report(&err);
    else printf("frame %u of %s -> %s\n", frame, o.cache, o.out);
    free(verts);
    fm_cache_close(r);
    return rc;
}

