/* Shared by the cache tests: scratch files, deterministic frames of every attribute kind, and a
 * checker that compares a cache's frames with the frames that went in. */
#ifndef FM_CACHE_HELPERS_H
#define FM_CACHE_HELPERS_H

#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static inline char *tmp_path(char *buf, const char *name)
{
    snprintf(buf, FM_PATH_MAX, "%s/cache_%s", FM_TEST_TMP, name);
    return buf;
}

static inline void partial_name(char *partial, const char *path) { snprintf(partial, FM_PATH_MAX + 16, "%s.partial", path); }

static inline int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static inline unsigned char *read_all(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    *len = 0;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = malloc(n > 0 ? (size_t)n : 1);
    if (buf) *len = fread(buf, 1, (size_t)n, f);
    fclose(f);
    return buf;
}

static inline void write_all(const char *path, const void *data, size_t len)
{
    FILE *f = fopen(path, "wb");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (!f) return;
    ENSURE(fwrite(data, 1, len, f) == len);
    fclose(f);
}

static inline int same_files(const char *a, const char *b)
{
    size_t na, nb;
    unsigned char *x = read_all(a, &na), *y = read_all(b, &nb);
    int same = x && y && na == nb && memcmp(x, y, na) == 0;
    free(x), free(y);
    return same;
}

static inline uint32_t bytes_u32(const unsigned char *p)
{
    uint32_t x;
    memcpy(&x, p, 4);
    return x;
}

static inline uint64_t bytes_u64(const unsigned char *p)
{
    uint64_t x;
    memcpy(&x, p, 8);
    return x;
}

/* Where chunk k starts and ends, from the index of a complete cache's bytes. */
static inline size_t chunk_start(const unsigned char *bytes, size_t len, uint32_t k)
{
    return (size_t)bytes_u64(bytes + bytes_u64(bytes + len - 16) + 8 + 16 * (size_t)k);
}

static inline size_t chunk_end(const unsigned char *bytes, size_t len, uint32_t k)
{
    return chunk_start(bytes, len, k) + (size_t)bytes_u64(bytes + bytes_u64(bytes + len - 16) + 16 + 16 * (size_t)k);
}

/* How test frames look: any bit pattern (NaNs and infinities included; for lossless checks) or
 * smooth bounded values that change a little from frame to frame (compressible, quantisable). */
typedef enum data_kind { DATA_RANDOM, DATA_SMOOTH } data_kind;

/* Attribute `attr` of frame `frame` (agents × components values), the same on every call. */
static inline void make_attr(fm_cache_attr attr, uint64_t agents, uint32_t frame, data_kind kind, void *out)
{
    const fm_cache_attr_info *info = fm_cache_attr_describe(attr);
    size_t count = (size_t)agents * (size_t)info->components;
    for (size_t j = 0; j < count; j++) {
        uint64_t state = ((uint64_t)attr << 56) ^ ((uint64_t)frame << 32) ^ j;
        uint64_t bits = test_next_u64(&state);
        if (info->scalar == FM_SCALAR_U8) {
            ((uint8_t *)out)[j] = kind == DATA_RANDOM ? (uint8_t)bits : (uint8_t)((frame / 3 + j / 5) % 4);
        } else if (info->scalar == FM_SCALAR_U32) {
            ((uint32_t *)out)[j] = kind == DATA_RANDOM ? (uint32_t)(bits >> 32) : (uint32_t)(j / (size_t)info->components);
        } else if (kind == DATA_RANDOM) {
            uint32_t u = (uint32_t)(bits >> 32);
            memcpy((float *)out + j, &u, 4);
        } else {
            ((float *)out)[j] = (float)(40.0 * sin(0.37 * (double)j + 0.05 * frame * (double)(1 + j % 7)) + (double)(j % 5));
        }
    }
}

/* Writes a finished cache of `frames` frames; returns 0 on success. */
static inline int write_attrs_cache(const char *path, uint64_t agents, uint32_t frames, const fm_cache_attr *attrs, int n,
                             const fm_cache_options *opts, data_kind kind)
{
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create_attrs(path, agents, 25.0, attrs, n, opts, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return -1;
    void *data[7]; /* every kind at most once (cache_format.h CACHE_MAX_ATTRS) */
    for (int i = 0; i < n; i++) data[i] = malloc(fm_cache_attr_describe(attrs[i])->bytes_per_agent * agents + 1);
    fm_status st = FM_OK;
    for (uint32_t f = 0; f < frames && st == FM_OK; f++) {
        for (int i = 0; i < n; i++) make_attr(attrs[i], agents, f, kind, data[i]);
        st = fm_cache_writer_add_frame_attrs(w, (const void *const *)data, &err);
        ENSURE_MSG(st == FM_OK, "%s", err.message);
    }
    for (int i = 0; i < n; i++) free(data[i]);
    if (st != FM_OK) return fm_cache_writer_abort(w), -1;
    st = fm_cache_writer_finish(w, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    return st == FM_OK ? 0 : -1;
}

/* Frame `frame` of every attribute equals what make_attr wrote: bitwise, or within quantum / 2
 * (plus the float rounding of the read value) for quantised f32 attributes. Returns 1 if equal. */
static inline int frame_matches(fm_cache_reader *r, uint32_t frame, data_kind kind, double quantum, const char *label)
{
    int ok = 1;
    uint64_t agents = fm_cache_agents(r);
    for (int i = 0; i < fm_cache_attr_count(r); i++) {
        const fm_cache_attr_info *info = fm_cache_attr_at(r, i);
        size_t bytes = info->bytes_per_agent * agents;
        unsigned char *got = malloc(bytes + 1), *want = malloc(bytes + 1);
        fm_error err = {0};
        memset(got, 0xA5, bytes);
        make_attr(info->attr, agents, frame, kind, want);
        fm_status st = fm_cache_read_attr(r, frame, info->attr, got, &err);
        ENSURE_MSG(st == FM_OK, "%s: frame %u %s: %s", label, frame, info->name, err.message);
        if (st != FM_OK) ok = 0;
        else if (info->scalar == FM_SCALAR_F32 && quantum > 0) {
            for (size_t j = 0; j < bytes / 4 && ok; j++) {
                double w = ((float *)want)[j], g = ((float *)got)[j];
                double tol = quantum / 2 * (1 + 1e-9) + FLT_EPSILON / 2 * (fabs(w) + quantum);
                ok = fabs(g - w) <= tol;
                ENSURE_MSG(ok, "%s: frame %u %s[%zu]: %.9g read back as %.9g (quantum %g)", label, frame, info->name, j, w, g, quantum);
            }
        } else {
            ok = memcmp(got, want, bytes) == 0;
            ENSURE_MSG(ok, "%s: frame %u %s differs", label, frame, info->name);
        }
        free(got), free(want);
    }
    return ok;
}

static const fm_cache_attr ALL_ATTRS[] = {FM_ATTR_TET_VERTICES, FM_ATTR_POSITION, FM_ATTR_VELOCITY,
                                          FM_ATTR_ORIENTATION, FM_ATTR_ID, FM_ATTR_PHASE, FM_ATTR_GROUP};
#define ALL_ATTR_COUNT 7

#endif
