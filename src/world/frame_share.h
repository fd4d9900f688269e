/* The cache written by P ranks in parallel (docs/scale-out.md): each rank filters and compresses
 * its share of every frame, the pieces [J r / P, J (r + 1) / P) of the cache (ids begin[r] …
 * begin[r + 1] − 1), and writes its blocks at their place in the frame's chunk through one MPI-IO
 * handle on the cache's .partial file; rank 0 writes the chunk's head and keeps the index.
 * A block's bytes do not depend on which rank or how many threads encode it, so the file is the
 * one process's, byte for byte, for any P and T. What a rank hands over is compressed: the frame's
 * filtering and compression, the run's serial term when rank 0 did it all, is spread over the
 * ranks. */
#ifndef FM_FRAME_SHARE_H
#define FM_FRAME_SHARE_H

#include "cache_format.h"
#include "dist.h"

typedef struct fm_frame_share {
    cache_share share;
    int64_t *begin; /* P + 1 bounds of the ranks' shares of the ids */
    uint64_t *at;   /* P: where each rank's blocks of this frame go in the file */
    fm_dist_file *file; /* every rank's handle on the cache's .partial */
    int on;         /* 0: one process, or no cache (nothing to encode) */
} fm_frame_share;

/* Every rank: the share of this rank of the cache rank 0 writes (`cache` there; NULL elsewhere),
 * encoding on `threads` threads. On one process, or with no cache on rank 0, f->on stays 0. A
 * resumed run's ranks get their shares of the writer's last frame (delta goes on from it). */
fm_status fm_frame_share_start(fm_frame_share *f, const fm_dist *d, fm_cache_writer *cache, int threads, int resumed,
                               fm_error *err);
/* Once the run keeps the share on: rank 0's writer frees its frame buffers, which the ranks' encoders
 * replace (fm_cache_writer_leave_frames_to_ranks). */
void fm_frame_share_commit(const fm_frame_share *f, fm_cache_writer *cache);
/* Collective (the file's handle is closed): every rank, after the run, before rank 0 finishes the
 * cache. */
void fm_frame_share_free(fm_frame_share *f);
/* Collective: every rank's blocks so far on disk (before a checkpoint counts their frames). */
fm_status fm_frame_share_sync(fm_frame_share *f, fm_error *err);
/* The rank whose share (begin[r] <= id < begin[r + 1], P + 1 bounds) holds `id`. */
int fm_frame_share_owner(const int64_t *begin, int ranks, int64_t id);
/* This rank's share of the ids: first … end − 1 (its encoder's agents). */
int64_t fm_frame_share_first(const fm_frame_share *f);
int64_t fm_frame_share_end(const fm_frame_share *f);
/* Frame k, the rank's share complete in arrays in id order from its first agent (by_kind, as
 * cache_share_encode takes them): encoded and written here, the chunk's head by rank 0. Every rank returns the same status;
 * *sent adds the bytes this rank sent. */
fm_status fm_frame_share_write(fm_frame_share *f, const fm_dist *d, fm_cache_writer *cache, const void *const *by_kind,
                               uint32_t k, int64_t *sent, fm_error *err);

#endif
