/* Writer resume (checkpoint / restart of a run): PATH.partial left by a killed run is reopened,
 * checked, cut after the frames to keep and continued; the finished file must be byte-identical to
 * an uninterrupted writer's, also with delta encoding (the previous frame is rebuilt) and
 * quantisation. flush() must leave every frame handed over on disk. */
#define _POSIX_C_SOURCE 200809L
#include "cache_helpers.h"

typedef struct config {
    const char *name;
    const fm_cache_attr *attrs;
    int attr_count;
    fm_cache_options opts;
} config;

/* Resumes PATH.partial (already in place) at frame `at`, adds frames at..total-1 and finishes;
 * returns 0 on success. */
static int resume_and_finish(const char *path, uint32_t at, uint32_t total, uint64_t agents, const config *c)
{
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_resume(path, at, &err);
    ENSURE_MSG(w != NULL, "%s: %s", c->name, err.message);
    if (!w) return -1;
    ENSURE(fm_cache_writer_frames(w) == at);
    void *data[ALL_ATTR_COUNT];
    for (int i = 0; i < c->attr_count; i++) data[i] = malloc(fm_cache_attr_describe(c->attrs[i])->bytes_per_agent * agents);
    for (uint32_t f = at; f < total; f++) {
        for (int i = 0; i < c->attr_count; i++) make_attr(c->attrs[i], agents, f, DATA_SMOOTH, data[i]);
        ENSURE_MSG(fm_cache_writer_add_frame_attrs(w, (const void *const *)data, &err) == FM_OK, "%s", err.message);
    }
    for (int i = 0; i < c->attr_count; i++) free(data[i]);
    ENSURE(fm_cache_writer_frames(w) == total);
    fm_status st = fm_cache_writer_finish(w, &err);
    ENSURE_MSG(st == FM_OK, "%s", err.message);
    return st == FM_OK ? 0 : -1;
}

/* A run killed at various points leaves PATH.partial cut somewhere after frame at-1: right after
 * it, every 37th byte after that, after the last frame (no index), inside the index, and with the
 * footer (killed before the rename). Resuming at `at` gives exactly the uninterrupted bytes. */
static void resume_from_cuts(const config *c, uint32_t at)
{
    enum { AGENTS = 25, FRAMES = 10 };
    char ref[FM_PATH_MAX], path[FM_PATH_MAX], partial[FM_PATH_MAX + 16], name[64];
    snprintf(name, sizeof name, "ref_%s.fmc", c->name);
    if (write_attrs_cache(tmp_path(ref, name), AGENTS, FRAMES, c->attrs, c->attr_count, &c->opts, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *want = read_all(ref, &len);
    if (!want) return;
    size_t index = (size_t)bytes_u64(want + len - 16), first = chunk_end(want, len, at - 1), tried = 0;
    snprintf(name, sizeof name, "resumed_%s.fmc", c->name);
    tmp_path(path, name);
    partial_name(partial, path);
    size_t cuts[64], n = 0;
    cuts[n++] = first;
    for (size_t cut = first + 7; cut < len && n < 60; cut += 37) cuts[n++] = cut;
    cuts[n++] = index, cuts[n++] = index + 5, cuts[n++] = len;
    for (size_t i = 0; i < n; i++) {
        remove(path);
        write_all(partial, want, cuts[i]);
        if (resume_and_finish(path, at, FRAMES, AGENTS, c) != 0) continue;
        ENSURE_MSG(same_files(ref, path), "%s: cut at %zu, resumed at %u: the file differs", c->name, cuts[i], at);
        ENSURE(!file_exists(partial));
        tried++;
    }
    ENSURE(tried >= 5);
    free(want);
}

static const fm_cache_attr TETS[] = {FM_ATTR_TET_VERTICES};

static void test_resume_is_byte_identical(void)
{
    config plain = {"plain", TETS, 1, fm_default_cache_options()};
    plain.opts.compression_level = 5;
    resume_from_cuts(&plain, 6);
    config delta = {"delta", ALL_ATTRS, ALL_ATTR_COUNT, fm_default_cache_options()};
    delta.opts.delta = 1, delta.opts.key_interval = 4, delta.opts.quantum = 1e-3;
    resume_from_cuts(&delta, 6); /* inside a key interval: the writer needs frame 5's words */
    resume_from_cuts(&delta, 8); /* at a key frame */
    resume_from_cuts(&delta, 1);
}

/* The state a real writer leaves on disk after flush(): every frame handed over is there, and
 * resuming from it is byte-identical again. */
static void test_resume_after_flush(void)
{
    enum { AGENTS = 25, FRAMES = 10, AT = 6 };
    const fm_cache_attr attrs[] = {FM_ATTR_POSITION, FM_ATTR_PHASE};
    config c = {"flush", attrs, 2, fm_default_cache_options()};
    c.opts.delta = 1, c.opts.key_interval = 4;
    char ref[FM_PATH_MAX], path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    if (write_attrs_cache(tmp_path(ref, "flush_ref.fmc"), AGENTS, FRAMES, attrs, 2, &c.opts, DATA_SMOOTH) != 0) return;
    tmp_path(path, "flush.fmc");
    partial_name(partial, path);
    remove(path);
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create_attrs(path, AGENTS, 25.0, attrs, 2, &c.opts, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    float pos[3 * AGENTS];
    uint8_t phase[AGENTS];
    const void *data[2] = {pos, phase};
    for (uint32_t f = 0; f < 8; f++) {
        make_attr(FM_ATTR_POSITION, AGENTS, f, DATA_SMOOTH, pos);
        make_attr(FM_ATTR_PHASE, AGENTS, f, DATA_SMOOTH, phase);
        ENSURE(fm_cache_writer_add_frame_attrs(w, data, &err) == FM_OK);
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
    if (resume_and_finish(path, AT, FRAMES, AGENTS, &c) == 0) ENSURE(same_files(ref, path));
}

/* Resume refuses a missing partial file, too few frames, a damaged frame and a format-1 file,
 * and leaves the partial file as it was. */
static void test_resume_refuses(void)
{
    char ref[FM_PATH_MAX], path[FM_PATH_MAX], partial[FM_PATH_MAX + 16];
    if (write_attrs_cache(tmp_path(ref, "refuse_ref.fmc"), 30, 5, TETS, 1, NULL, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(ref, &len);
    if (!bytes) return;
    tmp_path(path, "refuse.fmc");
    partial_name(partial, path);
    fm_error err = {0};
    remove(partial);
    ENSURE(fm_cache_writer_resume(path, 2, &err) == NULL && err.status == FM_ERR_INPUT &&
           strstr(err.message, "nothing to resume"));
    write_all(partial, bytes, chunk_start(bytes, len, 3) + 30); /* frames 0..2 complete */
    ENSURE(fm_cache_writer_resume(path, 4, &err) == NULL);
    ENSURE_MSG(err.status == FM_ERR_INPUT && strstr(err.message, "only 3 complete frames"), "'%s'", err.message);
    bytes[chunk_start(bytes, len, 1) + 24 + 20] ^= 0x40; /* inside frame 1's data */
    write_all(partial, bytes, len);
    ENSURE(fm_cache_writer_resume(path, 3, &err) == NULL);
    ENSURE_MSG(err.status == FM_ERR_INPUT && strstr(err.message, "chunk 1: checksum mismatch"), "'%s'", err.message);
    size_t still;
    unsigned char *kept = read_all(partial, &still);
    ENSURE(kept && still == len && memcmp(kept, bytes, len) == 0);
    free(kept), free(bytes);
    /* format 1 is read but no longer written */
    bytes = read_all(FM_SOURCE_DIR "/tests/data/cache_v1.fmc", &len);
    if (bytes) write_all(partial, bytes, len);
    ENSURE(fm_cache_writer_resume(path, 2, &err) == NULL);
    ENSURE_MSG(err.status == FM_ERR_INPUT && strstr(err.message, "format 1 cannot be resumed"), "'%s'", err.message);
    free(bytes);
    remove(partial);
}

int main(void)
{
    RUN_TEST(test_resume_is_byte_identical);
    RUN_TEST(test_resume_after_flush);
    RUN_TEST(test_resume_refuses);
    return test_result();
}
