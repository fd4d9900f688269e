/* The cache written by P ranks in parallel (frame_share.h, docs/scale-out.md). */
#include "frame_share.h"

#include <stdlib.h>
#include <string.h>

/* Rank 0 hands every rank its share of the resumed writer's last stored frame (the words delta
 * goes on from), an attribute at a time straight from the writer's words (its shares are ranges of
 * them), into the share's encoder. A record is one agent's bytes of the attribute, so MPI's int
 * counts reach 2^31 agents, not bytes. */
static fm_status hand_out_prev(fm_frame_share *f, const fm_dist *d, fm_cache_writer *cache, fm_error *err)
{
    cache_encoder *e = &f->share.enc;
    const int ranks = fm_dist_size(d), root = fm_dist_rank(d) == 0;
    int64_t *count = calloc((size_t)ranks, sizeof *count);
    fm_status st = count ? cache_encoder_alloc_prev(e, err) : fm_fail(err, FM_ERR_MEMORY, "out of memory resuming the cache");
    for (int r = 0; root && count && r < ranks; r++) count[r] = f->begin[r + 1] - f->begin[r];
    st = fm_dist_agree(d, st, err);
    for (int i = 0; st == FM_OK && i < e->l.attr_count; i++) {
        const size_t per = e->l.attrs[i]->bytes_per_agent;
        void *mine = NULL;
        int64_t got = 0;
        st = fm_dist_exchange(d, root ? fm_cache_writer_prev(cache, i) : NULL, count, per, &mine, &got, err);
        if (st == FM_OK && got > 0) memcpy(cache_encoder_prev(e, i), mine, per * (size_t)got);
        fm_free(mine);
    }
    free(count);
    return st;
}

/* Every rank's handle on the cache's .partial (rank 0 names it). */
static fm_status attach_file(fm_frame_share *f, const fm_dist *d, fm_cache_writer *cache, fm_error *err)
{
    char path[FM_PATH_MAX + 16] = {0};
    if (fm_dist_rank(d) == 0) snprintf(path, sizeof path, "%s", fm_cache_writer_partial_path(cache));
    fm_dist_bcast(d, path, sizeof path, 0);
    f->file = fm_dist_file_attach(d, path, err);
    return f->file ? FM_OK : err->status;
}

fm_status fm_frame_share_start(fm_frame_share *f, const fm_dist *d, fm_cache_writer *cache, int threads, int resumed,
                               fm_error *err)
{
    memset(f, 0, sizeof *f);
    if (fm_dist_size(d) < 2) return FM_OK;
    unsigned char header[CACHE_MAX_HEADER] = {0};
    uint32_t header_bytes = 0;
    if (fm_dist_rank(d) == 0 && cache) {
        const cache_layout *l = fm_cache_writer_layout(cache);
        cache_header_encode(l, header);
        header_bytes = l->header_bytes;
    }
    fm_dist_bcast(d, &header_bytes, sizeof header_bytes, 0);
    if (header_bytes == 0) return FM_OK;
    fm_dist_bcast(d, header, header_bytes, 0);
    const int ranks = fm_dist_size(d);
    f->begin = malloc(sizeof *f->begin * ((size_t)ranks + 1));
    f->at = malloc(sizeof *f->at * (size_t)ranks);
    fm_status st = f->begin && f->at ? cache_share_init(&f->share, header, header_bytes, fm_dist_rank(d), ranks, threads, err)
                                     : fm_fail(err, FM_ERR_MEMORY, "out of memory");
    if ((st = fm_dist_agree(d, st, err)) == FM_OK) st = attach_file(f, d, cache, err);
    if (st != FM_OK) return fm_frame_share_free(f), st;
    for (int r = 0; r <= ranks; r++) f->begin[r] = (int64_t)cache_share_agent_begin(&f->share.enc.l, r, ranks);
    f->on = 1;
    if (resumed && f->share.enc.l.opts.delta && (st = hand_out_prev(f, d, cache, err)) != FM_OK) fm_frame_share_free(f);
    return st;
}

void fm_frame_share_commit(const fm_frame_share *f, fm_cache_writer *cache)
{
    if (f->on && cache) fm_cache_writer_leave_frames_to_ranks(cache); /* cache: rank 0's */
}

void fm_frame_share_free(fm_frame_share *f)
{
    if (f->file) fm_dist_file_detach(f->file, NULL); /* a failed write was reported when it happened */
    cache_share_free(&f->share);
    free(f->begin), free(f->at);
    memset(f, 0, sizeof *f);
}

fm_status fm_frame_share_sync(fm_frame_share *f, fm_error *err)
{
    return f->file ? fm_dist_file_sync(f->file, err) : FM_OK;
}

int fm_frame_share_owner(const int64_t *begin, int ranks, int64_t id)
{
    int lo = 0, hi = ranks - 1;
    while (lo < hi) {
        const int mid = (lo + hi + 1) / 2;
        if (begin[mid] <= id) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}

int64_t fm_frame_share_first(const fm_frame_share *f) { return (int64_t)f->share.enc.agent_begin; }

int64_t fm_frame_share_end(const fm_frame_share *f) { return (int64_t)f->share.enc.agent_end; }

/* One rank's blocks of a frame: their length and CRC-32 (rank 0 combines the chunk's CRC). */
typedef struct run_record {
    uint64_t bytes;
    uint32_t crc, pad;
} run_record;

/* Rank 0: the chunk's head from every rank's block sizes and runs, and where each rank's run goes. */
static fm_status place_chunk(fm_frame_share *f, int ranks, fm_cache_writer *cache, const uint64_t *sizes, int64_t blocks,
                             const run_record *runs, cache_chunk_place *place, uint32_t k, fm_error *err)
{
    const uint64_t want = cache_table_bytes(&f->share.enc.l) / 8;
    if ((uint64_t)blocks != want)
        return fm_fail(err, FM_ERR_INTERNAL, "frame %u: the ranks encoded %lld blocks, not %llu", k, (long long)blocks,
                       (unsigned long long)want);
    uint32_t *crc = malloc(sizeof *crc * (size_t)ranks);
    uint64_t *bytes = malloc(sizeof *bytes * (size_t)ranks);
    fm_status st = crc && bytes ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory");
    for (int r = 0; st == FM_OK && r < ranks; r++) crc[r] = runs[r].crc, bytes[r] = runs[r].bytes;
    if (st == FM_OK) st = fm_cache_writer_chunk_head(cache, sizes, crc, bytes, ranks, place, err);
    for (int r = 0; st == FM_OK && r < ranks; r++)
        f->at[r] = (r ? f->at[r - 1] + bytes[r - 1] : place->pos + place->head_bytes);
    free(crc), free(bytes);
    return st;
}

fm_status fm_frame_share_write(fm_frame_share *f, const fm_dist *d, fm_cache_writer *cache, const void *const *by_kind,
                               uint32_t k, int64_t *sent, fm_error *err)
{
    cache_share *sh = &f->share;
    fm_status st = fm_dist_agree(d, cache_share_encode(sh, by_kind, k, err), err);
    const int64_t blocks = (int64_t)cache_encoder_blocks(&sh->enc);
    const int root = fm_dist_rank(d) == 0, ranks = fm_dist_size(d);
    const run_record mine = {sh->bytes, cache_crc32(0, sh->blocks, (size_t)sh->bytes), 0};
    void *sizes = NULL, *runs = NULL;
    int64_t all_blocks = 0, all_runs = 0;
    cache_chunk_place place = {0};
    if (st == FM_OK) st = fm_dist_gather(d, sh->sizes, blocks, sizeof(uint64_t), &sizes, &all_blocks, err);
    if (st == FM_OK) st = fm_dist_gather(d, &mine, 1, sizeof mine, &runs, &all_runs, err);
    if (st == FM_OK && root) st = place_chunk(f, ranks, cache, sizes, all_blocks, runs, &place, k, err);
    st = fm_dist_agree(d, st, err);
    if (st == FM_OK) fm_dist_bcast(d, f->at, sizeof *f->at * (size_t)ranks, 0);
    if (st == FM_OK && root) st = fm_dist_file_write_at(f->file, place.pos, place.head, place.head_bytes, err);
    if (st == FM_OK) st = fm_dist_file_write_at(f->file, f->at[fm_dist_rank(d)], sh->blocks, (size_t)sh->bytes, err);
    st = fm_dist_agree(d, st, err); /* every rank's blocks written: the chunk is complete */
    if (st == FM_OK && root) st = fm_cache_writer_note_chunk(cache, &place, err);
    if (!root) *sent += blocks * (int64_t)sizeof(uint64_t) + (int64_t)sizeof mine;
    fm_free(sizes), fm_free(runs);
    return fm_dist_agree(d, st, err);
}
