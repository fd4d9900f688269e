/* The cache's attribute kinds, options, header and filters (docs/cache-format.md). */
#include "cache_format.h"

#include <zlib.h>
#include <zstd.h>

#include <math.h>

const char CACHE_MAGIC[8] = {'F', 'M', 'C', 'A', 'C', 'H', 'E', '1'};
const char CACHE_END_MAGIC[8] = {'F', 'M', 'C', 'E', 'N', 'D', 0, 0};

static const fm_cache_attr_info ATTRS[] = {
    {FM_ATTR_TET_VERTICES, "tet_vertices", 12, FM_SCALAR_F32, 48},
    {FM_ATTR_POSITION, "position", 3, FM_SCALAR_F32, 12},
    {FM_ATTR_VELOCITY, "velocity", 3, FM_SCALAR_F32, 12},
    {FM_ATTR_ORIENTATION, "orientation", 4, FM_SCALAR_F32, 16},
    {FM_ATTR_ID, "id", 1, FM_SCALAR_U32, 4},
    {FM_ATTR_PHASE, "phase", 1, FM_SCALAR_U8, 1},
    {FM_ATTR_GROUP, "group", 1, FM_SCALAR_U8, 1},
};

const fm_cache_attr_info *fm_cache_attr_describe(fm_cache_attr attr)
{
    for (size_t i = 0; i < sizeof ATTRS / sizeof ATTRS[0]; i++)
        if (ATTRS[i].attr == attr) return &ATTRS[i];
    return NULL;
}

fm_cache_options fm_default_cache_options(void)
{
    /* delta: half the file size of the words scene and less writer time (docs/performance.md) */
    return (fm_cache_options){.compression_level = 1, .delta = 1, .key_interval = CACHE_DEFAULT_KEY_INTERVAL,
                              .quantum = 0, .piece_agents = CACHE_DEFAULT_PIECE};
}

/* status: FM_ERR_USAGE for options given by a caller, FM_ERR_INPUT for options read from a file. */
static fm_status check_options(const fm_cache_options *o, fm_status status, const char *path, fm_error *err)
{
    if (o->compression_level < CACHE_MIN_LEVEL || o->compression_level == 0 || o->compression_level > CACHE_MAX_LEVEL)
        return fm_fail(err, status, "%s: compression level %d is outside %d..-1 and 1..%d", path, o->compression_level,
                       CACHE_MIN_LEVEL, CACHE_MAX_LEVEL);
    if (o->key_interval < 1 || o->key_interval > CACHE_MAX_KEY_INTERVAL)
        return fm_fail(err, status, "%s: key interval %d is outside 1..%d", path, o->key_interval, CACHE_MAX_KEY_INTERVAL);
    if (!(o->quantum >= 0) || !isfinite(o->quantum))
        return fm_fail(err, status, "%s: quantum %g must be 0 (lossless) or a positive number", path, o->quantum);
    if (o->piece_agents < CACHE_MIN_PIECE || o->piece_agents > CACHE_MAX_PIECE)
        return fm_fail(err, status, "%s: %d agents per piece is outside %d..%d", path, o->piece_agents, CACHE_MIN_PIECE,
                       CACHE_MAX_PIECE);
    return FM_OK;
}

/* The filters the specification prescribes for an attribute under the options. */
static uint32_t filters_for(const fm_cache_attr_info *a, const fm_cache_options *o)
{
    uint32_t f = 0;
    if (a->scalar != FM_SCALAR_U8) f |= FILTER_SHUFFLE4;
    if (o->delta) f |= FILTER_DELTA;
    if (a->scalar == FM_SCALAR_F32 && o->quantum > 0) f |= FILTER_QUANTISE;
    return f;
}

fm_status cache_layout_init(cache_layout *l, uint64_t agents, double frame_rate, const fm_cache_attr *attrs,
                            int attr_count, const fm_cache_options *opts, const char *path, fm_error *err)
{
    memset(l, 0, sizeof *l);
    if (attr_count < 1 || attr_count > CACHE_MAX_ATTRS)
        return fm_fail(err, FM_ERR_USAGE, "%s: a cache holds 1 to %d attributes, not %d", path, CACHE_MAX_ATTRS, attr_count);
    fm_cache_options o = *opts;
    if (o.piece_agents == 0) o.piece_agents = CACHE_DEFAULT_PIECE;
    fm_status st = check_options(&o, FM_ERR_USAGE, path, err);
    if (st != FM_OK) return st;
    l->version = CACHE_VERSION;
    l->header_bytes = CACHE_FIXED_HEADER + CACHE_ATTR_RECORD * (uint32_t)attr_count;
    l->header_frames = 0; /* unknown until the writer finishes */
    l->agents = agents;
    l->frame_rate = frame_rate;
    l->opts = o;
    l->opts.delta = o.delta != 0;
    cache_layout_set_pieces(l, (uint64_t)o.piece_agents);
    for (int i = 0; i < attr_count; i++) {
        const fm_cache_attr_info *a = fm_cache_attr_describe(attrs[i]);
        if (!a) return fm_fail(err, FM_ERR_USAGE, "%s: unknown attribute kind %d", path, (int)attrs[i]);
        if (cache_attr_index(l, attrs[i]) >= 0)
            return fm_fail(err, FM_ERR_USAGE, "%s: attribute '%s' is given twice", path, a->name);
        l->attrs[i] = a;
        l->filters[i] = filters_for(a, &l->opts);
        l->attr_count = i + 1;
    }
    return FM_OK;
}

uint32_t cache_fixed_header_bytes(uint32_t version)
{
    return version >= 3 ? CACHE_FIXED_HEADER : CACHE_FIXED_HEADER_V2;
}

void cache_header_encode(const cache_layout *l, unsigned char *h)
{
    uint32_t records = cache_fixed_header_bytes(l->version);
    memset(h, 0, l->header_bytes);
    memcpy(h, CACHE_MAGIC, 8);
    put_u32(h + 8, l->version);
    put_u32(h + 12, l->header_bytes);
    put_u64(h + 16, l->agents);
    put_u32(h + 24, (uint32_t)l->attr_count);
    put_u32(h + 28, l->opts.delta ? HEADER_DELTA : 0);
    put_u32(h + 32, CACHE_CODEC_ZSTD);
    put_u32(h + 36, (uint32_t)l->opts.compression_level);
    put_f64(h + 40, l->frame_rate);
    put_u32(h + 48, (uint32_t)l->opts.key_interval);
    put_f64(h + 56, l->opts.quantum);
    if (l->version >= 3) put_u32(h + 64, l->header_frames);
    if (l->version >= 4) put_u32(h + 68, (uint32_t)l->piece_agents); /* format 3: 0 (reserved) */
    for (int i = 0; i < l->attr_count; i++) {
        unsigned char *a = h + records + CACHE_ATTR_RECORD * i;
        put_u32(a, (uint32_t)l->attrs[i]->attr);
        put_u32(a + 4, (uint32_t)l->attrs[i]->scalar);
        put_u32(a + 8, (uint32_t)l->attrs[i]->components);
        put_u32(a + 12, l->filters[i]);
    }
    put_u32(h + 52, cache_crc32(0, h, l->header_bytes)); /* computed with the field still 0 */
}

static fm_status decode_attr(cache_layout *l, int i, const unsigned char *a, const char *path, fm_error *err)
{
    const fm_cache_attr_info *info = fm_cache_attr_describe((fm_cache_attr)get_u32(a));
    if (!info) return fm_fail(err, FM_ERR_INPUT, "%s: attribute %d has unknown kind %u", path, i, get_u32(a));
    if (cache_attr_index(l, info->attr) >= 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: attribute '%s' appears twice", path, info->name);
    if (get_u32(a + 4) != (uint32_t)info->scalar || get_u32(a + 8) != (uint32_t)info->components)
        return fm_fail(err, FM_ERR_INPUT, "%s: attribute '%s' has the wrong type or component count", path, info->name);
    if (get_u32(a + 12) != filters_for(info, &l->opts))
        return fm_fail(err, FM_ERR_INPUT, "%s: attribute '%s' has unsupported filters %u", path, info->name, get_u32(a + 12));
    l->attrs[i] = info;
    l->filters[i] = get_u32(a + 12);
    l->attr_count = i + 1;
    return FM_OK;
}

fm_status cache_header_decode(cache_layout *l, const unsigned char *h, const char *path, fm_error *err)
{
    unsigned char zeroed_crc[4] = {0};
    uint32_t crc = cache_crc32(cache_crc32(cache_crc32(0, h, 52), zeroed_crc, 4), h + 56, l->header_bytes - 56);
    if (crc != get_u32(h + 52)) return fm_fail(err, FM_ERR_INPUT, "%s: header checksum mismatch", path);
    l->agents = get_u64(h + 16);
    l->attr_count = 0;
    l->opts.delta = (get_u32(h + 28) & HEADER_DELTA) != 0;
    l->opts.compression_level = (int)get_u32(h + 36);
    l->frame_rate = get_f64(h + 40);
    if (!(l->frame_rate > 0 && l->frame_rate <= 1e9))
        return fm_fail(err, FM_ERR_INPUT, "%s: damaged header: frame rate %g", path, l->frame_rate);
    l->opts.key_interval = (int)get_u32(h + 48);
    l->opts.quantum = get_f64(h + 56);
    l->opts.piece_agents = l->version >= 4 ? (int)FM_MIN(get_u32(h + 68), (uint32_t)INT32_MAX) : CACHE_DEFAULT_PIECE;
    if (get_u32(h + 32) != CACHE_CODEC_ZSTD || (get_u32(h + 28) & ~(uint32_t)HEADER_DELTA) != 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: unsupported codec or flags", path);
    fm_status st = check_options(&l->opts, FM_ERR_INPUT, path, err);
    if (st != FM_OK) return st;
    uint32_t count = get_u32(h + 24), records = cache_fixed_header_bytes(l->version);
    if (count < 1 || count > CACHE_MAX_ATTRS || l->header_bytes != records + CACHE_ATTR_RECORD * count)
        return fm_fail(err, FM_ERR_INPUT, "%s: bad attribute count %u for a %u-byte header", path, count, l->header_bytes);
    l->header_frames = l->version >= 3 ? get_u32(h + 64) : 0;
    if (l->version == 3 && get_u32(h + 68) != 0)
        return fm_fail(err, FM_ERR_INPUT, "%s: damaged header: reserved bytes 68..71 are not 0", path);
    cache_layout_set_pieces(l, l->version >= 4 ? (uint64_t)l->opts.piece_agents : 0);
    if (l->version < 4) l->opts.piece_agents = 0; /* one piece of every agent */
    for (uint32_t i = 0; i < count; i++) {
        st = decode_attr(l, (int)i, h + records + CACHE_ATTR_RECORD * i, path, err);
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

size_t cache_attr_bytes(const cache_layout *l, int i) { return (size_t)l->agents * l->attrs[i]->bytes_per_agent; }

size_t cache_frame_bytes(const cache_layout *l)
{
    size_t sum = 0;
    for (int i = 0; i < l->attr_count; i++) sum += cache_attr_bytes(l, i);
    return sum;
}

void cache_layout_set_pieces(cache_layout *l, uint64_t piece_agents)
{
    l->piece_agents = piece_agents ? piece_agents : FM_MAX(l->agents, 1); /* before format 4: one piece */
    l->pieces = FM_MAX((l->agents + l->piece_agents - 1) / l->piece_agents, 1);
}

uint64_t cache_piece_first(const cache_layout *l, uint64_t j) { return j * l->piece_agents; }

uint64_t cache_piece_agents(const cache_layout *l, uint64_t j)
{
    uint64_t first = cache_piece_first(l, j);
    return first < l->agents ? FM_MIN(l->piece_agents, l->agents - first) : 0;
}

size_t cache_block_bytes(const cache_layout *l, uint64_t j, int i)
{
    return (size_t)cache_piece_agents(l, j) * l->attrs[i]->bytes_per_agent;
}

uint64_t cache_table_bytes(const cache_layout *l) { return 8 * (uint64_t)l->attr_count * l->pieces; }

/* Every block at its bound: a full piece's bound times the full pieces, plus the last one's. */
uint64_t cache_payload_bound(const cache_layout *l)
{
    uint64_t sum = cache_table_bytes(l), last = l->pieces - 1;
    for (int i = 0; i < l->attr_count; i++)
        sum += last * ZSTD_compressBound(cache_block_bytes(l, 0, i)) + ZSTD_compressBound(cache_block_bytes(l, last, i));
    return sum;
}

int cache_is_key_frame(const cache_layout *l, uint32_t k)
{
    return !l->opts.delta || k % (uint32_t)l->opts.key_interval == 0;
}

int cache_attr_index(const cache_layout *l, fm_cache_attr attr)
{
    for (int i = 0; i < l->attr_count; i++)
        if (l->attrs[i]->attr == attr) return i;
    return -1;
}

/* zlib's crc32 takes uInt lengths: feed large buffers in pieces. */
uint32_t cache_crc32(uint32_t crc, const void *data, size_t n)
{
    const unsigned char *p = data;
    while (n > 0) {
        uInt part = n > (1u << 30) ? (1u << 30) : (uInt)n;
        crc = (uint32_t)crc32(crc, p, part);
        p += part, n -= part;
    }
    return crc;
}

uint32_t cache_chunk_crc(const unsigned char *chunk, uint64_t payload)
{
    return cache_crc32(cache_crc32(0, chunk, 12), chunk + 16, 8 + (size_t)payload);
}

/* One word in, one byte to each plane: the compiler keeps the four plane pointers in registers
 * and vectorises this, about 4x faster than a byte loop over (word, plane). */
void cache_shuffle4(const unsigned char *in, size_t count, unsigned char *out)
{
    unsigned char *p0 = out, *p1 = out + count, *p2 = out + 2 * count, *p3 = out + 3 * count;
    for (size_t i = 0; i < count; i++) {
        uint32_t w;
        memcpy(&w, in + 4 * i, 4);
        p0[i] = (unsigned char)w, p1[i] = (unsigned char)(w >> 8);
        p2[i] = (unsigned char)(w >> 16), p3[i] = (unsigned char)(w >> 24);
    }
}

void cache_shuffle_pieces(const cache_layout *l, int i, const unsigned char *in, unsigned char *out)
{
    for (uint64_t j = 0; j < l->pieces; j++) {
        size_t at = (size_t)cache_piece_first(l, j) * l->attrs[i]->bytes_per_agent;
        cache_shuffle4(in + at, cache_block_bytes(l, j, i) / 4, out + at);
    }
}

void cache_unshuffle_pieces(const cache_layout *l, int i, const unsigned char *in, unsigned char *out)
{
    for (uint64_t j = 0; j < l->pieces; j++) {
        size_t at = (size_t)cache_piece_first(l, j) * l->attrs[i]->bytes_per_agent;
        cache_unshuffle4(in + at, cache_block_bytes(l, j, i) / 4, out + at);
    }
}

void cache_unshuffle4(const unsigned char *in, size_t count, unsigned char *out)
{
    const unsigned char *p0 = in, *p1 = in + count, *p2 = in + 2 * count, *p3 = in + 3 * count;
    for (size_t i = 0; i < count; i++) {
        uint32_t w = (uint32_t)p0[i] | (uint32_t)p1[i] << 8 | (uint32_t)p2[i] << 16 | (uint32_t)p3[i] << 24;
        memcpy(out + 4 * i, &w, 4);
    }
}

void cache_xor(unsigned char *dst, const unsigned char *src, size_t n)
{
    for (size_t i = 0; i < n; i++) dst[i] ^= src[i];
}

int64_t cache_quantise(const float *in, size_t count, double quantum, int32_t *out)
{
    for (size_t i = 0; i < count; i++) {
        double m = rint((double)in[i] / quantum);
        if (!(fabs(m) < 2147483648.0)) return (int64_t)i;
        out[i] = (int32_t)m;
    }
    return -1;
}

void cache_dequantise(const int32_t *in, size_t count, double quantum, float *out)
{
    for (size_t i = 0; i < count; i++) out[i] = (float)((double)in[i] * quantum);
}
