/* The native frame cache's on-disk layout and filters, shared by the writer (cache_writer.c) and
 * the reader (cache_reader.c). docs/cache-format.md is the specification; the names here follow it.
 *
 * Format 4 (format 3 with the agents cut into pieces):
 *   header   72 bytes + 16 per attribute: magic, version, agents, attributes, options, frame rate,
 *            crc32 of the header, frame count (0 until the writer finishes), agents per piece S
 *   chunks   one per frame: "FRAM", frame, flags, crc32, payload size; then one u64 compressed size
 *            per block and the blocks, piece by piece: for each piece of S agents (the last one
 *            shorter), one zstd frame per attribute, filtered on its own (so a piece, and each
 *            attribute of it, decodes on its own, and ranks can encode their pieces in parallel)
 *   index    "FIDX", frame count, (offset, size) per chunk, crc32
 *   footer   u64 offset of the index, "FMCEND\0\0"
 * Format 3 (read only): format 4 with one piece of every agent (bytes 68..71 of the header are 0).
 * Format 2 (read only): format 3 without the frame count, a 64-byte fixed header.
 * Format 1 (read only): one attribute (tet vertices), 24-byte chunks without crc32 (zstd's own
 * checksum instead), an index of offsets only. */
#ifndef FM_CACHE_FORMAT_H
#define FM_CACHE_FORMAT_H

#include "fm_internal.h"

#include <stdint.h>
#include <string.h>
#include <zstd.h>

enum {
    CACHE_VERSION = 4,
    CACHE_FIXED_HEADER = 72,    /* formats 3 and 4 */
    CACHE_FIXED_HEADER_V2 = 64, /* formats 1 and 2: the bytes every reader reads first */
    CACHE_ATTR_RECORD = 16,
    CACHE_CHUNK_HEADER = 24,
    CACHE_FOOTER = 16,
    CACHE_MAX_ATTRS = 7, /* every kind at most once */
    CACHE_CODEC_ZSTD = 1,
    CACHE_DEFAULT_KEY_INTERVAL = 16,
    CACHE_MAX_KEY_INTERVAL = 1 << 16,
    CACHE_MIN_LEVEL = -7, /* zstd's fast levels -7 ... -1 (ZSTD_c_compressionLevel < 0), and 1 ... 19 */
    CACHE_MAX_LEVEL = 19,
    CACHE_WRITER_SLOTS = 2, /* frames handed over and not yet written before add_frame waits */
    CACHE_MAX_HEADER = CACHE_FIXED_HEADER + CACHE_ATTR_RECORD * CACHE_MAX_ATTRS,
    /* Agents per piece (format 4): large enough for zstd to find the same redundancy as in a whole
     * array (a piece of tets is 3 MiB), small enough that 2 … P writers share a frame. */
    CACHE_DEFAULT_PIECE = 1 << 16,
    CACHE_MIN_PIECE = 256,
    CACHE_MAX_PIECE = 1 << 30,
    CACHE_ENCODER_THREADS = 2, /* the writer thread's team that compresses a frame's blocks */
    CACHE_ATTR_KINDS = FM_ATTR_GROUP + 1, /* arrays indexed by fm_cache_attr */
};

/* Per-attribute filter bits (header attribute record, offset 12). */
enum { FILTER_SHUFFLE4 = 1, FILTER_DELTA = 2, FILTER_QUANTISE = 4 };
/* The words of the writer's message for a value the quantum cannot hold (the CLI names the scene's
 * output.quantum when it sees them). */
#define CACHE_QUANTUM_FAILURE "is not a finite multiple of quantum"

/* Chunk flags. */
enum { CHUNK_KEY_FRAME = 1 };
/* Header flags. */
enum { HEADER_DELTA = 1 };

extern const char CACHE_MAGIC[8];
extern const char CACHE_END_MAGIC[8];

/* Little-endian field access (the engine targets little-endian x86-64 and ARM64). */
static inline void put_u32(unsigned char *p, uint32_t x) { memcpy(p, &x, 4); }
static inline void put_u64(unsigned char *p, uint64_t x) { memcpy(p, &x, 8); }
static inline void put_f64(unsigned char *p, double x) { memcpy(p, &x, 8); }
static inline uint32_t get_u32(const unsigned char *p) { uint32_t x; memcpy(&x, p, 4); return x; }
static inline uint64_t get_u64(const unsigned char *p) { uint64_t x; memcpy(&x, p, 8); return x; }
static inline double get_f64(const unsigned char *p) { double x; memcpy(&x, p, 8); return x; }

/* What a cache holds and how it is encoded: everything the header says. */
typedef struct cache_layout {
    uint32_t version;
    uint32_t header_bytes;
    uint32_t header_frames;  /* format 3: the frame count in the header, 0 until the writer finishes */
    uint64_t agents;
    uint64_t piece_agents;   /* S: format 4's agents per piece; before it, every agent (one piece) */
    uint64_t pieces;         /* J = ceil(agents / S), at least 1 */
    double frame_rate;
    int attr_count;
    const fm_cache_attr_info *attrs[CACHE_MAX_ATTRS];
    uint32_t filters[CACHE_MAX_ATTRS];
    fm_cache_options opts;
} cache_layout;

/* Checks the attribute list and options and fills the layout (the current version, filters by the
 * rules of the specification, frame count 0). */
fm_status cache_layout_init(cache_layout *l, uint64_t agents, double frame_rate, const fm_cache_attr *attrs,
                            int attr_count, const fm_cache_options *opts, const char *path, fm_error *err);
/* S agents a piece (format 4), or 0 for one piece of every agent (formats 1 to 3): sets the
 * layout's piece size and count. */
void cache_layout_set_pieces(cache_layout *l, uint64_t piece_agents);
/* The header of l->version (2 or 3): l->header_bytes bytes. */
void cache_header_encode(const cache_layout *l, unsigned char *out);
/* Reads a version-2 or -3 header of l->header_bytes bytes (l->version and the size already read). */
fm_status cache_header_decode(cache_layout *l, const unsigned char *h, const char *path, fm_error *err);

/* Where the attribute records start: after the fixed part of the header of that version. */
uint32_t cache_fixed_header_bytes(uint32_t version);

/* Bytes of attribute i in one frame, and their sum over attributes. */
size_t cache_attr_bytes(const cache_layout *l, int i);
size_t cache_frame_bytes(const cache_layout *l);
/* Piece j: its first agent, its agents, and the bytes of attribute i in it (one block). */
uint64_t cache_piece_first(const cache_layout *l, uint64_t j);
uint64_t cache_piece_agents(const cache_layout *l, uint64_t j);
size_t cache_block_bytes(const cache_layout *l, uint64_t j, int i);
/* The size table's bytes: one u64 per block, J × A. */
uint64_t cache_table_bytes(const cache_layout *l);
/* Largest compressed payload (size table and blocks) a chunk of this layout can have. */
uint64_t cache_payload_bound(const cache_layout *l);
/* Frame k is stored whole (not as a delta) when it is a key frame. */
int cache_is_key_frame(const cache_layout *l, uint32_t k);
int cache_attr_index(const cache_layout *l, fm_cache_attr attr);

uint32_t cache_crc32(uint32_t crc, const void *data, size_t n);
/* The chunk checksum: crc32 over chunk bytes [0, 12) and [16, 24 + payload). */
uint32_t cache_chunk_crc(const unsigned char *chunk, uint64_t payload);

/* Byte k of 4-byte word i goes to k * count + i (and back). */
void cache_shuffle4(const unsigned char *in, size_t count, unsigned char *out);
void cache_unshuffle4(const unsigned char *in, size_t count, unsigned char *out);
/* The same, piece by piece, over attribute i of a whole frame (the shuffle of format 4). */
void cache_shuffle_pieces(const cache_layout *l, int i, const unsigned char *in, unsigned char *out);
void cache_unshuffle_pieces(const cache_layout *l, int i, const unsigned char *in, unsigned char *out);
void cache_xor(unsigned char *dst, const unsigned char *src, size_t n);
/* Rounds each float to the nearest multiple of quantum, stored as the int32 multiple. Returns the
 * index of the first value that does not fit (non-finite or |x / quantum| >= 2^31), or -1. */
int64_t cache_quantise(const float *in, size_t count, double quantum, int32_t *out);
void cache_dequantise(const int32_t *in, size_t count, double quantum, float *out);

/* The filters and compression of the pieces [piece_begin, piece_end) of every frame (format 4): the
 * writer encodes all of them; on P ranks each rank encodes its own (cache_parts.c). A block goes
 * through one zstd context with no workers, so its bytes do not depend on who encodes it, nor on
 * how many threads share the frame. */
typedef struct cache_encoder {
    cache_layout l;
    uint64_t piece_begin, piece_end, agent_begin, agent_end;
    size_t attr_at[CACHE_MAX_ATTRS]; /* attribute i's words of the range in stored and prev */
    unsigned char *stored;           /* this frame's stored words (quantised, shuffled, delta) */
    unsigned char *prev;             /* delta: the previous frame's, before the delta */
    size_t *bound_at;                /* block b's place in the output before compaction */
    unsigned char **scratch;         /* a thread's quantised block */
    ZSTD_CCtx **cctx;                /* a thread's compressor */
    int threads;
    char path[FM_PATH_MAX];          /* for messages */
} cache_encoder;

fm_status cache_encoder_init(cache_encoder *e, const cache_layout *l, uint64_t piece_begin, uint64_t piece_end,
                             int threads, const char *path, fm_error *err);
/* cache_encoder_init in two parts: the range and its blocks' bounds, then the buffers and compressors
 * (the writer makes them only once it encodes a frame: on P ranks it never does). */
fm_status cache_encoder_init_bounds(cache_encoder *e, const cache_layout *l, uint64_t piece_begin, uint64_t piece_end,
                                    int threads, const char *path, fm_error *err);
fm_status cache_encoder_alloc_buffers(cache_encoder *e, fm_error *err);
/* Delta: prev alone (a resumed writer takes the last stored frame into it); alloc_buffers keeps it. */
fm_status cache_encoder_alloc_prev(cache_encoder *e, fm_error *err);
void cache_encoder_free(cache_encoder *e);
/* Frees the encoder's buffers and compressors but keeps its blocks' bounds (bound_at). */
void cache_encoder_keep_bounds(cache_encoder *e);
/* Blocks of the range, and the bytes they can take compressed. */
uint64_t cache_encoder_blocks(const cache_encoder *e);
uint64_t cache_encoder_bound(const cache_encoder *e);
/* Frame k: data[i] holds attribute i of the range's agents (agent_begin first). The blocks go to
 * out one after another, piece by piece and attribute by attribute within a piece, their sizes to
 * sizes[b], their total to *bytes. */
fm_status cache_encode_frame(cache_encoder *e, const void *const *data, uint32_t k, unsigned char *out, uint64_t *sizes,
                             uint64_t *bytes, fm_error *err);
/* Delta: attribute i's stored words of the range at the previous frame (resume fills them). */
unsigned char *cache_encoder_prev(cache_encoder *e, int i);

/* A rank's share of every frame of a cache written by P ranks (docs/scale-out.md): the pieces
 * [J r / P, J (r + 1) / P), which the rank encodes and writes at its place in the frame's chunk
 * (fm_cache_writer_chunk_head). Blocks do not depend on who encodes them, so the file is the one
 * process's. */
typedef struct cache_share {
    cache_encoder enc;
    unsigned char *blocks; /* this frame's blocks, one after another */
    uint64_t *sizes;       /* their compressed sizes */
    uint64_t bytes;        /* their total */
    uint32_t *ids;         /* agent_begin … agent_end − 1, the range's `id` attribute */
} cache_share;

/* The first agent of rank r's share among `ranks` (r = ranks: every agent). */
uint64_t cache_share_agent_begin(const cache_layout *l, int r, int ranks);
/* The share of `rank`, from the writer's header bytes (rank 0 sends them to all), encoding on
 * `threads` threads. */
fm_status cache_share_init(cache_share *sh, const unsigned char *header, uint32_t header_bytes, int rank, int ranks,
                           int threads, fm_error *err);
void cache_share_free(cache_share *sh);
/* Frame k: by_kind[FM_ATTR_x] (CACHE_ATTR_KINDS entries) points at attribute x of the share's
 * agents in id order, its first agent (agent_begin) first; the id attribute comes from the share. */
fm_status cache_share_encode(cache_share *sh, const void *const *by_kind, uint32_t k, fm_error *err);

/* A frame whose blocks P ranks encoded and write themselves (frame_share.c): where its chunk goes
 * and its head (header and size table), which rank 0 writes there; the ranks' blocks follow, rank
 * after rank. */
typedef struct cache_chunk_place {
    uint64_t pos;              /* the chunk's first byte in the file */
    const unsigned char *head; /* header and size table, head_bytes of them */
    size_t head_bytes;
    uint64_t chunk_bytes;      /* head and blocks */
} cache_chunk_place;
const char *fm_cache_writer_partial_path(const fm_cache_writer *w);
/* sizes[b] for every block of the chunk; runs_crc and run_bytes: each rank's blocks' CRC-32 and
 * length, in rank order (the chunk's CRC is combined from them). Waits for the frames handed over
 * before it. */
fm_status fm_cache_writer_chunk_head(fm_cache_writer *w, const uint64_t *sizes, const uint32_t *run_crc,
                                     const uint64_t *run_bytes, int runs, cache_chunk_place *place, fm_error *err);
/* Once every rank wrote its part: the chunk in the index, the stream after it. */
fm_status fm_cache_writer_note_chunk(fm_cache_writer *w, const cache_chunk_place *place, fm_error *err);
/* Delta: attribute i's stored words of every agent at the last frame (a resumed writer hands the
 * ranks their shares of it). */
const unsigned char *fm_cache_writer_prev(fm_cache_writer *w, int i);
/* On P ranks, once the ranks have their shares: the ranks encode and write every frame, so the
 * writer frees what encoding a frame takes (its hand-over slots and encoder's buffers, about 6
 * frames' bytes, made on the first add_frame or a resume) and its ids, and keeps the chunk heads and
 * the index. add_frame is refused from then on. */
void fm_cache_writer_leave_frames_to_ranks(fm_cache_writer *w);

/* The writer's layout (morph_run.c and flock_run.c hand over the attributes it asks for). */
const cache_layout *fm_cache_writer_layout(const fm_cache_writer *w);
/* The agents' ids 0 … n−1 as the `id` attribute of a frame in id order (both runs hand over their
 * frames in id order); NULL if the cache has no id attribute. */
const uint32_t *fm_cache_writer_ids(const fm_cache_writer *w);
/* Seconds add_frame has waited for the writer so far (bench_cache): 0 when it keeps up. */
double fm_cache_writer_wait_seconds(const fm_cache_writer *w);
/* What zstd's compression contexts hold now, their working memory included (ZSTD_sizeof_CCtx):
 * fixed, not per agent (tests/cli/test_bad_input.c leaves it out of the per-agent comparison). */
size_t fm_cache_writer_zstd_bytes(const fm_cache_writer *w);

/* For resume: the reader's layout, the end of chunk k, a chunk's check, and attribute i's stored
 * words (after quantisation and shuffle, with deltas undone) at frame k. */
const cache_layout *cache_reader_layout(const fm_cache_reader *r);
uint64_t cache_reader_chunk_end(const fm_cache_reader *r, uint32_t k);
fm_status cache_reader_check_chunk(fm_cache_reader *r, uint32_t k, fm_error *err);
fm_status cache_reader_stored(fm_cache_reader *r, uint32_t k, int i, const unsigned char **words, fm_error *err);
const uint64_t *cache_reader_offsets(const fm_cache_reader *r);

#endif
