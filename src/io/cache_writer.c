/* The frame cache writer (docs/cache-format.md, format 4; cache_format.h has the layout).
 *
 * The step loop only pays for a copy: add_frame hands the frame over into a ring of two (waiting
 * only while two frames are still to be written) and a worker thread filters, compresses (with a
 * team of CACHE_ENCODER_THREADS, a piece at a time: cache_encode.c) and appends them in order. The file's bytes do not depend on the timing. The writer works on
 * PATH.partial and renames it to PATH only after the index, the footer and the header's frame
 * count are on disk, so a file under the final name is always complete. Until then the header's
 * frame count is 0 ("still being written"). */
#define _POSIX_C_SOURCE 200809L
#include "cache_format.h"

#include <zlib.h>
#include <zstd.h>

#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct fm_cache_writer {
    fm_output_file out;      /* PATH.partial until finish() */
    cache_layout l;
    uint32_t handed;         /* frames handed over by add_frame (or kept by resume) */
    size_t attr_at[CACHE_MAX_ATTRS]; /* attribute i's place in a slot and prev (64-byte aligned) */
    cache_encoder enc;       /* every piece */
    uint64_t *block_sizes;   /* the chunk's size table before it is written */
    uint32_t *ids;           /* 0 … n−1 when the layout has the id attribute */
    unsigned char *chunk;
    uint64_t *offsets, *sizes;
    uint32_t frames, index_cap;
    uint64_t pos;
    /* the worker */
    pthread_t thread;
    int thread_started;
    int team;                /* the worker's encoder team: 0 starting, 1 up, else the errno that stopped it */
    pthread_mutex_t lock;
    pthread_cond_t changed;
    /* A ring of frames handed over, attributes at attr_at. With two, the step loop hands frame k+1
     * over while k is being written instead of waiting for it (docs/performance.md#cache-writer). */
    unsigned char *slot[CACHE_WRITER_SLOTS]; /* slot_bytes each, made with the first frame */
    size_t slot_bytes;
    int ranks_write;         /* P ranks encode and write the frames (leave_frames_to_ranks) */
    int next, queued;        /* the slot the worker takes next; frames handed over and not yet written */
    int stop;
    fm_status worker_status; /* the first failure, reported by the next call */
    fm_error worker_err;
    double wait_seconds;     /* add_frame's time waiting for a free slot: 0 when the writer keeps up */
    fm_cache_frame_tap tap;  /* fm_cache_writer_set_tap's, or NULL */
    void *tap_user;
};

static void *worker_main(void *arg);

/* The hand-over slots and the encoder's buffers, made when the first frame comes (or a resume
 * takes over the last one): a writer whose frames the ranks write never needs them. */
static fm_status frame_buffers(fm_cache_writer *w, fm_error *err)
{
    if (w->slot[0]) return FM_OK;
    if (w->ranks_write) return fm_fail(err, FM_ERR_INTERNAL, "%s: the ranks write this cache's frames, not the writer", w->out.path);
    int ok = 1;
    for (int s = 0; s < CACHE_WRITER_SLOTS; s++) ok &= (w->slot[s] = fm_alloc(w->slot_bytes)) != NULL;
    if (ok && cache_encoder_alloc_buffers(&w->enc, err) == FM_OK) return FM_OK;
    for (int s = 0; s < CACHE_WRITER_SLOTS; s++) fm_free(w->slot[s]), w->slot[s] = NULL;
    return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for the frames of %llu agents", w->out.path,
                   (unsigned long long)w->l.agents);
}

const cache_layout *fm_cache_writer_layout(const fm_cache_writer *w) { return &w->l; }
const uint32_t *fm_cache_writer_ids(const fm_cache_writer *w) { return w->ids; }
double fm_cache_writer_wait_seconds(const fm_cache_writer *w) { return w->wait_seconds; }

static fm_status write_bytes(fm_cache_writer *w, const void *data, size_t n, fm_error *err)
{
    if (fwrite(data, 1, n, w->out.f) != n)
        return fm_fail(err, FM_ERR_IO, "%s: write failed: %s%s", w->out.partial, strerror(errno), fm_write_hint(errno));
    w->pos += n;
    return FM_OK;
}

static size_t align64(size_t n) { return (n + 63) / 64 * 64; }

/* A writer with its buffers and compressor, without a file or a thread yet. */
static fm_cache_writer *writer_alloc(const cache_layout *l, const char *path, fm_error *err)
{
    fm_cache_writer *w = calloc(1, sizeof *w);
    if (!w) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    w->out.fd = w->out.dir = -1; /* no file yet: abort() has nothing to close */
    w->l = *l;
    size_t total = 0;
    for (int i = 0; i < l->attr_count; i++) {
        w->attr_at[i] = total;
        total += align64(cache_attr_bytes(l, i));
    }
    w->slot_bytes = total;
    pthread_mutex_init(&w->lock, NULL);
    pthread_cond_init(&w->changed, NULL);
    w->chunk = malloc(CACHE_CHUNK_HEADER + cache_payload_bound(l));
    w->block_sizes = malloc(cache_table_bytes(l));
    int with_ids = cache_attr_index(l, FM_ATTR_ID) >= 0;
    if (with_ids && (w->ids = fm_alloc(sizeof(uint32_t) * (size_t)l->agents)) != NULL)
        for (uint64_t a = 0; a < l->agents; a++) w->ids[a] = (uint32_t)a;
    if (!w->chunk || !w->block_sizes || (with_ids && !w->ids) ||
        cache_encoder_init_bounds(&w->enc, l, 0, l->pieces, CACHE_ENCODER_THREADS, path, err) != FM_OK) {
        fm_cache_writer_abort(w);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache of %llu agents", (unsigned long long)l->agents), NULL;
    }
    return w;
}

/* Starts the writer thread; on failure frees w (and deletes its partial file). */
static fm_cache_writer *writer_start(fm_cache_writer *w, fm_error *err)
{
    w->out.keep_partial_on_failure = 1; /* a cache that fails to finish keeps its complete frames */
    int e = pthread_create(&w->thread, NULL, worker_main, w);
    if (!e) { /* the worker starts its encoder team while this thread waits (and allocates nothing) */
        pthread_mutex_lock(&w->lock);
        while (!w->team) pthread_cond_wait(&w->changed, &w->lock);
        pthread_mutex_unlock(&w->lock);
        w->thread_started = 1;
        if (w->team == 1) return w;
        e = w->team;
    }
    /* EAGAIN: no memory for a stack (ulimit -v) or the thread limit; out of memory either way */
    fm_fail(err, e == EAGAIN ? FM_ERR_MEMORY : FM_ERR_INTERNAL, "%s: cannot start the cache writer's threads: %s%s",
            w->out.path, strerror(e), e == EAGAIN ? " (out of memory for their stacks, or the thread limit)" : "");
    fm_cache_writer_abort(w);
    return NULL;
}

fm_cache_writer *fm_cache_writer_create_attrs(const char *path, uint64_t agents, double frame_rate,
                                              const fm_cache_attr *attrs, int attr_count,
                                              const fm_cache_options *opts, fm_error *err)
{
    cache_layout l;
    fm_cache_options defaults = fm_default_cache_options();
    if (cache_layout_init(&l, agents, frame_rate, attrs, attr_count, opts ? opts : &defaults, path, err) != FM_OK)
        return NULL;
    fm_cache_writer *w = writer_alloc(&l, path, err);
    if (!w) return NULL;
    unsigned char header[CACHE_MAX_HEADER];
    cache_header_encode(&l, header); /* frame count 0 until finish() */
    if (fm_output_open_fixed(&w->out, path, err) != FM_OK || write_bytes(w, header, l.header_bytes, err) != FM_OK) {
        fm_cache_writer_abort(w);
        return NULL;
    }
    return writer_start(w, err);
}

fm_cache_writer *fm_cache_writer_create(const char *path, uint64_t agents, double frame_rate,
                                        int level, fm_error *err)
{
    fm_cache_options opts = fm_default_cache_options();
    opts.compression_level = level;
    const fm_cache_attr tets = FM_ATTR_TET_VERTICES;
    return fm_cache_writer_create_attrs(path, agents, frame_rate, &tets, 1, &opts, err);
}

static fm_status grow_index(fm_cache_writer *w, fm_error *err)
{
    if (w->frames < w->index_cap) return FM_OK;
    uint32_t cap = w->index_cap ? 2 * w->index_cap : 256;
    uint64_t *offsets = realloc(w->offsets, sizeof *offsets * cap);
    if (offsets) w->offsets = offsets;
    uint64_t *sizes = offsets ? realloc(w->sizes, sizeof *sizes * cap) : NULL;
    if (!sizes) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache index");
    w->sizes = sizes, w->index_cap = cap;
    return FM_OK;
}

static fm_status append_chunk(fm_cache_writer *w, uint64_t packed, fm_error *err);

/* Filters, compresses and appends one frame (the worker's job). */
static fm_status write_frame(fm_cache_writer *w, const unsigned char *frame, fm_error *err)
{
    const cache_layout *l = &w->l;
    uint32_t k = w->frames;
    fm_status st = FM_OK;
    const void *data[CACHE_MAX_ATTRS];
    for (int i = 0; i < l->attr_count; i++) data[i] = frame + w->attr_at[i];
    uint64_t packed = 0;
    if (st == FM_OK)
        st = cache_encode_frame(&w->enc, data, k, w->chunk + CACHE_CHUNK_HEADER + cache_table_bytes(l), w->block_sizes,
                                &packed, err);
    return st == FM_OK ? append_chunk(w, packed, err) : st;
}

/* Chunk w->frames's head in w->chunk, all but its CRC: the header and the size table of blocks
 * `sizes` (`packed` bytes in all). */
static void put_chunk_head(fm_cache_writer *w, const uint64_t *sizes, uint64_t packed)
{
    const uint64_t table = cache_table_bytes(&w->l);
    for (uint64_t b = 0; b < table / 8; b++) put_u64(w->chunk + CACHE_CHUNK_HEADER + 8 * b, sizes[b]);
    memcpy(w->chunk, "FRAM", 4);
    put_u32(w->chunk + 4, w->frames);
    put_u32(w->chunk + 8, cache_is_key_frame(&w->l, w->frames) ? CHUNK_KEY_FRAME : 0);
    put_u64(w->chunk + 16, table + packed);
}

/* Appends chunk w->frames: its blocks (`packed` bytes) already after the size table's place in
 * w->chunk, their sizes in w->block_sizes. */
static fm_status append_chunk(fm_cache_writer *w, uint64_t packed, fm_error *err)
{
    const uint32_t k = w->frames;
    fm_status st = grow_index(w, err);
    if (st != FM_OK) return st;
    put_chunk_head(w, w->block_sizes, packed);
    const size_t at = CACHE_CHUNK_HEADER + cache_table_bytes(&w->l) + packed;
    put_u32(w->chunk + 12, cache_chunk_crc(w->chunk, at - CACHE_CHUNK_HEADER));
    w->offsets[k] = w->pos, w->sizes[k] = at;
    if ((st = write_bytes(w, w->chunk, at, err)) == FM_OK) w->frames++;
    return st;
}

static void *worker_main(void *arg)
{
    fm_cache_writer *w = arg;
    const int e = fm_threads_start_team(w->enc.threads); /* libgomp would end the process in the first frame */
    pthread_mutex_lock(&w->lock);
    w->team = e ? e : 1;
    pthread_cond_broadcast(&w->changed);
    if (e) w->stop = 1;
    for (;;) {
        while (!w->queued && !w->stop) pthread_cond_wait(&w->changed, &w->lock);
        if (!w->queued) break;
        const unsigned char *frame = w->slot[w->next]; /* add_frame does not touch a queued slot */
        pthread_mutex_unlock(&w->lock);
        fm_error err = {0};
        fm_status st = w->worker_status == FM_OK ? write_frame(w, frame, &err) : FM_OK;
        pthread_mutex_lock(&w->lock);
        if (st != FM_OK) w->worker_status = st, w->worker_err = err;
        w->next = (w->next + 1) % CACHE_WRITER_SLOTS;
        w->queued--;
        pthread_cond_broadcast(&w->changed);
    }
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

/* Waits until at most `queued` frames are waiting for the worker; returns its first failure.
 * Called with the lock held. */
static fm_status wait_queue(fm_cache_writer *w, int queued, fm_error *err)
{
    while (w->queued > queued) pthread_cond_wait(&w->changed, &w->lock);
    if (w->worker_status != FM_OK && err) *err = w->worker_err;
    return w->worker_status;
}

/* Waits until the worker has written every frame handed over. Called with the lock held. */
static fm_status wait_idle(fm_cache_writer *w, fm_error *err) { return wait_queue(w, 0, err); }

/* The frame goes into the ring's next free slot; the copy runs outside the lock, since the worker
 * only reads queued slots (one producer: the slot's place stays (next + queued) mod slots as the
 * worker advances next and lowers queued together). */
fm_status fm_cache_writer_add_frame_attrs(fm_cache_writer *w, const void *const *data, fm_error *err)
{
    if (w->tap) w->tap(w->handed, data, w->tap_user);
    if (frame_buffers(w, err) != FM_OK) return err->status;
    double t0 = fm_seconds();
    pthread_mutex_lock(&w->lock);
    fm_status st = wait_queue(w, CACHE_WRITER_SLOTS - 1, err);
    w->wait_seconds += fm_seconds() - t0;
    unsigned char *slot = w->slot[(w->next + w->queued) % CACHE_WRITER_SLOTS];
    pthread_mutex_unlock(&w->lock);
    if (st != FM_OK) return st;
    for (int i = 0; i < w->l.attr_count; i++) memcpy(slot + w->attr_at[i], data[i], cache_attr_bytes(&w->l, i));
    pthread_mutex_lock(&w->lock);
    w->queued++;
    w->handed++;
    pthread_cond_broadcast(&w->changed);
    pthread_mutex_unlock(&w->lock);
    return st;
}

/* Each block within the bound the writer's encoder gives it (it holds every piece); their total. */
static fm_status check_blocks(const fm_cache_writer *w, const uint64_t *sizes, uint64_t *packed, fm_error *err)
{
    *packed = 0;
    for (uint64_t b = 0; b < cache_table_bytes(&w->l) / 8; b++) {
        const uint64_t bound = w->enc.bound_at[b + 1] - w->enc.bound_at[b];
        if (sizes[b] > bound)
            return fm_fail(err, FM_ERR_INTERNAL, "%s: frame %u: block %llu of %llu bytes exceeds its bound %llu", w->out.path,
                           w->frames, (unsigned long long)b, (unsigned long long)sizes[b], (unsigned long long)bound);
        *packed += sizes[b];
    }
    return FM_OK;
}

const char *fm_cache_writer_partial_path(const fm_cache_writer *w) { return w->out.partial; }

fm_status fm_cache_writer_chunk_head(fm_cache_writer *w, const uint64_t *sizes, const uint32_t *run_crc,
                                     const uint64_t *run_bytes, int runs, cache_chunk_place *place, fm_error *err)
{
    double t0 = fm_seconds();
    pthread_mutex_lock(&w->lock);
    fm_status st = wait_idle(w, err); /* the frames handed over before this one go first */
    pthread_mutex_unlock(&w->lock);
    w->wait_seconds += fm_seconds() - t0;
    uint64_t packed = 0, runs_total = 0;
    if (st == FM_OK) st = check_blocks(w, sizes, &packed, err);
    if (st == FM_OK) st = grow_index(w, err);
    if (st != FM_OK) return st;
    const uint64_t table = cache_table_bytes(&w->l);
    const uint32_t k = w->frames;
    put_chunk_head(w, sizes, packed);
    /* cache_chunk_crc's bytes: the header but its CRC, the table, then the ranks' runs in order */
    uLong crc = cache_crc32(cache_crc32(0, w->chunk, 12), w->chunk + 16, 8 + (size_t)table);
    for (int r = 0; r < runs; r++) crc = crc32_combine(crc, run_crc[r], (z_off_t)run_bytes[r]), runs_total += run_bytes[r];
    if (runs_total != packed)
        return fm_fail(err, FM_ERR_INTERNAL, "%s: frame %u: the ranks wrote %llu bytes of blocks, not %llu", w->out.path, k,
                       (unsigned long long)runs_total, (unsigned long long)packed);
    put_u32(w->chunk + 12, (uint32_t)crc);
    *place = (cache_chunk_place){w->pos, w->chunk, CACHE_CHUNK_HEADER + (size_t)table, CACHE_CHUNK_HEADER + table + packed};
    return FM_OK;
}

fm_status fm_cache_writer_note_chunk(fm_cache_writer *w, const cache_chunk_place *place, fm_error *err)
{
    const uint32_t k = w->frames;
    w->offsets[k] = place->pos, w->sizes[k] = place->chunk_bytes;
    w->pos = place->pos + place->chunk_bytes, w->frames++, w->handed++;
    if (fseeko(w->out.f, (off_t)w->pos, SEEK_SET) == 0) return FM_OK; /* where the index will go */
    return fm_fail(err, FM_ERR_IO, "%s: cannot seek: %s", w->out.partial, strerror(errno));
}

const unsigned char *fm_cache_writer_prev(fm_cache_writer *w, int i) { return cache_encoder_prev(&w->enc, i); }

size_t fm_cache_writer_zstd_bytes(const fm_cache_writer *w)
{
    size_t bytes = 0;
    for (int t = 0; w->enc.cctx && t < w->enc.threads; t++) bytes += ZSTD_sizeof_CCtx(w->enc.cctx[t]);
    return bytes;
}

void fm_cache_writer_leave_frames_to_ranks(fm_cache_writer *w)
{
    pthread_mutex_lock(&w->lock);
    wait_idle(w, NULL); /* nothing was handed over: the worker is idle */
    pthread_mutex_unlock(&w->lock);
    for (int s = 0; s < CACHE_WRITER_SLOTS; s++) fm_free(w->slot[s]), w->slot[s] = NULL;
    fm_free(w->ids), w->ids = NULL;
    cache_encoder_keep_bounds(&w->enc); /* chunk_head checks the ranks' blocks against the bounds */
    w->ranks_write = 1;
    unsigned char *head = realloc(w->chunk, CACHE_CHUNK_HEADER + cache_table_bytes(&w->l));
    if (head) w->chunk = head; /* else the larger buffer stays */
}

fm_status fm_cache_writer_add_frame(fm_cache_writer *w, const float *verts, fm_error *err)
{
    if (w->l.attr_count != 1 || w->l.attrs[0]->attr != FM_ATTR_TET_VERTICES)
        return fm_fail(err, FM_ERR_USAGE, "%s: the cache holds %d attributes; frames go in with fm_cache_writer_add_frame_attrs",
                       w->out.path, w->l.attr_count);
    const void *data[1] = {verts};
    return fm_cache_writer_add_frame_attrs(w, data, err);
}

uint32_t fm_cache_writer_frames(const fm_cache_writer *w) { return w->handed; }
uint64_t fm_cache_writer_agents(const fm_cache_writer *w) { return w->l.agents; }
int fm_cache_writer_attr_count(const fm_cache_writer *w) { return w->l.attr_count; }

const fm_cache_attr_info *fm_cache_writer_attr_at(const fm_cache_writer *w, int i)
{
    return i >= 0 && i < w->l.attr_count ? w->l.attrs[i] : NULL;
}

void fm_cache_writer_set_tap(fm_cache_writer *w, fm_cache_frame_tap tap, void *user)
{
    w->tap = tap, w->tap_user = user;
}

fm_status fm_cache_writer_flush(fm_cache_writer *w, fm_error *err)
{
    pthread_mutex_lock(&w->lock);
    fm_status st = wait_idle(w, err);
    if (st == FM_OK && (fflush(w->out.f) != 0 || fsync(fileno(w->out.f)) != 0))
        st = fm_fail(err, FM_ERR_IO, "%s: cannot flush to disk: %s", w->out.partial, strerror(errno));
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
    for (int s = 0; s < CACHE_WRITER_SLOTS; s++) fm_free(w->slot[s]);
    fm_free(w->ids);
    cache_encoder_free(&w->enc);
    free(w->chunk), free(w->block_sizes), free(w->offsets), free(w->sizes);
    free(w);
}

static fm_status write_index_and_footer(fm_cache_writer *w, fm_error *err)
{
    uint64_t index_pos = w->pos;
    size_t bytes = 16 + 16 * (size_t)w->frames;
    unsigned char *index = malloc(bytes);
    if (!index) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache index");
    memcpy(index, "FIDX", 4);
    put_u32(index + 4, w->frames);
    for (uint32_t k = 0; k < w->frames; k++) {
        put_u64(index + 8 + 16 * (size_t)k, w->offsets[k]);
        put_u64(index + 16 + 16 * (size_t)k, w->sizes[k]);
    }
    put_u32(index + bytes - 8, cache_crc32(0, index, bytes - 8));
    put_u32(index + bytes - 4, 0);
    fm_status st = write_bytes(w, index, bytes, err);
    free(index);
    unsigned char footer[CACHE_FOOTER];
    put_u64(footer, index_pos);
    memcpy(footer + 8, CACHE_END_MAGIC, 8);
    return st == FM_OK ? write_bytes(w, footer, sizeof footer, err) : st;
}

/* The header's frame count, 0 since create, becomes F once the index is written; the header crc
 * is recomputed with it. fm_output_commit then fsyncs and renames. */
static fm_status patch_header_frames(fm_cache_writer *w, fm_error *err)
{
    unsigned char header[CACHE_MAX_HEADER];
    w->l.header_frames = w->frames;
    cache_header_encode(&w->l, header);
    if (fseeko(w->out.f, 0, SEEK_SET) != 0 || fwrite(header, 1, w->l.header_bytes, w->out.f) != w->l.header_bytes)
        return fm_fail(err, FM_ERR_IO, "%s: cannot write the header's frame count: %s%s", w->out.partial, strerror(errno),
                       fm_write_hint(errno));
    return FM_OK;
}

fm_status fm_cache_writer_finish(fm_cache_writer *w, fm_error *err)
{
    fm_status st = stop_worker(w, err);
    if (st == FM_OK) st = write_index_and_footer(w, err);
    if (st == FM_OK) st = patch_header_frames(w, err);
    if (st == FM_OK) st = fm_output_commit(&w->out, NULL, err);
    else fm_output_keep_partial(&w->out); /* its complete frames stay readable */
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

/* Stops the writer and keeps PATH.partial with the frames written so far (for --resume). Its
 * header's frame count stays 0: the file is unfinished (a resumed writer appends to it), and a
 * reader finds its frames by walking the chunks in any case. */
void fm_cache_writer_close_partial(fm_cache_writer *w)
{
    if (!w) return;
    stop_worker(w, NULL);
    fm_output_keep_partial(&w->out);
    free_writer(w);
}

/* ---------------------------------------------------------------- resume */

/* Checks the first `frames` chunks of the partial cache (headers and checksums), takes over
 * their index entries and, for delta, the stored words of frame frames-1. */
static fm_status take_over_prefix(fm_cache_writer *w, fm_cache_reader *r, uint32_t frames, fm_error *err)
{
    const cache_layout *l = cache_reader_layout(r);
    if (fm_cache_frames(r) < frames)
        return fm_fail(err, FM_ERR_INPUT, "%s: cannot resume after frame %u: only %u complete frames are readable",
                       w->out.partial, frames, fm_cache_frames(r));
    fm_status st = FM_OK;
    w->pos = l->header_bytes;
    for (uint32_t k = 0; k < frames && st == FM_OK; k++) {
        if ((st = cache_reader_check_chunk(r, k, err)) != FM_OK || (st = grow_index(w, err)) != FM_OK) break;
        w->offsets[k] = cache_reader_offsets(r)[k];
        w->sizes[k] = cache_reader_chunk_end(r, k) - w->offsets[k];
        w->pos = cache_reader_chunk_end(r, k);
        w->frames = w->handed = k + 1;
    }
    if (st == FM_OK && l->opts.delta && frames > 0) st = cache_encoder_alloc_prev(&w->enc, err); /* the last frame's words */
    for (int i = 0; i < l->attr_count && st == FM_OK && l->opts.delta && frames > 0; i++) {
        const unsigned char *words;
        if ((st = cache_reader_stored(r, frames - 1, i, &words, err)) == FM_OK)
            memcpy(cache_encoder_prev(&w->enc, i), words, cache_attr_bytes(l, i));
    }
    return st;
}

fm_cache_writer *fm_cache_writer_resume(const char *path, uint32_t frames, fm_error *err)
{
    fm_output_file probe;
    if (fm_output_name(&probe, path, err) != FM_OK) return NULL;
    if (access(probe.partial, F_OK) != 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: nothing to resume: %s does not exist", path, probe.partial), NULL;
    fm_cache_reader *r = fm_cache_open(probe.partial, err);
    if (!r) return NULL;
    if (cache_reader_layout(r)->version != CACHE_VERSION) {
        fm_fail(err, FM_ERR_INPUT, "%s: cache format %u cannot be resumed (this build writes format %d)",
                probe.partial, cache_reader_layout(r)->version, CACHE_VERSION);
        return fm_cache_close(r), NULL;
    }
    fm_cache_writer *w = writer_alloc(cache_reader_layout(r), path, err);
    if (!w) return fm_cache_close(r), NULL;
    snprintf(w->out.partial, sizeof w->out.partial, "%s", probe.partial); /* for messages */
    fm_status st = take_over_prefix(w, r, frames, err);
    fm_cache_close(r);
    if (st == FM_OK) st = fm_output_reopen(&w->out, path, w->pos, err);
    if (st != FM_OK) {
        free_writer(w); /* PATH.partial stays as it was */
        return NULL;
    }
    return writer_start(w, err);
}
