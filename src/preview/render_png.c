/* PNG output of the preview renderer: 8-bit sRGB through libpng, written as PATH.partial and
 * renamed when complete. */
#define _POSIX_C_SOURCE 200809L
#include "render.h"

#include <errno.h>
#include <png.h>
#include <stdio.h>
#include <string.h>

typedef struct png_failure {
    char message[256];
} png_failure;

static void png_error_fn(png_structp png, png_const_charp msg)
{
    png_failure *pf = png_get_error_ptr(png);
    snprintf(pf->message, sizeof pf->message, "%s", msg);
    png_longjmp(png, 1);
}

static void png_warning_fn(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

/* Returns 0 on success, -1 on failure with pf->message set (errno may say more). */
static int write_png_stream(FILE *f, const unsigned char *rgb, int width, int height,
                            png_failure *pf)
{
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, pf, png_error_fn,
                                              png_warning_fn);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        snprintf(pf->message, sizeof pf->message, "libpng could not start");
        return -1;
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return -1;
    }
    png_init_io(png, f);
    png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 8, PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    for (int y = 0; y < height; y++) png_write_row(png, rgb + (size_t)y * (size_t)width * 3);
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    return 0;
}

fm_status fm_write_png(const unsigned char *rgb, int width, int height, const char *path,
                       fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "render: no output path given");
    if (!rgb || width < 1 || height < 1 || width > FM_RENDER_MAX_DIM || height > FM_RENDER_MAX_DIM)
        return fm_fail(err, FM_ERR_USAGE, "cannot write '%s': no %dx%d image to write", path,
                       width, height);
    fm_output_file out;
    fm_status st = fm_output_open(&out, path, err);
    if (st != FM_OK) return st;
    png_failure pf = {""};
    errno = 0;
    if (write_png_stream(out.f, rgb, width, height, &pf) != 0) {
        int e = errno ? errno : EIO;
        fm_output_discard(&out);
        if (pf.message[0]) return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s", path, pf.message);
        return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", path, strerror(e), fm_write_hint(e));
    }
    return fm_output_commit(&out, NULL, err);
}

