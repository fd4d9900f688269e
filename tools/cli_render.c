/* flockmorph render: one frame of a cache to a PNG preview. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const USAGE_RENDER =
    "usage: flockmorph render CACHE -o FILE.png [--frame K] [--size WxH] [--view front|top|side]\n"
    "\n"
    "Renders frame K (default: the last; negative counts from the end) with an orthographic\n"
    "camera fitted to the whole animation's bounds (front looks along +Y, top along -Z, side\n"
    "along -X; default front, 960x540).\n";


/* Bounds of every frame of the cache, so a sequence of renders shares one camera. */
static int animation_bounds(fm_cache_reader *r, double b[6])
{
    size_t n = fm_cache_agents(r);
    float *v = malloc(sizeof(float) * 12 * (n ? n : 1));
    fm_error err = {0};
    if (!v) return -1;
    for (int k = 0; k < 3; k++) b[k] = 1e300, b[3 + k] = -1e300;
    for (uint32_t f = 0; f < fm_cache_frames(r); f++) {
        if (fm_cache_read_frame(r, f, v, &err) != FM_OK) return free(v), cli_report(&err);
        for (size_t i = 0; i < 4 * n; i++)
            for (int k = 0; k < 3; k++) {
                double x = v[3 * i + k];
                if (x < b[k]) b[k] = x;
                if (x > b[3 + k]) b[3 + k] = x;
            }
    }
    free(v);
    return 0;
}

static int set_view(const char *view, fm_render_opts *ro)
{
    static const struct { const char *name; double dir[3], up[3]; } views[] = {
        {"front", {0, 1, 0}, {0, 0, 1}}, {"top", {0, 0, -1}, {0, 1, 0}}, {"side", {-1, 0, 0}, {0, 0, 1}}};
    for (size_t i = 0; i < sizeof views / sizeof views[0]; i++)
        if (!strcmp(view, views[i].name)) {
            memcpy(ro->view_dir, views[i].dir, sizeof ro->view_dir);
            memcpy(ro->up, views[i].up, sizeof ro->up);
            return 0;
        }
    return -1;
}

int cli_render(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_RENDER), 0;
    cli_frame_options o;
    int rc = cli_parse_frame_options(argc, argv, USAGE_RENDER, 0, &o);
    if (rc) return rc;
    fm_render_opts ro = fm_default_render_opts();
    if (set_view(o.view, &ro)) return cli_usage_error(USAGE_RENDER, "--view is front, top or side, not '%s'", o.view);
    ro.width = o.width, ro.height = o.height;
    fm_cache_reader *r;
    float *verts;
    uint32_t frame;
    if ((rc = cli_load_frame(&o, &r, &verts, &frame))) return rc;
    double bounds[6];
    fm_error err = {0};
    if ((rc = animation_bounds(r, bounds)) == 0) {
        ro.bounds = bounds;
        if (fm_render_tets_png(verts, fm_cache_agents(r), &ro, o.out, &err) != FM_OK) rc = cli_report(&err);
        else printf("frame %u of %s -> %s\n", frame, o.cache, o.out);
    }
    free(verts);
    fm_cache_close(r);
    return rc;
}

