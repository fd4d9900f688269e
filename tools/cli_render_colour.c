/* flockmorph render's colouring (docs/render.md, "Colour"): by speed on the viridis map, with one
 * scale for every frame of a render call; by phase; or by agent id, the library's gradient. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "cli_colour.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The scale's upper end is this percentile of the speeds in at most SCALE_FRAMES frames, and of
 * at most SCALE_VALUES speeds in all (fewer frames for a large flock). */
#define SCALE_PERCENTILE 0.99
#define SCALE_FRAMES 64
#define SCALE_VALUES (1u << 24)

/* ---------------------------------------------------------------- options */

/* "LO:HI" with LO < HI; -1 if it is not that. */
static int parse_range(const char *spec, double *lo, double *hi)
{
    const char *colon = strchr(spec, ':');
    char first[64];
    if (!colon || (size_t)(colon - spec) >= sizeof first) return -1;
    memcpy(first, spec, (size_t)(colon - spec));
    first[colon - spec] = 0;
    if (cli_parse_number(first, lo) || cli_parse_number(colon + 1, hi)) return -1;
    return *lo < *hi ? 0 : -1;
}

int cli_colour_parse(const char *mode, const char *range, const char *usage, cli_colour_options *o)
{
    memset(o, 0, sizeof *o);
    if (!mode || !strcmp(mode, "speed")) o->mode = CLI_COLOUR_SPEED;
    else if (!strcmp(mode, "phase")) o->mode = CLI_COLOUR_PHASE;
    else if (!strcmp(mode, "id")) o->mode = CLI_COLOUR_ID;
    else return cli_usage_error(usage, "--color is speed, phase or id, not '%s'", mode);
    if (!range) return 0;
    if (o->mode != CLI_COLOUR_SPEED)
        return cli_usage_error(usage, "--color-range %s sets the scale of --color speed; phase and id have none", range);
    if (parse_range(range, &o->lo, &o->hi))
        return cli_usage_error(usage, "--color-range wants LO:HI, two numbers with LO < HI (units/s), not '%s'", range);
    o->fixed_range = 1;
    return 0;
}

/* ---------------------------------------------------------------- the cache's values */

int cli_colour_open(cli_colouring *c, const cli_colour_options *o, fm_cache_reader *r, const char *path, int points)
{
    memset(c, 0, sizeof *c);
    c->o = *o, c->r = r, c->path = path, c->points = points;
    c->n = fm_cache_agents(r);
    c->velocity = fm_cache_has_attr(r, FM_ATTR_VELOCITY);
    if (o->mode == CLI_COLOUR_PHASE && !fm_cache_has_attr(r, FM_ATTR_PHASE)) {
        fprintf(stderr, "flockmorph: error: --color phase: %s has no phase attribute (flockmorph inspect lists its "
                "attributes); use --color speed or --color id\n", path);
        return FM_ERR_USAGE;
    }
    size_t n = c->n ? c->n : 1;
    c->value = malloc(sizeof(float) * 3 * n);
    c->scratch = malloc(sizeof(float) * (points || c->velocity ? 3 : 12) * n);
    c->here = malloc(sizeof(double) * 3 * n);
    c->there = malloc(sizeof(double) * 3 * n);
    c->phase = malloc(n);
    if (!c->value || !c->scratch || !c->here || !c->there || !c->phase) {
        fprintf(stderr, "flockmorph: error: out of memory for the colours of %zu agents\n", c->n);
        return FM_ERR_MEMORY;
    }
    return 0;
}

void cli_colour_free(cli_colouring *c)
{
    free(c->value), free(c->scratch), free(c->here), free(c->there), free(c->phase);
    memset(c, 0, sizeof *c);
}

static int read_attr(cli_colouring *c, uint32_t frame, fm_cache_attr attr, void *out)
{
    fm_error err = {0};
    fm_status st = attr == FM_ATTR_TET_VERTICES ? fm_cache_read_frame(c->r, frame, out, &err)
                                                : fm_cache_read_attr(c->r, frame, attr, out, &err);
    return st == FM_OK ? 0 : cli_report(&err);
}

/* Each agent's centre in one frame: its position, or its tet's centroid. */
static int read_centres(cli_colouring *c, uint32_t frame, double *centre)
{
    int rc = read_attr(c, frame, c->points ? FM_ATTR_POSITION : FM_ATTR_TET_VERTICES, c->scratch);
    if (rc) return rc;
    for (size_t i = 0; i < c->n; i++)
        for (int k = 0; k < 3; k++) {
            if (c->points) {
                centre[3 * i + k] = c->scratch[3 * i + k];
                continue;
            }
            const float *t = c->scratch + 12 * i;
            centre[3 * i + k] = 0.25 * ((double)t[k] + t[3 + k] + t[6 + k] + t[9 + k]);
        }
    return 0;
}

static double norm3(double x, double y, double z)
{
    return sqrt(x * x + y * y + z * z);
}

/* Speeds from the velocity attribute. */
static int velocity_speeds(cli_colouring *c, uint32_t frame, float *speed)
{
    int rc = read_attr(c, frame, FM_ATTR_VELOCITY, c->scratch);
    for (size_t i = 0; i < c->n && !rc; i++) {
        const float *v = c->scratch + 3 * i;
        speed[i] = (float)norm3(v[0], v[1], v[2]);
    }
    return rc;
}

/* Speeds from the centres' displacement between the previous frame and this one (frame 0: this one
 * and the next) times the frame rate; 0 in a cache of one frame. */
static int displacement_speeds(cli_colouring *c, uint32_t frame, float *speed)
{
    if (fm_cache_frames(c->r) < 2) {
        for (size_t i = 0; i < c->n; i++) speed[i] = 0.0f;
        return 0;
    }
    uint32_t other = frame > 0 ? frame - 1 : frame + 1;
    int rc = read_centres(c, other, c->there); /* the earlier frame first: the reader decodes forwards */
    if (!rc) rc = read_centres(c, frame, c->here);
    double rate = fm_cache_frame_rate(c->r);
    for (size_t i = 0; i < c->n && !rc; i++) {
        const double *a = c->here + 3 * i, *b = c->there + 3 * i;
        speed[i] = (float)(norm3(a[0] - b[0], a[1] - b[1], a[2] - b[2]) * rate);
    }
    return rc;
}

static int frame_speeds(cli_colouring *c, uint32_t frame, float *speed)
{
    return c->velocity ? velocity_speeds(c, frame, speed) : displacement_speeds(c, frame, speed);
}

/* ---------------------------------------------------------------- the scale */

static void swap_float(float *a, float *b)
{
    float t = *a;
    *a = *b, *b = t;
}

/* The k-th smallest of v[0 .. m - 1] (0-based; v is reordered): Wirth's selection. */
static float select_kth(float *v, size_t m, size_t k)
{
    int64_t lo = 0, hi = (int64_t)m - 1, kk = (int64_t)k;
    while (lo < hi) {
        float pivot = v[kk];
        int64_t i = lo, j = hi;
        do {
            while (v[i] < pivot) i++;
            while (pivot < v[j]) j--;
            if (i <= j) swap_float(v + i++, v + j--);
        } while (i <= j);
        if (j < kk) lo = i;
        if (kk < i) hi = j;
    }
    return v[kk];
}

/* The frames the scale is taken from: all of first, first + step, ... last, or `want` of them
 * spread evenly (the first and the last among them). */
static uint32_t scale_frame(uint32_t first, uint32_t step, uint32_t count, uint32_t want, uint32_t k)
{
    uint64_t i = want > 1 ? (uint64_t)k * (count - 1) / (want - 1) : 0;
    return first + (uint32_t)i * step;
}

/* The SCALE_PERCENTILE speed (nearest rank) of the finite speeds in `want` of the `count` frames;
 * 0 if there is none. */
static int speed_percentile(cli_colouring *c, uint32_t first, uint32_t step, uint32_t count, uint32_t want,
                            double *p)
{
    float *all = malloc(sizeof(float) * (size_t)want * (c->n ? c->n : 1));
    if (!all) return fprintf(stderr, "flockmorph: error: out of memory for the speed scale\n"), FM_ERR_MEMORY;
    size_t m = 0;
    int rc = 0;
    for (uint32_t k = 0; k < want && !rc; k++) {
        rc = frame_speeds(c, scale_frame(first, step, count, want, k), c->value);
        for (size_t i = 0; i < c->n && !rc; i++)
            if (isfinite(c->value[i])) all[m++] = c->value[i];
    }
    *p = 0.0;
    if (!rc && m > 0) *p = select_kth(all, m, (size_t)ceil(SCALE_PERCENTILE * (double)m) - 1);
    free(all);
    return rc;
}

static void print_speed_scale(const cli_colouring *c, const char *rule)
{
    char how[96];
    if (c->velocity) snprintf(how, sizeof how, "|velocity|");
    else snprintf(how, sizeof how, "the %s's displacement from frame to frame x %g fps", c->points ? "point" : "tet centroid",
                  fm_cache_frame_rate(c->r));
    fprintf(stderr, "render: colour by speed (%s, units/s) from %.4g (dark violet) to %.4g (yellow), %s\n", how, c->o.lo,
            c->o.hi, rule);
}

int cli_colour_fix_scale(cli_colouring *c, uint32_t first, uint32_t last, uint32_t step)
{
    if (c->o.mode == CLI_COLOUR_PHASE) {
        fprintf(stderr, "render: colour by phase: 0 waiting blue, 1 flying orange, 2 homing purple, 3 arrived green\n");
        return 0;
    }
    if (c->o.mode == CLI_COLOUR_ID) {
        fprintf(stderr, "render: colour by agent id: from blue (the first) through teal, green and amber to coral\n");
        return 0;
    }
    if (c->o.fixed_range) return print_speed_scale(c, "as --color-range sets it"), 0;
    uint32_t count = (last - first) / step + 1, want = count < SCALE_FRAMES ? count : SCALE_FRAMES;
    uint64_t most = c->n > 0 ? SCALE_VALUES / c->n : SCALE_FRAMES;
    if (want > most) want = most > 0 ? (uint32_t)most : 1;
    double p;
    int rc = speed_percentile(c, first, step, count, want, &p);
    if (rc) return rc;
    c->o.lo = 0.0, c->o.hi = p > 0.0 ? p : 1.0;
    char rule[192];
    const char *fix = "; --color-range LO:HI sets it";
    if (!(p > 0.0)) snprintf(rule, sizeof rule, "since no agent moves in the %u frames looked at%s", want, fix);
    else if (count == 1) snprintf(rule, sizeof rule, "0 to the 99th percentile of frame %u's speeds%s", first, fix);
    else if (want == count) snprintf(rule, sizeof rule, "0 to the 99th percentile of the speeds in the %u frames rendered%s", count, fix);
    else snprintf(rule, sizeof rule, "0 to the 99th percentile of the speeds in %u of the %u frames rendered, evenly spread%s",
                  want, count, fix);
    print_speed_scale(c, rule);
    return 0;
}

/* ---------------------------------------------------------------- one frame */

static int phase_colours(cli_colouring *c, uint32_t frame)
{
    int rc = read_attr(c, frame, FM_ATTR_PHASE, c->phase);
    for (size_t i = 0; i < c->n && !rc; i++) fm_render_phase_colour(c->phase[i], c->value + 3 * i);
    return rc;
}

int cli_colour_frame(cli_colouring *c, uint32_t frame, fm_render_colours *out)
{
    memset(out, 0, sizeof *out);
    if (c->o.mode == CLI_COLOUR_ID) return out->mode = FM_COLOUR_INDEX, 0;
    if (c->o.mode == CLI_COLOUR_PHASE) {
        out->mode = FM_COLOUR_RGB, out->rgb = c->value;
        return phase_colours(c, frame);
    }
    out->mode = FM_COLOUR_VALUE, out->values = c->value, out->lo = c->o.lo, out->hi = c->o.hi;
    return frame_speeds(c, frame, c->value);
}
