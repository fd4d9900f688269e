/* Cache format 4: every attribute kind under every option (delta, key interval, quantum, level,
 * piece size), random access against sequential reading, the quantisation bound, sizes, argument
 * errors, writer bytes that do not depend on the OpenMP thread count, and blocks whose bytes do not
 * depend on who encodes them (the parallel write of P ranks). */
#define _POSIX_C_SOURCE 200809L
#include "cache_format.h"
#include "cache_helpers.h"

#include <omp.h>

static void test_attribute_table(void)
{
    const struct { fm_cache_attr attr; const char *name; int components; fm_cache_scalar scalar; size_t bytes; } want[] = {
        {FM_ATTR_TET_VERTICES, "tet_vertices", 12, FM_SCALAR_F32, 48}, {FM_ATTR_POSITION, "position", 3, FM_SCALAR_F32, 12},
        {FM_ATTR_VELOCITY, "velocity", 3, FM_SCALAR_F32, 12},        {FM_ATTR_ORIENTATION, "orientation", 4, FM_SCALAR_F32, 16},
        {FM_ATTR_ID, "id", 1, FM_SCALAR_U32, 4},                     {FM_ATTR_PHASE, "phase", 1, FM_SCALAR_U8, 1},
        {FM_ATTR_GROUP, "group", 1, FM_SCALAR_U8, 1},
    };
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++) {
        const fm_cache_attr_info *a = fm_cache_attr_describe(want[i].attr);
        ENSURE(a && a->attr == want[i].attr && !strcmp(a->name, want[i].name) && a->components == want[i].components &&
               a->scalar == want[i].scalar && a->bytes_per_agent == want[i].bytes);
    }
    ENSURE(fm_cache_attr_describe((fm_cache_attr)0) == NULL && fm_cache_attr_describe((fm_cache_attr)8) == NULL);
    fm_cache_options o = fm_default_cache_options();
    ENSURE(o.compression_level == 1 && o.delta == 1 && o.key_interval == 16 && o.quantum == 0);
}

/* Writes all seven attributes under `opts` and reads every frame back twice: in order, and in a
 * shuffled order with a second reader (random access, across key intervals with delta). */
static void round_trip(const char *name, uint64_t agents, uint32_t frames, const fm_cache_options *opts, data_kind kind)
{
    char path[FM_PATH_MAX];
    if (write_attrs_cache(tmp_path(path, name), agents, frames, ALL_ATTRS, ALL_ATTR_COUNT, opts, kind) != 0) return;
    fm_error err = {0};
    fm_cache_reader *seq = fm_cache_open(path, &err), *rnd = fm_cache_open(path, &err);
    ENSURE_MSG(seq && rnd, "%s", err.message);
    if (seq && rnd) {
        ENSURE(fm_cache_version(seq) == 4 && fm_cache_agents(seq) == agents && fm_cache_frames(seq) == frames);
        ENSURE(fm_cache_header_frames(seq) == frames);
        ENSURE(fm_cache_frame_rate(seq) == 25.0 && fm_cache_warning(seq)[0] == 0 && fm_cache_attr_count(seq) == ALL_ATTR_COUNT);
        for (int i = 0; i < ALL_ATTR_COUNT; i++) ENSURE(fm_cache_attr_at(seq, i)->attr == ALL_ATTRS[i] && fm_cache_has_attr(seq, ALL_ATTRS[i]));
        fm_cache_options got = fm_cache_get_options(seq);
        ENSURE(got.compression_level == opts->compression_level && got.delta == (opts->delta != 0) &&
               got.key_interval == opts->key_interval && got.quantum == opts->quantum &&
               got.piece_agents == (opts->piece_agents ? opts->piece_agents : 65536));
        for (uint32_t f = 0; f < frames; f++) frame_matches(seq, f, kind, opts->quantum, name);
        uint64_t state = 77;
        uint32_t order[64];
        for (uint32_t i = 0; i < frames; i++) order[i] = i;
        for (uint32_t i = frames - 1; i > 0; i--) {
            uint32_t j = (uint32_t)(test_next_u64(&state) % (i + 1)), t = order[i];
            order[i] = order[j], order[j] = t;
        }
        for (uint32_t i = 0; i < frames; i++) frame_matches(rnd, order[i], kind, opts->quantum, name);
    }
    fm_cache_close(seq), fm_cache_close(rnd);
}

static void test_round_trip_every_attribute_and_option(void)
{
    fm_cache_options o = fm_default_cache_options();
    o.delta = 0;
    round_trip("attrs_whole.fmc", 23, 9, &o, DATA_RANDOM);
    o.delta = 1, o.key_interval = 4;
    round_trip("attrs_delta.fmc", 23, 11, &o, DATA_RANDOM);       /* bitwise, NaN payloads included */
    round_trip("attrs_delta_smooth.fmc", 500, 11, &o, DATA_SMOOTH);
    o.key_interval = 1;
    round_trip("attrs_delta_k1.fmc", 23, 5, &o, DATA_RANDOM);
    o = fm_default_cache_options(), o.delta = 0, o.quantum = 1e-3;
    round_trip("attrs_quantum.fmc", 300, 6, &o, DATA_SMOOTH);
    o.delta = 1, o.key_interval = 3, o.compression_level = 19;
    round_trip("attrs_quantum_delta.fmc", 300, 10, &o, DATA_SMOOTH);
    o.quantum = 0.25;
    round_trip("attrs_coarse.fmc", 50, 4, &o, DATA_SMOOTH);
    o = fm_default_cache_options(), o.compression_level = -7; /* zstd's fastest level allowed */
    round_trip("attrs_fast.fmc", 23, 9, &o, DATA_RANDOM);
    o.compression_level = -1, o.quantum = 1e-3;
    round_trip("attrs_fast_quantum.fmc", 300, 6, &o, DATA_SMOOTH);
    o = fm_default_cache_options(), o.piece_agents = 256, o.key_interval = 3;
    round_trip("attrs_pieces.fmc", 1000, 7, &o, DATA_RANDOM); /* 4 pieces, the last one of 232 agents */
    o.quantum = 1e-3;
    round_trip("attrs_pieces_quantum.fmc", 1000, 7, &o, DATA_SMOOTH);
    o = fm_default_cache_options(), o.piece_agents = 256, o.delta = 0;
    round_trip("attrs_pieces_exact.fmc", 512, 3, &o, DATA_RANDOM); /* two full pieces */
    o.piece_agents = 0;                                              /* the default */
    round_trip("attrs_pieces_default.fmc", 70000, 2, &o, DATA_SMOOTH);
}

/* Sequential reading decodes one chunk per frame, so random access must give the same bits even
 * when it starts a key interval in the middle or jumps back; both equal what was written. */
static void test_delta_random_access_matches_sequential(void)
{
    char path[FM_PATH_MAX];
    const fm_cache_attr attrs[] = {FM_ATTR_POSITION, FM_ATTR_PHASE};
    fm_cache_options o = fm_default_cache_options();
    o.delta = 1, o.key_interval = 5;
    if (write_attrs_cache(tmp_path(path, "delta_seq.fmc"), 64, 23, attrs, 2, &o, DATA_SMOOTH) != 0) return;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (!r) return;
    float seq[23][192], got[192];
    for (uint32_t f = 0; f < 23; f++) ENSURE(fm_cache_read_attr(r, f, FM_ATTR_POSITION, seq[f], &err) == FM_OK);
    const uint32_t jumps[] = {22, 3, 4, 9, 8, 10, 0, 21, 14, 13, 12, 6, 7, 19, 1, 20};
    for (size_t i = 0; i < sizeof jumps / sizeof jumps[0]; i++) {
        ENSURE(fm_cache_read_attr(r, jumps[i], FM_ATTR_POSITION, got, &err) == FM_OK);
        ENSURE_MSG(memcmp(got, seq[jumps[i]], sizeof got) == 0, "frame %u differs after a jump", jumps[i]);
    }
    for (uint32_t f = 0; f < 23; f++) {
        float want[192];
        make_attr(FM_ATTR_POSITION, 64, f, DATA_SMOOTH, want);
        ENSURE_MSG(memcmp(want, seq[f], sizeof want) == 0, "sequential frame %u differs from what was written", f);
    }
    fm_cache_close(r);
}

/* The bound: |read - written| <= quantum / 2 (plus the read float's own rounding), and the error
 * really is that large, so the values were rounded; values beyond 2^31 quanta are refused. */
static void test_quantisation_bound(void)
{
    char path[FM_PATH_MAX];
    const double quantum = 0.01;
    const fm_cache_attr attr = FM_ATTR_VELOCITY;
    fm_cache_options o = fm_default_cache_options();
    o.quantum = quantum;
    enum { N = 4000 };
    float in[3 * N], out[3 * N];
    uint64_t state = 5;
    for (int i = 0; i < 3 * N; i++) in[i] = (float)(200 * test_uniform(&state) - 100);
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create_attrs(tmp_path(path, "quantum.fmc"), N, 24, &attr, 1, &o, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    const void *data[1] = {in};
    ENSURE(fm_cache_writer_add_frame_attrs(w, data, &err) == FM_OK && fm_cache_writer_finish(w, &err) == FM_OK);
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE(r && fm_cache_read_attr(r, 0, attr, out, &err) == FM_OK);
    double worst = 0;
    for (int i = 0; i < 3 * N && r; i++) {
        double e = fabs((double)out[i] - in[i]);
        worst = fmax(worst, e);
        ENSURE_MSG(e <= quantum / 2 + FLT_EPSILON * 100, "%.9g read back as %.9g", in[i], out[i]);
        double m = (double)out[i] / quantum; /* a multiple of quantum, up to float rounding */
        ENSURE_MSG(fabs(m - rint(m)) < 1e-3, "%.9g is not a multiple of %g", out[i], quantum);
    }
    ENSURE_MSG(worst > 0.45 * quantum, "largest error %g: values were not rounded to %g", worst, quantum);
    fm_cache_close(r);

    /* 1e8 / 1e-3 = 1e11 quanta: too many for int32 */
    o.quantum = 1e-3;
    w = fm_cache_writer_create_attrs(tmp_path(path, "quantum_big.fmc"), N, 24, &attr, 1, &o, &err);
    ENSURE(w != NULL);
    if (!w) return;
    in[3 * 17 + 1] = 1e8f;
    fm_status st = fm_cache_writer_add_frame_attrs(w, data, &err);
    if (st == FM_OK) st = fm_cache_writer_finish(w, &err);
    else fm_cache_writer_abort(w);
    ENSURE_MSG(st == FM_ERR_INPUT && strstr(err.message, "velocity") && strstr(err.message, "agent 17") &&
               strstr(err.message, "frame 0"), "status %d '%s'", (int)st, err.message);
    ENSURE(!file_exists(path));
    /* in pieces: the message names the first agent in id order, here in the 12th piece of 16 */
    in[3 * 17 + 1] = 0;
    in[3 * 3000] = 1e8f, in[3 * 3900 + 2] = 1e8f;
    o.piece_agents = 256;
    w = fm_cache_writer_create_attrs(tmp_path(path, "quantum_pieces.fmc"), N, 24, &attr, 1, &o, &err);
    ENSURE(w != NULL);
    if (!w) return;
    st = fm_cache_writer_add_frame_attrs(w, data, &err);
    if (st == FM_OK) st = fm_cache_writer_finish(w, &err);
    else fm_cache_writer_abort(w);
    ENSURE_MSG(st == FM_ERR_INPUT && strstr(err.message, "agent 3000:"), "status %d '%s'", (int)st, err.message);
}

static void test_sizes(void)
{
    char path[FM_PATH_MAX];
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_ID, FM_ATTR_PHASE};
    if (write_attrs_cache(tmp_path(path, "sizes.fmc"), 200, 7, attrs, 3, NULL, DATA_SMOOTH) != 0) return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(r && bytes, "%s", err.message);
    if (r && bytes) {
        uint64_t header = bytes_u32(bytes + 12), index = bytes_u64(bytes + len - 16), sum = 0;
        ENSURE(header == 72 + 3 * 16 && fm_cache_file_bytes(r) == len);
        ENSURE(fm_cache_raw_bytes(r) == 7ull * 200 * (48 + 4 + 1));
        for (uint32_t f = 0; f < 7; f++) sum += fm_cache_frame_bytes(r, f);
        ENSURE(fm_cache_frame_bytes(r, 7) == 0);
        ENSURE(fm_cache_compressed_bytes(r) == sum && header + sum == index);
        ENSURE(len == index + 16 + 16 * 7 + 16);
        ENSURE(fm_cache_compressed_bytes(r) < fm_cache_raw_bytes(r)); /* ids and phases compress */
    }
    fm_cache_close(r);
    free(bytes);
}

static void expect_create_fails(const fm_cache_attr *attrs, int n, const fm_cache_options *o, const char *what)
{
    char path[FM_PATH_MAX];
    fm_error err = {0};
    fm_cache_writer *w = fm_cache_writer_create_attrs(tmp_path(path, "bad_args.fmc"), 10, 24, attrs, n, o, &err);
    ENSURE_MSG(w == NULL && err.status == FM_ERR_USAGE && strstr(err.message, what), "'%s' lacks '%s'", err.message, what);
    fm_cache_writer_abort(w);
    ENSURE(!file_exists(path));
}

static void test_argument_errors(void)
{
    const fm_cache_attr twice[] = {FM_ATTR_POSITION, FM_ATTR_ID, FM_ATTR_POSITION}, unknown[] = {(fm_cache_attr)42};
    fm_cache_options o = fm_default_cache_options();
    expect_create_fails(twice, 3, &o, "'position' is given twice");
    expect_create_fails(unknown, 1, &o, "unknown attribute kind 42");
    expect_create_fails(ALL_ATTRS, 0, &o, "1 to 7 attributes");
    o.key_interval = 0;
    expect_create_fails(ALL_ATTRS, 1, &o, "key interval 0");
    o = fm_default_cache_options(), o.quantum = -1;
    expect_create_fails(ALL_ATTRS, 1, &o, "quantum");
    o = fm_default_cache_options(), o.compression_level = 30;
    expect_create_fails(ALL_ATTRS, 1, &o, "compression level 30");
    o.compression_level = 0;
    expect_create_fails(ALL_ATTRS, 1, &o, "compression level 0 is outside -7..-1 and 1..19");
    o.compression_level = -8;
    expect_create_fails(ALL_ATTRS, 1, &o, "compression level -8");
    o = fm_default_cache_options(), o.piece_agents = 255;
    expect_create_fails(ALL_ATTRS, 1, &o, "255 agents per piece is outside 256..1073741824");
    o.piece_agents = -1;
    expect_create_fails(ALL_ATTRS, 1, &o, "-1 agents per piece");

    /* the tet shorthand on a cache of other attributes, and reading a missing attribute */
    char path[FM_PATH_MAX];
    fm_error err = {0};
    const fm_cache_attr two[] = {FM_ATTR_TET_VERTICES, FM_ATTR_PHASE};
    fm_cache_writer *w = fm_cache_writer_create_attrs(tmp_path(path, "shorthand.fmc"), 2, 24, two, 2, NULL, &err);
    ENSURE_MSG(w != NULL, "%s", err.message);
    if (!w) return;
    float verts[24] = {0};
    uint8_t phase[2] = {1, 3};
    ENSURE(fm_cache_writer_add_frame(w, verts, &err) == FM_ERR_USAGE && strstr(err.message, "add_frame_attrs"));
    const void *data[2] = {verts, phase};
    ENSURE(fm_cache_writer_add_frame_attrs(w, data, &err) == FM_OK && fm_cache_writer_finish(w, &err) == FM_OK);
    fm_cache_reader *r = fm_cache_open(path, &err);
    float pos[6];
    uint8_t got[2];
    ENSURE(r && fm_cache_read_attr(r, 0, FM_ATTR_POSITION, pos, &err) == FM_ERR_INPUT && strstr(err.message, "no position attribute"));
    ENSURE(r && fm_cache_read_attr(r, 0, FM_ATTR_PHASE, got, &err) == FM_OK && got[0] == 1 && got[1] == 3);
    ENSURE(r && fm_cache_read_frame(r, 0, verts, &err) == FM_OK);
    fm_cache_close(r);
}

/* The writer's bytes do not depend on OpenMP's thread count (zstd's workers are fixed); frames
 * large enough for zstd to split them into several jobs. */
static void test_bytes_independent_of_threads(void)
{
    char one[FM_PATH_MAX], two[FM_PATH_MAX];
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_PHASE};
    fm_cache_options o = fm_default_cache_options();
    o.delta = 1, o.key_interval = 2;
    int before = omp_get_max_threads();
    omp_set_num_threads(1);
    int a = write_attrs_cache(tmp_path(one, "threads1.fmc"), 60000, 3, attrs, 2, &o, DATA_SMOOTH);
    omp_set_num_threads(2);
    int b = write_attrs_cache(tmp_path(two, "threads2.fmc"), 60000, 3, attrs, 2, &o, DATA_SMOOTH);
    omp_set_num_threads(before);
    ENSURE(a == 0 && b == 0 && same_files(one, two));
}

/* Encodes frames 0..2 of `agents` smooth tets and phases, pieces [first, end) with `threads`, into
 * out (the blocks) and sizes; returns the bytes, or 0 on failure. */
static uint64_t encode_range(const cache_layout *l, uint64_t first, uint64_t end, int threads, unsigned char *out,
                             uint64_t *sizes)
{
    cache_encoder e;
    fm_error err = {0};
    if (cache_encoder_init(&e, l, first, end, threads, "encode", &err) != FM_OK) return 0;
    const uint64_t a0 = e.agent_begin, count = e.agent_end - e.agent_begin;
    float *verts = malloc(sizeof(float) * 12 * (size_t)l->agents);
    uint8_t *phase = malloc((size_t)l->agents);
    uint64_t total = 0, bytes = 0, blocks = cache_encoder_blocks(&e);
    for (uint32_t k = 0; k < 3 && verts && phase; k++) {
        make_attr(FM_ATTR_TET_VERTICES, l->agents, k, DATA_SMOOTH, verts);
        make_attr(FM_ATTR_PHASE, l->agents, k, DATA_SMOOTH, phase);
        const void *data[2] = {verts + 12 * a0, phase + a0};
        if (cache_encode_frame(&e, data, k, out + total, sizes + k * blocks, &bytes, &err) != FM_OK) break;
        total += bytes;
    }
    ENSURE_MSG(count == 0 || total > 0, "%s", err.message);
    free(verts), free(phase);
    cache_encoder_free(&e);
    return total;
}

/* A frame's blocks are the same bytes whoever encodes them: one thread or three, all pieces at once
 * or in two runs of pieces (two ranks' shares), with delta across frames. The parallel write of a
 * run on P ranks relies on this. */
static void test_blocks_independent_of_encoder(void)
{
    enum { AGENTS = 3000, PIECE = 256, PIECES = 12, BLOCKS = 2 * PIECES };
    const fm_cache_attr attrs[] = {FM_ATTR_TET_VERTICES, FM_ATTR_PHASE};
    fm_cache_options o = fm_default_cache_options();
    o.piece_agents = PIECE, o.key_interval = 2;
    cache_layout l;
    fm_error err = {0};
    ENSURE(cache_layout_init(&l, AGENTS, 24, attrs, 2, &o, "encode", &err) == FM_OK && l.pieces == PIECES);
    const size_t cap = 3 * (size_t)cache_payload_bound(&l);
    unsigned char *whole = malloc(cap), *again = malloc(cap), *split = malloc(cap);
    uint64_t sizes_whole[3 * BLOCKS], sizes_again[3 * BLOCKS], sizes_a[3 * 10], sizes_b[3 * 14];
    if (!whole || !again || !split) return free(whole), free(again), free(split);
    uint64_t n_whole = encode_range(&l, 0, PIECES, 1, whole, sizes_whole);
    uint64_t n_again = encode_range(&l, 0, PIECES, 3, again, sizes_again);
    ENSURE(n_whole > 0 && n_whole == n_again && memcmp(whole, again, n_whole) == 0);
    ENSURE(memcmp(sizes_whole, sizes_again, sizeof sizes_whole) == 0);
    /* pieces 0..4 and 5..11 (the last piece shorter), each frame's blocks one run after the other */
    uint64_t n_a = encode_range(&l, 0, 5, 2, split, sizes_a);
    uint64_t n_b = encode_range(&l, 5, PIECES, 1, split + n_a, sizes_b);
    ENSURE(n_a + n_b == n_whole);
    uint64_t at_whole = 0, at_a = 0, at_b = n_a;
    for (int k = 0; k < 3; k++) {
        for (int b = 0; b < BLOCKS; b++) {
            const uint64_t size = b < 10 ? sizes_a[k * 10 + b] : sizes_b[k * 14 + b - 10];
            uint64_t *at = b < 10 ? &at_a : &at_b;
            ENSURE_MSG(size == sizes_whole[k * BLOCKS + b] && memcmp(whole + at_whole, split + *at, size) == 0,
                       "frame %d block %d differs", k, b);
            at_whole += size, *at += size;
        }
    }
    free(whole), free(again), free(split);
}

/* Sets the header's version and bytes 68..71 (format 4's piece size, format 3's reserved field),
 * with the header crc to match, and writes the file to path. */
static void rewrite_header(unsigned char *bytes, size_t len, uint32_t version, uint32_t at68, const char *path)
{
    const uint32_t zero = 0, header = bytes_u32(bytes + 12);
    memcpy(bytes + 8, &version, 4), memcpy(bytes + 68, &at68, 4), memcpy(bytes + 52, &zero, 4);
    const uint32_t crc = cache_crc32(0, bytes, header);
    memcpy(bytes + 52, &crc, 4);
    write_all(path, bytes, len);
}

static void expect_open_refused(const char *path, const char *message)
{
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    ENSURE_MSG(!r && strstr(err.message, message), "%s", err.message);
    fm_cache_close(r);
}

/* A format-3 cache (one piece of every agent, bytes 68..71 reserved as 0) still reads: a
 * one-piece format-4 file with its header rewritten to format 3 gives every frame's values. A
 * non-zero reserved field is refused in format 3, and a piece size outside its range in format 4. */
static void test_format_3_still_reads(void)
{
    enum { AGENTS = 300, FRAMES = 5 };
    char path[FM_PATH_MAX], v3[FM_PATH_MAX];
    fm_cache_options o = fm_default_cache_options();
    o.key_interval = 2;
    if (write_attrs_cache(tmp_path(path, "format4_one_piece.fmc"), AGENTS, FRAMES, ALL_ATTRS, ALL_ATTR_COUNT, &o, DATA_SMOOTH) != 0)
        return;
    size_t len;
    unsigned char *bytes = read_all(path, &len);
    ENSURE(bytes && len > 72 && bytes_u32(bytes + 8) == 4 && bytes_u32(bytes + 68) == 65536);
    if (!bytes) return;
    rewrite_header(bytes, len, 3, 0, tmp_path(v3, "format3.fmc"));
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(v3, &err);
    ENSURE_MSG(r != NULL, "%s", err.message);
    if (r) {
        ENSURE(fm_cache_version(r) == 3 && fm_cache_frames(r) == FRAMES && fm_cache_get_options(r).piece_agents == 0);
        for (uint32_t f = 0; f < FRAMES; f++) frame_matches(r, f, DATA_SMOOTH, 0, "format 3");
        fm_cache_close(r);
    }
    rewrite_header(bytes, len, 3, 7, v3);
    expect_open_refused(v3, "reserved bytes 68..71 are not 0");
    rewrite_header(bytes, len, 4, 255, v3);
    expect_open_refused(v3, "255 agents per piece is outside 256..1073741824");
    free(bytes);
}

int main(void)
{
    RUN_TEST(test_attribute_table);
    RUN_TEST(test_round_trip_every_attribute_and_option);
    RUN_TEST(test_delta_random_access_matches_sequential);
    RUN_TEST(test_quantisation_bound);
    RUN_TEST(test_sizes);
    RUN_TEST(test_argument_errors);
    RUN_TEST(test_bytes_independent_of_threads);
    RUN_TEST(test_blocks_independent_of_encoder);
    RUN_TEST(test_format_3_still_reads);
    return test_result();
}
