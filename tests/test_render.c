/* fm_render_tets_png: render small scenes, read the PNG back with libpng and check where the
 * pixels landed. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef FM_TEST_TMP
#error "FM_TEST_TMP must name a scratch directory"
#endif

/* ---------------------------------------------------------------- helpers */

typedef struct rgb_image {
    int width, height;
    unsigned char *rgb;
} rgb_image;

static const unsigned char *pixel(const rgb_image *im, int x, int y)
{
    return im->rgb + 3 * ((size_t)y * (size_t)im->width + (size_t)x);
}

/* Reads an 8-bit RGB PNG (anything else fails); 0 on success. */
static int read_png(const char *path, rgb_image *out)
{
    memset(out, 0, sizeof *out);
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path)) return 1;
    if (img.format != PNG_FORMAT_RGB) { /* 8-bit, colour, no alpha, no palette */
        png_image_free(&img);
        return 2;
    }
    out->rgb = malloc(PNG_IMAGE_SIZE(img));
    if (!out->rgb || !png_image_finish_read(&img, NULL, out->rgb, 0, NULL)) {
        png_image_free(&img);
        free(out->rgb);
        out->rgb = NULL;
        return 3;
    }
    out->width = (int)img.width;
    out->height = (int)img.height;
    return 0;
}

static int file_exists(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (f) fclose(f);
    return f != NULL;
}

static char *tmp_path(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s/%s", FM_TEST_TMP, name);
    return buf;
}

/* Renders and reads the result back; 0 on success. */
static int render_and_read(const float *verts, size_t n, const fm_render_opts *opts,
                           const char *name, rgb_image *out)
{
    char path[512], partial[600];
    tmp_path(path, sizeof path, name);
    snprintf(partial, sizeof partial, "%s.partial", path);
    remove(path);
    fm_error err = {0};
    fm_status s = fm_render_tets_png(verts, n, opts, path, &err);
    ENSURE_MSG(s == FM_OK, "%s: status %d: %s", name, (int)s, err.message);
    ENSURE_MSG(!file_exists(partial), "%s left behind", partial);
    memset(out, 0, sizeof *out);
    if (s != FM_OK) return 1;
    int rc = read_png(path, out);
    ENSURE_MSG(rc == 0, "%s: cannot read the PNG back (%d)", name, rc);
    if (rc == 0) {
        ENSURE_MSG(out->width == opts->width && out->height == opts->height,
                   "%s: %dx%d, expected %dx%d", name, out->width, out->height, opts->width,
                   opts->height);
        if (out->width != opts->width || out->height != opts->height) rc = 4;
    }
    remove(path);
    return rc;
}

/* Foreground = any pixel that differs from the top-left corner (the scenes leave it empty). */
typedef struct coverage {
    long fg, bg;
    int x0, x1, y0, y1; /* foreground pixel bounding box (inclusive) */
} coverage;

static int is_fg(const rgb_image *im, int x, int y)
{
    return memcmp(pixel(im, x, y), pixel(im, 0, 0), 3) != 0;
}

static coverage cover(const rgb_image *im)
{
    coverage c = {0, 0, im->width, -1, im->height, -1};
    for (int y = 0; y < im->height; y++)
        for (int x = 0; x < im->width; x++) {
            if (!is_fg(im, x, y)) {
                c.bg++;
                continue;
            }
            c.fg++;
            if (x < c.x0) c.x0 = x;
            if (x > c.x1) c.x1 = x;
            if (y < c.y0) c.y0 = y;
            if (y > c.y1) c.y1 = y;
        }
    return c;
}

/* A tet whose back face (v0 v1 v2) lies in the plane y = y0 as the triangle
 * (cx - w, cz - h), (cx + w, cz - h), (cx, cz + h) in (x, z), with the apex v3 sticking out
 * towards -Y (towards the default camera) over the triangle's centroid. Positive volume. */
static void make_tet(float *t, double cx, double y0, double cz, double w, double h, double depth)
{
    const double v[4][3] = {{cx - w, y0, cz - h},
                            {cx + w, y0, cz - h},
                            {cx, y0, cz + h},
                            {cx, y0 - depth, cz - h / 3.0}};
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++) t[3 * i + k] = (float)v[i][k];
}

static const double unit_box[6] = {-1, -1, -1, 1, 1, 1};

/* Where the default view (along +Y, up +Z) puts world (x, z) once the box [-1, 1]^3 is fitted
 * into W x H with margin m: the box spans 2 x 2 on the image plane. */
static double box_scale(const fm_render_opts *o)
{
    double sx = o->width * (1.0 - 2.0 * o->margin) / 2.0;
    double sy = o->height * (1.0 - 2.0 * o->margin) / 2.0;
    return sx < sy ? sx : sy;
}
static double px_of(const fm_render_opts *o, double x)
{
    return 0.5 * o->width + x * box_scale(o);
}
static double py_of(const fm_render_opts *o, double z)
{
    return 0.5 * o->height - z * box_scale(o);
}

/* ---------------------------------------------------------------- tests */

static void test_defaults(void)
{
    fm_render_opts o = fm_default_render_opts();
    ENSURE(o.width == 960 && o.height == 540);
    ENSURE(o.view_dir[0] == 0 && o.view_dir[1] == 1 && o.view_dir[2] == 0);
    ENSURE(o.up[0] == 0 && o.up[1] == 0 && o.up[2] == 1);
    ENSURE_NEAR(o.margin, 0.05, 1e-15);
    ENSURE(o.bounds == NULL);
}

/* One tet in the right half of a fixed box, seen from the front. */
static void test_front_view_right_half(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.bounds = unit_box;
    float tet[12];
    make_tet(tet, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4); /* x in [0.3, 0.9], z in [-0.5, 0.5] */
    rgb_image im;
    if (render_and_read(tet, 1, &o, "fm_test_render_front.png", &im) != 0) return;

    const unsigned char *bg = pixel(&im, 0, 0);
    ENSURE_MSG(bg[0] + bg[1] + bg[2] < 3 * 80, "background %d %d %d is not dark", bg[0], bg[1],
               bg[2]);
    coverage c = cover(&im);
    ENSURE_MSG(c.fg > 0, "no foreground pixels");
    ENSURE_MSG(c.bg > 4 * c.fg, "background %ld does not dominate foreground %ld", c.bg, c.fg);

    /* Projected bounding box of the tet, in pixel-centre coordinates, +-2 pixels. */
    double bx0 = px_of(&o, 0.3), bx1 = px_of(&o, 0.9);
    double by0 = py_of(&o, 0.5), by1 = py_of(&o, -0.5);
    ENSURE_MSG(c.x0 + 0.5 >= bx0 - 2 && c.x1 + 0.5 <= bx1 + 2 && c.y0 + 0.5 >= by0 - 2 &&
                   c.y1 + 0.5 <= by1 + 2,
               "foreground [%d, %d] x [%d, %d] outside [%.1f, %.1f] x [%.1f, %.1f]", c.x0, c.x1,
               c.y0, c.y1, bx0, bx1, by0, by1);
    /* ... and it fills that box (the tet is not a speck). */
    ENSURE_MSG(c.x0 + 0.5 <= bx0 + 2 && c.x1 + 0.5 >= bx1 - 2 && c.y0 + 0.5 <= by0 + 2 &&
                   c.y1 + 0.5 >= by1 - 2,
               "foreground [%d, %d] x [%d, %d] does not reach [%.1f, %.1f] x [%.1f, %.1f]", c.x0,
               c.x1, c.y0, c.y1, bx0, bx1, by0, by1);
    /* +X is on the right: everything lies in the right half. */
    ENSURE_MSG(c.x0 >= im.width / 2, "foreground starts at x = %d, left of the centre", c.x0);
    /* The silhouette is the back triangle (the apex projects inside it): no holes. */
    double area = 0.5 * (bx1 - bx0) * (by1 - by0);
    ENSURE_MSG(fabs((double)c.fg - area) < 0.015 * area, "%ld foreground pixels, expected %.0f",
               c.fg, area);
    free(im.rgb);
}

/* Flat shading with the light at the camera's upper left: the face turned up and left is the
 * brightest of the three visible faces, and each face is one flat colour. */
static void test_shading(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.bounds = unit_box;
    float tet[12];
    make_tet(tet, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4);
    rgb_image im;
    if (render_and_read(tet, 1, &o, "fm_test_render_shading.png", &im) != 0) return;
    /* Visible faces as (apex, a, b): left (3, 2, 0), right (3, 1, 2), bottom (3, 0, 1). */
    static const int faces[3][3] = {{3, 2, 0}, {3, 1, 2}, {3, 0, 1}};
    int sum[3];
    const unsigned char *col[3];
    for (int f = 0; f < 3; f++) {
        double x = 0, z = 0;
        for (int k = 0; k < 3; k++) {
            x += tet[3 * faces[f][k] + 0] / 3.0;
            z += tet[3 * faces[f][k] + 2] / 3.0;
        }
        int px = (int)floor(px_of(&o, x)), py = (int)floor(py_of(&o, z));
        col[f] = pixel(&im, px, py);
        sum[f] = col[f][0] + col[f][1] + col[f][2];
        ENSURE_MSG(is_fg(&im, px, py), "face %d centre (%d, %d) is background", f, px, py);
        /* Flat: the 5 x 5 block around the face's centre has one colour. */
        for (int dy = -2; dy <= 2; dy++)
            for (int dx = -2; dx <= 2; dx++)
                ENSURE_MSG(memcmp(pixel(&im, px + dx, py + dy), col[f], 3) == 0,
                           "face %d is not flat at (%d, %d)", f, px + dx, py + dy);
    }
    ENSURE_MSG(sum[0] > sum[1] + 60 && sum[0] > sum[2] + 60,
               "upper-left face (%d) is not clearly the brightest (right %d, bottom %d)", sum[0],
               sum[1], sum[2]);
    /* Grey-blue: blue >= green >= red on the lit face. */
    ENSURE_MSG(col[0][2] >= col[0][1] && col[0][1] >= col[0][0], "lit face colour %d %d %d",
               col[0][0], col[0][1], col[0][2]);
    free(im.rgb);
}

/* +Z is at the top: a tet in the upper left of the box lands in the upper-left quadrant. */
static void test_up_is_up(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.bounds = unit_box;
    float tet[12];
    make_tet(tet, -0.5, 0.0, 0.5, 0.3, 0.3, 0.4); /* x in [-0.8, -0.2], z in [0.2, 0.8] */
    rgb_image im;
    if (render_and_read(tet, 1, &o, "fm_test_render_up.png", &im) != 0) return;
    coverage c = cover(&im);
    ENSURE(c.fg > 0);
    ENSURE_MSG(c.x1 < im.width / 2 && c.y1 < im.height / 2,
               "foreground [%d, %d] x [%d, %d] is not in the upper-left quadrant", c.x0, c.x1,
               c.y0, c.y1);
    ENSURE_NEAR(c.y0 + 0.5, py_of(&o, 0.8), 2.0);
    ENSURE_NEAR(c.y1 + 0.5, py_of(&o, 0.2), 2.0);
    free(im.rgb);
}

/* Seen from behind (looking along -Y, up +Z) the silhouette is the mirror image: +X is on
 * the left. */
static void test_mirror_from_behind(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.bounds = unit_box;
    float tet[12];
    make_tet(tet, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4);
    rgb_image front, back;
    if (render_and_read(tet, 1, &o, "fm_test_render_mirror_a.png", &front) != 0) return;
    o.view_dir[1] = -1.0;
    if (render_and_read(tet, 1, &o, "fm_test_render_mirror_b.png", &back) != 0) {
        free(front.rgb);
        return;
    }
    coverage cf = cover(&front), cb = cover(&back);
    ENSURE(cb.fg > 0);
    ENSURE_MSG(cb.x1 < back.width / 2, "from behind, foreground reaches x = %d", cb.x1);
    long differ = 0;
    for (int y = 0; y < front.height; y++)
        for (int x = 0; x < front.width; x++)
            if (is_fg(&front, x, y) != is_fg(&back, front.width - 1 - x, y)) differ++;
    ENSURE_MSG(differ <= cf.fg / 100, "%ld pixels differ from the mirror image (of %ld)", differ,
               cf.fg);
    free(front.rgb);
    free(back.rgb);
}

/* With no bounds the tets' bounding box is fitted: its limiting extent (here the height)
 * spans the image minus the margins, centred. */
static void test_fit_to_tets(void)
{
    fm_render_opts o = fm_default_render_opts();
    float tet[12];
    make_tet(tet, 5.0, 3.0, -7.0, 0.3, 0.5, 0.4); /* 0.6 wide, 1.0 tall */
    rgb_image im;
    if (render_and_read(tet, 1, &o, "fm_test_render_fit.png", &im) != 0) return;
    coverage c = cover(&im);
    double scale = o.height * (1.0 - 2.0 * o.margin) / 1.0; /* height-limited */
    double top = o.margin * o.height, bottom = o.height - top;
    double left = 0.5 * o.width - 0.3 * scale, right = 0.5 * o.width + 0.3 * scale;
    /* (the top is a 33-degree spike whose first pixel centres sit a little below its tip) */
    ENSURE_NEAR(c.y0 + 0.5, top, 3.0);
    ENSURE_NEAR(c.y1 + 0.5, bottom, 1.5);
    ENSURE_NEAR(c.x0 + 0.5, left, 1.5);
    ENSURE_NEAR(c.x1 + 0.5, right, 1.5);
    free(im.rgb);

    /* An oblique view still keeps everything inside the margins. */
    o.view_dir[0] = 1.0, o.view_dir[1] = 2.0, o.view_dir[2] = -1.5;
    o.up[0] = 0.3;
    if (render_and_read(tet, 1, &o, "fm_test_render_oblique.png", &im) != 0) return;
    c = cover(&im);
    ENSURE(c.fg > 1000);
    ENSURE_MSG(c.x0 >= o.margin * o.width - 1 && c.x1 <= (1 - o.margin) * o.width &&
                   c.y0 >= o.margin * o.height - 1 && c.y1 <= (1 - o.margin) * o.height,
               "oblique foreground [%d, %d] x [%d, %d] crosses the margin", c.x0, c.x1, c.y0,
               c.y1);
    free(im.rgb);
}

/* The nearer tet wins wherever they overlap, whichever is drawn first. */
static void test_depth_buffer(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.bounds = unit_box;
    float scene[24], swapped[24];
    make_tet(scene, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4);         /* A: near, y in [-0.4, 0] */
    make_tet(scene + 12, 0.5, 0.5, 0.05, 0.5, 0.85, 0.4);  /* B: far behind, covering A */
    memcpy(swapped, scene + 12, sizeof(float) * 12);
    memcpy(swapped + 12, scene, sizeof(float) * 12);
    rgb_image a, b, ab, ba;
    int rc = render_and_read(scene, 1, &o, "fm_test_render_z_a.png", &a);
    rc |= render_and_read(scene + 12, 1, &o, "fm_test_render_z_b.png", &b);
    rc |= render_and_read(scene, 2, &o, "fm_test_render_z_ab.png", &ab);
    rc |= render_and_read(swapped, 2, &o, "fm_test_render_z_ba.png", &ba);
    if (rc == 0) {
        long in_a = 0, b_differs = 0, wrong_ab = 0, wrong_ba = 0, b_missing = 0;
        for (int y = 0; y < a.height; y++)
            for (int x = 0; x < a.width; x++) {
                if (!is_fg(&a, x, y)) continue;
                in_a++;
                if (!is_fg(&b, x, y)) b_missing++;
                if (memcmp(pixel(&b, x, y), pixel(&a, x, y), 3) != 0) b_differs++;
                if (memcmp(pixel(&ab, x, y), pixel(&a, x, y), 3) != 0) wrong_ab++;
                if (memcmp(pixel(&ba, x, y), pixel(&a, x, y), 3) != 0) wrong_ba++;
            }
        ENSURE_MSG(b_missing == 0, "B does not cover A (%ld pixels)", b_missing);
        ENSURE_MSG(b_differs > in_a / 2, "B's colour matches A's too often to tell them apart");
        ENSURE_MSG(wrong_ab == 0, "A then B: %ld of A's %ld pixels show B", wrong_ab, in_a);
        ENSURE_MSG(wrong_ba == 0, "B then A: %ld of A's %ld pixels show B", wrong_ba, in_a);
    }
    free(a.rgb);
    free(b.rgb);
    free(ab.rgb);
    free(ba.rgb);
}

/* NaN and infinite vertices and zero-area tets are skipped without a crash. */
static void test_nan_and_degenerate(void)
{
    fm_render_opts o = fm_default_render_opts();
    float scene[12 * 4];
    make_tet(scene, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4);
    for (int k = 0; k < 12; k++) scene[12 + k] = NAN;      /* all NaN */
    make_tet(scene + 24, -0.5, 0.0, 0.5, 0.3, 0.3, 0.4);
    scene[24 + 9] = INFINITY;                              /* v3 = (inf, NaN, z) */
    scene[24 + 10] = NAN;
    for (int k = 0; k < 12; k++) scene[36 + k] = 0.25f;    /* all four vertices equal */

    /* The bounds are fitted to the finite vertices only; the first tet and the third tet's
     * face (0, 2, 1), the one without v3, are drawn, left and right of the centre. */
    rgb_image im;
    if (render_and_read(scene, 4, &o, "fm_test_render_nan.png", &im) == 0) {
        coverage c = cover(&im);
        ENSURE(c.fg > 1000);
        ENSURE_MSG(c.x0 < im.width / 2 && c.x1 > im.width / 2 && c.y0 >= o.margin * im.height - 1,
                   "foreground [%d, %d] x [%d, %d]", c.x0, c.x1, c.y0, c.y1);
        free(im.rgb);
    }
    /* ... and with fixed bounds, the degenerate tet alone draws nothing. */
    o.bounds = unit_box;
    if (render_and_read(scene + 36, 1, &o, "fm_test_render_degenerate.png", &im) == 0) {
        coverage c = cover(&im);
        ENSURE_MSG(c.fg == 0, "a zero-volume point tet drew %ld pixels", c.fg);
        free(im.rgb);
    }
    /* Only non-finite tets and no bounds: nothing to fit, a background image. */
    o.bounds = NULL;
    if (render_and_read(scene + 12, 1, &o, "fm_test_render_allnan.png", &im) == 0) {
        ENSURE(cover(&im).fg == 0);
        free(im.rgb);
    }
}

/* n == 0 gives a valid, all-background PNG of the requested size, with or without bounds. */
static void test_empty(void)
{
    fm_render_opts o = fm_default_render_opts();
    o.width = 64;
    o.height = 48;
    for (int pass = 0; pass < 2; pass++) {
        o.bounds = pass ? unit_box : NULL;
        rgb_image im;
        if (render_and_read(NULL, 0, &o, "fm_test_render_empty.png", &im) != 0) continue;
        ENSURE_MSG(cover(&im).fg == 0, "empty scene has foreground pixels");
        const unsigned char *bg = pixel(&im, 0, 0);
        ENSURE(bg[0] + bg[1] + bg[2] < 3 * 80);
        free(im.rgb);
    }
}

static void test_errors(void)
{
    float tet[12];
    make_tet(tet, 0.6, 0.0, 0.0, 0.3, 0.5, 0.4);
    fm_render_opts o = fm_default_render_opts();
    char path[512], partial[600];

    tmp_path(path, sizeof path, "fm_no_such_dir/out.png");
    snprintf(partial, sizeof partial, "%s.partial", path);
    fm_error err = {0};
    fm_status s = fm_render_tets_png(tet, 1, &o, path, &err);
    ENSURE_MSG(s == FM_ERR_IO, "status %d", (int)s);
    ENSURE_MSG(strstr(err.message, path) && strstr(err.message, "No such file"),
               "message: %s", err.message);
    ENSURE(!file_exists(path) && !file_exists(partial));

    /* Bad options are usage errors and write nothing. */
    tmp_path(path, sizeof path, "fm_test_render_badopts.png");
    remove(path);
    fm_render_opts bad[4] = {o, o, o, o};
    bad[0].width = 0;
    bad[1].up[1] = 1.0, bad[1].up[2] = 0.0; /* parallel to view_dir */
    bad[2].margin = 0.5;
    bad[3].view_dir[1] = 0.0;
    for (int i = 0; i < 4; i++) {
        s = fm_render_tets_png(tet, 1, &bad[i], path, &err);
        ENSURE_MSG(s == FM_ERR_USAGE, "bad option set %d: status %d", i, (int)s);
        ENSURE(!file_exists(path));
    }
}

int main(void)
{
    RUN_TEST(test_defaults);
    RUN_TEST(test_front_view_right_half);
    RUN_TEST(test_shading);
    RUN_TEST(test_up_is_up);
    RUN_TEST(test_mirror_from_behind);
    RUN_TEST(test_fit_to_tets);
    RUN_TEST(test_depth_buffer);
    RUN_TEST(test_nan_and_degenerate);
    RUN_TEST(test_empty);
    RUN_TEST(test_errors);
    return test_result();
}
