/* `flockmorph render --color` (tools/cli_render_colour.c, docs/render.md "Colour") on tiny caches
 * written through the public writer, with two agents side by side, A on the left and B on the
 * right, seen from the front without the ground: the faster agent takes the map's upper end, one
 * scale holds for every frame of a call, --color-range clamps, a tet cache's speed is its
 * centroid's displacement times the frame rate, and --color phase uses the palette. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#ifndef FM_TEST_TMP
#error "FM_TEST_TMP must name a scratch directory"
#endif

#define SIZE "--size 160x96 --view front --no-ground"

/* ---------------------------------------------------------------- images and the CLI */

typedef struct image {
    int width, height;
    unsigned char *rgb;
} image;

static image read_png(const char *path)
{
    image im = {0, 0, NULL};
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path)) return im;
    img.format = PNG_FORMAT_RGB;
    im.rgb = malloc(PNG_IMAGE_SIZE(img));
    if (!im.rgb || !png_image_finish_read(&img, NULL, im.rgb, 0, NULL)) {
        png_image_free(&img);
        free(im.rgb);
        im.rgb = NULL;
        return im;
    }
    im.width = (int)img.width, im.height = (int)img.height;
    return im;
}

static char *tmp_path(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s/colour_%s", FM_TEST_TMP, name);
    return buf;
}

static char g_err[1 << 14]; /* the last command's stderr */

/* Runs `flockmorph ARGS`; its exit status (-1 if it did not exit normally). */
static int cli(const char *args)
{
    char err_path[512], cmd[4096];
    tmp_path(err_path, sizeof err_path, "stderr.txt");
    snprintf(cmd, sizeof cmd, "'%s' %s >/dev/null 2>'%s'", FM_CLI, args, err_path);
    int status = system(cmd);
    g_err[0] = 0;
    FILE *f = fopen(err_path, "rb");
    if (f) g_err[fread(g_err, 1, sizeof g_err - 1, f)] = 0, fclose(f);
    return status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* `render CACHE -o OUT OPTS` into an image (rgb NULL if it failed). */
static image render(const char *cache, const char *opts)
{
    char out[512], args[2048];
    tmp_path(out, sizeof out, "out.png");
    remove(out);
    snprintf(args, sizeof args, "render '%s' -o '%s' " SIZE " %s", cache, out, opts);
    int rc = cli(args);
    ENSURE_MSG(rc == 0, "render %s: exit %d: %s", opts, rc, g_err);
    image im = rc == 0 ? read_png(out) : (image){0, 0, NULL};
    ENSURE_MSG(rc != 0 || im.rgb, "cannot read %s", out);
    return im;
}

static const unsigned char *pixel(const image *im, int x, int y)
{
    return im->rgb + 3 * ((size_t)y * (size_t)im->width + (size_t)x);
}

/* 1 if the left (side 0) or right (side 1) halves of a and b are the same bytes. */
static int same_half(const image *a, const image *b, int side)
{
    if (!a->rgb || !b->rgb || a->width != b->width || a->height != b->height) return 0;
    int half = a->width / 2;
    for (int y = 0; y < a->height; y++)
        if (memcmp(pixel(a, side * half, y), pixel(b, side * half, y), 3 * (size_t)half)) return 0;
    return 1;
}

typedef enum hue { YELLOW, VIOLET, ORANGE, GREEN } hue;

static int has_hue(const unsigned char *p, hue h)
{
    switch (h) {
    case YELLOW: return p[0] > p[2] + 40 && p[1] > p[2] + 40;      /* viridis' upper end */
    case VIOLET: return p[2] > p[1] + 20 && p[0] > p[1];           /* its lower end */
    case ORANGE: return p[0] > p[2] + 60 && p[0] > p[1] + 20;      /* phase 1 */
    case GREEN: return p[1] > p[0] + 60 && p[1] > p[2] + 10;       /* phase 3 */
    }
    return 0;
}

/* Every foreground pixel (not the top-left corner's background) of one half has hue h; there are
 * enough of them. */
static void ensure_half_hue(const image *im, int side, hue h, const char *what)
{
    if (!im->rgb) return;
    long count = 0, wrong = 0;
    int half = im->width / 2;
    for (int y = 0; y < im->height; y++)
        for (int x = side * half; x < (side + 1) * half; x++) {
            const unsigned char *p = pixel(im, x, y);
            if (!memcmp(p, im->rgb, 3)) continue;
            count++, wrong += !has_hue(p, h);
        }
    ENSURE_MSG(count > 200 && wrong == 0, "%s: %ld pixels, %ld not of the expected hue", what, count, wrong);
}

/* ---------------------------------------------------------------- caches */

#define RATE 24.0

/* Two points, A at x = -1 and B at x = +1, standing still, with the velocities speed[f][agent]
 * (along +Z) in frames f = 0, 1, 2. */
static int write_points(const char *path, const float speed[3][2])
{
    const fm_cache_attr attrs[2] = {FM_ATTR_POSITION, FM_ATTR_VELOCITY};
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create_attrs(path, 2, RATE, attrs, 2, NULL, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return -1;
    const float pos[6] = {-1, 0, 0, 1, 0, 0};
    for (int f = 0; f < 3; f++) {
        const float vel[6] = {0, 0, speed[f][0], 0, 0, speed[f][1]};
        const void *data[2] = {pos, vel};
        ENSURE(fm_cache_writer_add_frame_attrs(w, data, &err) == FM_OK);
    }
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    return 0;
}

/* A regular-ish tet of edge about 0.8 centred at (x, 0, 0). */
static void tet_at(float *t, double x)
{
    const double v[4][3] = {{-0.4, -0.25, -0.3}, {0.4, -0.25, -0.3}, {0.0, -0.25, 0.4}, {0.0, 0.4, 0.0}};
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++) t[3 * i + k] = (float)(v[i][k] + (k == 0 ? x : 0.0));
}

/* Tets A (moving right by xa[f]) and B (still at x = 2) over 3 frames, with the phases 1 and 3 when
 * `phase`. */
static int write_tets(const char *path, const double xa[3], int phase)
{
    const fm_cache_attr attrs[2] = {FM_ATTR_TET_VERTICES, FM_ATTR_PHASE};
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create_attrs(path, 2, RATE, attrs, phase ? 2 : 1, NULL, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return -1;
    const uint8_t phases[2] = {FM_PHASE_FLYING, FM_PHASE_ARRIVED};
    for (int f = 0; f < 3; f++) {
        float tets[24];
        tet_at(tets, xa[f]), tet_at(tets + 12, 2.0);
        const void *data[2] = {tets, phases};
        ENSURE(fm_cache_writer_add_frame_attrs(w, data, &err) == FM_OK);
    }
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    return 0;
}

/* ---------------------------------------------------------------- tests */

/* Default scale (0 to the 99th percentile over the frames rendered, here 10): in frame 0 the faster
 * agent B (10) is yellow; in frame 2, where B slows to 1, it is violet. A flies at 5 in both, and
 * its pixels are the same bytes in both frames of one call, though frame 2 alone would scale to
 * its own maximum, 5, and draw A differently. */
static void test_speed_scale_is_one_for_the_call(void)
{
    char cache[512], pattern[512], args[2048], f0[600], f2[600];
    const float speed[3][2] = {{5, 10}, {5, 10}, {5, 1}};
    tmp_path(cache, sizeof cache, "points.fmc");
    if (write_points(cache, speed)) return;
    tmp_path(pattern, sizeof pattern, "seq.%d.png");
    snprintf(args, sizeof args, "render '%s' -o '%s' --frames 0:2 " SIZE, cache, pattern);
    int rc = cli(args);
    ENSURE_MSG(rc == 0, "exit %d: %s", rc, g_err);
    ENSURE_MSG(strstr(g_err, "colour by speed (|velocity|, units/s) from 0 (dark violet) to 10 (yellow), 0 to the "
                      "99th percentile of the speeds in the 3 frames rendered"), "%s", g_err);
    tmp_path(f0, sizeof f0, "seq.0.png"), tmp_path(f2, sizeof f2, "seq.2.png");
    image a = read_png(f0), b = read_png(f2), alone = render(cache, "--frame 2");
    ENSURE(a.rgb && b.rgb);
    ensure_half_hue(&a, 1, YELLOW, "frame 0, B at 10 of 0..10");
    ensure_half_hue(&b, 1, VIOLET, "frame 2, B at 1 of 0..10");
    ENSURE_MSG(same_half(&a, &b, 0), "A flies at 5 in frames 0 and 2 but has two colours in one call");
    ENSURE_MSG(!same_half(&a, &b, 1), "B's colour did not change with its speed");
    ensure_half_hue(&alone, 0, YELLOW, "frame 2 alone, A at 5 of 0..5");
    ENSURE_MSG(!same_half(&alone, &b, 0), "frame 2 alone has the scale of frames 0..2");
    free(a.rgb), free(b.rgb), free(alone.rgb);
}

/* --color-range clamps: with 0:4 both agents (5 and 10) are drawn as a speed of 4, A the same bytes
 * as with 0:5 (A exactly at the top); with 20:30 both are at the bottom, A as with 5:30. */
static void test_color_range_clamps(void)
{
    char cache[512];
    tmp_path(cache, sizeof cache, "points.fmc");
    image low = render(cache, "--frame 0 --color-range 0:4"), top = render(cache, "--frame 0 --color-range 0:5");
    image high = render(cache, "--frame 0 --color-range 20:30"), bottom = render(cache, "--frame 0 --color-range 5:30");
    image mid = render(cache, "--frame 0 --color-range 0:10");
    ENSURE_MSG(strstr(g_err, "from 0 (dark violet) to 10 (yellow), as --color-range sets it"), "%s", g_err);
    ensure_half_hue(&low, 0, YELLOW, "A at 5 of 0..4");
    ensure_half_hue(&low, 1, YELLOW, "B at 10 of 0..4");
    ensure_half_hue(&high, 0, VIOLET, "A at 5 of 20..30");
    ensure_half_hue(&high, 1, VIOLET, "B at 10 of 20..30");
    ENSURE_MSG(same_half(&low, &top, 0), "A above the range is not drawn as the range's top");
    ENSURE_MSG(same_half(&high, &bottom, 0), "A below the range is not drawn as the range's bottom");
    ENSURE_MSG(!same_half(&mid, &top, 0) && !same_half(&mid, &bottom, 0), "A at 5 of 0..10 is at an end");
    free(low.rgb), free(top.rgb), free(high.rgb), free(bottom.rgb), free(mid.rgb);
}

/* A's pixels drawn with --color-range lo:hi are those of a speed clamped to the top (above) or to
 * the bottom (below) of the range. */
static void ensure_speed_between(const char *cache, int frame, double below, double above)
{
    char opts[4][160];
    snprintf(opts[0], sizeof opts[0], "--frame %d --color-range 0:%g", frame, below);
    snprintf(opts[1], sizeof opts[1], "--frame %d --color-range 0:%g", frame, below / 4);
    snprintf(opts[2], sizeof opts[2], "--frame %d --color-range %g:%g", frame, above, 4 * above);
    snprintf(opts[3], sizeof opts[3], "--frame %d --color-range %g:%g", frame, 2 * above, 4 * above);
    image im[4];
    for (int i = 0; i < 4; i++) im[i] = render(cache, opts[i]);
    ENSURE_MSG(same_half(&im[0], &im[1], 0), "frame %d: A is slower than %g", frame, below);
    ENSURE_MSG(same_half(&im[2], &im[3], 0), "frame %d: A is faster than %g", frame, above);
    ENSURE_MSG(!same_half(&im[0], &im[2], 0), "frame %d: the top and bottom look alike", frame);
    for (int i = 0; i < 4; i++) free(im[i].rgb);
}

/* A tet cache has no velocity: A's speed is its centroid's displacement times 24 fps, from the
 * previous frame (frame 0: to the next). A moves 0.1 then 0.3: 2.4 units/s in frames 0 and 1,
 * 7.2 in frame 2. */
static void test_tet_speed_from_centroids(void)
{
    char cache[512];
    const double xa[3] = {-2.0, -1.9, -1.6};
    tmp_path(cache, sizeof cache, "tets.fmc");
    if (write_tets(cache, xa, 0)) return;
    ensure_speed_between(cache, 0, 2.39, 2.41);
    ensure_speed_between(cache, 1, 2.39, 2.41);
    ensure_speed_between(cache, 2, 7.19, 7.21);
    image im = render(cache, "--frame 2");
    ENSURE_MSG(strstr(g_err, "tet centroid's displacement from frame to frame x 24 fps") &&
                   strstr(g_err, "to 7.2 (yellow), 0 to the 99th percentile of frame 2's speeds"), "%s", g_err);
    ensure_half_hue(&im, 0, YELLOW, "A, the fastest");
    ensure_half_hue(&im, 1, VIOLET, "B, standing still");
    free(im.rgb);
}

/* --color phase: A flying (orange), B arrived (green); id: the old gradient, blue to coral. */
static void test_phase_and_id(void)
{
    char cache[512];
    const double xa[3] = {-2.0, -2.0, -2.0};
    tmp_path(cache, sizeof cache, "phases.fmc");
    if (write_tets(cache, xa, 1)) return;
    image im = render(cache, "--color phase");
    ENSURE_MSG(strstr(g_err, "colour by phase: 0 waiting blue, 1 flying orange, 2 homing purple, 3 arrived green"),
               "%s", g_err);
    ensure_half_hue(&im, 0, ORANGE, "A, flying");
    ensure_half_hue(&im, 1, GREEN, "B, arrived");
    free(im.rgb);
    image id = render(cache, "--color id");
    ENSURE_MSG(strstr(g_err, "colour by agent id"), "%s", g_err);
    long blue = 0, coral = 0;
    for (int y = 0; id.rgb && y < id.height; y++)
        for (int x = 0; x < id.width; x++) {
            const unsigned char *p = pixel(&id, x, y);
            if (!memcmp(p, id.rgb, 3)) continue;
            if (x < id.width / 2) blue += p[2] > p[0] + 20;
            else coral += p[0] > p[2] + 20;
        }
    ENSURE_MSG(blue > 200 && coral > 200, "--color id: %ld blue pixels on the left, %ld coral on the right", blue,
               coral);
    free(id.rgb);
}

int main(void)
{
    RUN_TEST(test_speed_scale_is_one_for_the_call);
    RUN_TEST(test_color_range_clamps);
    RUN_TEST(test_tet_speed_from_centroids);
    RUN_TEST(test_phase_and_id);
    return test_result();
}
