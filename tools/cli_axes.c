/* --up, --scale and --preset: the axes and units of the files flockmorph writes for other tools
 * (docs/export.md#axes). `export` and `run` parse and apply them here alike, so that a file either
 * writes stands where the other's would. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "export.h"
#include "geom.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* What each preset stands for (docs/export.md#presets). */
static const cli_preset PRESETS[] = {{"houdini", 1, 1, 1001}, {"maya", 1, 1, 1}, {"blender", 0, 0, 1}};

static const cli_preset *preset_named(const char *name)
{
    for (size_t i = 0; i < sizeof PRESETS / sizeof PRESETS[0]; i++)
        if (!strcmp(name, PRESETS[i].name)) return &PRESETS[i];
    return NULL;
}

int cli_axes_parse(const char *usage, const char *option, const char *value, cli_axes_options *o)
{
    if (!strcmp(option, "--up")) {
        if (strcmp(value, "y") && strcmp(value, "z"))
            return cli_usage_error(usage, "--up wants z (as the cache) or y (Y-up), not '%s'", value);
        o->up_y = !strcmp(value, "y"), o->has_up = 1;
    } else if (!strcmp(option, "--scale")) {
        if (cli_parse_positive(value, &o->scale) || o->scale > 1e6 || o->scale < 1e-6)
            return cli_usage_error(usage, "--scale wants a factor from 1e-6 to 1e6, not '%s'", value);
    } else if (!strcmp(option, "--preset")) {
        if (!(o->preset = preset_named(value)))
            return cli_usage_error(usage, "--preset wants houdini, maya or blender, not '%s'", value);
    } else return 1;
    return 0;
}

cli_axes cli_axes_chosen(const cli_axes_options *o)
{
    cli_axes a = {o->has_up ? o->up_y : o->preset ? o->preset->up_y : 0, o->scale > 0 ? o->scale : 1.0};
    return a;
}

void cli_axes_to(const cli_axes *a, float *xyz, size_t n)
{
    if (a->up_y) fm_export_up_y(xyz, n);
    fm_export_scale(xyz, n, a->scale);
}

int cli_axes_mesh_to(const cli_axes *a, fm_mesh *m)
{
    float *xyz = malloc(sizeof(float) * 3 * (size_t)(m->nv ? m->nv : 1));
    if (!xyz) return fprintf(stderr, "flockmorph: error: out of memory for the obstacles\n"), FM_ERR_MEMORY;
    for (int64_t i = 0; i < 3 * m->nv; i++) xyz[i] = (float)m->v[i];
    cli_axes_to(a, xyz, (size_t)m->nv);
    for (int64_t i = 0; i < 3 * m->nv; i++) m->v[i] = xyz[i];
    free(xyz);
    return 0;
}

