/* The frame cache reader: formats 1 to 4 (docs/cache-format.md; cache_format.h has the layout).
 *
 * Random access by frame through the index. With delta encoding a frame is rebuilt from the last
 * key frame before it; the last decoded frame of each attribute is kept, so reading frames in
 * order decodes one chunk per frame. A cache without a valid index is opened up to its last
 * complete chunk, with a warning. */
#define _POSIX_C_SOURCE 200809L
#include "cache_format.h"

#include <zstd.h>

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { V1_FLOATS_PER_AGENT = 12, V1_FILTER_SHUFFLE4 = 1 };

struct fm_cache_reader {
    FILE *f;
    char path[FM_PATH_MAX];
    char warning[FM_PATH_MAX + 200]; /* non-empty when the cache was recovered without its index */
    cache_layout l;
    uint64_t file_bytes;
    uint32_t frames;
    uint64_t *offsets, *sizes;       /* chunk k: where it starts and its bytes */
    unsigned char *chunk;            /* the last chunk read, checked */
    uint64_t chunk_cap;
    int64_t chunk_frame;
    unsigned char *words[CACHE_MAX_ATTRS]; /* attribute i's stored words at frame words_frame[i] */
    int64_t words_frame[CACHE_MAX_ATTRS];
    unsigned char *scratch;          /* one attribute */
    ZSTD_DCtx *dctx;
};

static fm_status read_at(fm_cache_reader *r, uint64_t pos, void *buf, size_t n, fm_error *err)
{
    if (fseeko(r->f, (off_t)pos, SEEK_SET) != 0 || fread(buf, 1, n, r->f) != n)
        return fm_fail(err, FM_ERR_INPUT, "%s: truncated or unreadable at byte %llu", r->path, (unsigned long long)pos);
    return FM_OK;
}

/* ---------------------------------------------------------------- header */

/* Format 1: tet vertices only, shuffled, no delta, no quantisation. */
static fm_status read_header_v1(fm_cache_reader *r, const unsigned char *h, fm_error *err)
{
    if (get_u32(h + 24) != V1_FLOATS_PER_AGENT || get_u32(h + 28) != V1_FILTER_SHUFFLE4 || get_u32(h + 32) != CACHE_CODEC_ZSTD)
        return fm_fail(err, FM_ERR_INPUT, "%s: unsupported attribute layout, filter or codec", r->path);
    cache_layout *l = &r->l;
    l->header_bytes = CACHE_FIXED_HEADER_V2;
    l->agents = get_u64(h + 16);
    l->frame_rate = get_f64(h + 40);
    if (!(l->frame_rate > 0 && l->frame_rate <= 1e9))
        return fm_fail(err, FM_ERR_INPUT, "%s: damaged header: frame rate %g", r->path, l->frame_rate);
    l->attr_count = 1;
    l->attrs[0] = fm_cache_attr_describe(FM_ATTR_TET_VERTICES);
    l->filters[0] = FILTER_SHUFFLE4;
    l->opts = fm_default_cache_options();
    l->opts.delta = 0;
    l->opts.compression_level = (int)get_u32(h + 36);
    cache_layout_set_pieces(l, 0);
    return FM_OK;
}

/* Formats 2 and 3: the attribute records and the rest of the header after the first 64 bytes. */
static fm_status read_header_attrs(fm_cache_reader *r, const unsigned char *first, fm_error *err)
{
    unsigned char h[CACHE_MAX_HEADER];
    uint32_t records = cache_fixed_header_bytes(r->l.version);
    r->l.header_bytes = get_u32(first + 12);
    if (r->l.header_bytes < records + CACHE_ATTR_RECORD || r->l.header_bytes > records + CACHE_ATTR_RECORD * CACHE_MAX_ATTRS ||
        (r->l.header_bytes - records) % CACHE_ATTR_RECORD != 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: bad header size %u", r->path, r->l.header_bytes);
    memcpy(h, first, CACHE_FIXED_HEADER_V2);
    fm_status st = read_at(r, CACHE_FIXED_HEADER_V2, h + CACHE_FIXED_HEADER_V2, r->l.header_bytes - CACHE_FIXED_HEADER_V2, err);
    return st == FM_OK ? cache_header_decode(&r->l, h, r->path, err) : st;
}

static fm_status read_header(fm_cache_reader *r, fm_error *err)
{
    unsigned char h[CACHE_FIXED_HEADER_V2] = {0};
    size_t got = fread(h, 1, sizeof h, r->f);
    if (memcmp(h, CACHE_MAGIC, got < 8 ? got : 8) != 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: not a flockmorph cache (bad magic)", r->path);
    if (got < sizeof h)
        return fm_fail(err, FM_ERR_INPUT, "%s: truncated: %zu bytes, shorter than the cache header", r->path, got);
    r->l.version = get_u32(h + 8);
    fm_status st;
    if (r->l.version == 1) st = read_header_v1(r, h, err);
    else if (r->l.version >= 2 && r->l.version <= CACHE_VERSION) st = read_header_attrs(r, h, err);
    else
        return fm_fail(err, FM_ERR_INPUT, "%s: cache version %u is not supported (this build reads 1 to %d)", r->path,
                       r->l.version, CACHE_VERSION);
    if (st == FM_OK && r->l.agents > ((uint64_t)1 << 40))
        return fm_fail(err, FM_ERR_INPUT, "%s: implausible agent count", r->path);
    return st;
}

/* ---------------------------------------------------------------- chunks */

static uint64_t v1_payload_bound(const cache_layout *l) { return ZSTD_compressBound(cache_attr_bytes(l, 0)); }

/* Checks a chunk header as frame k's (tag, frame, flags, sizes) and gives the chunk's bytes. */
static int chunk_header_ok(const fm_cache_reader *r, const unsigned char *h, uint32_t k, uint64_t *bytes)
{
    if (memcmp(h, "FRAM", 4) != 0 || get_u32(h + 4) != k) return 0;
    if (r->l.version == 1) {
        *bytes = CACHE_CHUNK_HEADER + get_u64(h + 8);
        return get_u64(h + 8) <= v1_payload_bound(&r->l) && get_u64(h + 16) == cache_attr_bytes(&r->l, 0);
    }
    uint64_t payload = get_u64(h + 16);
    *bytes = CACHE_CHUNK_HEADER + payload;
    return get_u32(h + 8) == (cache_is_key_frame(&r->l, k) ? (uint32_t)CHUNK_KEY_FRAME : 0u) &&
           payload >= cache_table_bytes(&r->l) && payload <= cache_payload_bound(&r->l);
}

/* Formats 2 to 4: the block size table adds up to the payload and no block exceeds its bound. */
static int block_sizes_ok(const fm_cache_reader *r, const unsigned char *table, uint64_t payload)
{
    uint64_t sum = cache_table_bytes(&r->l);
    for (uint64_t j = 0; j < r->l.pieces; j++)
        for (int i = 0; i < r->l.attr_count; i++) {
            uint64_t c = get_u64(table + 8 * (j * (uint64_t)r->l.attr_count + (uint64_t)i));
            if (c > ZSTD_compressBound(cache_block_bytes(&r->l, j, i))) return 0;
            sum += c;
        }
    return sum == payload;
}

/* Reads chunk k into r->chunk and checks its header, checksum and block sizes. */
static fm_status load_chunk(fm_cache_reader *r, uint32_t k, fm_error *err)
{
    if (r->chunk_frame == (int64_t)k) return FM_OK;
    r->chunk_frame = -1;
    uint64_t bytes = r->sizes[k], stated;
    if (bytes < CACHE_CHUNK_HEADER || bytes > r->chunk_cap)
        return fm_fail(err, FM_ERR_INPUT, "%s: frame %u: damaged chunk header", r->path, k);
    fm_status st = read_at(r, r->offsets[k], r->chunk, (size_t)bytes, err);
    if (st != FM_OK) return st;
    int header_ok = chunk_header_ok(r, r->chunk, k, &stated) && stated == bytes;
    if (r->l.version != 1 && header_ok && cache_chunk_crc(r->chunk, bytes - CACHE_CHUNK_HEADER) != get_u32(r->chunk + 12))
        return fm_fail(err, FM_ERR_INPUT, "%s: chunk %u: checksum mismatch (frame %u is corrupt)", r->path, k, k);
    if (!header_ok || (r->l.version != 1 && !block_sizes_ok(r, r->chunk + CACHE_CHUNK_HEADER, bytes - CACHE_CHUNK_HEADER)))
        return fm_fail(err, FM_ERR_INPUT, "%s: frame %u: damaged chunk header", r->path, k);
    r->chunk_frame = k;
    return FM_OK;
}

static fm_status corrupt(const fm_cache_reader *r, uint32_t k, int i, size_t got, fm_error *err)
{
    return fm_fail(err, FM_ERR_INPUT, "%s: frame %u is corrupt (%s: %s)", r->path, k, r->l.attrs[i]->name,
                   ZSTD_isError(got) ? ZSTD_getErrorName(got) : "wrong size");
}

/* Decompresses attribute i of chunk k into dst (the attribute's bytes): its block in each piece,
 * each into the piece's place. */
static fm_status decode_block(fm_cache_reader *r, uint32_t k, int i, unsigned char *dst, fm_error *err)
{
    fm_status st = load_chunk(r, k, err);
    if (st != FM_OK) return st;
    if (r->l.version == 1) {
        size_t want = cache_attr_bytes(&r->l, 0);
        size_t got = ZSTD_decompressDCtx(r->dctx, dst, want, r->chunk + CACHE_CHUNK_HEADER, (size_t)(r->sizes[k] - CACHE_CHUNK_HEADER));
        return ZSTD_isError(got) || got != want ? corrupt(r, k, i, got, err) : FM_OK;
    }
    const unsigned char *table = r->chunk + CACHE_CHUNK_HEADER, *block = table + cache_table_bytes(&r->l);
    const uint64_t blocks = cache_table_bytes(&r->l) / 8, a = (uint64_t)r->l.attr_count;
    for (uint64_t b = 0; b < blocks; b++) {
        const uint64_t packed = get_u64(table + 8 * b), j = b / a;
        if ((int)(b % a) == i) {
            size_t want = cache_block_bytes(&r->l, j, i);
            size_t got = ZSTD_decompressDCtx(r->dctx, dst + (size_t)cache_piece_first(&r->l, j) * r->l.attrs[i]->bytes_per_agent,
                                             want, block, (size_t)packed);
            if (ZSTD_isError(got) || got != want) return corrupt(r, k, i, got, err);
        }
        block += packed;
    }
    return FM_OK;
}

/* Attribute i's stored words at frame k into r->words[i]: with delta, from the last key frame
 * (or the frame decoded last, when it lies between) forward. */
static fm_status decode_stored(fm_cache_reader *r, uint32_t k, int i, fm_error *err)
{
    if (r->words_frame[i] == (int64_t)k) return FM_OK;
    uint32_t start = k;
    if (r->l.filters[i] & FILTER_DELTA) {
        uint32_t key = k - k % (uint32_t)r->l.opts.key_interval;
        start = r->words_frame[i] >= (int64_t)key && r->words_frame[i] < (int64_t)k ? (uint32_t)r->words_frame[i] + 1 : key;
    }
    r->words_frame[i] = -1;
    size_t bytes = cache_attr_bytes(&r->l, i);
    for (uint32_t j = start; j <= k; j++) {
        int whole = j == start && cache_is_key_frame(&r->l, j);
        fm_status st = decode_block(r, j, i, whole || !(r->l.filters[i] & FILTER_DELTA) ? r->words[i] : r->scratch, err);
        if (st != FM_OK) return st;
        if (!whole && (r->l.filters[i] & FILTER_DELTA)) cache_xor(r->words[i], r->scratch, bytes);
    }
    r->words_frame[i] = k;
    return FM_OK;
}

/* ---------------------------------------------------------------- index */

static fm_status alloc_index(fm_cache_reader *r, uint32_t cap, fm_error *err)
{
    uint64_t *offsets = realloc(r->offsets, sizeof *offsets * (cap ? cap : 1));
    if (offsets) r->offsets = offsets;
    uint64_t *sizes = offsets ? realloc(r->sizes, sizeof *sizes * (cap ? cap : 1)) : NULL;
    if (!sizes) return fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache index");
    r->sizes = sizes;
    return FM_OK;
}

/* Without a valid index (a run that was killed, a file cut short) the chunks are walked from the
 * header; every complete one is a readable frame. Contents are still checked when read. */
static fm_status scan_chunks(fm_cache_reader *r, const char *why, fm_error *err)
{
    uint64_t pos = r->l.header_bytes;
    uint32_t cap = 0;
    size_t head = CACHE_CHUNK_HEADER + (r->l.version == 1 ? 0 : (size_t)cache_table_bytes(&r->l));
    const int fits = head <= r->file_bytes; /* a size table larger than the file: no chunk to find */
    unsigned char *h = fits ? malloc(head) : NULL;
    if (fits && !h) return fm_fail(err, FM_ERR_MEMORY, "out of memory reading %s", r->path);
    fm_error ignored;
    uint32_t announced = r->l.header_frames; /* format 3, a finished file cut short: no more than this */
    r->frames = 0;
    for (;;) {
        uint64_t bytes;
        if (!fits || (announced && r->frames == announced) || pos + head > r->file_bytes ||
            read_at(r, pos, h, head, &ignored) != FM_OK)
            break;
        if (!chunk_header_ok(r, h, r->frames, &bytes) || pos + bytes > r->file_bytes ||
            (r->l.version != 1 && !block_sizes_ok(r, h + CACHE_CHUNK_HEADER, bytes - CACHE_CHUNK_HEADER)))
            break;
        if (r->frames == cap && alloc_index(r, cap = cap ? 2 * cap : 256, err) != FM_OK) return free(h), FM_ERR_MEMORY;
        r->offsets[r->frames] = pos, r->sizes[r->frames] = bytes;
        r->frames++;
        pos += bytes;
    }
    free(h);
    int n = snprintf(r->warning, sizeof r->warning, "%s: %s; recovered the %u complete frames before byte %llu",
                     r->path, why, r->frames, (unsigned long long)pos);
    if (announced && n > 0 && (size_t)n < sizeof r->warning)
        snprintf(r->warning + n, sizeof r->warning - (size_t)n, " (the header announces %u)", announced);
    return FM_OK;
}

/* Format 1's index holds offsets only; the writer put chunks one after another, so a chunk ends
 * where the next one (or the index) starts. */
static fm_status read_index_v1(fm_cache_reader *r, uint64_t index_pos, uint32_t frames, fm_error *err)
{
    unsigned char *raw = malloc(8 * (size_t)frames + 1);
    fm_status st = raw && alloc_index(r, frames, err) == FM_OK ? read_at(r, index_pos + 8, raw, 8 * (size_t)frames, err)
                                                               : fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache index");
    for (uint32_t k = 0; k < frames && st == FM_OK; k++) r->offsets[k] = get_u64(raw + 8 * (size_t)k);
    for (uint32_t k = 0; k < frames && st == FM_OK; k++)
        r->sizes[k] = (k + 1 < frames ? r->offsets[k + 1] : index_pos) - r->offsets[k];
    if (st == FM_OK) r->frames = frames;
    free(raw);
    return st;
}

/* Format 2: (offset, size) per chunk and a crc32; returns 0 if the index is damaged. */
static int read_index_v2(fm_cache_reader *r, uint64_t index_pos, uint32_t frames, fm_error *err, fm_status *st)
{
    size_t bytes = 16 + 16 * (size_t)frames;
    unsigned char *raw = malloc(bytes);
    *st = raw && alloc_index(r, frames, err) == FM_OK ? read_at(r, index_pos, raw, bytes, err)
                                                      : fm_fail(err, FM_ERR_MEMORY, "out of memory for the cache index");
    int ok = *st == FM_OK && cache_crc32(0, raw, bytes - 8) == get_u32(raw + bytes - 8);
    for (uint32_t k = 0; k < frames && ok; k++) {
        r->offsets[k] = get_u64(raw + 8 + 16 * (size_t)k);
        r->sizes[k] = get_u64(raw + 16 + 16 * (size_t)k);
        ok = r->offsets[k] >= r->l.header_bytes && r->sizes[k] <= index_pos && r->offsets[k] <= index_pos - r->sizes[k];
    }
    if (ok) r->frames = frames;
    free(raw);
    return ok;
}

/* Bytes of an index of F frames: format 1 "FIDX", F, offsets; formats 2 and 3 add sizes and a crc32. */
static uint64_t index_bytes(const fm_cache_reader *r, uint64_t frames)
{
    return r->l.version == 1 ? 8 + 8 * frames : 16 + 16 * frames;
}

static fm_status read_index(fm_cache_reader *r, fm_error *err)
{
    unsigned char footer[CACHE_FOOTER], h[8];
    if (r->file_bytes < r->l.header_bytes + index_bytes(r, 0) + CACHE_FOOTER ||
        read_at(r, r->file_bytes - CACHE_FOOTER, footer, CACHE_FOOTER, err) != FM_OK ||
        memcmp(footer + 8, CACHE_END_MAGIC, 8) != 0)
        return scan_chunks(r, "incomplete cache (no index: the run did not finish or the file was cut short)", err);
    uint64_t index_pos = get_u64(footer);
    const char *damaged = "the frame index is damaged";
    if (index_pos < r->l.header_bytes || index_pos + 8 > r->file_bytes - CACHE_FOOTER ||
        read_at(r, index_pos, h, 8, err) != FM_OK || memcmp(h, "FIDX", 4) != 0 ||
        index_bytes(r, get_u32(h + 4)) != r->file_bytes - CACHE_FOOTER - index_pos)
        return scan_chunks(r, damaged, err);
    if (r->l.version == 1) return read_index_v1(r, index_pos, get_u32(h + 4), err);
    fm_status st;
    if (!read_index_v2(r, index_pos, get_u32(h + 4), err, &st) && st == FM_OK) return scan_chunks(r, damaged, err);
    return st;
}

/* Format 3: the header's frame count is 0 while the writer runs and F once it has finished
 * (docs/cache-format.md, Writing and completeness). With a valid index, 0 means the writer stopped
 * between the footer and the header (recovered like a file without footer); any other count must
 * equal the index's. An empty finished cache has 0 in both. */
static fm_status check_header_frames(fm_cache_reader *r, fm_error *err)
{
    uint32_t announced = r->l.header_frames;
    if (r->l.version < 3 || r->warning[0] || announced == r->frames) return FM_OK;
    if (announced == 0)
        return scan_chunks(r, "incomplete cache (frame count 0 in the header: the writer did not finish)", err);
    return fm_fail(err, FM_ERR_INPUT, "%s: damaged cache: the header says %u frames but the index lists %u", r->path,
                   announced, r->frames);
}

/* ---------------------------------------------------------------- open, close */

static fm_status alloc_buffers(fm_cache_reader *r, fm_error *err)
{
    size_t largest = 0;
    r->chunk_cap = CACHE_CHUNK_HEADER + (r->l.version == 1 ? v1_payload_bound(&r->l) : cache_payload_bound(&r->l));
    r->chunk = malloc((size_t)r->chunk_cap);
    int ok = r->chunk != NULL;
    for (int i = 0; i < r->l.attr_count; i++) {
        largest = FM_MAX(largest, cache_attr_bytes(&r->l, i));
        r->words[i] = fm_alloc(cache_attr_bytes(&r->l, i));
        r->words_frame[i] = -1;
        ok = ok && r->words[i];
    }
    r->scratch = fm_alloc(largest);
    r->dctx = ZSTD_createDCtx();
    if (!ok || !r->scratch || !r->dctx) return fm_fail(err, FM_ERR_MEMORY, "out of memory reading %s", r->path);
    return FM_OK;
}

/* The frames of agents × bytes per agent must come from the chunks of this file, and zstd shrinks by
 * at most about 2^15:1 (a run-length block): a header claiming far more is damaged, not a huge
 * cache, and must not make open allocate terabytes (fuzz regression huge_agent_count). */
static fm_status check_plausible(const fm_cache_reader *r, fm_error *err)
{
    uint64_t raw = 0;
    for (int i = 0; i < r->l.attr_count; i++) raw += cache_attr_bytes(&r->l, i);
    if (r->frames > 0 && raw / 65536 > r->file_bytes)
        return fm_fail(err, FM_ERR_INPUT, "%s: damaged header: frames of %llu agents cannot come from a file of %llu bytes",
                       r->path, (unsigned long long)r->l.agents, (unsigned long long)r->file_bytes);
    return FM_OK;
}

/* The ratio check above leaves a lie of a few thousand times the agents (a header claiming 2^24
 * agents in a cache of megabytes), which would still size buffers of gigabytes and fail as out of
 * memory (exit 4) rather than as the damage it is (issue 42). Frame 0's chunk tells: the block
 * table the header's agents imply must fit in it and add up to it (as every chunk's must when it is
 * read), and its first block's zstd header, which states its content size (the writer always
 * records it), must give the size those agents make. */
static fm_status check_first_chunk(fm_cache_reader *r, fm_error *err)
{
    const uint64_t chunk = r->sizes[0], table = r->l.version == 1 ? 0 : cache_table_bytes(&r->l);
    if (chunk < CACHE_CHUNK_HEADER || table > chunk - CACHE_CHUNK_HEADER)
        return fm_fail(err, FM_ERR_INPUT, "%s: damaged header: %llu agents need a block table of %llu bytes, more than "
                       "frame 0's chunk of %llu bytes holds", r->path, (unsigned long long)r->l.agents,
                       (unsigned long long)table, (unsigned long long)chunk);
    const size_t n = (size_t)FM_MIN(table + 18, chunk - CACHE_CHUNK_HEADER); /* 18: zstd's longest frame header */
    unsigned char *bytes = malloc(n ? n : 1);
    if (!bytes) return fm_fail(err, FM_ERR_MEMORY, "out of memory reading %s", r->path);
    fm_status st = read_at(r, r->offsets[0] + CACHE_CHUNK_HEADER, bytes, n, err);
    if (st == FM_OK && table > 0 && !block_sizes_ok(r, bytes, chunk - CACHE_CHUNK_HEADER))
        st = fm_fail(err, FM_ERR_INPUT, "%s: damaged header: the block table that %llu agents make (%llu blocks) does "
                     "not add up to frame 0's chunk", r->path, (unsigned long long)r->l.agents,
                     (unsigned long long)(table / 8));
    const unsigned long long stated = st == FM_OK ? ZSTD_getFrameContentSize(bytes + table, n - table) : 0;
    const uint64_t want = r->l.version == 1 ? cache_attr_bytes(&r->l, 0) : cache_block_bytes(&r->l, 0, 0);
    if (st == FM_OK && stated != ZSTD_CONTENTSIZE_UNKNOWN && stated != ZSTD_CONTENTSIZE_ERROR && stated != want)
        st = fm_fail(err, FM_ERR_INPUT, "%s: damaged header: %llu agents make frame 0's first block %llu bytes, but it "
                     "holds %llu", r->path, (unsigned long long)r->l.agents, (unsigned long long)want, stated);
    free(bytes);
    return st;
}

fm_cache_reader *fm_cache_open(const char *path, fm_error *err)
{
    fm_cache_reader *r = calloc(1, sizeof *r);
    if (!r) return fm_fail(err, FM_ERR_MEMORY, "out of memory"), NULL;
    snprintf(r->path, sizeof r->path, "%s", path);
    r->chunk_frame = -1;
    if (fm_check_input_file(path, "cache", err) != FM_OK) return fm_cache_close(r), NULL;
    r->f = fopen(path, "rb");
    if (!r->f) {
        fm_fail(err, errno == ENOENT ? FM_ERR_INPUT : FM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
        fm_cache_close(r);
        return NULL;
    }
    fm_status st = read_header(r, err);
    if (st == FM_OK && fseeko(r->f, 0, SEEK_END) != 0) st = fm_fail(err, FM_ERR_IO, "%s: cannot seek", path);
    if (st == FM_OK) r->file_bytes = (uint64_t)ftello(r->f);
    if (st == FM_OK) st = read_index(r, err);
    if (st == FM_OK) st = check_header_frames(r, err);
    if (st == FM_OK) st = check_plausible(r, err);
    if (st == FM_OK && r->frames > 0) st = check_first_chunk(r, err);
    if (st == FM_OK && r->frames > 0) st = alloc_buffers(r, err); /* no frames: nothing to read into */
    if (st != FM_OK) {
        fm_cache_close(r);
        return NULL;
    }
    return r;
}

void fm_cache_close(fm_cache_reader *r)
{
    if (!r) return;
    if (r->f) fclose(r->f);
    for (int i = 0; i < CACHE_MAX_ATTRS; i++) fm_free(r->words[i]);
    free(r->offsets), free(r->sizes), free(r->chunk), fm_free(r->scratch);
    ZSTD_freeDCtx(r->dctx);
    free(r);
}

/* ---------------------------------------------------------------- queries */

uint64_t fm_cache_agents(const fm_cache_reader *r) { return r->l.agents; }
const char *fm_cache_warning(const fm_cache_reader *r) { return r->warning; }
uint32_t fm_cache_frames(const fm_cache_reader *r) { return r->frames; }
double fm_cache_frame_rate(const fm_cache_reader *r) { return r->l.frame_rate; }
uint32_t fm_cache_version(const fm_cache_reader *r) { return r->l.version; }
uint32_t fm_cache_header_frames(const fm_cache_reader *r) { return r->l.header_frames; }
fm_cache_options fm_cache_get_options(const fm_cache_reader *r) { return r->l.opts; }
int fm_cache_attr_count(const fm_cache_reader *r) { return r->l.attr_count; }
int fm_cache_has_attr(const fm_cache_reader *r, fm_cache_attr attr) { return cache_attr_index(&r->l, attr) >= 0; }
uint64_t fm_cache_file_bytes(const fm_cache_reader *r) { return r->file_bytes; }
uint64_t fm_cache_raw_bytes(const fm_cache_reader *r) { return (uint64_t)r->frames * cache_frame_bytes(&r->l); }

const fm_cache_attr_info *fm_cache_attr_at(const fm_cache_reader *r, int i)
{
    return i >= 0 && i < r->l.attr_count ? r->l.attrs[i] : NULL;
}

uint64_t fm_cache_frame_bytes(const fm_cache_reader *r, uint32_t frame)
{
    return frame < r->frames ? r->sizes[frame] : 0;
}

uint64_t fm_cache_compressed_bytes(const fm_cache_reader *r)
{
    uint64_t sum = 0;
    for (uint32_t k = 0; k < r->frames; k++) sum += r->sizes[k];
    return sum;
}

fm_status fm_cache_read_attr(fm_cache_reader *r, uint32_t frame, fm_cache_attr attr, void *out, fm_error *err)
{
    int i = cache_attr_index(&r->l, attr);
    const fm_cache_attr_info *info = fm_cache_attr_describe(attr);
    if (i < 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: the cache has no %s attribute", r->path, info ? info->name : "such");
    if (frame >= r->frames)
        return fm_fail(err, FM_ERR_USAGE, "%s: frame %u does not exist (the cache has %u frames)", r->path, frame, r->frames);
    fm_status st = decode_stored(r, frame, i, err);
    if (st != FM_OK) return st;
    size_t bytes = cache_attr_bytes(&r->l, i);
    uint32_t filters = r->l.filters[i];
    if (filters & FILTER_QUANTISE) {
        cache_unshuffle_pieces(&r->l, i, r->words[i], r->scratch);
        cache_dequantise((const int32_t *)r->scratch, bytes / 4, r->l.opts.quantum, out);
    } else if (filters & FILTER_SHUFFLE4) {
        cache_unshuffle_pieces(&r->l, i, r->words[i], out);
    } else {
        memcpy(out, r->words[i], bytes);
    }
    return FM_OK;
}

fm_status fm_cache_read_frame(fm_cache_reader *r, uint32_t frame, float *out, fm_error *err)
{
    return fm_cache_read_attr(r, frame, FM_ATTR_TET_VERTICES, out, err);
}

/* ---------------------------------------------------------------- for resume */

const cache_layout *cache_reader_layout(const fm_cache_reader *r) { return &r->l; }
const uint64_t *cache_reader_offsets(const fm_cache_reader *r) { return r->offsets; }
uint64_t cache_reader_chunk_end(const fm_cache_reader *r, uint32_t k) { return r->offsets[k] + r->sizes[k]; }
fm_status cache_reader_check_chunk(fm_cache_reader *r, uint32_t k, fm_error *err) { return load_chunk(r, k, err); }

fm_status cache_reader_stored(fm_cache_reader *r, uint32_t k, int i, const unsigned char **words, fm_error *err)
{
    fm_status st = decode_stored(r, k, i, err);
    *words = r->words[i];
    return st;
}
