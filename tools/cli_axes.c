/* --up, --scale and --preset: the axes and units of the files flockmorph writes for other tools
 * (docs/export.md#axes). `export` and `run` parse and apply them here alike, so that a file either
 * writes stands where the other's would. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "export.h"
#include "geom.h"

#include <math.h>
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

json_t *cli_axes_json(const cli_axes_options *o)
{
    const cli_axes a = cli_axes_chosen(o);
    return json_pack("{s:s, s:f, s:o}", "up", a.up_y ? "y" : "z", "scale", a.scale, "preset",
                     o->preset ? json_string(o->preset->name) : json_null());
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

/* ---------------------------------------------------------------- a file's own convention */

#define AXES_PREFIX "flockmorph axes: "

void cli_axes_comment(const cli_axes *a, char *out, size_t size)
{
    char scale[32];
    for (int digits = 15; digits <= 17; digits++) { /* the fewest digits that read back exactly */
        snprintf(scale, sizeof scale, "%.*g", digits, a->scale);
        if (strtod(scale, NULL) == a->scale) break;
    }
    snprintf(out, size, AXES_PREFIX "up %s, scale %s", a->up_y ? "y" : "z", scale);
}

/* "up y, scale 2.5" (after the prefix, up to the line's end): 0 and *a, or -1. */
static int parse_axes_text(const char *text, cli_axes *a)
{
    char up, rest[8];
    double scale;
    if (sscanf(text, "up %c, scale %lf%7s", &up, &scale, rest) != 2 || (up != 'y' && up != 'z') ||
        !(scale >= 1e-6 && scale <= 1e6))
        return -1;
    a->up_y = up == 'y', a->scale = scale;
    return 0;
}

/* The header's text lines: a PLY's comments up to end_header, an OBJ's leading # lines. */
static const char *header_comment(const char *line, int ply)
{
    if (ply) return strncmp(line, "comment ", 8) ? NULL : line + 8;
    return line[0] == '#' ? line + 1 + (line[1] == ' ') : NULL;
}

int cli_axes_of_file(const char *path, cli_axes *a, char *line, size_t size)
{
    FILE *f = fopen(path, "rb");
    int found = 0, ply = 0;
    for (int n = 0; f && !found && n < 4096 && fgets(line, (int)size, f); n++) {
        line[strcspn(line, "\r\n")] = 0;
        if (n == 0 && (ply = !strcmp(line, "ply"))) continue;
        if (ply ? !strcmp(line, "end_header") : line[0] != '#') break;
        const char *text = header_comment(line, ply);
        if (text && !strncmp(text, AXES_PREFIX, sizeof AXES_PREFIX - 1))
            found = parse_axes_text(text + sizeof AXES_PREFIX - 1, a) ? -1 : 1;
    }
    if (f) fclose(f);
    return found;
}

/* The float c nearest to w / scale. For the vertex v that was written, |scale c - w| <= |scale v - w|
 * <= half an ulp of w, so the same scale sends c to w again: c is v wherever no other float lands on
 * w (any power of two), and otherwise a float that every export with that scale writes as v. A tie,
 * or w / scale rounded twice (to double, to float), could still move c by one float: the neighbours
 * are tried then. */
static float unscaled(float w, double scale)
{
    float c = (float)(w / scale), below = nextafterf(c, -INFINITY), above = nextafterf(c, INFINITY);
    if ((float)(scale * c) == w) return c;
    if ((float)(scale * below) == w) return below;
    return (float)(scale * above) == w ? above : c;
}

void cli_axes_mesh_from(const cli_axes *a, fm_mesh *m)
{
    for (int64_t i = 0; i < m->nv; i++) {
        double *v = m->v + 3 * i;
        float p[3];
        for (int k = 0; k < 3; k++) p[k] = a->scale == 1.0 ? (float)v[k] : unscaled((float)v[k], a->scale);
        if (a->up_y) { /* (x, z, -y) back to (x, y, z): exact */
            float y = -p[2];
            p[2] = p[1], p[1] = y;
        }
        for (int k = 0; k < 3; k++) v[k] = p[k];
    }
}
