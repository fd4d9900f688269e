/* Point caches: one file holding every frame of a fixed set of points, the format the mesh-cache
 * deformers of Blender (Mesh Cache modifier), Maya, 3ds Max and Cinema 4D read
 * (include/flockmorph/export.h, docs/export.md).
 *
 *   PC2  little-endian: "POINTCACHE2\0", int32 version 1, int32 points, float32 start frame,
 *        float32 sample rate (frames between samples), int32 samples; then per sample and point
 *        float32 x, y, z
 *   MDD  big-endian: int32 frames, int32 points, float32 time of each frame (seconds); then per
 *        frame and point float32 x, y, z
 *
 * Both headers give the frame count, so the writer is told it up front and refuses a finish
 * with fewer or more frames. Written as PATH.partial and renamed when complete. */
#define _POSIX_C_SOURCE 200809L
#include "export.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

struct fm_pointcache_writer {
    fm_output_file out;
    fm_export_format format;
    size_t points, frames, added;
    int failed;             /* a write failed: errno was saved in error_number */
    int error_number;
    unsigned char *buf;     /* one frame's bytes */
};

static void put_u32(unsigned char *p, uint32_t v, int big_endian)
{
    for (int k = 0; k < 4; k++) p[big_endian ? 3 - k : k] = (unsigned char)(v >> (8 * k));
}

static void put_f32(unsigned char *p, float v, int big_endian)
{
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits);
    put_u32(p, bits, big_endian);
}

static int big_endian(const fm_pointcache_writer *w) { return w->format == FM_EXPORT_MDD; }

static void write_bytes(fm_pointcache_writer *w, const void *p, size_t bytes)
{
    if (w->failed || fwrite(p, 1, bytes, w->out.f) == bytes) return;
    w->failed = 1, w->error_number = errno ? errno : EIO;
}

static void write_pc2_header(fm_pointcache_writer *w, double start, double step)
{
    unsigned char h[32];
    memcpy(h, "POINTCACHE2", 12); /* with its terminating zero: 12 bytes */
    put_u32(h + 12, 1, 0);
    put_u32(h + 16, (uint32_t)w->points, 0);
    put_f32(h + 20, (float)start, 0);
    put_f32(h + 24, (float)step, 0);
    put_u32(h + 28, (uint32_t)w->frames, 0);
    write_bytes(w, h, sizeof h);
}

/* Frame j's time: (start + j * step) / rate seconds. */
static void write_mdd_header(fm_pointcache_writer *w, double start, double step, double rate)
{
    unsigned char h[8], t[4];
    put_u32(h, (uint32_t)w->frames, 1);
    put_u32(h + 4, (uint32_t)w->points, 1);
    write_bytes(w, h, sizeof h);
    for (size_t j = 0; j < w->frames; j++) {
        put_f32(t, (float)((start + (double)j * step) / rate), 1);
        write_bytes(w, t, sizeof t);
    }
}

static fm_status check_create(const fm_pointcache_options *o, const char *path, fm_error *err)
{
    if (!path || !*path) return fm_fail(err, FM_ERR_USAGE, "export: no output path given");
    if (o->format != FM_EXPORT_PC2 && o->format != FM_EXPORT_MDD)
        return fm_fail(err, FM_ERR_USAGE, "cannot write '%s' as a point cache: the format is not pc2 or mdd", path);
    if (o->points > (size_t)INT32_MAX || o->frames > (size_t)INT32_MAX)
        return fm_fail(err, FM_ERR_INPUT, "cannot export %zu points x %zu frames to '%s': the %s header "
                       "counts in int32", o->points, o->frames, path, fm_export_extension(o->format));
    if (!isfinite(o->start_frame) || !(o->frame_step > 0) || !isfinite(o->frame_step))
        return fm_fail(err, FM_ERR_USAGE, "'%s': start frame %g and frame step %g must be finite and the "
                       "step positive", path, o->start_frame, o->frame_step);
    if (o->format == FM_EXPORT_MDD && !(o->frame_rate > 0 && isfinite(o->frame_rate)))
        return fm_fail(err, FM_ERR_INPUT, "'%s': MDD stores frame times and needs a positive frame rate, "
                       "not %g", path, o->frame_rate);
    return FM_OK;
}

fm_pointcache_writer *fm_pointcache_create(const char *path, const fm_pointcache_options *o, fm_error *err)
{
    if (check_create(o, path, err) != FM_OK) return NULL;
    fm_pointcache_writer *w = calloc(1, sizeof *w);
    if (w) w->buf = malloc(12 * (o->points ? o->points : 1));
    if (!w || !w->buf) {
        if (w) free(w);
        fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame of %zu points ('%s')", o->points, path);
        return NULL;
    }
    w->format = o->format, w->points = o->points, w->frames = o->frames;
    if (fm_output_open(&w->out, path, err) != FM_OK) {
        free(w->buf), free(w);
        return NULL;
    }
    errno = 0;
    if (o->format == FM_EXPORT_PC2) write_pc2_header(w, o->start_frame, o->frame_step);
    else write_mdd_header(w, o->start_frame, o->frame_step, o->frame_rate);
    return w;
}

fm_status fm_pointcache_add(fm_pointcache_writer *w, const float *xyz, fm_error *err)
{
    if (w->added >= w->frames)
        return fm_fail(err, FM_ERR_USAGE, "'%s': the header announced %zu frames; frame %zu is one too many",
                       w->out.path, w->frames, w->added);
    for (size_t i = 0; i < 3 * w->points; i++) {
        if (!isfinite(xyz[i]))
            return fm_fail(err, FM_ERR_INPUT, "cannot export to '%s': point %zu of sample %zu is not finite",
                           w->out.path, i / 3, w->added);
        put_f32(w->buf + 4 * i, xyz[i], big_endian(w));
    }
    errno = 0;
    write_bytes(w, w->buf, 12 * w->points);
    w->added++;
    if (!w->failed) return FM_OK;
    return fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", w->out.path, strerror(w->error_number),
                   fm_write_hint(w->error_number));
}

void fm_pointcache_abort(fm_pointcache_writer *w)
{
    if (!w) return;
    fm_output_discard(&w->out);
    free(w->buf), free(w);
}

fm_status fm_pointcache_finish(fm_pointcache_writer *w, fm_error *err)
{
    fm_status st = FM_OK;
    if (w->failed)
        st = fm_fail(err, FM_ERR_IO, "cannot write '%s': %s%s", w->out.path, strerror(w->error_number),
                     fm_write_hint(w->error_number));
    else if (w->added != w->frames)
        st = fm_fail(err, FM_ERR_USAGE, "'%s': %zu of the %zu frames the header announced were written",
                     w->out.path, w->added, w->frames);
    if (st != FM_OK) {
        fm_pointcache_abort(w);
        return st;
    }
    st = fm_output_commit(&w->out, NULL, err);
    free(w->buf), free(w);
    return st;
}
