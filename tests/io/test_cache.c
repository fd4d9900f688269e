/* The frame cache through the public API: bitwise round trips in random frame order, the
 * PATH.partial protocol, and damaged files (truncated, corrupted, not a cache) that must fail
 * with FM_ERR_INPUT and a message instead of crashing or returning wrong data. */
#define _POSIX_C_SOURCE 200809L
#include "cache_helpers.h"
#include "full_disk.h"

#include <unistd.h>
#include <zlib.h>

static uint64_t rng_state = 0x2545f4914f6cdd1dull;

static uint64_t rng_next(void) { return test_next_u64(&rng_state); }

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

/* ---------------------------------------------------------------- damaged files (format 3) */

/* A cache cut at every byte: a cut inside the header is an error; any later cut opens with a
 * warning and exactly the frames whose chunks are complete, equal to what was written. */
static void test_truncated_at_every_byte(void)
{
    enum { FRAMES = 5 };
    char path[FM_PATH_MAX], cut[FM_PATH_MAX];
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_PHASE};
    fm_cache_options opts = fm_default_cache_options();
    opts.delta = 1, opts.key_interval = 2;
    if (write_attrs_cache(tmp_path(path, "whole.fmc"), 3, FRAMES, attrs, 2, &opts, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    if (!bytes) return;
    size_t header = bytes_u32(bytes + 12), ends[FRAMES];
    for (uint32_t k = 0; k < FRAMES; k++) ends[k] = chunk_end(bytes, len, k);
    ENSURE(header == 72 + 2 * 16 && chunk_start(bytes, len, 0) == header);
    tmp_path(cut, "cut.fmc");
    for (size_t at = 0; at < len; at++) {
        write_all(cut, bytes, at);
        fm_error err = {0};
        fm_cache_reader *r = fm_cache_open(cut, &err);
        if (at < header) { /* no complete header: nothing to recover */
            ENSURE_MSG(r == NULL && err.status == FM_ERR_INPUT && strstr(err.message, cut) &&
                       (strstr(err.message, "truncated") || strstr(err.message, "not a flockmorph cache")),
                       "cut at %zu: '%s'", at, err.message);
            fm_cache_close(r);
            continue;
        }
        ENSURE_MSG(r != NULL, "cut at %zu: %s", at, err.message);
        if (!r) continue;
        uint32_t complete = 0;
        while (complete < FRAMES && ends[complete] <= at) complete++;
        ENSURE_MSG(fm_cache_frames(r) == complete, "cut at %zu: %u frames, %u complete", at, fm_cache_frames(r), complete);
        ENSURE_MSG(strstr(fm_cache_warning(r), cut) && strstr(fm_cache_warning(r), "recovered") &&
                   strstr(fm_cache_warning(r), "(the header announces 5)"), "cut at %zu: warning '%s'", at, fm_cache_warning(r));
        ENSURE(fm_cache_header_frames(r) == FRAMES);
        for (uint32_t f = 0; f < fm_cache_frames(r); f++) frame_matches(r, f, DATA_SMOOTH, 0, "truncated");
        fm_cache_close(r);
    }
    free(bytes);
}

/* Every byte of frame 1's chunk flipped in turn: reading frame 1 fails with an error naming it
 * (a checksum mismatch for anything but the tag, frame number and payload size, which the header
 * check catches first), and frames 0 and 2 still read back. */
static void test_flipped_byte_fails_its_checksum(void)
{
    char path[FM_PATH_MAX], bad[FM_PATH_MAX];
    const fm_cache_attr attrs[] = {FM_ATTR_POSITION, FM_ATTR_ID};
    fm_cache_options whole = fm_default_cache_options();
    whole.delta = 0; /* every frame on its own: frame 2 does not build on frame 1 */
    if (write_attrs_cache(tmp_path(path, "flip.fmc"), 30, 3, attrs, 2, &whole, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    if (!bytes) return;
    size_t from = chunk_start(bytes, len, 1), to = chunk_end(bytes, len, 1);
    tmp_path(bad, "flipped.fmc");
    int mismatches = 0;
    for (size_t at = from; at < to; at++) {
        bytes[at] ^= 0x10;
        write_all(bad, bytes, len);
        bytes[at] ^= 0x10;
        fm_error err = {0};
        fm_cache_reader *r = fm_cache_open(bad, &err);
        ENSURE_MSG(r != NULL && fm_cache_warning(r)[0] == 0, "flip at %zu: %s", at, err.message);
        if (!r) continue;
        float got[90];
        fm_status st = fm_cache_read_attr(r, 1, FM_ATTR_POSITION, got, &err);
        ENSURE_MSG(st == FM_ERR_INPUT && strstr(err.message, "frame 1") && strstr(err.message, bad),
                   "flip at chunk byte %zu: status %d '%s'", at - from, (int)st, err.message);
        int in_header = at - from < 12 || (at - from >= 16 && at - from < 24);
        if (!in_header) {
            ENSURE_MSG(strstr(err.message, "checksum mismatch"), "flip at chunk byte %zu: '%s'", at - from, err.message);
            mismatches++;
        }
        frame_matches(r, 0, DATA_SMOOTH, 0, "flip");
        frame_matches(r, 2, DATA_SMOOTH, 0, "flip");
        fm_cache_close(r);
    }
    ENSURE(mismatches > 20);
    free(bytes);
}

/* With delta a damaged frame also spoils the frames that build on it, but not the next key frame
 * and those after it. */
static void test_flip_with_delta(void)
{
    char path[FM_PATH_MAX];
    const fm_cache_attr attrs[] = {FM_ATTR_VELOCITY};
    fm_cache_options opts = fm_default_cache_options();
    opts.delta = 1, opts.key_interval = 3;
    if (write_attrs_cache(tmp_path(path, "flip_delta.fmc"), 40, 7, attrs, 1, &opts, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    if (!bytes) return;
    bytes[chunk_end(bytes, len, 1) - 3] ^= 0x01;
    write_all(path, bytes, len);
    free(bytes);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    float got[120];
    for (uint32_t f = 0; f < 7; f++) {
        if (f == 1 || f == 2) {
            ENSURE(fm_cache_read_attr(r, f, FM_ATTR_VELOCITY, got, &err) == FM_ERR_INPUT);
            ENSURE_MSG(strstr(err.message, "chunk 1: checksum mismatch (frame 1 is corrupt)"), "frame %u: '%s'", f, err.message);
        } else {
            frame_matches(r, f, DATA_SMOOTH, 0, "delta flip");
        }
    }
    fm_cache_close(r);
}

static void test_damaged_header_and_index(void)
{
    char path[FM_PATH_MAX];
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_PHASE};
    if (write_attrs_cache(tmp_path(path, "header.fmc"), 4, 3, attrs, 2, NULL, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    if (!bytes) return;
    for (size_t at = 16; at < bytes_u32(bytes + 12); at++) { /* past magic, version and header size */
        bytes[at] ^= 0x08;
        write_all(path, bytes, len);
        bytes[at] ^= 0x08;
        expect_open_fails(path, "header checksum mismatch");
    }
    /* an index entry damaged: the chunks are walked instead, with a warning */
    size_t index = (size_t)bytes_u64(bytes + len - 16);
    bytes[index + 8 + 16 + 3] ^= 0x01;
    write_all(path, bytes, len);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (r) {
        ENSURE_MSG(strstr(fm_cache_warning(r), "index is damaged") && fm_cache_frames(r) == 3, "'%s'", fm_cache_warning(r));
        for (uint32_t f = 0; f < 3; f++) frame_matches(r, f, DATA_SMOOTH, 0, "damaged index");
        fm_cache_close(r);
    }
    free(bytes);
}

/* ---------------------------------------------------------------- the header's frame count (format 3) */

/* Sets the frame count at header offset 64 and recomputes the header crc (offset 52) to match, as
 * zlib's crc32 of the header with the crc field 0: a header that is consistent in itself. */
static void set_header_frames(unsigned char *bytes, uint32_t frames)
{
    uint32_t size = bytes_u32(bytes + 12), crc;
    memcpy(bytes + 64, &frames, 4);
    memset(bytes + 52, 0, 4);
    crc = (uint32_t)crc32(0, bytes, size);
    memcpy(bytes + 52, &crc, 4);
}

static const fm_cache_attr COUNT_ATTRS[] = {FM_ATTR_TET_VERTICES, FM_ATTR_ID, FM_ATTR_PHASE};

/* A finished cache states its frame count in the header, equal to the frames that read back; an
 * empty one states 0 and is still complete. */
static void test_header_frame_count_when_finished(void)
{
    char path[FM_PATH_MAX];
    if (write_attrs_cache(tmp_path(path, "count.fmc"), 4, 6, COUNT_ATTRS, 3, NULL, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    ENSURE(bytes && len > 72 && bytes_u32(bytes + 8) == 4 && bytes_u32(bytes + 64) == 6 && bytes_u32(bytes + 68) == 65536);
    free(bytes);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    ENSURE(fm_cache_header_frames(r) == 6 && fm_cache_frames(r) == 6 && fm_cache_warning(r)[0] == 0);
    uint32_t readable = 0;
    float buf[48];
    while (readable < 100 && fm_cache_read_frame(r, readable, buf, &err) == FM_OK) readable++;
    ENSURE_MSG(readable == fm_cache_header_frames(r) && err.status == FM_ERR_USAGE, "%u frames read, the header says %u",
               readable, fm_cache_header_frames(r));
    for (uint32_t f = 0; f < readable; f++) frame_matches(r, f, DATA_SMOOTH, 0, "count");
    fm_cache_close(r);
    if (write_attrs_cache(tmp_path(path, "count_empty.fmc"), 4, 0, COUNT_ATTRS, 3, NULL, DATA_SMOOTH) != 0) return;
    r = fm_cache_open(path, &err);
    ENSURE_MSG(r && fm_cache_header_frames(r) == 0 && fm_cache_frames(r) == 0 && fm_cache_warning(r)[0] == 0, "%s",
               r ? fm_cache_warning(r) : err.message);
    fm_cache_close(r);
}

/* A header whose (checksummed) frame count is not the index's is refused; a count of 0 next to a
 * valid index (the writer stopped between the footer and the header) is recovered by walking. */
static void test_header_frame_count_disagrees(void)
{
    char path[FM_PATH_MAX];
    if (write_attrs_cache(tmp_path(path, "count_bad.fmc"), 4, 6, COUNT_ATTRS, 3, NULL, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    if (!bytes) return;
    const uint32_t wrong[] = {7, 5, 1, UINT32_MAX};
    for (int i = 0; i < 4; i++) {
        char want[96];
        set_header_frames(bytes, wrong[i]);
        write_all(path, bytes, len);
        snprintf(want, sizeof want, "the header says %u frames but the index lists 6", wrong[i]);
        expect_open_fails(path, want);
    }
    set_header_frames(bytes, 0);
    write_all(path, bytes, len);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (r) {
        ENSURE_MSG(fm_cache_frames(r) == 6 && strstr(fm_cache_warning(r), "frame count 0 in the header") &&
                   strstr(fm_cache_warning(r), "recovered the 6 complete frames"), "'%s'", fm_cache_warning(r));
        for (uint32_t f = 0; f < 6; f++) frame_matches(r, f, DATA_SMOOTH, 0, "count 0");
        fm_cache_close(r);
    }
    free(bytes);
}

static void add_count_frame(fm_cache_writer *w, uint32_t f)
{
    uint8_t tets[4 * 48], ids[4 * 4], phases[4];
    make_attr(FM_ATTR_TET_VERTICES, 4, f, DATA_SMOOTH, tets);
    make_attr(FM_ATTR_ID, 4, f, DATA_SMOOTH, ids);
    make_attr(FM_ATTR_PHASE, 4, f, DATA_SMOOTH, phases);
    const void *data[3] = {tets, ids, phases};
    fm_error err = {0};
    ENSURE_MSG(fm_cache_writer_add_frame_attrs(w, data, &err) == FM_OK, "%s", err.message);
}

/* Opens `file` and checks it holds `frames` complete frames, recovered with a warning, and a header
 * frame count of 0. */
static void expect_unfinished(const char *file, uint32_t frames, const char *label)
{
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(file, &err);
    ENSURE_MSG(r != NULL, "%s: %s", label, err.message);
    if (!r) return;
    ENSURE_MSG(fm_cache_header_frames(r) == 0 && fm_cache_frames(r) == frames && strstr(fm_cache_warning(r), "recovered"),
               "%s: %u frames (want %u), header %u, '%s'", label, fm_cache_frames(r), frames, fm_cache_header_frames(r),
               fm_cache_warning(r));
    for (uint32_t f = 0; f < fm_cache_frames(r); f++) frame_matches(r, f, DATA_SMOOTH, 0, label);
    fm_cache_close(r);
}

/* While the writer runs, and in a file closed as partial (an interrupted run), the header's count
 * is 0 and the file opens up to its last complete frame, also when cut inside a chunk; a resumed
 * writer patches the true count in when it finishes. */
static void test_header_frame_count_while_writing(void)
{
    char path[FM_PATH_MAX], partial[FM_PATH_MAX + 16], cut[FM_PATH_MAX];
    partial_name(partial, tmp_path(path, "count_run.fmc"));
    remove(path), remove(partial);
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create_attrs(path, 4, 25.0, COUNT_ATTRS, 3, NULL, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    for (uint32_t f = 0; f < 3; f++) add_count_frame(w, f);
    ENSURE(fm_cache_writer_flush(w, &err) == FM_OK);
    expect_unfinished(partial, 3, "flushed");
    add_count_frame(w, 3);
    fm_cache_writer_close_partial(w);
    expect_unfinished(partial, 4, "closed as partial");
    size_t len;
    unsigned char *bytes = read_all(partial, &len);
    if (!bytes) return;
    ENSURE(bytes_u32(bytes + 64) == 0);
    write_all(tmp_path(cut, "count_cut.fmc"), bytes, len - 3); /* inside the last chunk */
    expect_unfinished(cut, 3, "cut mid-chunk");
    free(bytes);
    w = fm_cache_writer_resume(path, 4, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    for (uint32_t f = 4; f < 6; f++) add_count_frame(w, f);
    ENSURE_MSG(fm_cache_writer_finish(w, &err) == FM_OK, "%s", err.message);
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r && fm_cache_header_frames(r) == 6 && fm_cache_frames(r) == 6 && !fm_cache_warning(r)[0], "%s", err.message);
    fm_cache_close(r);
    char whole[FM_PATH_MAX];
    if (write_attrs_cache(tmp_path(whole, "count_whole.fmc"), 4, 6, COUNT_ATTRS, 3, NULL, DATA_SMOOTH) == 0)
        ENSURE_MSG(same_files(path, whole), "a resumed cache differs from one written in one go");
}

/* ---------------------------------------------------------------- format 1 */

/* tests/data/cache_v1.fmc was written by the format-1 writer (commit a2f5f1b): 5 agents, 3 frames
 * at 24 fps, zstd level 3, float i of frame f = 0.001 i + f. */
static const char V1_FIXTURE[] = FM_SOURCE_DIR "/tests/data/cache_v1.fmc";

static void v1_frame(float *out, uint32_t f)
{
    for (int i = 0; i < 60; i++) out[i] = (float)(0.001 * (double)i + f);
}

static void test_reads_format_1(void)
{
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(V1_FIXTURE, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    ENSURE(fm_cache_version(r) == 1 && fm_cache_agents(r) == 5 && fm_cache_frames(r) == 3);
    ENSURE(fm_cache_frame_rate(r) == 24.0 && fm_cache_warning(r)[0] == 0);
    ENSURE(fm_cache_attr_count(r) == 1 && fm_cache_attr_at(r, 0)->attr == FM_ATTR_TET_VERTICES);
    ENSURE(fm_cache_has_attr(r, FM_ATTR_TET_VERTICES) && !fm_cache_has_attr(r, FM_ATTR_PHASE));
    fm_cache_options o = fm_cache_get_options(r);
    ENSURE(o.compression_level == 3 && o.delta == 0 && o.quantum == 0);
    ENSURE(fm_cache_raw_bytes(r) == 3 * 5 * 48 && fm_cache_file_bytes(r) == 702);
    float got[60], want[60];
    for (int pass = 0; pass < 2; pass++)
        for (uint32_t f = 0; f < 3; f++) {
            uint32_t k = pass ? 2 - f : f;
            ENSURE_MSG(fm_cache_read_frame(r, k, got, &err) == FM_OK, "%s", err.message);
            v1_frame(want, k);
            ENSURE_MSG(memcmp(got, want, sizeof want) == 0, "format 1 frame %u differs", k);
        }
    uint8_t phase[5];
    ENSURE(fm_cache_read_attr(r, 0, FM_ATTR_PHASE, phase, &err) == FM_ERR_INPUT && strstr(err.message, "no phase attribute"));
    fm_cache_close(r);
}

/* A format-1 file cut short is recovered; a flipped byte in its data fails zstd's checksum. */
static void test_format_1_damaged(void)
{
    char path[FM_PATH_MAX];
    size_t len;
    unsigned char *bytes = read_all(V1_FIXTURE, &len);
    ENSURE(bytes && len == 702);
    if (!bytes) return;
    size_t index = (size_t)bytes_u64(bytes + len - 16), chunk2 = (size_t)bytes_u64(bytes + index + 8 + 16);
    write_all(tmp_path(path, "v1_cut.fmc"), bytes, chunk2 + 5);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r && fm_cache_frames(r) == 2 && strstr(fm_cache_warning(r), "recovered"), "%s", r ? fm_cache_warning(r) : err.message);
    float got[60], want[60];
    ENSURE(r && fm_cache_read_frame(r, 1, got, &err) == FM_OK);
    v1_frame(want, 1);
    ENSURE(memcmp(got, want, sizeof want) == 0);
    fm_cache_close(r);
    size_t chunk1 = (size_t)bytes_u64(bytes + index + 8 + 8);
    bytes[chunk1 + 24 + 12] ^= 0x20;
    write_all(path, bytes, len);
    r = fm_cache_open(path, &err);
    ENSURE(r && fm_cache_read_frame(r, 1, got, &err) == FM_ERR_INPUT && strstr(err.message, "frame 1"));
    ENSURE(r && fm_cache_read_frame(r, 2, got, &err) == FM_OK);
    fm_cache_close(r);
    free(bytes);
}

/* tests/data/cache_v2.fmc was written by the format-2 writer (commit 712c02c): 5 agents, 4 frames
 * at 24 fps, tet_vertices and phase, zstd level 3, delta with key interval 2; float i of frame f =
 * 0.001 i + f, the phase of agent a at frame f = (a + f) mod 4. */
static const char V2_FIXTURE[] = FM_SOURCE_DIR "/tests/data/cache_v2.fmc";

static void v2_frame_matches(fm_cache_reader *r, uint32_t f)
{
    float got[60], want[60];
    uint8_t phase[5];
    fm_error err = {0};
    v1_frame(want, f);
    ENSURE_MSG(fm_cache_read_frame(r, f, got, &err) == FM_OK && memcmp(got, want, sizeof want) == 0,
               "format 2 frame %u: %s", f, err.message);
    ENSURE_MSG(fm_cache_read_attr(r, f, FM_ATTR_PHASE, phase, &err) == FM_OK, "%s", err.message);
    for (int a = 0; a < 5; a++) ENSURE_MSG(phase[a] == (a + f) % 4, "format 2 frame %u: phase[%d] = %u", f, a, phase[a]);
}

static void test_reads_format_2(void)
{
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(V2_FIXTURE, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    ENSURE(fm_cache_version(r) == 2 && fm_cache_agents(r) == 5 && fm_cache_frames(r) == 4 && fm_cache_header_frames(r) == 0);
    ENSURE(fm_cache_frame_rate(r) == 24.0 && fm_cache_warning(r)[0] == 0 && fm_cache_attr_count(r) == 2);
    fm_cache_options o = fm_cache_get_options(r);
    ENSURE(o.compression_level == 3 && o.delta == 1 && o.key_interval == 2 && o.quantum == 0);
    const uint32_t order[] = {3, 0, 1, 2, 2, 0, 3};
    for (int i = 0; i < 7; i++) v2_frame_matches(r, order[i]);
    fm_cache_close(r);
    /* cut inside its last chunk: the first three frames are recovered */
    char path[FM_PATH_MAX];
    size_t len;
    unsigned char *bytes = read_all(V2_FIXTURE, &len);
    if (!bytes) return;
    write_all(tmp_path(path, "v2_cut.fmc"), bytes, chunk_end(bytes, len, 3) - 1);
    r = fm_cache_open(path, &err);
    ENSURE_MSG(r && fm_cache_frames(r) == 3 && strstr(fm_cache_warning(r), "recovered"), "%s", r ? fm_cache_warning(r) : err.message);
    for (uint32_t f = 0; r && f < 3; f++) v2_frame_matches(r, f);
    fm_cache_close(r);
    free(bytes);
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
    expect_open_fails(path, "version 7 is not supported (this build reads 1 to 4)");
}

/* A write that fails on the writer thread (a full disk, tests/helpers/full_disk.h: the partial
 * file is made, every write fails) is reported by a later call, and nothing is left under the
 * final name. */
static void test_write_failure_on_the_writer_thread(void)
{
    struct stat st;
    char dir[FM_PATH_MAX], path[FM_PATH_MAX + 16];
    if (full_disk_mount(tmp_path(dir, "full_disk"), 0) != 0) return;
    snprintf(path, sizeof path, "%s/full.fmc", dir);
    fm_error err = {0};
    /* the header is buffered by stdio, so creation succeeds */
    fm_cache_writer *w = fm_cache_writer_create(path, 100000, 24, 1, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return full_disk_unmount(dir);
    float *frame = calloc(12 * 100000, sizeof(float));
    fm_status status = FM_OK;
    for (int f = 0; f < 4 && status == FM_OK; f++) status = fm_cache_writer_add_frame(w, frame, &err);
    if (status == FM_OK) status = fm_cache_writer_finish(w, &err);
    else fm_cache_writer_abort(w);
    ENSURE_MSG(status == FM_ERR_IO && strstr(err.message, "No space left"), "status %d: %s", (int)status, err.message);
    ENSURE(strstr(err.message, path) != NULL);
    ENSURE(stat(path, &st) != 0); /* no cache under the final name */
    free(frame);
    full_disk_unmount(dir);
}

/* Two writers of one cache path (a library user's mistake; a run holds its folder's lock): the
 * second makes PATH.partial afresh, the first's finish fails naming the replacement and leaves the
 * second's file alone, and the second's cache is complete under the final name. */
static void test_second_writer_of_one_path(void)
{
    char path[FM_PATH_MAX];
    tmp_path(path, "twice.fmc");
    remove(path);
    float frame[12 * 8] = {0};
    fm_error err = {0};
    fm_cache_writer *a = fm_cache_writer_create(path, 8, 24, 1, &err), *b = fm_cache_writer_create(path, 8, 24, 1, &err);
    ENSURE_MSG(a && b, "%s", err.message);
    if (!a || !b) return fm_cache_writer_abort(a), fm_cache_writer_abort(b);
    ENSURE(fm_cache_writer_add_frame(a, frame, &err) == FM_OK);
    for (int f = 0; f < 3; f++) ENSURE(fm_cache_writer_add_frame(b, frame, &err) == FM_OK);
    ENSURE_MSG(fm_cache_writer_finish(a, &err) == FM_ERR_IO && strstr(err.message, "another writer"), "%s", err.message);
    ENSURE_MSG(fm_cache_writer_finish(b, &err) == FM_OK, "%s", err.message);
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r && fm_cache_frames(r) == 3 && !fm_cache_warning(r)[0], "%s", err.message);
    fm_cache_close(r);
}

int main(void)
{
    RUN_TEST(test_second_writer_of_one_path);
    RUN_TEST(test_write_failure_on_the_writer_thread);
    RUN_TEST(test_round_trip_bitwise);
    RUN_TEST(test_zero_frames);
    RUN_TEST(test_read_past_end);
    RUN_TEST(test_partial_until_finish);
    RUN_TEST(test_abort_removes_everything);
    RUN_TEST(test_create_in_missing_directory);
    RUN_TEST(test_truncated_at_every_byte);
    RUN_TEST(test_flipped_byte_fails_its_checksum);
    RUN_TEST(test_flip_with_delta);
    RUN_TEST(test_damaged_header_and_index);
    RUN_TEST(test_reads_format_1);
    RUN_TEST(test_format_1_damaged);
    RUN_TEST(test_reads_format_2);
    RUN_TEST(test_header_frame_count_when_finished);
    RUN_TEST(test_header_frame_count_disagrees);
    RUN_TEST(test_header_frame_count_while_writing);
    RUN_TEST(test_not_a_cache);
    RUN_TEST(test_bad_version);
    return test_result();
}
