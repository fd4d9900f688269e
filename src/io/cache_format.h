/* The native frame cache's on-disk layout and filters, shared by the writer (cache_writer.c) and
 * the reader (cache_reader.c). docs/cache-format.md is the specification; the names here follow it.
 *
 * Format 3 (format 2 plus the frame count in the header):
 *   header   72 bytes + 16 per attribute: magic, version, agents, attributes, options, frame rate,
 *            crc32 of the header, frame count (0 until the writer finishes)
 *   chunks   one per frame: "FRAM", frame, flags, crc32, payload size; then one u64 compressed size
 *            per attribute and one zstd frame per attribute (each attribute decodes on its own)
 *   index    "FIDX", frame count, (offset, size) per chunk, crc32
 *   footer   u64 offset of the index, "FMCEND\0\0"
 * Format 2 (read only): format 3 without the frame count, a 64-byte fixed header.
 * Format 1 (read only): one attribute (tet vertices), 24-byte chunks without crc32 (zstd's own
 * checksum instead), an index of offsets only. */
#ifndef FM_CACHE_FORMAT_H
#define FM_CACHE_FORMAT_H

#include "fm_internal.h"

#include <stdint.h>
#include <string.h>

enum {
    CACHE_VERSION = 3,
    CACHE_FIXED_HEADER = 72,    /* format 3 */
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
/* The header of l->version (2 or 3): l->header_bytes bytes. */
void cache_header_encode(const cache_layout *l, unsigned char *out);
/* Reads a version-2 or -3 header of l->header_bytes bytes (l->version and the size already read). */
fm_status cache_header_decode(cache_layout *l, const unsigned char *h, const char *path, fm_error *err);

/* Where the attribute records start: after the fixed part of the header of that version. */
uint32_t cache_fixed_header_bytes(uint32_t version);

/* Bytes of attribute i in one frame, and their sum over attributes. */
size_t cache_attr_bytes(const cache_layout *l, int i);
size_t cache_frame_bytes(const cache_layout *l);
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
void cache_xor(unsigned char *dst, const unsigned char *src, size_t n);
/* Rounds each float to the nearest multiple of quantum, stored as the int32 multiple. Returns the
 * index of the first value that does not fit (non-finite or |x / quantum| >= 2^31), or -1. */
int64_t cache_quantise(const float *in, size_t count, double quantum, int32_t *out);
void cache_dequantise(const int32_t *in, size_t count, double quantum, float *out);

/* The writer's layout (morph_run.c and flock_run.c hand over the attributes it asks for). */
const cache_layout *fm_cache_writer_layout(const fm_cache_writer *w);
/* The agents' ids 0 … n−1 as the `id` attribute of a frame in id order (both runs hand over their
 * frames in id order); NULL if the cache has no id attribute. */
const uint32_t *fm_cache_writer_ids(const fm_cache_writer *w);
/* Seconds add_frame has waited for the writer so far (bench_cache): 0 when it keeps up. */
double fm_cache_writer_wait_seconds(const fm_cache_writer *w);

/* For resume: the reader's layout, the end of chunk k, a chunk's check, and attribute i's stored
 * words (after quantisation and shuffle, with deltas undone) at frame k. */
const cache_layout *cache_reader_layout(const fm_cache_reader *r);
uint64_t cache_reader_chunk_end(const fm_cache_reader *r, uint32_t k);
fm_status cache_reader_check_chunk(fm_cache_reader *r, uint32_t k, fm_error *err);
fm_status cache_reader_stored(fm_cache_reader *r, uint32_t k, int i, const unsigned char **words, fm_error *err);
const uint64_t *cache_reader_offsets(const fm_cache_reader *r);

#endif
