/* Checkpoints: the state of a run at a frame boundary, so a killed or interrupted run can resume
 * and finish with the same bytes as an uninterrupted one (docs/resume.md specifies the file).
 *
 *   header   72 bytes: "FMCHKPT\0", version, member count, scene hash, model hash, agents,
 *            frames written, layout hash, piece count S, statistics bytes
 *   stats    the scalars of the mode's statistics table, in order (the tetra morph:
 *            inverted_tet_frames, simulate_seconds, output_seconds, min_vertex_clearance), then its per-frame values
 *            if it has any: for frames 1 .. frames-1, the mode's doubles a frame (the tetra morph's
 *            MDE fraction, the shape flock's measures), f64 each
 *   members  for each entry of the mode's member table, in order: name length (u32), name, byte
 *            count (u64), the bytes (a per-agent array: agents x element size)
 *   pieces   S records: the piece's end agent (u64), then for each per-agent member the XXH3-64 of
 *            its bytes over the piece's agents (the pieces tile 0 … agents − 1 in order)
 *   trailer  XXH3-64 of every byte before it but the per-agent arrays' (the pieces cover those)
 * Little-endian, like the cache. The pieces let P ranks write and checksum their agents' bytes at
 * once, each at its own offsets (MPI-IO), while rank 0 writes the rest. Hashes are XXH3-64
 * (libxxhash): the scene hash of the canonical
 * parameter bytes (fm_scene_def_feed), the mode's hash of every array the step reads from its model
 * (the tets after TetGen and subdivision or the samples, the path, the obstacle distance grids), so a resume with
 * other meshes, another TetGen or other parameters is refused instead of producing a different
 * animation.
 *
 * The file does not know the modes: each hands over an fm_ckpt_store (checkpoint.h) with its member
 * table, statistics table, model hash and checks; the scene hash covers the mode, so one mode's
 * checkpoint is refused by the other. */
#define _POSIX_C_SOURCE 200809L
#include "checkpoint.h"
#include "scene_internal.h"

#include <xxhash.h>

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum { CHECKPOINT_VERSION = 4, HEADER_BYTES = 72, TRAILER_BYTES = 8, NAME_MAX_BYTES = 64 };
static const char MAGIC[8] = {'F', 'M', 'C', 'H', 'K', 'P', 'T', 0};

typedef struct header {
    uint32_t version, members;
    uint64_t scene_hash, model_hash, agents, frames, layout_hash, pieces, stats_bytes;
} header;

static void put_u32(unsigned char *p, uint32_t x) { memcpy(p, &x, 4); }
static void put_u64(unsigned char *p, uint64_t x) { memcpy(p, &x, 8); }
static uint32_t get_u32(const unsigned char *p) { uint32_t x; memcpy(&x, p, 4); return x; }
static uint64_t get_u64(const unsigned char *p) { uint64_t x; memcpy(&x, p, 8); return x; }

/* ---------------------------------------------------------------- hashes */

void fm_hash_bytes(const void *bytes, size_t n, void *state)
{
    if (n) XXH3_64bits_update((XXH3_state_t *)state, bytes, n);
}

fm_hash *fm_hash_begin(void)
{
    XXH3_state_t *h = XXH3_createState();
    if (h) XXH3_64bits_reset(h);
    return h;
}

uint64_t fm_hash_end(fm_hash *h)
{
    uint64_t x = XXH3_64bits_digest(h);
    XXH3_freeState(h);
    return x;
}

static uint64_t scene_hash(const fm_scene_def *def)
{
    XXH3_state_t *h = fm_hash_begin();
    if (!h) return 0;
    fm_scene_def_feed(def, fm_hash_bytes, h);
    return fm_hash_end(h);
}

void fm_hash_sdf(fm_hash *h, const fm_obstacles *o)
{
    if (!o) return fm_hash_bytes("none", 4, h);
    fm_sdf_view v = fm_obstacles_sdf(o);
    fm_hash_bytes(v.n, sizeof v.n, h), fm_hash_bytes(v.origin, sizeof v.origin, h);
    fm_hash_bytes(&v.voxel, sizeof v.voxel, h), fm_hash_bytes(&v.far, sizeof v.far, h);
    fm_hash_bytes(v.d, sizeof(float) * (size_t)v.n[0] * (size_t)v.n[1] * (size_t)v.n[2], h);
}

/* The saved members' names and sizes: a build whose store differs cannot read the file. */
static uint64_t layout_hash(const fm_store_member *members, int count)
{
    XXH3_state_t *h = fm_hash_begin();
    if (!h) return 0;
    for (int i = 0; i < count; i++) {
        const fm_store_member *mb = &members[i];
        uint64_t bytes = mb->bytes, per_agent = (uint64_t)mb->per_agent;
        fm_hash_bytes(mb->name, strlen(mb->name) + 1, h);
        fm_hash_bytes(&bytes, sizeof bytes, h), fm_hash_bytes(&per_agent, sizeof per_agent, h);
    }
    return fm_hash_end(h);
}

/* Where a member's bytes are: the array a pointer member points at, or the member itself. An array
 * this run does not have (NULL) has no bytes. */
static void *member_data(void *base, int64_t n, const fm_store_member *mb, uint64_t *bytes)
{
    char *field = (char *)base + mb->offset;
    *bytes = mb->per_agent ? (uint64_t)mb->bytes * (uint64_t)n : mb->bytes;
    if (!mb->per_agent) return field;
    void *array;
    memcpy(&array, field, sizeof array);
    if (!array) *bytes = 0;
    return array;
}

/* The per-agent members: each has one hash a piece. */
static int array_count(const fm_store_member *members, int count)
{
    int arrays = 0;
    for (int i = 0; i < count; i++) arrays += members[i].per_agent;
    return arrays;
}

/* A piece's record in the file: its end agent, then a hash per per-agent member (u64 each). */
static size_t record_words(int arrays) { return 1 + (size_t)arrays; }

static uint64_t stats_bytes(const fm_ckpt_store *c)
{
    uint64_t bytes = 0;
    for (int i = 0; i < c->stats_count; i++) bytes += c->stats[i].bytes;
    if (c->per_frame) bytes += sizeof(double) * (uint64_t)c->per_frame_width * (uint64_t)(c->frames - 1);
    return bytes;
}

/* Where each member's bytes start in the file (every rank computes the same). */
static void member_offsets(const fm_ckpt_store *c, uint64_t *data_at)
{
    uint64_t at = HEADER_BYTES + stats_bytes(c);
    for (int i = 0; i < c->member_count; i++) {
        uint64_t bytes;
        member_data(c->state, c->n, &c->members[i], &bytes);
        at += 4 + strlen(c->members[i].name) + 8;
        data_at[i] = at, at += bytes;
    }
}

fm_ckpt_store fm_ckpt_on_ranks(fm_ckpt_store c, const fm_dist *dist, const fm_ckpt_part *parts, int part_count)
{
    c.dist = dist, c.part_count = FM_MIN(part_count, 2);
    for (int q = 0; q < c.part_count; q++) c.parts[q] = parts[q];
    return c;
}

fm_ckpt_part fm_ckpt_share(int64_t n, int64_t piece, int rank, int ranks)
{
    piece = FM_MAX(piece, 1);
    const int64_t pieces = (n + piece - 1) / piece;
    const int64_t first = FM_MIN(piece * (pieces * rank / ranks), n), end = FM_MIN(piece * (pieces * (rank + 1) / ranks), n);
    return (fm_ckpt_part){first, end - first, first};
}

/* ---------------------------------------------------------------- writing */

/* This rank's parts cut into pieces of c->piece_agents (counted from each part's first agent), as
 * records of first agent, end agent and each per-agent member's hash over the piece. */
static uint64_t *hash_pieces(const fm_ckpt_store *c, size_t words, int64_t *count)
{
    const fm_ckpt_part whole = {0, c->n, 0}, *parts = c->part_count ? c->parts : &whole;
    const int part_count = c->part_count ? c->part_count : 1;
    const int64_t size = FM_MAX(c->piece_agents > 0 ? c->piece_agents : c->n, 1);
    *count = 0;
    for (int q = 0; q < part_count; q++) *count += (parts[q].count + size - 1) / size;
    uint64_t *rec = malloc(sizeof(uint64_t) * words * (size_t)FM_MAX(*count, 1)), *r = rec;
    for (int q = 0; rec && q < part_count; q++)
        for (int64_t off = 0; off < parts[q].count; off += size, r += words) {
            const int64_t agents = FM_MIN(size, parts[q].count - off);
            r[0] = (uint64_t)(parts[q].first + off), r[1] = r[0] + (uint64_t)agents;
            for (int i = 0, j = 2; i < c->member_count; i++) {
                const fm_store_member *mb = &c->members[i];
                uint64_t bytes;
                const char *data = member_data(c->state, c->n, mb, &bytes);
                if (!mb->per_agent) continue;
                const size_t at = mb->bytes * (size_t)(parts[q].at + off);
                r[j++] = bytes ? XXH3_64bits(data + at, mb->bytes * (size_t)agents) : XXH3_64bits(NULL, 0);
            }
        }
    return rec;
}

/* This rank's parts of every per-agent array, each at its place in the file. */
static void write_arrays(fm_dist_file *f, const fm_ckpt_store *c, const uint64_t *data_at)
{
    const fm_ckpt_part whole = {0, c->n, 0}, *parts = c->part_count ? c->parts : &whole;
    for (int q = 0; q < (c->part_count ? c->part_count : 1); q++)
        for (int i = 0; i < c->member_count; i++) {
            const fm_store_member *mb = &c->members[i];
            uint64_t bytes;
            const char *data = member_data(c->state, c->n, mb, &bytes);
            if (!mb->per_agent || !bytes || !parts[q].count) continue;
            fm_dist_file_write_at(f, data_at[i] + mb->bytes * (uint64_t)parts[q].first, data + mb->bytes * (size_t)parts[q].at,
                                  mb->bytes * (size_t)parts[q].count, NULL); /* a failure is kept for the commit */
        }
}

/* Rank 0's bytes, in file order, hashed for the trailer: everything but the per-agent arrays. */
typedef struct sink {
    fm_dist_file *f;
    uint64_t at;
    XXH3_state_t *hash;
} sink;

static void put(sink *k, const void *bytes, size_t n)
{
    if (!n) return;
    fm_dist_file_write_at(k->f, k->at, bytes, n, NULL); /* a failure is kept for the commit */
    fm_hash_bytes(bytes, n, k->hash);
    k->at += n;
}

static void put_header(sink *k, const fm_ckpt_store *c, uint64_t pieces)
{
    unsigned char h[HEADER_BYTES] = {0};
    memcpy(h, MAGIC, 8);
    put_u32(h + 8, CHECKPOINT_VERSION);
    put_u32(h + 12, (uint32_t)c->member_count);
    put_u64(h + 16, scene_hash(c->def));
    put_u64(h + 24, c->model_hash);
    put_u64(h + 32, (uint64_t)c->n);
    put_u64(h + 40, (uint64_t)c->frames);
    put_u64(h + 48, layout_hash(c->members, c->member_count));
    put_u64(h + 56, pieces);
    put_u64(h + 64, stats_bytes(c));
    put(k, h, sizeof h);
}

static void put_stats(sink *k, const fm_ckpt_store *c)
{
    for (int i = 0; i < c->stats_count; i++) put(k, (const char *)c->run_stats + c->stats[i].offset, c->stats[i].bytes);
    if (c->per_frame) put(k, *c->per_frame, sizeof(double) * (size_t)c->per_frame_width * (size_t)(c->frames - 1));
}

/* Each member's heading and a scalar's bytes; an array's bytes are the ranks' (write_arrays). */
static void put_members(sink *k, const fm_ckpt_store *c, const uint64_t *data_at)
{
    for (int i = 0; i < c->member_count; i++) {
        const fm_store_member *mb = &c->members[i];
        uint32_t len = (uint32_t)strlen(mb->name);
        uint64_t bytes;
        const void *data = member_data(c->state, c->n, mb, &bytes);
        put(k, &len, 4), put(k, mb->name, len), put(k, &bytes, 8);
        if (mb->per_agent) k->at = data_at[i] + bytes;
        else put(k, data, (size_t)bytes);
    }
}

static int by_first(const void *a, const void *b)
{
    const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* Rank 0: every rank's piece records sorted, checked to tile the agents, and put as the table. */
static fm_status put_pieces(sink *k, const fm_ckpt_store *c, uint64_t *rec, int64_t count, size_t words, fm_error *err)
{
    if (count > 0) qsort(rec, (size_t)count, sizeof(uint64_t) * words, by_first); /* a shot's file has none (rec NULL) */
    uint64_t end = 0;
    for (int64_t p = 0; p < count; p++) {
        const uint64_t *r = rec + words * (size_t)p;
        if (r[0] != end || r[1] <= r[0]) break;
        end = r[1];
        put(k, r + 1, sizeof(uint64_t) * (words - 1)); /* the end and the hashes */
    }
    if (end == (uint64_t)c->n) return FM_OK;
    return fm_fail(err, FM_ERR_INTERNAL, "checkpoint: the ranks' pieces do not cover the %lld agents", (long long)c->n);
}

/* Rank 0's part of the file: the header, the statistics, the member headings and scalars, the
 * piece table and the trailer. */
static fm_status put_rest(fm_dist_file *f, const fm_ckpt_store *c, const uint64_t *data_at, uint64_t *rec, int64_t count,
                          size_t words, fm_error *err)
{
    sink k = {f, 0, fm_hash_begin()};
    if (!k.hash) return fm_fail(err, FM_ERR_MEMORY, "out of memory");
    put_header(&k, c, (uint64_t)count);
    put_stats(&k, c);
    put_members(&k, c, data_at);
    fm_status st = put_pieces(&k, c, rec, count, words, err);
    unsigned char trailer[TRAILER_BYTES];
    put_u64(trailer, fm_hash_end(k.hash));
    if (st == FM_OK) fm_dist_file_write_at(f, k.at, trailer, sizeof trailer, NULL);
    return st;
}

fm_status fm_ckpt_save(const char *path, const fm_ckpt_store *c, fm_error *err)
{
    fm_status st = FM_OK;
    if (c->frames < 1) st = fm_fail(err, FM_ERR_INTERNAL, "%s: a checkpoint needs at least frame 0", path);
    else if (c->per_frame && !*c->per_frame && c->frames > 1)
        st = fm_fail(err, FM_ERR_INTERNAL, "%s: no per-frame statistics for %lld frames", path, (long long)c->frames);
    const size_t words = 1 + record_words(array_count(c->members, c->member_count)); /* + the first agent */
    int64_t count = 0, total = 0;
    uint64_t *mine = st == FM_OK ? hash_pieces(c, words, &count) : NULL, *all = NULL;
    uint64_t *data_at = malloc(sizeof(uint64_t) * (size_t)c->member_count);
    if (st == FM_OK && (!mine || !data_at)) st = fm_fail(err, FM_ERR_MEMORY, "out of memory for a checkpoint");
    st = fm_dist_agree(c->dist, st, err);
    if (st == FM_OK) st = fm_dist_gather(c->dist, mine, count, sizeof(uint64_t) * words, (void **)&all, &total, err);
    fm_dist_file *f = st == FM_OK ? fm_dist_file_open(c->dist, path, err) : NULL;
    if (f) {
        member_offsets(c, data_at);
        write_arrays(f, c, data_at);
        if (fm_dist_rank(c->dist) == 0) st = put_rest(f, c, data_at, all, total, words, err);
        st = fm_dist_file_commit(f, st, err); /* every rank's writes, synced, then renamed */
    } else if (st == FM_OK) {
        st = err->status;
    }
    free(mine), free(data_at), fm_free(all);
    return st;
}

/* ---------------------------------------------------------------- reading */

typedef struct source {
    FILE *f;
    const char *path;
    fm_error *err;
    off_t size;
    XXH3_state_t *sum;      /* the trailer's: every byte but the per-agent arrays' */
    unsigned char *scratch; /* where bytes go that no store takes (a check) */
} source;

enum { SCRATCH_BYTES = 1 << 20 };

fm_status fm_ckpt_damaged(const char *path, const char *what, fm_error *err)
{
    return fm_fail(err, FM_ERR_INPUT, "%s: damaged checkpoint (%s); it cannot be used: run again without --resume", path,
                   what);
}

static fm_status damaged(const source *src, const char *what) { return fm_ckpt_damaged(src->path, what, src->err); }

/* n bytes into buf (the scratch when NULL: then n is at most SCRATCH_BYTES), hashed into `hash`. */
static fm_status read_into(const source *src, void *buf, size_t n, XXH3_state_t *hash)
{
    if (!buf) buf = src->scratch;
    if (n && fread(buf, 1, n, src->f) != n) return damaged(src, "shorter than its contents");
    fm_hash_bytes(buf, n, hash);
    return FM_OK;
}

/* Bytes the trailer covers, in chunks through the scratch when there is no buf. */
static fm_status get(const source *src, void *buf, uint64_t n)
{
    fm_status st = FM_OK;
    for (uint64_t done = 0; st == FM_OK && done < n; done += SCRATCH_BYTES)
        st = read_into(src, buf ? (char *)buf + done : NULL, (size_t)FM_MIN(n - done, SCRATCH_BYTES), src->sum);
    return st;
}

/* One piece of a per-agent array, checked against its hash in the table. */
static fm_status get_piece(const source *src, char *buf, uint64_t n, uint64_t expected)
{
    XXH3_state_t *h = fm_hash_begin();
    if (!h) return fm_fail(src->err, FM_ERR_MEMORY, "out of memory");
    fm_status st = FM_OK;
    for (uint64_t done = 0; st == FM_OK && done < n; done += SCRATCH_BYTES)
        st = read_into(src, buf ? buf + done : NULL, (size_t)FM_MIN(n - done, SCRATCH_BYTES), h);
    const uint64_t got = fm_hash_end(h);
    return st == FM_OK && got != expected ? damaged(src, "checksum mismatch") : st;
}

static fm_status read_header(source *src, header *h)
{
    if (fseeko(src->f, 0, SEEK_END) != 0) return fm_fail(src->err, FM_ERR_IO, "%s: cannot seek", src->path);
    src->size = ftello(src->f);
    rewind(src->f);
    unsigned char b[HEADER_BYTES];
    if (fread(b, 1, sizeof b, src->f) != sizeof b || memcmp(b, MAGIC, 8) != 0)
        return fm_fail(src->err, FM_ERR_INPUT, "%s: not a flockmorph checkpoint", src->path);
    h->version = get_u32(b + 8);
    if (h->version != CHECKPOINT_VERSION)
        return fm_fail(src->err, FM_ERR_INPUT, "%s: checkpoint version %u; this flockmorph reads version %d: "
                       "finish the run with the flockmorph that started it, or run again without --resume",
                       src->path, h->version, CHECKPOINT_VERSION);
    fm_hash_bytes(b, sizeof b, src->sum);
    h->members = get_u32(b + 12);
    h->scene_hash = get_u64(b + 16), h->model_hash = get_u64(b + 24);
    h->agents = get_u64(b + 32), h->frames = get_u64(b + 40), h->layout_hash = get_u64(b + 48);
    h->pieces = get_u64(b + 56), h->stats_bytes = get_u64(b + 64);
    return src->size < HEADER_BYTES + TRAILER_BYTES ? damaged(src, "too short") : FM_OK;
}

/* The header's scene and layout, then counts that the file's size can hold. */
static fm_status check_header(const source *src, const header *h, const fm_scene_def *def, const fm_store_member *members,
                              int count)
{
    if (h->scene_hash != scene_hash(def)) /* first: the other mode's file is another scene's */
        return fm_fail(src->err, FM_ERR_INPUT, "%s: written for a different scene: the parameters of %s differ from "
                       "the run it saved; resume with the same scene file, or run again without --resume",
                       src->path, def->scene_path[0] ? def->scene_path : "this scene");
    if (h->members != (uint32_t)count || h->layout_hash != layout_hash(members, count))
        return fm_fail(src->err, FM_ERR_INPUT, "%s: written by a flockmorph whose agent store differs from this "
                       "one; finish the run with that build, or run again without --resume", src->path);
    const uint64_t room = (uint64_t)(src->size - HEADER_BYTES - TRAILER_BYTES);
    const uint64_t record = sizeof(uint64_t) * record_words(array_count(members, count));
    if (h->frames < 1 || h->frames > UINT32_MAX || h->stats_bytes > room)
        return damaged(src, "impossible frame count");
    if (h->pieces > room / record || h->pieces > h->agents || (h->agents > 0) != (h->pieces > 0))
        return damaged(src, "impossible piece count");
    return FM_OK;
}

/* The piece table at the end (its bytes hashed later, in file order): ends rising to the agents. */
static fm_status read_table(const source *src, const header *h, size_t words, uint64_t **table)
{
    const size_t bytes = sizeof(uint64_t) * words * (size_t)h->pieces;
    *table = malloc(FM_MAX(bytes, 1));
    if (!*table) return fm_fail(src->err, FM_ERR_MEMORY, "out of memory for a checkpoint's table");
    if (fseeko(src->f, src->size - TRAILER_BYTES - (off_t)bytes, SEEK_SET) != 0 || fread(*table, 1, bytes, src->f) != bytes ||
        fseeko(src->f, HEADER_BYTES, SEEK_SET) != 0)
        return damaged(src, "shorter than its contents");
    uint64_t end = 0;
    for (uint64_t p = 0; p < h->pieces; p++) {
        if ((*table)[words * p] <= end) return damaged(src, "piece table");
        end = (*table)[words * p];
    }
    return end == h->agents ? FM_OK : damaged(src, "piece table");
}

/* The statistics into c's (or skipped, for a check), their size the one c expects. */
static fm_status read_stats(const source *src, const header *h, const fm_ckpt_store *c)
{
    if (!c) return get(src, NULL, h->stats_bytes);
    fm_ckpt_store expect = *c;
    expect.frames = (int64_t)h->frames;
    if (h->stats_bytes != stats_bytes(&expect)) return damaged(src, "unexpected statistics");
    fm_status st = FM_OK;
    for (int i = 0; i < c->stats_count && st == FM_OK; i++) st = get(src, (char *)c->run_stats + c->stats[i].offset, c->stats[i].bytes);
    if (st != FM_OK || !c->per_frame) return st;
    size_t count = (size_t)c->per_frame_width * (size_t)(h->frames - 1);
    *c->per_frame = malloc(sizeof(double) * (count ? count : 1));
    if (!*c->per_frame) return fm_fail(src->err, FM_ERR_MEMORY, "out of memory for the per-frame statistics");
    return get(src, *c->per_frame, sizeof(double) * count);
}

/* Member i's heading: its name and a byte count the store (or, for a check, the table) allows. */
static fm_status read_heading(const source *src, const header *h, const fm_store_member *mb, const fm_ckpt_store *c,
                              uint64_t *bytes)
{
    uint32_t len;
    char name[NAME_MAX_BYTES];
    fm_status st = get(src, &len, 4);
    if (st == FM_OK && len >= sizeof name) return damaged(src, "member name too long");
    if (st == FM_OK) st = get(src, name, len);
    if (st == FM_OK) st = get(src, bytes, 8);
    if (st != FM_OK) return st;
    name[len] = 0;
    uint64_t want = mb->per_agent ? mb->bytes * h->agents : mb->bytes;
    if (c) member_data(c->state, c->n, mb, &want);
    int fits = *bytes == want || (!c && mb->per_agent && *bytes == 0); /* an array a run may not have */
    return strcmp(name, mb->name) == 0 && fits ? FM_OK : damaged(src, "unexpected member");
}

/* A per-agent array, piece by piece against the table's j-th hashes, into `data` (or skipped). With
 * a part (a rank's share on P ranks) only agents part->first … part->first + part->count − 1 go to
 * data, from its element part->at; every piece is read and checked all the same. */
static fm_status read_array(const source *src, const header *h, const uint64_t *table, size_t words, int j, size_t elem,
                            uint64_t bytes, char *data, const fm_ckpt_part *part)
{
    fm_status st = FM_OK;
    for (uint64_t p = 0, first = 0; st == FM_OK && p < h->pieces; p++) {
        const uint64_t end = table[words * p], n = bytes ? elem * (end - first) : 0;
        const uint64_t lo = part ? FM_MAX(first, (uint64_t)part->first) : first;
        const uint64_t hi = part ? FM_MIN(end, (uint64_t)(part->first + part->count)) : end;
        char *to = data && n && lo < hi ? data + elem * (lo - (part ? (uint64_t)(part->first - part->at) : 0)) : NULL;
        char *whole = to && (lo != first || hi != end) ? malloc(n) : NULL; /* a piece the part cuts */
        if (to && (lo != first || hi != end) && !whole) return fm_fail(src->err, FM_ERR_MEMORY, "out of memory");
        st = get_piece(src, whole ? whole : to, n, table[words * p + 1 + (size_t)j]);
        if (st == FM_OK && whole) memcpy(to, whole + elem * (lo - first), elem * (hi - lo));
        free(whole);
        first = end;
    }
    return st;
}

static fm_status read_members(const source *src, const header *h, const fm_store_member *members, int count,
                              const fm_ckpt_store *c, const uint64_t *table, size_t words)
{
    for (int i = 0, j = 0; i < count; i++) {
        const fm_store_member *mb = &members[i];
        uint64_t bytes, ignored;
        fm_status st = read_heading(src, h, mb, c, &bytes);
        char *data = c ? member_data(c->state, c->n, mb, &ignored) : NULL;
        const fm_ckpt_part *part = c && c->part_count > 0 ? &c->parts[0] : NULL;
        if (st == FM_OK && mb->per_agent) st = read_array(src, h, table, words, j++, mb->bytes, bytes, data, part);
        else if (st == FM_OK) st = get(src, data, bytes);
        if (st != FM_OK) return st;
    }
    const off_t table_at = src->size - TRAILER_BYTES - (off_t)(sizeof(uint64_t) * words * h->pieces);
    return ftello(src->f) == table_at ? FM_OK : damaged(src, "unexpected bytes after the state");
}

/* The table's bytes in the trailer's hash (they come last), then the trailer. */
static fm_status check_trailer(const source *src, const header *h, const uint64_t *table, size_t words)
{
    fm_hash_bytes(table, sizeof(uint64_t) * words * (size_t)h->pieces, src->sum);
    unsigned char trailer[TRAILER_BYTES];
    if (fseeko(src->f, src->size - TRAILER_BYTES, SEEK_SET) != 0 || fread(trailer, 1, sizeof trailer, src->f) != sizeof trailer)
        return damaged(src, "shorter than its contents");
    return get_u64(trailer) == XXH3_64bits_digest(src->sum) ? FM_OK : damaged(src, "checksum mismatch");
}

static fm_status open_source(source *src)
{
    struct stat file;
    fm_status checked = stat(src->path, &file) == 0 ? fm_check_input_file(src->path, "checkpoint", src->err) : FM_OK;
    if (checked != FM_OK) return checked; /* a FIFO or device there would block or never end */
    errno = 0;
    src->f = fopen(src->path, "rb");
    if (!src->f)
        return fm_fail(src->err, errno == ENOENT ? FM_ERR_INPUT : FM_ERR_IO, "%s: cannot open the checkpoint: %s%s",
                       src->path, strerror(errno), errno == ENOENT ? " (nothing to resume)" : "");
    src->sum = fm_hash_begin(), src->scratch = malloc(SCRATCH_BYTES);
    return src->sum && src->scratch ? FM_OK : fm_fail(src->err, FM_ERR_MEMORY, "out of memory");
}

static void close_source(source *src)
{
    if (src->f) fclose(src->f);
    if (src->sum) fm_hash_end(src->sum);
    free(src->scratch);
}

/* The whole file, checked: header, then (with a store c) the agent count and model hash, then every
 * byte against the piece hashes and the trailer, c's state and statistics filled on the way. */
static fm_status read_checkpoint(source *src, header *h, const fm_scene_def *def, const fm_store_member *members,
                                 int count, const fm_ckpt_store *c)
{
    fm_status st = open_source(src);
    if (st == FM_OK) st = read_header(src, h);
    if (st == FM_OK) st = check_header(src, h, def, members, count);
    if (st == FM_OK && c && (h->agents != (uint64_t)c->n || h->model_hash != c->model_hash))
        st = fm_fail(src->err, FM_ERR_INPUT, "%s: written for a different model: %s differ from the run it saved "
                     "(another mesh file or TetGen version?); run again without --resume", src->path, c->model_what);
    const size_t words = record_words(array_count(members, count));
    uint64_t *table = NULL;
    if (st == FM_OK) st = read_table(src, h, words, &table);
    if (st == FM_OK) st = read_stats(src, h, c);
    if (st == FM_OK) st = read_members(src, h, members, count, c, table, words);
    if (st == FM_OK) st = check_trailer(src, h, table, words);
    free(table);
    return st;
}

fm_status fm_ckpt_check(const char *path, const fm_scene_def *def, const fm_store_member *members, int count,
                        fm_error *err)
{
    source src = {NULL, path, err, 0, NULL, NULL};
    header h = {0};
    fm_status st = read_checkpoint(&src, &h, def, members, count, NULL);
    close_source(&src);
    return st;
}

fm_status fm_ckpt_load(const char *path, fm_ckpt_store *c, int64_t *frames, fm_error *err)
{
    source src = {NULL, path, err, 0, NULL, NULL};
    header h = {0};
    fm_status st = read_checkpoint(&src, &h, c->def, c->members, c->member_count, c);
    const char *bad = st == FM_OK && c->check ? c->check(c->state) : NULL;
    if (bad) st = damaged(&src, bad);
    close_source(&src);
    *frames = (int64_t)h.frames;
    return st;
}
