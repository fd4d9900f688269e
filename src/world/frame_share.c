/* The cache written by P ranks in parallel (frame_share.h, docs/scale-out.md). */
#include "frame_share.h"

#include <stdlib.h>
#include <string.h>

/* Rank 0 hands every rank its share of the resumed writer's last stored frame (the words delta
 * goes on from): attribute after attribute, as the share's encoder keeps them. A record is one
 * agent's bytes of every attribute, so MPI's int counts reach 2^31 agents, not bytes. */
static fm_status hand_out_prev(fm_frame_share *f, const fm_dist *d, fm_cache_writer *cache, fm_error *err)
{
    const cache_layout *l = &f->share.enc.l;
    const int ranks = fm_dist_size(d), root = fm_dist_rank(d) == 0;
    size_t record = 0;
    for (int i = 0; i < l->attr_count; i++) record += l->attrs[i]->bytes_per_agent;
    int64_t *count = calloc((size_t)ranks, sizeof *count);
    unsigned char *send = root ? fm_alloc(FM_MAX(cache_frame_bytes(l), 1)) : NULL;
    fm_status st = count && (send || !root) ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "out of memory resuming the cache");
    size_t at = 0;
    for (int r = 0; st == FM_OK && root && r < ranks; r++) {
        count[r] = f->begin[r + 1] - f->begin[r];
        for (int i = 0; i < l->attr_count; i++) {
            const size_t per = l->attrs[i]->bytes_per_agent, bytes = per * (size_t)count[r];
            memcpy(send + at, fm_cache_writer_prev(cache, i) + per * (size_t)f->begin[r], bytes);
            at += bytes;
        }
    }
    st = fm_dist_agree(d, st, err);
    void *mine = NULL;
    int64_t got = 0;
    if (st == FM_OK) st = fm_dist_exchange(d, send, count, record, &mine, &got, err);
    if (st == FM_OK && got > 0) memcpy(cache_encoder_prev(&f->share.enc, 0), mine, record * (size_t)got); /* the attributes follow one another */
    fm_free(send), fm_free(mine), free(count);
    return st;
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
    fm_status st = f->begin ? cache_share_init(&f->share, header, header_bytes, fm_dist_rank(d), ranks, threads, err)
                            : fm_fail(err, FM_ERR_MEMORY, "out of memory");
    if ((st = fm_dist_agree(d, st, err)) != FM_OK) return fm_frame_share_free(f), st;
    for (int r = 0; r <= ranks; r++) f->begin[r] = (int64_t)cache_share_agent_begin(&f->share.enc.l, r, ranks);
    f->on = 1;
    if (resumed && f->share.enc.l.opts.delta && (st = hand_out_prev(f, d, cache, err)) != FM_OK) fm_frame_share_free(f);
    return st;
}

void fm_frame_share_free(fm_frame_share *f)
{
    cache_share_free(&f->share);
    free(f->begin);
    memset(f, 0, sizeof *f);
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

fm_status fm_frame_share_write(fm_frame_share *f, const fm_dist *d, fm_cache_writer *cache, const void *const *by_kind,
                               uint32_t k, int64_t *sent, fm_error *err)
{
    cache_share *sh = &f->share;
    fm_status st = fm_dist_agree(d, cache_share_encode(sh, by_kind, k, err), err);
    const int64_t blocks = (int64_t)cache_encoder_blocks(&sh->enc), root = fm_dist_rank(d) == 0;
    void *sizes = NULL, *bytes = NULL;
    int64_t all_blocks = 0, all_bytes = 0;
    if (st == FM_OK) st = fm_dist_gather(d, sh->sizes, blocks, sizeof(uint64_t), &sizes, &all_blocks, err);
    if (st == FM_OK) st = fm_dist_gather(d, sh->blocks, (int64_t)sh->bytes, 1, &bytes, &all_bytes, err);
    if (st == FM_OK && !root) *sent += blocks * (int64_t)sizeof(uint64_t) + (int64_t)sh->bytes;
    if (st == FM_OK && root) {
        if ((uint64_t)all_blocks != cache_table_bytes(&sh->enc.l) / 8)
            st = fm_fail(err, FM_ERR_INTERNAL, "frame %u: the ranks encoded %lld blocks, not %llu", k, (long long)all_blocks,
                         (unsigned long long)(cache_table_bytes(&sh->enc.l) / 8));
        else
            st = fm_cache_writer_add_blocks(cache, sizes, bytes, err);
    }
    fm_free(sizes), fm_free(bytes);
    return fm_dist_agree(d, st, err);
}
