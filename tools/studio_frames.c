/* The studio's binary frame message (docs/studio.md, "Frames") and the played cache.
 *
 *   0   "FMF1"
 *   4   u32 generation      the run it is of (a page drops frames of an older one)
 *   8   u32 frame
 *   12  u32 agents
 *   16  u32 attribute count A
 *   20  A × {u32 attribute (fm_cache_attr), u32 offset, u32 bytes}
 *   ... each attribute's array at its offset (16-byte aligned, so a Float32Array views it in place)
 *
 * Little-endian, as the cache is. The arrays are the writer's own bytes (the run's tap) or the
 * reader's (playback): no conversion, so a test compares them with the cache byte for byte.
 * Orientation is left out: the page does not draw it, and it is a third of a point flock's bytes. */
#define _POSIX_C_SOURCE 200809L
#include "studio.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FRAME_HEAD 20
#define FRAME_ATTR_ENTRY 12

static size_t align16(size_t n) { return (n + 15) / 16 * 16; }

static int sent(const fm_cache_attr_info *a) { return a->attr != FM_ATTR_ORIENTATION; }

static void put32(unsigned char *p, uint32_t v) { memcpy(p, &v, 4); } /* x86-64: little-endian */

/* Bytes of the message, or 0 when it would not fit the header's 32-bit offsets. */
static size_t frame_bytes(uint64_t agents, int attr_count, const fm_cache_attr_info *const *attrs, int *shown)
{
    *shown = 0;
    size_t at = FRAME_HEAD;
    for (int i = 0; i < attr_count; i++) *shown += sent(attrs[i]);
    at = align16(at + (size_t)*shown * FRAME_ATTR_ENTRY);
    for (int i = 0; i < attr_count; i++)
        if (sent(attrs[i])) at = align16(at + (size_t)agents * attrs[i]->bytes_per_agent);
    return at > UINT32_MAX ? 0 : at;
}

studio_frame *studio_frame_make(uint32_t generation, uint32_t frame, uint64_t agents, int attr_count,
                                const fm_cache_attr_info *const *attrs, const void *const *data)
{
    int shown;
    size_t bytes = frame_bytes(agents, attr_count, attrs, &shown);
    studio_frame *f = bytes ? calloc(1, sizeof *f + bytes) : NULL;
    if (!f) return NULL;
    f->bytes = bytes;
    unsigned char *m = f->data;
    memcpy(m, "FMF1", 4);
    put32(m + 4, generation), put32(m + 8, frame), put32(m + 12, (uint32_t)agents), put32(m + 16, (uint32_t)shown);
    size_t at = align16(FRAME_HEAD + (size_t)shown * FRAME_ATTR_ENTRY);
    unsigned char *entry = m + FRAME_HEAD;
    for (int i = 0; i < attr_count; i++) {
        if (!sent(attrs[i])) continue;
        size_t n = (size_t)agents * attrs[i]->bytes_per_agent;
        put32(entry, (uint32_t)attrs[i]->attr), put32(entry + 4, (uint32_t)at), put32(entry + 8, (uint32_t)n);
        memcpy(m + at, data[i], n);
        entry += FRAME_ATTR_ENTRY, at = align16(at + n);
    }
    return f;
}

const char *studio_kind(int attr_count, const fm_cache_attr_info *const *attrs)
{
    for (int i = 0; i < attr_count; i++)
        if (attrs[i]->attr == FM_ATTR_TET_VERTICES) return "tets";
    return "points";
}

/* ---------------------------------------------------------------- playback */

int studio_playback_open(studio *s)
{
    int rc = cli_open_cache(s->path, &s->reader); /* prints a partial cache's warning */
    if (rc) return rc;
    const fm_cache_attr_info *attrs[16];
    int n = fm_cache_attr_count(s->reader);
    for (int i = 0; i < n && i < 16; i++) attrs[i] = fm_cache_attr_at(s->reader, i);
    snprintf(s->kind, sizeof s->kind, "%s", studio_kind(n, attrs));
    s->agents = fm_cache_agents(s->reader);
    s->frame_rate = fm_cache_frame_rate(s->reader);
    s->frame_count = fm_cache_frames(s->reader);
    s->stage = "playback";
    if (s->agents > UINT32_MAX / 48)
        return fprintf(stderr, "flockmorph: %s: %llu agents are more than the studio streams\n", s->path,
                       (unsigned long long)s->agents), FM_ERR_USAGE;
    return 0;
}

studio_frame *studio_playback_frame(studio *s, uint32_t k, char *msg, size_t size)
{
    int n = fm_cache_attr_count(s->reader);
    if (n > 16) n = 16;
    const fm_cache_attr_info *attrs[16] = {0};
    void *data[16] = {0};
    fm_error err = {0};
    fm_status st = FM_OK;
    for (int i = 0; i < n && st == FM_OK; i++) {
        attrs[i] = fm_cache_attr_at(s->reader, i);
        if (attrs[i]->attr == FM_ATTR_ORIENTATION) continue;
        data[i] = malloc((size_t)s->agents * attrs[i]->bytes_per_agent + 16);
        st = data[i] ? fm_cache_read_attr(s->reader, k, attrs[i]->attr, data[i], &err)
                     : fm_fail(&err, FM_ERR_MEMORY, "out of memory for frame %u", k);
    }
    studio_frame *f = st == FM_OK ? studio_frame_make(0, k, s->agents, n, attrs, (const void *const *)data) : NULL;
    if (st == FM_OK && !f) snprintf(msg, size, "out of memory for frame %u", k);
    if (st != FM_OK) snprintf(msg, size, "%s", err.message);
    for (int i = 0; i < n; i++) free(data[i]);
    return f;
}

/* stats.json's plain values (numbers, strings, booleans), from beside the cache; NULL without one. */
static json_t *stats_beside(const char *cache)
{
    char path[FM_PATH_MAX + 16];
    const char *slash = strrchr(cache, '/');
    int dir = slash ? (int)(slash - cache + 1) : 0;
    snprintf(path, sizeof path, "%.*sstats.json", dir, cache);
    json_t *all = json_load_file(path, 0, NULL), *plain = json_object(), *v;
    const char *key;
    json_object_foreach(all, key, v) if (json_is_number(v) || json_is_string(v) || json_is_boolean(v))
        json_object_set(plain, key, v);
    json_decref(all);
    return json_object_size(plain) ? plain : (json_decref(plain), NULL);
}

json_t *studio_cache_json(studio *s)
{
    fm_cache_reader *r = s->reader;
    json_t *names = json_array();
    for (int i = 0; i < fm_cache_attr_count(r); i++) json_array_append_new(names, json_string(fm_cache_attr_at(r, i)->name));
    const fm_cache_options o = fm_cache_get_options(r);
    json_t *stats = stats_beside(s->path);
    return json_pack("{sIsIsfsisosIsIsIsisbsisfssso*}", "agents", (json_int_t)s->agents, "frames", (json_int_t)s->frame_count,
                     "frame_rate", s->frame_rate, "version", (int)fm_cache_version(r), "attributes", names, "file_bytes",
                     (json_int_t)fm_cache_file_bytes(r), "raw_bytes", (json_int_t)fm_cache_raw_bytes(r),
                     "compressed_bytes", (json_int_t)fm_cache_compressed_bytes(r), "compression_level",
                     o.compression_level, "delta", o.delta, "key_interval", o.key_interval, "quantum", o.quantum,
                     "warning", fm_cache_warning(r), "stats", stats);
}
