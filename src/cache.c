/* The native frame cache (docs/cache-format.md is the specification).
 *
 *   header   64 bytes: "FMCACHE1", version, header size, agents, floats per agent, filter, codec,
 *            frame rate
 *   chunks   one per frame: "FRAM", frame index, compressed size, raw size, then a zstd frame
 *            (with zstd's content checksum) of the frame's floats after a 4-byte shuffle
 *   index    "FIDX", frame count, one u64 file offset per chunk
 *   footer   u64 offset of the index, "FMCEND\0\0"
 * The writer works on PATH.partial and renames it to PATH only after the footer is on disk, so a
 * file under the final name is always complete. */
#define _POSIX_C_SOURCE 200809L
#include "fm_internal.h"

#include <zstd.h>

#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum {
    CACHE_VERSION = 1,
    HEADER_BYTES = 64,
    CHUNK_HEADER_BYTES = 24,
    FLOATS_PER_AGENT = 12,
    FILTER_SHUFFLE4 = 1,
    CODEC_ZSTD = 1,
};
enum { ZSTD_WORKERS = 2 };
static const char MAGIC[8] = {'F', 'M', 'C', 'A', 'C', 'H', 'E', '1'};
static const char END_MAGIC[8] = {'F', 'M', 'C', 'E', 'N', 'D', 0, 0};

/* Little-endian field access (the engine targets little-endian x86-64 and ARM64). */
static void put_u32(unsigned char *p, uint32_t x) { memcpy(p, &x, 4); }
static void put_u64(unsigned char *p, uint64_t x) { memcpy(p, &x, 8); }
static uint32_t get_u32(const unsigned char *p) { uint32_t x; memcpy(&x, p, 4); return x; }
static uint64_t get_u64(const unsigned char *p) { uint64_t x; memcpy(&x, p, 8); return x; }

/* Byte k of float i goes to plane k: exponent bytes line up and compress far better. */
static void shuffle4(const unsigned char *in, size_t count, unsigned char *out)
{
    for (size_t i = 0; i < count; i++)
        for (int k = 0; k < 4; k++) out[k * count + i] = in[4 * i + k];
}

static void unshuffle4(const unsigned char *in, size_t count, unsigned char *out)
{
    for (size_t i = 0; i < count; i++)
        for (int k = 0; k < 4; k++) out[4 * i + k] = in[k * count + i];
}

/* Frames are compressed and written by a worker thread, so the step loop only pays for a copy:
 * add_frame hands the frame over (waiting while the previous one is still being written) and
 * returns. The file's bytes do not depend on the timing. */
struct fm_cache_writer {
    fm_output_file out;      /* PATH.partial until finish() */
    uint64_t agents;
    size_t raw_bytes;
    unsigned char *shuffled, *packed;
    size_t packed_cap;
    ZSTD_CCtx *cctx;
    uint64_t *offsets;
    uint32_t frames, offsets_cap;
    uint64_t pos;
    /* the worker */
    pthread_t thread;
    int thread_started;
    pthread_mutex_t lock;
    pthread_cond_t changed;
    unsigned char *pending;  /* the frame handed over, raw floats */
    int has_pending, stop;
    fm_status worker_status; /* the first failure, reported by the next call */
    fm_error worker_err;
};

static void *worker_main(void *arg);

static fm_status write_bytes(fm_cache_writer *w, const void *data, size_t n, fm_error *err)
{
    if (fwrite(data, 1, n, w->out.f) != n)
        return fm_fail(err, FM_ERR_IO, "%s: write failed: %s", w->out.partial, strerror(errno));
    w->pos += n;
    return FM_OK;
}

static fm_status write_header(fm_cache_writer *w, double frame_rate, fm_error *err)
{
    unsigned char h[HEADER_BYTES] = {0};
    memcpy(h, MAGIC, 8);
    put_u32(h + 8, CACHE_VERSION);
    put_u32(h + 12, HEADER_BYTES);
    put_u64(h + 16, w->agents);
    put_u32(h + 24, FLOATS_PER_AGENT);
    put_u32(h + 28, FILTER_SHUFFLE4);
    put_u32(h + 32, CODEC_ZSTD);
    memcpy(h + 40, &frame_rate, 8);
    return write_bytes(w, h, sizeof h, err);
}

fm_cache_writer *fm_cache_writer_create(const char *path, uint64_t agents, double frame_rate,
                                        int level, fm_error *err)
{
    fm_cache_writer *w = calloc(1, sizeof *w);
    if (!w) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    w->agents = agents;
    w->raw_bytes = (size_t)agents * FLOATS_PER_AGENT * sizeof(float);
    w->packed_cap = ZSTD_compressBound(w->raw_bytes);
    w->shuffled = malloc(w->raw_bytes ? w->raw_bytes : 1);
    w->pending = malloc(w->raw_bytes ? w->raw_bytes : 1);
    w->packed = malloc(w->packed_cap);
    w->cctx = ZSTD_createCCtx();
    pthread_mutex_init(&w->lock, NULL);
    pthread_cond_init(&w->changed, NULL);
    if (!w->shuffled || !w->pending || !w->packed || !w->cctx) {
        fm_cache_writer_abort(w);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache of %llu agents", (unsigned long long)agents), NULL;
    }
    ZSTD_CCtx_setParameter(w->cctx, ZSTD_c_compressionLevel, level);
    ZSTD_CCtx_setParameter(w->cctx, ZSTD_c_checksumFlag, 1);
    /* zstd's own workers, a fixed number whatever the run's thread count: the compressed bytes
     * depend on nbWorkers, so fixing it keeps caches identical for any --threads. Ignored (one
     * thread) where libzstd lacks multithreading. */
    ZSTD_CCtx_setParameter(w->cctx, ZSTD_c_nbWorkers, ZSTD_WORKERS);
    if (fm_output_open(&w->out, path, err) != FM_OK || write_header(w, frame_rate, err) != FM_OK) {
        fm_cache_writer_abort(w);
        return NULL;
    }
    if (pthread_create(&w->thread, NULL, worker_main, w) != 0) {
        fm_fail(err, FM_ERR_INTERNAL, "%s: cannot start the cache writer thread", path);
        fm_cache_writer_abort(w);
        return NULL;
    }
    w->thread_started = 1;
    return w;
}

/* Compresses and appends one frame (the worker's job). */
static fm_status write_frame(fm_cache_writer *w, const unsigned char *raw, fm_error *err)
{
    if (w->frames == w->offsets_cap) {
        uint32_t cap = w->offsets_cap ? 2 * w->offsets_cap : 256;
        uint64_t *grown = realloc(w->offsets, sizeof *grown * cap);
        if (!grown) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache index");
        w->offsets = grown, w->offsets_cap = cap;
    }
    shuffle4(raw, w->raw_bytes / 4, w->shuffled);
    size_t packed = ZSTD_compress2(w->cctx, w->packed, w->packed_cap, w->shuffled, w->raw_bytes);
    if (ZSTD_isError(packed))
        return fm_fail(err, FM_ERR_INTERNAL, "%s: zstd failed: %s", w->out.path, ZSTD_getErrorName(packed));
    unsigned char h[CHUNK_HEADER_BYTES];
    memcpy(h, "FRAM", 4);
    put_u32(h + 4, w->frames);
    put_u64(h + 8, packed);
    put_u64(h + 16, w->raw_bytes);
    w->offsets[w->frames] = w->pos;
    fm_status st = write_bytes(w, h, sizeof h, err);
    if (st == FM_OK) st = write_bytes(w, w->packed, packed, err);
    if (st == FM_OK) w->frames++;
    return st;
}

static void *worker_main(void *arg)
{
    fm_cache_writer *w = arg;
    pthread_mutex_lock(&w->lock);
    for (;;) {
        while (!w->has_pending && !w->stop) pthread_cond_wait(&w->changed, &w->lock);
        if (!w->has_pending) break;
        pthread_mutex_unlock(&w->lock);
        fm_error err = {0};
        fm_status st = w->worker_status == FM_OK ? write_frame(w, w->pending, &err) : FM_OK;
        pthread_mutex_lock(&w->lock);
        if (st != FM_OK) w->worker_status = st, w->worker_err = err;
        w->has_pending = 0;
        pthread_cond_broadcast(&w->changed);
    }
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

/* Waits until the worker holds no frame; returns its first failure. Called with the lock held. */
static fm_status wait_idle(fm_cache_writer *w, fm_error *err)
{
    while (w->has_pending) pthread_cond_wait(&w->changed, &w->lock);
    if (w->worker_status != FM_OK && err) *err = w->worker_err;
    return w->worker_status;
}

fm_status fm_cache_writer_add_frame(fm_cache_writer *w, const float *verts, fm_error *err)
{
    pthread_mutex_lock(&w->lock);
    fm_status st = wait_idle(w, err);
    if (st == FM_OK) {
        memcpy(w->pending, verts, w->raw_bytes);
        w->has_pending = 1;
        pthread_cond_broadcast(&w->changed);
    }
    pthread_mutex_unlock(&w->lock);
    return st;
}

/* Lets the worker finish what it holds and ends it; returns its first failure. */
static fm_status stop_worker(fm_cache_writer *w, fm_error *err)
{
    if (!w->thread_started) return w->worker_status;
    pthread_mutex_lock(&w->lock);
    fm_status st = wait_idle(w, err);
    w->stop = 1;
    pthread_cond_broadcast(&w->changed);
    pthread_mutex_unlock(&w->lock);
    pthread_join(w->thread, NULL);
    w->thread_started = 0;
    return st;
}

static void free_writer(fm_cache_writer *w)
{
    stop_worker(w, NULL);
    pthread_mutex_destroy(&w->lock);
    pthread_cond_destroy(&w->changed);
    free(w->shuffled), free(w->packed), free(w->offsets), free(w->pending);
    ZSTD_freeCCtx(w->cctx);
    free(w);
}

static fm_status write_index_and_footer(fm_cache_writer *w, fm_error *err)
{
    uint64_t index_pos = w->pos;
    unsigned char h[8];
    memcpy(h, "FIDX", 4);
    put_u32(h + 4, w->frames);
    fm_status st = write_bytes(w, h, sizeof h, err);
    for (uint32_t i = 0; i < w->frames && st == FM_OK; i++) {
        unsigned char o[8];
        put_u64(o, w->offsets[i]);
        st = write_bytes(w, o, 8, err);
    }
    unsigned char footer[16];
    put_u64(footer, index_pos);
    memcpy(footer + 8, END_MAGIC, 8);
    if (st == FM_OK) st = write_bytes(w, footer, sizeof footer, err);
    return st;
}

fm_status fm_cache_writer_finish(fm_cache_writer *w, fm_error *err)
{
    fm_status st = stop_worker(w, err);
    if (st == FM_OK) st = write_index_and_footer(w, err);
    if (st == FM_OK) st = fm_output_commit(&w->out, NULL, err);
    else fm_output_discard(&w->out);
    free_writer(w);
    return st;
}

void fm_cache_writer_abort(fm_cache_writer *w)
{
    if (!w) return;
    stop_worker(w, NULL);
    fm_output_discard(&w->out);
    free_writer(w);
}

/* ---------------------------------------------------------------- reader */

struct fm_cache_reader {
    FILE *f;
    char path[FM_PATH_MAX];
    char warning[FM_PATH_MAX + 160]; /* non-empty when the cache was recovered without its index */
    uint64_t agents;
    double frame_rate;
    uint32_t frames;
    uint64_t *offsets;
    size_t raw_bytes;
    uint64_t file_bytes;
    unsigned char *packed, *shuffled; /* allocated on the first read (reserve_buffers) */
    size_t packed_cap, packed_alloc;
};

static fm_status read_at(fm_cache_reader *r, uint64_t pos, void *buf, size_t n, fm_error *err)
{
    if (fseeko(r->f, (off_t)pos, SEEK_SET) != 0 || fread(buf, 1, n, r->f) != n)
        return fm_fail(err, FM_ERR_INPUT, "%s: truncated or unreadable at byte %llu", r->path, (unsigned long long)pos);
    return FM_OK;
}

static fm_status read_header(fm_cache_reader *r, fm_error *err)
{
    unsigned char h[HEADER_BYTES] = {0};
    size_t got = fread(h, 1, sizeof h, r->f);
    if (memcmp(h, MAGIC, got < 8 ? got : 8) != 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: not a flockmorph cache (bad magic)", r->path);
    if (got < sizeof h)
        return fm_fail(err, FM_ERR_INPUT, "%s: truncated: %zu bytes, shorter than the cache header", r->path, got);
    if (get_u32(h + 8) != CACHE_VERSION)
        return fm_fail(err, FM_ERR_INPUT, "%s: cache version %u is not supported (this build reads %d)", r->path, get_u32(h + 8), CACHE_VERSION);
    if (get_u32(h + 24) != FLOATS_PER_AGENT || get_u32(h + 28) != FILTER_SHUFFLE4 || get_u32(h + 32) != CODEC_ZSTD)
        return fm_fail(err, FM_ERR_INPUT, "%s: unsupported attribute layout, filter or codec", r->path);
    r->agents = get_u64(h + 16);
    memcpy(&r->frame_rate, h + 40, 8);
    if (!(r->frame_rate > 0 && r->frame_rate <= 1e9))
        return fm_fail(err, FM_ERR_INPUT, "%s: damaged header: frame rate %g", r->path, r->frame_rate);
    if (r->agents > ((uint64_t)1 << 40)) return fm_fail(err, FM_ERR_INPUT, "%s: implausible agent count", r->path);
    r->raw_bytes = (size_t)r->agents * FLOATS_PER_AGENT * sizeof(float);
    return FM_OK;
}

static fm_status grow_offsets(fm_cache_reader *r, uint32_t *cap, fm_error *err)
{
    if (r->frames < *cap) return FM_OK;
    *cap = *cap ? 2 * *cap : 256;
    uint64_t *grown = realloc(r->offsets, sizeof *grown * *cap);
    if (!grown) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache index");
    r->offsets = grown;
    return FM_OK;
}

/* Without a valid index (a run that was killed, a file cut short) the chunks are walked from the
 * header; every complete one is a readable frame. Contents are still checked when read. */
static fm_status scan_chunks(fm_cache_reader *r, uint64_t size, const char *why, fm_error *err)
{
    uint64_t pos = HEADER_BYTES, packed_cap = ZSTD_compressBound(r->raw_bytes);
    uint32_t cap = 0;
    r->frames = 0;
    for (;;) {
        unsigned char h[CHUNK_HEADER_BYTES];
        fm_error ignored;
        if (pos + CHUNK_HEADER_BYTES > size || read_at(r, pos, h, sizeof h, &ignored) != FM_OK) break;
        uint64_t packed = get_u64(h + 8);
        if (memcmp(h, "FRAM", 4) != 0 || get_u32(h + 4) != r->frames || get_u64(h + 16) != r->raw_bytes ||
            packed > packed_cap || pos + CHUNK_HEADER_BYTES + packed > size)
            break;
        fm_status st = grow_offsets(r, &cap, err);
        if (st != FM_OK) return st;
        r->offsets[r->frames++] = pos;
        pos += CHUNK_HEADER_BYTES + packed;
    }
    snprintf(r->warning, sizeof r->warning, "%s: %s; recovered the %u complete frames before byte %llu",
             r->path, why, r->frames, (unsigned long long)pos);
    return FM_OK;
}

static fm_status read_index(fm_cache_reader *r, fm_error *err)
{
    unsigned char footer[16], h[8];
    if (fseeko(r->f, 0, SEEK_END) != 0) return fm_fail(err, FM_ERR_IO, "%s: cannot seek", r->path);
    uint64_t size = (uint64_t)ftello(r->f);
    r->file_bytes = size;
    if (size < HEADER_BYTES + 24 || read_at(r, size - 16, footer, 16, err) != FM_OK || memcmp(footer + 8, END_MAGIC, 8) != 0)
        return scan_chunks(r, size, "incomplete cache (no index: the run did not finish or the file was cut short)", err);
    uint64_t index_pos = get_u64(footer);
    if (index_pos + 8 > size - 16 || read_at(r, index_pos, h, 8, err) != FM_OK || memcmp(h, "FIDX", 4) != 0 ||
        (uint64_t)get_u32(h + 4) * 8 != size - 16 - index_pos - 8)
        return scan_chunks(r, size, "the frame index is damaged", err);
    r->frames = get_u32(h + 4);
    r->offsets = malloc(sizeof *r->offsets * (r->frames ? r->frames : 1));
    if (!r->offsets) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache index");
    for (uint32_t i = 0; i < r->frames; i++) {
        unsigned char o[8];
        fm_status st = read_at(r, index_pos + 8 + 8ull * i, o, 8, err);
        if (st != FM_OK) return st;
        r->offsets[i] = get_u64(o);
    }
    return FM_OK;
}

fm_cache_reader *fm_cache_open(const char *path, fm_error *err)
{
    fm_cache_reader *r = calloc(1, sizeof *r);
    if (!r) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    snprintf(r->path, sizeof r->path, "%s", path);
    r->f = fopen(path, "rb");
    if (!r->f) {
        fm_fail(err, errno == ENOENT ? FM_ERR_INPUT : FM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
        fm_cache_close(r);
        return NULL;
    }
    fm_status st = read_header(r, err);
    if (st == FM_OK) st = read_index(r, err);
    if (st != FM_OK) {
        fm_cache_close(r);
        return NULL;
    }
    r->packed_cap = ZSTD_compressBound(r->raw_bytes);
    return r;
}

uint64_t fm_cache_agents(const fm_cache_reader *r) { return r->agents; }
const char *fm_cache_warning(const fm_cache_reader *r) { return r->warning; }
uint32_t fm_cache_frames(const fm_cache_reader *r) { return r->frames; }
double fm_cache_frame_rate(const fm_cache_reader *r) { return r->frame_rate; }

/* The read buffers are sized on the first read, not at open: a damaged header's agent count must
 * not make open allocate terabytes, and a chunk's compressed size is checked against the file. */
static fm_status reserve_buffers(fm_cache_reader *r, uint64_t packed, fm_error *err)
{
    if (packed > r->packed_alloc) {
        unsigned char *grown = realloc(r->packed, packed);
        if (!grown) return fm_fail(err, FM_ERR_MEMORY, "out of memory reading %s", r->path);
        r->packed = grown, r->packed_alloc = packed;
    }
    if (!r->shuffled && !(r->shuffled = malloc(r->raw_bytes ? r->raw_bytes : 1)))
        return fm_fail(err, FM_ERR_MEMORY, "out of memory reading %s", r->path);
    return FM_OK;
}

fm_status fm_cache_read_frame(fm_cache_reader *r, uint32_t frame, float *out, fm_error *err)
{
    if (frame >= r->frames)
        return fm_fail(err, FM_ERR_USAGE, "%s: frame %u does not exist (the cache has %u frames)", r->path, frame, r->frames);
    unsigned char h[CHUNK_HEADER_BYTES];
    fm_status st = read_at(r, r->offsets[frame], h, sizeof h, err);
    if (st != FM_OK) return st;
    uint64_t packed = get_u64(h + 8);
    if (memcmp(h, "FRAM", 4) != 0 || get_u32(h + 4) != frame || packed > r->packed_cap || get_u64(h + 16) != r->raw_bytes ||
        packed > r->file_bytes - r->offsets[frame] - CHUNK_HEADER_BYTES)
        return fm_fail(err, FM_ERR_INPUT, "%s: frame %u: damaged chunk header", r->path, frame);
    if ((st = reserve_buffers(r, packed, err)) != FM_OK) return st;
    if ((st = read_at(r, r->offsets[frame] + CHUNK_HEADER_BYTES, r->packed, packed, err)) != FM_OK) return st;
    size_t got = ZSTD_decompress(r->shuffled, r->raw_bytes, r->packed, packed);
    if (ZSTD_isError(got) || got != r->raw_bytes)
        return fm_fail(err, FM_ERR_INPUT, "%s: frame %u is corrupt (%s)", r->path, frame,
                       ZSTD_isError(got) ? ZSTD_getErrorName(got) : "wrong size");
    unshuffle4(r->shuffled, r->raw_bytes / 4, (unsigned char *)out);
    return FM_OK;
}

void fm_cache_close(fm_cache_reader *r)
{
    if (!r) return;
    if (r->f) fclose(r->f);
    free(r->offsets), free(r->packed), free(r->shuffled);
    free(r);
}
