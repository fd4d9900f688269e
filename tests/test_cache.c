/* The frame cache through the public API: bitwise round trips in random frame order, the
 * PATH.partial protocol, and damaged files (truncated, corrupted, not a cache) that must fail
 * with FM_ERR_INPUT and a message instead of crashing or returning wrong data. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "test_macros.h"

#include <float.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static uint64_t rng_state = 0x2545f4914f6cdd1dull;

static uint64_t rng_next(void) { return test_next_u64(&rng_state); }

static char *tmp_path(char *buf, const char *name)
{
    snprintf(buf, FM_PATH_MAX, "%s/cache_%s", FM_TEST_TMP, name);
    return buf;
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static unsigned char *read_all(const char *path, size_t *len)
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

static void write_all(const char *path, const void *data, size_t len)
{
    FILE *f = fopen(path, "wb");
    ENSURE_MSG(f != NULL, "cannot create %s", path);
    if (!f) return;
    ENSURE(fwrite(data, 1, len, f) == len);
    fclose(f);
}

static uint64_t get_u64(const unsigned char *p)
{
    uint64_t x;
    memcpy(&x, p, 8);
    return x;
}

/* Random float bit patterns (never NaN) with edge values planted at fixed places. */
static void random_frame(float *out, size_t count)
{
    static const float edges[] = {-0.0f, 0.0f, FLT_TRUE_MIN, -FLT_TRUE_MIN, 1e-40f, -3e-39f, FLT_MIN,
                                  FLT_MAX, -FLT_MAX, 1e38f, -1e30f, INFINITY, -INFINITY, 1.0f};
    for (size_t i = 0; i < count; i++) {
        uint32_t bits;
        do bits = (uint32_t)(rng_next() >> 32);
        while ((bits & 0x7f800000u) == 0x7f800000u && (bits & 0x007fffffu) != 0);
        memcpy(&out[i], &bits, 4);
    }
    for (size_t i = 0; i < sizeof edges / sizeof edges[0] && 7 * i < count; i++) out[7 * i] = edges[i];
}

/* Smooth, compressible frames, so zstd uses real compressed blocks. */
static void smooth_frame(float *out, size_t count, uint32_t frame)
{
    for (size_t i = 0; i < count; i++) out[i] = (float)(0.001 * (double)i + frame);
}

/* Writes a finished cache of `frames` frames of `agents` agents; frame data in data (may be
 * NULL: smooth frames). Returns 0 on success. */
static int write_cache(const char *path, uint64_t agents, uint32_t frames, double rate, int level, const float *data)
{
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(path, agents, rate, level, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return -1;
    size_t count = 12 * (size_t)agents;
    float *frame = malloc(sizeof(float) * (count ? count : 1));
    for (uint32_t f = 0; f < frames; f++) {
        if (data) memcpy(frame, data + f * count, sizeof(float) * count);
        else smooth_frame(frame, count, f);
        ENSURE_MSG(fm_cache_writer_add_frame(w, frame, &err) == FM_OK, "%s", err.message);
    }
    free(frame);
    fm_status st = fm_cache_writer_finish(w, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    return st == FM_OK ? 0 : -1;
}

/* ---------------------------------------------------------------- round trips */

static void round_trip(const char *name, uint64_t agents, uint32_t frames, int level)
{
    char path[FM_PATH_MAX];
    size_t count = 12 * (size_t)agents;
    float *data = malloc(sizeof(float) * count * frames), *got = malloc(sizeof(float) * count);
    for (uint32_t f = 0; f < frames; f++) random_frame(data + f * count, count);
    if (write_cache(tmp_path(path, name), agents, frames, 29.97, level, data) == 0) {
        fm_error err = {0};
        fm_cache_reader *r = fm_cache_open(path, &err);
        ENSURE_MSG(r != NULL, "%s", err.message);
        if (r) {
            ENSURE(fm_cache_agents(r) == agents);
            ENSURE(fm_cache_frames(r) == frames);
            ENSURE(fm_cache_frame_rate(r) == 29.97);
            /* every frame twice, in a random order */
            uint32_t order[64];
            for (uint32_t i = 0; i < 2 * frames; i++) order[i] = i % frames;
            for (uint32_t i = 2 * frames - 1; i > 0; i--) {
                uint32_t j = (uint32_t)(rng_next() % (i + 1)), t = order[i];
                order[i] = order[j], order[j] = t;
            }
            for (uint32_t i = 0; i < 2 * frames; i++) {
                uint32_t f = order[i];
                memset(got, 0xAB, sizeof(float) * count);
                ENSURE_MSG(fm_cache_read_frame(r, f, got, &err) == FM_OK, "%s", err.message);
                ENSURE_MSG(memcmp(got, data + f * count, sizeof(float) * count) == 0, "%s: frame %u differs", name, f);
            }
            fm_cache_close(r);
        }
    }
    free(data), free(got);
}

static void test_round_trip_bitwise(void)
{
    round_trip("rt_small.fmc", 37, 9, 3);
    round_trip("rt_one.fmc", 1, 3, 1);
    round_trip("rt_large.fmc", 3001, 5, 19); /* 144 kB frames: more than one zstd block */
}

static void test_zero_frames(void)
{
    char path[FM_PATH_MAX];
    if (write_cache(tmp_path(path, "zero.fmc"), 5, 0, 24.0, 3, NULL) != 0) return;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    ENSURE(fm_cache_frames(r) == 0 && fm_cache_agents(r) == 5 && fm_cache_frame_rate(r) == 24.0);
    float buf[60];
    ENSURE(fm_cache_read_frame(r, 0, buf, &err) != FM_OK);
    fm_cache_close(r);
}

static void test_read_past_end(void)
{
    char path[FM_PATH_MAX];
    if (write_cache(tmp_path(path, "past_end.fmc"), 4, 3, 24.0, 3, NULL) != 0) return;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    float buf[48], want[48];
    fm_status st = fm_cache_read_frame(r, 3, buf, &err);
    ENSURE(st != FM_OK && err.status == st);
    ENSURE_MSG(strstr(err.message, "frame 3") != NULL, "'%s'", err.message);
    ENSURE(fm_cache_read_frame(r, UINT32_MAX, buf, &err) != FM_OK);
    /* the reader still works after the errors */
    ENSURE(fm_cache_read_frame(r, 2, buf, &err) == FM_OK);
    smooth_frame(want, 48, 2);
    ENSURE(memcmp(buf, want, sizeof want) == 0);
    fm_cache_close(r);
}

/* ---------------------------------------------------------------- PATH.partial */

static void test_partial_until_finish(void)
{
    char path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    tmp_path(path, "partial.fmc");
    snprintf(partial, sizeof partial, "%s.partial", path);
    remove(path), remove(partial);
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(path, 2, 24.0, 3, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    float frame[24] = {0};
    ENSURE(fm_cache_writer_add_frame(w, frame, &err) == FM_OK);
    ENSURE(!file_exists(path) && file_exists(partial));
    ENSURE(fm_cache_open(path, &err) == NULL);
    ENSURE(fm_cache_writer_finish(w, &err) == FM_OK);
    ENSURE(file_exists(path) && !file_exists(partial));
}

static void test_abort_removes_everything(void)
{
    char path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    tmp_path(path, "abort.fmc");
    snprintf(partial, sizeof partial, "%s.partial", path);
    remove(path), remove(partial);
    fm_error err = {0};
    float frame[36] = {1, 2, 3};
    fm_cache_writer *w = fm_cache_writer_create(path, 3, 24.0, 3, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    ENSURE(fm_cache_writer_add_frame(w, frame, &err) == FM_OK);
    ENSURE(fm_cache_writer_add_frame(w, frame, &err) == FM_OK);
    fm_cache_writer_abort(w);
    ENSURE(!file_exists(path) && !file_exists(partial));
    /* aborting a rewrite keeps the earlier complete cache */
    if (write_cache(path, 3, 2, 24.0, 3, NULL) != 0) return;
    w = fm_cache_writer_create(path, 3, 30.0, 3, &err);
    ENSURE(w != NULL);
    fm_cache_writer_abort(w);
    ENSURE(!file_exists(partial));
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL && fm_cache_frames(r) == 2 && fm_cache_frame_rate(r) == 24.0, "%s", err.message);
    fm_cache_close(r);
}

static void test_create_in_missing_directory(void)
{
    char path[FM_PATH_MAX];
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(tmp_path(path, "no_such_dir/x.fmc"), 3, 24.0, 3, &err);
    ENSURE(w == NULL);
    fm_cache_writer_abort(w);
    ENSURE(err.status == FM_ERR_IO && strstr(err.message, "no_such_dir") != NULL);
}

/* ---------------------------------------------------------------- damaged files */

/* Opening must fail with FM_ERR_INPUT, the path and `what` in the message. */
static void expect_open_fails(const char *path, const char *what)
{
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r == NULL, "%s opened", path);
    fm_cache_close(r);
    ENSURE_MSG(err.status == FM_ERR_INPUT, "status %d: %s", (int)err.status, err.message);
    ENSURE_MSG(strstr(err.message, path) != NULL && strstr(err.message, what) != NULL, "'%s' lacks '%s'",
               err.message, what);
}

/* A cache cut at any byte: a cut inside the header is an error; any later cut opens with a warning
 * and exactly the frames whose chunks are complete, bitwise equal to the whole cache's. */
static void test_truncated(void)
{
    char path[FM_PATH_MAX], cut[FM_PATH_MAX];
    const uint64_t agents = 20;
    if (write_cache(tmp_path(path, "whole.fmc"), agents, 4, 24.0, 3, NULL) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    ENSURE(bytes != NULL && len > 100);
    if (!bytes) return;
    size_t index = (size_t)get_u64(bytes + len - 16);
    ENSURE(index > 64 && index < len - 16 && memcmp(bytes + index, "FIDX", 4) == 0);
    size_t chunk_end[4]; /* where each frame's chunk ends */
    for (int f = 0; f < 4; f++) {
        size_t at = (size_t)get_u64(bytes + index + 8 + 8 * (size_t)f);
        chunk_end[f] = at + 24 + (size_t)get_u64(bytes + at + 8);
    }
    fm_error err = {0};
    fm_cache_reader *whole = fm_cache_open(path, &err);
    ENSURE(whole && fm_cache_warning(whole)[0] == 0);
    float *want = malloc(sizeof(float) * 12 * agents), *got = malloc(sizeof(float) * 12 * agents);
    const size_t at[] = {0, 7, 40, 63, 64, 64 + 10, 64 + 24 + 5, chunk_end[0], chunk_end[1] + 1, index / 2, index,
                         index + 4, index + 8 + 3, len - 16, len - 9, len - 1};
    tmp_path(cut, "cut.fmc");
    for (size_t i = 0; i < sizeof at / sizeof at[0] && whole; i++) {
        write_all(cut, bytes, at[i]);
        memset(&err, 0, sizeof err);
        fm_cache_reader *r = fm_cache_open(cut, &err);
        if (at[i] < 64) { /* no complete header: nothing to recover */
            ENSURE_MSG(r == NULL && err.status == FM_ERR_INPUT && strstr(err.message, cut) &&
                       (strstr(err.message, "truncated") || strstr(err.message, "not a flockmorph cache")),
                       "cut at %zu: '%s'", at[i], err.message);
            fm_cache_close(r);
            continue;
        }
        ENSURE_MSG(r != NULL, "cut at %zu: %s", at[i], err.message);
        if (!r) continue;
        uint32_t complete = 0;
        while (complete < 4 && chunk_end[complete] <= at[i]) complete++;
        ENSURE_MSG(fm_cache_frames(r) == complete, "cut at %zu: %u frames, %u complete", at[i], fm_cache_frames(r), complete);
        ENSURE_MSG(strstr(fm_cache_warning(r), cut) && strstr(fm_cache_warning(r), "recovered"),
                   "cut at %zu: warning '%s'", at[i], fm_cache_warning(r));
        for (uint32_t f = 0; f < fm_cache_frames(r); f++) {
            ENSURE(fm_cache_read_frame(whole, f, want, &err) == FM_OK && fm_cache_read_frame(r, f, got, &err) == FM_OK);
            ENSURE(memcmp(want, got, sizeof(float) * 12 * agents) == 0);
        }
        fm_cache_close(r);
    }
    fm_cache_close(whole);
    free(want), free(got), free(bytes);
}

/* Flips one byte at `offset` within frame 1's chunk (or its compressed data) and expects frame 1
 * to fail with FM_ERR_INPUT while frames 0 and 2 still read back intact. */
static void flip_in_frame1(const char *name, int in_data, size_t offset)
{
    char path[FM_PATH_MAX];
    if (write_cache(tmp_path(path, name), 30, 3, 24.0, 3, NULL) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    if (!bytes) return;
    size_t index = (size_t)get_u64(bytes + len - 16);
    size_t chunk = (size_t)get_u64(bytes + index + 8 + 8);
    size_t packed = (size_t)get_u64(bytes + chunk + 8);
    ENSURE(memcmp(bytes + chunk, "FRAM", 4) == 0 && packed > 8);
    size_t pos = chunk + (in_data ? 24 + (offset < packed ? offset : packed - 1) : offset);
    bytes[pos] ^= 0x5a;
    write_all(path, bytes, len);
    free(bytes);

    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    float got[360], want[360];
    fm_status st = fm_cache_read_frame(r, 1, got, &err);
    ENSURE_MSG(st == FM_ERR_INPUT && err.status == FM_ERR_INPUT, "%s: status %d", name, (int)st);
    ENSURE_MSG(strstr(err.message, "frame 1") != NULL, "'%s'", err.message);
    for (uint32_t f = 0; f < 3; f += 2) {
        ENSURE(fm_cache_read_frame(r, f, got, &err) == FM_OK);
        smooth_frame(want, 360, f);
        ENSURE(memcmp(got, want, sizeof want) == 0);
    }
    fm_cache_close(r);
}

static void test_corrupt_chunk(void)
{
    flip_in_frame1("flip_magic.fmc", 1, 0);      /* zstd frame magic */
    flip_in_frame1("flip_middle.fmc", 1, 40);    /* compressed block */
    flip_in_frame1("flip_checksum.fmc", 1, 1000); /* last byte: the content checksum */
    flip_in_frame1("flip_header.fmc", 0, 4);     /* the chunk's frame number */
    flip_in_frame1("flip_rawsize.fmc", 0, 16);   /* the chunk's raw size */
}

static void test_not_a_cache(void)
{
    char path[FM_PATH_MAX], text[1024];
    memset(text, 'x', sizeof text);
    memcpy(text, "{\"agents\": 5}\n", 14);
    write_all(tmp_path(path, "text.fmc"), text, sizeof text);
    expect_open_fails(path, "not a flockmorph cache");
    /* a file shorter than the header that does not start like one is not a cache either */
    write_all(tmp_path(path, "short.fmc"), "hello\n", 6);
    expect_open_fails(path, "not a flockmorph cache");
}

static void test_bad_version(void)
{
    char path[FM_PATH_MAX];
    if (write_cache(tmp_path(path, "version.fmc"), 2, 1, 24.0, 3, NULL) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    if (!bytes) return;
    bytes[8] = 7; /* version field */
    write_all(path, bytes, len);
    free(bytes);
    expect_open_fails(path, "version 7");
}

/* A write that fails on the writer thread (the partial file is a symlink to /dev/full, which
 * takes the open and fails every write) is reported by a later call, and nothing is left under
 * the final name. */
static void test_write_failure_on_the_writer_thread(void)
{
    struct stat st;
    if (stat("/dev/full", &st) != 0) return;
    char path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    tmp_path(path, "full.fmc");
    snprintf(partial, sizeof partial, "%s.partial", path);
    remove(path), remove(partial);
    if (symlink("/dev/full", partial) != 0) return;
    fm_error err = {0};
    /* the 64-byte header is buffered by stdio, so creation succeeds */
    fm_cache_writer *w = fm_cache_writer_create(path, 100000, 24, 1, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return remove(partial), (void)0;
    float *frame = calloc(12 * 100000, sizeof(float));
    fm_status status = FM_OK;
    for (int f = 0; f < 4 && status == FM_OK; f++) status = fm_cache_writer_add_frame(w, frame, &err);
    if (status == FM_OK) status = fm_cache_writer_finish(w, &err);
    else fm_cache_writer_abort(w);
    ENSURE_MSG(status == FM_ERR_IO, "status %d: %s", (int)status, err.message);
    ENSURE(strstr(err.message, path) != NULL);
    ENSURE(stat(path, &st) != 0); /* no cache under the final name */
    free(frame);
    remove(partial);
}

/* ---------------------------------------------------------------- resume */

static void partial_name(char *partial, const char *path) { snprintf(partial, FM_PATH_MAX + 16, "%s.partial", path); }

/* Resumes PATH.partial (already in place) at frame `at`, adds frames at..total-1 as smooth frames
 * and finishes; returns 0 on success. */
static int resume_and_finish(const char *path, uint32_t at, uint32_t total, uint64_t agents)
{
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_resume(path, at, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return -1;
    ENSURE(fm_cache_writer_frames(w) == at);
    float *frame = malloc(sizeof(float) * 12 * agents);
    for (uint32_t f = at; f < total; f++) {
        smooth_frame(frame, 12 * agents, f);
        ENSURE_MSG(fm_cache_writer_add_frame(w, frame, &err) == FM_OK, "%s", err.message);
    }
    ENSURE(fm_cache_writer_frames(w) == total);
    free(frame);
    fm_status st = fm_cache_writer_finish(w, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    return st == FM_OK ? 0 : -1;
}

/* A run killed at various points leaves PATH.partial cut somewhere; resuming at frame 6 and adding
 * frames 6..9 gives exactly the bytes of an uninterrupted run. */
static void test_resume_is_byte_identical(void)
{
    enum { AGENTS = 25, FRAMES = 10, AT = 6 };
    char ref[FM_PATH_MAX], path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    if (write_cache(tmp_path(ref, "resume_ref.fmc"), AGENTS, FRAMES, 24.0, 5, NULL) != 0) return;
    size_t len;
    unsigned char *want = read_all(ref, &len);
    if (!want) return;
    size_t index = (size_t)get_u64(want + len - 16), chunk[FRAMES + 1];
    for (int f = 0; f < FRAMES; f++) chunk[f] = (size_t)get_u64(want + index + 8 + 8 * (size_t)f);
    chunk[FRAMES] = index;
    /* where the killed run's file ends: right after frame 5, in frame 6's chunk header, in frame 7's
     * data, after frame 9 (no index), inside the index, and with the footer (killed before the rename) */
    const size_t cuts[] = {chunk[AT], chunk[AT] + 10, chunk[AT + 1] + 30, index, index + 12, len};
    tmp_path(path, "resume.fmc");
    partial_name(partial, path);
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        remove(path);
        write_all(partial, want, cuts[i]);
        if (resume_and_finish(path, AT, FRAMES, AGENTS) != 0) continue;
        size_t got_len;
        unsigned char *got = read_all(path, &got_len);
        ENSURE_MSG(got && got_len == len && memcmp(got, want, len) == 0, "cut at %zu: resumed file differs", cuts[i]);
        ENSURE(!file_exists(partial));
        free(got);
    }
    free(want);
}

/* The state a real writer leaves on disk after flush(): resume from it, byte-identical again. */
static void test_resume_after_flush(void)
{
    enum { AGENTS = 25, FRAMES = 10, AT = 6 };
    char ref[FM_PATH_MAX], path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    if (write_cache(tmp_path(ref, "flush_ref.fmc"), AGENTS, FRAMES, 24.0, 5, NULL) != 0) return;
    tmp_path(path, "flush.fmc");
    partial_name(partial, path);
    remove(path);
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create(path, AGENTS, 24.0, 5, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    float frame[12 * AGENTS];
    for (uint32_t f = 0; f < 8; f++) {
        smooth_frame(frame, 12 * AGENTS, f);
        ENSURE(fm_cache_writer_add_frame(w, frame, &err) == FM_OK);
    }
    ENSURE(fm_cache_writer_flush(w, &err) == FM_OK && fm_cache_writer_frames(w) == 8);
    size_t len;
    unsigned char *on_disk = read_all(partial, &len); /* what a kill now would leave */
    fm_cache_writer_abort(w);
    if (!on_disk) return;
    write_all(partial, on_disk, len);
    free(on_disk);
    fm_cache_reader *r = fm_cache_open(partial, &err);
    ENSURE_MSG(r && fm_cache_frames(r) == 8, "flushed frames not all on disk: %s", r ? fm_cache_warning(r) : err.message);
    fm_cache_close(r);
    if (resume_and_finish(path, AT, FRAMES, AGENTS) != 0) return;
    size_t a_len, b_len;
    unsigned char *a = read_all(ref, &a_len), *b = read_all(path, &b_len);
    ENSURE(a && b && a_len == b_len && memcmp(a, b, a_len) == 0);
    free(a), free(b);
}

/* Resume refuses a partial file with too few frames or a damaged frame, and leaves it alone. */
static void test_resume_refuses(void)
{
    char ref[FM_PATH_MAX], path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    if (write_cache(tmp_path(ref, "refuse_ref.fmc"), 30, 5, 24.0, 3, NULL) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(ref, &len);
    if (!bytes) return;
    tmp_path(path, "refuse.fmc");
    partial_name(partial, path);
    fm_error err = {0};
    remove(partial);
    ENSURE(fm_cache_writer_resume(path, 2, &err) == NULL && err.status == FM_ERR_INPUT &&
           strstr(err.message, "nothing to resume"));
    size_t index = (size_t)get_u64(bytes + len - 16), chunk3 = (size_t)get_u64(bytes + index + 8 + 24);
    write_all(partial, bytes, chunk3 + 30); /* frames 0..2 complete */
    ENSURE(fm_cache_writer_resume(path, 4, &err) == NULL);
    ENSURE_MSG(err.status == FM_ERR_INPUT && strstr(err.message, "only 3 complete frames"), "'%s'", err.message);
    size_t chunk1 = (size_t)get_u64(bytes + index + 8 + 8);
    bytes[chunk1 + 24 + 20] ^= 0x40; /* inside frame 1's compressed data */
    write_all(partial, bytes, len);
    ENSURE(fm_cache_writer_resume(path, 3, &err) == NULL);
    ENSURE_MSG(err.status == FM_ERR_INPUT && strstr(err.message, "frame 1"), "'%s'", err.message);
    size_t still;
    unsigned char *kept = read_all(partial, &still);
    ENSURE(kept && still == len && memcmp(kept, bytes, len) == 0);
    free(kept), free(bytes);
    remove(partial);
}

int main(void)
{
    RUN_TEST(test_write_failure_on_the_writer_thread);
    RUN_TEST(test_round_trip_bitwise);
    RUN_TEST(test_zero_frames);
    RUN_TEST(test_read_past_end);
    RUN_TEST(test_partial_until_finish);
    RUN_TEST(test_abort_removes_everything);
    RUN_TEST(test_create_in_missing_directory);
    RUN_TEST(test_truncated);
    RUN_TEST(test_corrupt_chunk);
    RUN_TEST(test_not_a_cache);
    RUN_TEST(test_bad_version);
    RUN_TEST(test_resume_is_byte_identical);
    RUN_TEST(test_resume_after_flush);
    RUN_TEST(test_resume_refuses);
    return test_result();
}
