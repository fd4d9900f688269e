/* The preview renderer's colours (docs/render.md, "Colour"): the gradient over agent index, the
 * viridis colormap of per-agent values, the phase palette, and each drawing's per-agent colours in
 * linear light, computed once per frame on one thread (so they cannot depend on the thread count). */
#include "render.h"

#include <string.h>

/* The agent gradient, from agent 0 to agent n - 1: blue, teal, green, amber, coral. */
static const double fm_ramp_srgb[FM_RAMP_STOPS][3] = {
    {0.27, 0.47, 0.80}, {0.19, 0.70, 0.73}, {0.54, 0.77, 0.31}, {0.94, 0.71, 0.20}, {0.88, 0.35, 0.31}};

/* viridis (van der Walt and Smith for matplotlib 2.0, CC0): entries round(k * 255 / 32), k = 0..32,
 * of matplotlib's 256-entry table (lib/matplotlib/_cm_listed.py), sRGB. Linear interpolation in
 * sRGB between these stops stays within 1.7 / 255 of the full table. */
#define FM_VIRIDIS_STOPS 33
static const float fm_viridis_srgb[FM_VIRIDIS_STOPS][3] = {
    {0.267004f, 0.004874f, 0.329415f}, /*   0 */
    {0.277018f, 0.050344f, 0.375715f}, /*   8 */
    {0.282327f, 0.094955f, 0.417331f}, /*  16 */
    {0.282884f, 0.135920f, 0.453427f}, /*  24 */
    {0.278826f, 0.175490f, 0.483397f}, /*  32 */
    {0.270595f, 0.214069f, 0.507052f}, /*  40 */
    {0.258965f, 0.251537f, 0.524736f}, /*  48 */
    {0.244972f, 0.287675f, 0.537260f}, /*  56 */
    {0.229739f, 0.322361f, 0.545706f}, /*  64 */
    {0.214298f, 0.355619f, 0.551184f}, /*  72 */
    {0.199430f, 0.387607f, 0.554642f}, /*  80 */
    {0.185556f, 0.418570f, 0.556753f}, /*  88 */
    {0.172719f, 0.448791f, 0.557885f}, /*  96 */
    {0.160665f, 0.478540f, 0.558115f}, /* 104 */
    {0.149039f, 0.508051f, 0.557250f}, /* 112 */
    {0.137770f, 0.537492f, 0.554906f}, /* 120 */
    {0.127568f, 0.566949f, 0.550556f}, /* 128 */
    {0.121148f, 0.592739f, 0.544641f}, /* 135 */
    {0.120081f, 0.622161f, 0.534946f}, /* 143 */
    {0.130067f, 0.651384f, 0.521608f}, /* 151 */
    {0.153894f, 0.680203f, 0.504172f}, /* 159 */
    {0.191090f, 0.708366f, 0.482284f}, /* 167 */
    {0.239374f, 0.735588f, 0.455688f}, /* 175 */
    {0.296479f, 0.761561f, 0.424223f}, /* 183 */
    {0.360741f, 0.785964f, 0.387814f}, /* 191 */
    {0.430983f, 0.808473f, 0.346476f}, /* 199 */
    {0.506271f, 0.828786f, 0.300362f}, /* 207 */
    {0.585678f, 0.846661f, 0.249897f}, /* 215 */
    {0.668054f, 0.861999f, 0.196293f}, /* 223 */
    {0.751884f, 0.874951f, 0.143228f}, /* 231 */
    {0.835270f, 0.886029f, 0.102646f}, /* 239 */
    {0.916242f, 0.896091f, 0.100717f}, /* 247 */
    {0.993248f, 0.906157f, 0.143936f}, /* 255 */
};

/* Okabe and Ito's colour-blind-safe palette: fm_phase 0 waiting blue, 1 flying orange, 2 homing
 * reddish purple, 3 arrived bluish green. */
#define FM_PHASES 4
static const float fm_phase_srgb[FM_PHASES][3] = {
    {0.000f, 0.447f, 0.698f}, {0.902f, 0.624f, 0.000f}, {0.800f, 0.475f, 0.655f}, {0.000f, 0.620f, 0.451f}};
/* A NaN value, a phase outside the palette, an rgb with a NaN channel. */
static const float fm_unknown_srgb[3] = {0.50f, 0.50f, 0.50f};

double fm_srgb_to_linear(double c)
{
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

void fm_render_colormap(double u, float srgb[3])
{
    if (isnan(u)) {
        memcpy(srgb, fm_unknown_srgb, sizeof fm_unknown_srgb);
        return;
    }
    double x = fmin(fmax(u, 0.0), 1.0) * (FM_VIRIDIS_STOPS - 1);
    int i = (int)x;
    if (i > FM_VIRIDIS_STOPS - 2) i = FM_VIRIDIS_STOPS - 2;
    float f = (float)(x - i);
    const float *a = fm_viridis_srgb[i], *b = fm_viridis_srgb[i + 1];
    for (int k = 0; k < 3; k++) srgb[k] = a[k] + f * (b[k] - a[k]);
}

void fm_render_phase_colour(unsigned phase, float srgb[3])
{
    memcpy(srgb, phase < FM_PHASES ? fm_phase_srgb[phase] : fm_unknown_srgb, 3 * sizeof(float));
}

static void linear3(const float srgb[3], float out[3])
{
    for (int k = 0; k < 3; k++) out[k] = (float)fm_srgb_to_linear(srgb[k]);
}

void fm_colour_tables_init(fm_colour_tables *t)
{
    for (int i = 0; i < FM_RAMP_STOPS; i++)
        for (int k = 0; k < 3; k++) t->ramp[i][k] = (float)fm_srgb_to_linear(fm_ramp_srgb[i][k]);
    for (int j = 0; j < FM_MAP_LUT; j++) {
        float srgb[3];
        fm_render_colormap((double)j / (FM_MAP_LUT - 1), srgb);
        linear3(srgb, t->map[j]);
    }
    linear3(fm_unknown_srgb, t->unknown);
}

fm_status fm_check_colours(const fm_render_colours *c, size_t n, fm_error *err)
{
    if (!c || c->mode == FM_COLOUR_INDEX) return FM_OK;
    if (c->mode == FM_COLOUR_VALUE) {
        if (n > 0 && !c->values) return fm_fail(err, FM_ERR_USAGE, "render: colour by value, but no values given");
        if (!(isfinite(c->lo) && isfinite(c->hi) && c->lo < c->hi))
            return fm_fail(err, FM_ERR_USAGE, "render: the colour range %g .. %g is not finite with lo < hi",
                           c->lo, c->hi);
        return FM_OK;
    }
    if (c->mode == FM_COLOUR_RGB)
        return n > 0 && !c->rgb ? fm_fail(err, FM_ERR_USAGE, "render: colour by rgb, but no colours given")
                                : FM_OK;
    return fm_fail(err, FM_ERR_USAGE, "render: unknown colour mode %d", (int)c->mode);
}

/* Agent `agent` of n: its place on the gradient, interpolated in linear light. */
static void index_colour(const fm_colour_tables *t, size_t agent, size_t n, float out[3])
{
    double u = n > 1 ? (double)agent / (double)(n - 1) * (FM_RAMP_STOPS - 1) : 0.0;
    int i = (int)u;
    if (i >= FM_RAMP_STOPS - 1) i = FM_RAMP_STOPS - 2;
    float f = (float)(u - i);
    for (int k = 0; k < 3; k++) out[k] = t->ramp[i][k] + f * (t->ramp[i + 1][k] - t->ramp[i][k]);
}

/* A value on the colormap: the nearest of FM_MAP_LUT entries (u within 1 / (2 (FM_MAP_LUT - 1))). */
static void value_colour(const fm_colour_tables *t, float value, double lo, double hi, float out[3])
{
    if (isnan(value)) {
        memcpy(out, t->unknown, sizeof t->unknown);
        return;
    }
    double u = fmin(fmax((value - lo) / (hi - lo), 0.0), 1.0);
    memcpy(out, t->map[(int)(u * (FM_MAP_LUT - 1) + 0.5)], 3 * sizeof(float));
}

static void rgb_colour(const fm_colour_tables *t, const float srgb[3], float out[3])
{
    if (isnan(srgb[0]) || isnan(srgb[1]) || isnan(srgb[2])) {
        memcpy(out, t->unknown, sizeof t->unknown);
        return;
    }
    for (int k = 0; k < 3; k++) out[k] = (float)fm_srgb_to_linear(fmin(fmax(srgb[k], 0.0f), 1.0f));
}

void fm_agent_colours(const fm_colour_tables *t, const fm_render_colours *c, size_t n, float *out)
{
    fm_render_colour_mode mode = c ? c->mode : FM_COLOUR_INDEX;
    for (size_t i = 0; i < n; i++) {
        if (mode == FM_COLOUR_VALUE) value_colour(t, c->values[i], c->lo, c->hi, out + 3 * i);
        else if (mode == FM_COLOUR_RGB) rgb_colour(t, c->rgb + 3 * i, out + 3 * i);
        else index_colour(t, i, n, out + 3 * i);
    }
}
