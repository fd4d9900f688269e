/* The encoding of a frame's blocks (docs/cache-format.md, format 4: filters and compression, piece
 * by piece). The writer runs it over every piece on its own thread team; a rank of a run on P ranks
 * over the pieces it owns (cache_parts.c). The team compresses each block into its place at zstd's
 * bound, then the blocks close up in order, so the bytes do not depend on the team's size. */
#include "cache_format.h"

#include <omp.h>
#include <zstd.h>
#include <zstd_errors.h>
#include <stdlib.h>

uint64_t cache_encoder_blocks(const cache_encoder *e)
{
    return (e->piece_end - e->piece_begin) * (uint64_t)e->l.attr_count;
}

uint64_t cache_encoder_bound(const cache_encoder *e) { return e->bound_at[cache_encoder_blocks(e)]; }

unsigned char *cache_encoder_prev(cache_encoder *e, int i) { return e->prev + e->attr_at[i]; }

static uint64_t block_piece(const cache_encoder *e, uint64_t b) { return e->piece_begin + b / (uint64_t)e->l.attr_count; }
static int block_attr(const cache_encoder *e, uint64_t b) { return (int)(b % (uint64_t)e->l.attr_count); }

/* Block b's words in stored and prev. */
static size_t block_at(const cache_encoder *e, uint64_t b)
{
    const uint64_t j = block_piece(e, b);
    const int i = block_attr(e, b);
    return e->attr_at[i] + (size_t)(cache_piece_first(&e->l, j) - e->agent_begin) * e->l.attrs[i]->bytes_per_agent;
}

fm_status cache_encoder_init_bounds(cache_encoder *e, const cache_layout *l, uint64_t piece_begin, uint64_t piece_end,
                                    int threads, const char *path, fm_error *err)
{
    memset(e, 0, sizeof *e);
    e->l = *l;
    e->piece_begin = piece_begin, e->piece_end = piece_end;
    e->agent_begin = FM_MIN(cache_piece_first(l, piece_begin), l->agents);
    e->agent_end = FM_MIN(cache_piece_first(l, piece_end), l->agents);
    e->threads = FM_MAX(threads, 1);
    snprintf(e->path, sizeof e->path, "%s", path);
    size_t total = 0;
    for (int i = 0; i < l->attr_count; i++) {
        e->attr_at[i] = total;
        total += (size_t)(e->agent_end - e->agent_begin) * l->attrs[i]->bytes_per_agent;
    }
    const uint64_t blocks = cache_encoder_blocks(e);
    e->bound_at = malloc(sizeof *e->bound_at * (size_t)(blocks + 1));
    if (!e->bound_at) return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for the cache's block table", path);
    e->bound_at[0] = 0;
    for (uint64_t b = 0; b < blocks; b++)
        e->bound_at[b + 1] = e->bound_at[b] + ZSTD_compressBound(cache_block_bytes(l, block_piece(e, b), block_attr(e, b)));
    return FM_OK;
}

/* The range's words of every attribute (stored and prev hold that many bytes). */
static size_t range_bytes(const cache_encoder *e)
{
    size_t total = 0;
    for (int i = 0; i < e->l.attr_count; i++) total += (size_t)(e->agent_end - e->agent_begin) * e->l.attrs[i]->bytes_per_agent;
    return total;
}

fm_status cache_encoder_alloc_prev(cache_encoder *e, fm_error *err)
{
    if (e->prev || !e->l.opts.delta) return FM_OK;
    if ((e->prev = fm_alloc(FM_MAX(range_bytes(e), 1)))) return FM_OK;
    return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for the previous frame of %llu agents", e->path,
                   (unsigned long long)(e->agent_end - e->agent_begin));
}

fm_status cache_encoder_alloc_buffers(cache_encoder *e, fm_error *err)
{
    const cache_layout *l = &e->l;
    size_t total = range_bytes(e), largest = 0;
    for (int i = 0; i < l->attr_count; i++)
        largest = FM_MAX(largest, cache_block_bytes(l, e->piece_begin, i)); /* the first piece is a full one */
    if (cache_encoder_alloc_prev(e, err) != FM_OK) return err->status; /* a resumed writer's may be there */
    e->stored = fm_alloc(FM_MAX(total, 1));
    e->scratch = calloc((size_t)e->threads, sizeof *e->scratch);
    e->cctx = calloc((size_t)e->threads, sizeof *e->cctx);
    int ok = e->stored && (!l->opts.delta || e->prev) && e->scratch && e->cctx;
    for (int t = 0; ok && t < e->threads; t++) {
        ok = (e->scratch[t] = fm_alloc(FM_MAX(largest, 1))) != NULL && (e->cctx[t] = ZSTD_createCCtx()) != NULL;
        if (ok) ZSTD_CCtx_setParameter(e->cctx[t], ZSTD_c_compressionLevel, l->opts.compression_level);
    }
    if (ok) return FM_OK;
    cache_encoder_keep_bounds(e);
    return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for the cache encoder of %llu agents", e->path,
                   (unsigned long long)(e->agent_end - e->agent_begin));
}

fm_status cache_encoder_init(cache_encoder *e, const cache_layout *l, uint64_t piece_begin, uint64_t piece_end,
                             int threads, const char *path, fm_error *err)
{
    fm_status st = cache_encoder_init_bounds(e, l, piece_begin, piece_end, threads, path, err);
    if (st == FM_OK) st = cache_encoder_alloc_buffers(e, err);
    if (st != FM_OK) cache_encoder_free(e);
    return st;
}

void cache_encoder_keep_bounds(cache_encoder *e)
{
    for (int t = 0; t < e->threads && e->scratch; t++) fm_free(e->scratch[t]);
    for (int t = 0; t < e->threads && e->cctx; t++) ZSTD_freeCCtx(e->cctx[t]);
    fm_free(e->stored), fm_free(e->prev), free(e->scratch), free(e->cctx);
    e->stored = e->prev = NULL, e->scratch = NULL, e->cctx = NULL;
}

void cache_encoder_free(cache_encoder *e)
{
    cache_encoder_keep_bounds(e);
    free(e->bound_at);
    memset(e, 0, sizeof *e);
}

/* Stored words and prev become the delta to the previous frame and the current frame's words. */
static void delta_encode(unsigned char *stored, unsigned char *prev, size_t n)
{
    for (size_t j = 0; j < n; j++) {
        unsigned char cur = stored[j];
        stored[j] ^= prev[j];
        prev[j] = cur;
    }
}

/* Block b of frame k quantised, shuffled and delta-encoded into stored. Returns the index of the
 * block's first value the quantum cannot hold, or -1. */
static int64_t filter_block(cache_encoder *e, const void *const *data, uint64_t b, uint32_t k, unsigned char *scratch)
{
    const int i = block_attr(e, b);
    const size_t at = block_at(e, b), bytes = cache_block_bytes(&e->l, block_piece(e, b), i);
    const unsigned char *src = (const unsigned char *)data[i] + (at - e->attr_at[i]);
    const uint32_t filters = e->l.filters[i];
    unsigned char *stored = e->stored + at;
    if (filters & FILTER_QUANTISE) {
        int64_t bad = cache_quantise((const float *)src, bytes / 4, e->l.opts.quantum, (int32_t *)scratch);
        if (bad >= 0) return bad;
        src = scratch;
    }
    if (filters & FILTER_SHUFFLE4) cache_shuffle4(src, bytes / 4, stored);
    else memcpy(stored, src, bytes);
    if (!(filters & FILTER_DELTA)) return -1;
    if (cache_is_key_frame(&e->l, k)) memcpy(e->prev + at, stored, bytes);
    else delta_encode(stored, e->prev + at, bytes);
    return -1;
}

/* The first failure in the order the blocks of one attribute, then the next, would meet it (the
 * message of a quantum that cannot hold a value names its first agent). */
static fm_status first_failure(const cache_encoder *e, const void *const *data, uint32_t k, const int64_t *bad,
                               const size_t *packed, fm_error *err)
{
    const uint64_t pieces = e->piece_end - e->piece_begin;
    for (int i = 0; i < e->l.attr_count; i++)
        for (uint64_t p = 0; p < pieces; p++) {
            const uint64_t b = p * (uint64_t)e->l.attr_count + (uint64_t)i;
            if (bad[b] >= 0) {
                const size_t local = (block_at(e, b) - e->attr_at[i]) / 4 + (size_t)bad[b];
                const int64_t agent = (int64_t)e->agent_begin + (int64_t)(local / (size_t)e->l.attrs[i]->components);
                return fm_fail(err, FM_ERR_INPUT, "%s: frame %u, %s, agent %lld: %g " CACHE_QUANTUM_FAILURE " %g below 2^31",
                               e->path, k, e->l.attrs[i]->name, (long long)agent, (double)((const float *)data[i])[local],
                               e->l.opts.quantum);
            }
            if (ZSTD_isError(packed[b])) /* zstd allocates its window in the first call */
                return fm_fail(err, ZSTD_getErrorCode(packed[b]) == ZSTD_error_memory_allocation ? FM_ERR_MEMORY
                                                                                                   : FM_ERR_INTERNAL,
                               "%s: zstd failed: %s", e->path, ZSTD_getErrorName(packed[b]));
        }
    return FM_OK;
}

fm_status cache_encode_frame(cache_encoder *e, const void *const *data, uint32_t k, unsigned char *out, uint64_t *sizes,
                             uint64_t *bytes, fm_error *err)
{
    const int64_t blocks = (int64_t)cache_encoder_blocks(e);
    int64_t *bad = malloc(sizeof *bad * (size_t)FM_MAX(blocks, 1));
    size_t *packed = malloc(sizeof *packed * (size_t)FM_MAX(blocks, 1));
    if (!bad || !packed) return free(bad), free(packed), fm_fail(err, FM_ERR_MEMORY, "%s: out of memory", e->path);
#pragma omp parallel for num_threads(e->threads) schedule(dynamic, 1)
    for (int64_t b = 0; b < blocks; b++) {
        const int t = omp_get_thread_num();
        bad[b] = filter_block(e, data, (uint64_t)b, k, e->scratch[t]);
        packed[b] = 0;
        if (bad[b] < 0) {
            const size_t n = cache_block_bytes(&e->l, block_piece(e, (uint64_t)b), block_attr(e, (uint64_t)b));
            packed[b] = ZSTD_compress2(e->cctx[t], out + e->bound_at[b], e->bound_at[b + 1] - e->bound_at[b],
                                       e->stored + block_at(e, (uint64_t)b), n);
        }
    }
    fm_status st = first_failure(e, data, k, bad, packed, err);
    uint64_t at = 0;
    for (int64_t b = 0; b < blocks && st == FM_OK; b++) { /* close up: a block only moves towards the start */
        memmove(out + at, out + e->bound_at[b], packed[b]);
        sizes[b] = packed[b];
        at += packed[b];
    }
    *bytes = at;
    free(bad), free(packed);
    return st;
}

/* ---------------------------------------------------------------- a rank's share */

uint64_t cache_share_agent_begin(const cache_layout *l, int r, int ranks)
{
    const uint64_t piece = l->pieces * (uint64_t)r / (uint64_t)ranks; /* J r / P: every rank at most one piece more */
    return FM_MIN(cache_piece_first(l, piece), l->agents);
}

fm_status cache_share_init(cache_share *sh, const unsigned char *header, uint32_t header_bytes, int rank, int ranks,
                           int threads, fm_error *err)
{
    memset(sh, 0, sizeof *sh);
    cache_layout l;
    memset(&l, 0, sizeof l);
    if (header_bytes < CACHE_FIXED_HEADER || header_bytes > CACHE_MAX_HEADER)
        return fm_fail(err, FM_ERR_INTERNAL, "a cache share from a %u-byte header", header_bytes);
    l.version = get_u32(header + 8), l.header_bytes = header_bytes;
    fm_status st = cache_header_decode(&l, header, "the cache's header from rank 0", err);
    if (st != FM_OK) return st;
    const uint64_t begin = l.pieces * (uint64_t)rank / (uint64_t)ranks, end = l.pieces * (uint64_t)(rank + 1) / (uint64_t)ranks;
    if ((st = cache_encoder_init(&sh->enc, &l, begin, end, threads, "the cache share", err)) != FM_OK) return st;
    const uint64_t agents = sh->enc.agent_end - sh->enc.agent_begin, blocks = cache_encoder_blocks(&sh->enc);
    sh->blocks = fm_alloc(FM_MAX((size_t)cache_encoder_bound(&sh->enc), 1));
    sh->sizes = malloc(sizeof *sh->sizes * (size_t)FM_MAX(blocks, 1));
    sh->ids = fm_alloc(sizeof *sh->ids * (size_t)FM_MAX(agents, 1));
    if (!sh->blocks || !sh->sizes || !sh->ids) {
        cache_share_free(sh);
        return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache share of %llu agents", (unsigned long long)agents);
    }
    for (uint64_t a = 0; a < agents; a++) sh->ids[a] = (uint32_t)(sh->enc.agent_begin + a);
    return FM_OK;
}

void cache_share_free(cache_share *sh)
{
    cache_encoder_free(&sh->enc);
    fm_free(sh->blocks), free(sh->sizes), fm_free(sh->ids);
    memset(sh, 0, sizeof *sh);
}

fm_status cache_share_encode(cache_share *sh, const void *const *by_kind, uint32_t k, fm_error *err)
{
    const cache_layout *l = &sh->enc.l;
    const void *data[CACHE_MAX_ATTRS];
    for (int i = 0; i < l->attr_count; i++) {
        const fm_cache_attr kind = l->attrs[i]->attr;
        const unsigned char *all = kind == FM_ATTR_ID ? NULL : by_kind[kind];
        if (kind != FM_ATTR_ID && !all)
            return fm_fail(err, FM_ERR_INTERNAL, "a cache share was given no %s", l->attrs[i]->name);
        data[i] = kind == FM_ATTR_ID ? (const void *)sh->ids : all;
    }
    return cache_encode_frame(&sh->enc, data, k, sh->blocks, sh->sizes, &sh->bytes, err);
}
