/* Checkpoints: the state of a run at a frame boundary, so a killed or interrupted run can resume
 * and finish with the same bytes as an uninterrupted one (docs/resume.md specifies the file).
 *
 *   header   64 bytes: "FMCHKPT\0", version, member count, scene hash, model hash, agents,
 *            frames written, layout hash, 0
 *   stats    the scalars of the mode's statistics table, in order (the tetra morph:
 *            inverted_tet_frames, simulate_seconds, output_seconds, min_vertex_clearance), then its per-frame values
 *            if it has any: for frames 1 .. frames-1, the mode's doubles a frame (the tetra morph's
 *            MDE fraction, the shape flock's measures), f64 each
 *   members  for each entry of the mode's member table, in order: name length (u32), name, byte
 *            count (u64), the bytes (a per-agent array: agents x element size)
 *   trailer  XXH3-64 of every byte before it
 * Little-endian, like the cache. Hashes are XXH3-64 (libxxhash): the scene hash of the canonical
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
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

enum { CHECKPOINT_VERSION = 3, HEADER_BYTES = 64, TRAILER_BYTES = 8, NAME_MAX_BYTES = 64 };
static const char MAGIC[8] = {'F', 'M', 'C', 'H', 'K', 'P', 'T', 0};

typedef struct header {
    uint32_t version, members;
    uint64_t scene_hash, model_hash, agents, frames, layout_hash;
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

/* ---------------------------------------------------------------- writing */

typedef struct sink {
    FILE *f;
    XXH3_state_t *hash;
} sink;

static void put(sink *k, const void *bytes, size_t n)
{
    if (!n) return;
    fwrite(bytes, 1, n, k->f); /* errors are collected by fm_output_commit (ferror) */
    fm_hash_bytes(bytes, n, k->hash);
}

static void put_header(sink *k, const fm_ckpt_store *c)
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
    put(k, h, sizeof h);
}

static void put_stats(sink *k, const fm_ckpt_store *c)
{
    for (int i = 0; i < c->stats_count; i++) put(k, (const char *)c->run_stats + c->stats[i].offset, c->stats[i].bytes);
    if (c->per_frame) put(k, *c->per_frame, sizeof(double) * (size_t)c->per_frame_width * (size_t)(c->frames - 1));
}

static void put_members(sink *k, const fm_ckpt_store *c)
{
    for (int i = 0; i < c->member_count; i++) {
        const fm_store_member *mb = &c->members[i];
        uint32_t len = (uint32_t)strlen(mb->name);
        uint64_t bytes;
        const void *data = member_data(c->state, c->n, mb, &bytes);
        put(k, &len, 4), put(k, mb->name, len), put(k, &bytes, 8), put(k, data, (size_t)bytes);
    }
}

/* After the rename, the directory entry itself must reach the disk for the file to survive a
 * crash under its new name. */
static void sync_directory(const char *path)
{
    char dir[FM_PATH_MAX];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash == dir) dir[1] = 0; /* "/name": the root */
    else if (slash) *slash = 0;
    int fd = open(slash ? dir : ".", O_RDONLY);
    if (fd >= 0) fsync(fd), close(fd);
}

fm_status fm_ckpt_save(const char *path, const fm_ckpt_store *c, fm_error *err)
{
    if (c->frames < 1) return fm_fail(err, FM_ERR_INTERNAL, "%s: a checkpoint needs at least frame 0", path);
    if (c->per_frame && !*c->per_frame && c->frames > 1)
        return fm_fail(err, FM_ERR_INTERNAL, "%s: no per-frame statistics for %lld frames", path, (long long)c->frames);
    fm_output_file out;
    fm_status st = fm_output_open(&out, path, err);
    if (st != FM_OK) return st;
    sink k = {out.f, fm_hash_begin()};
    if (!k.hash) return fm_output_discard(&out), fm_fail(err, FM_ERR_MEMORY, "out of memory");
    setvbuf(out.f, NULL, _IOFBF, 1 << 20);
    put_header(&k, c);
    put_stats(&k, c);
    put_members(&k, c);
    unsigned char trailer[TRAILER_BYTES];
    put_u64(trailer, fm_hash_end(k.hash));
    fwrite(trailer, 1, sizeof trailer, out.f);
    st = fm_output_commit(&out, NULL, err); /* fflush, fsync, rename */
    if (st == FM_OK) sync_directory(path);
    return st;
}

/* ---------------------------------------------------------------- reading */

typedef struct source {
    FILE *f;
    const char *path;
    fm_error *err;
    off_t size;
} source;

static fm_status damaged(const source *src, const char *what)
{
    return fm_fail(src->err, FM_ERR_INPUT, "%s: damaged checkpoint (%s); it cannot be used: run again without --resume",
                   src->path, what);
}

static fm_status get(const source *src, void *buf, size_t n)
{
    return fread(buf, 1, n, src->f) == n ? FM_OK : damaged(src, "shorter than its contents");
}

/* Hashes everything before the trailer and compares: a flipped or missing byte anywhere fails. */
static fm_status verify_checksum(source *src)
{
    if (fseeko(src->f, 0, SEEK_END) != 0) return fm_fail(src->err, FM_ERR_IO, "%s: cannot seek", src->path);
    off_t size = src->size = ftello(src->f);
    if (size < HEADER_BYTES + TRAILER_BYTES) return damaged(src, "too short");
    rewind(src->f);
    XXH3_state_t *h = fm_hash_begin();
    if (!h) return fm_fail(src->err, FM_ERR_MEMORY, "out of memory");
    unsigned char buf[1 << 16], trailer[TRAILER_BYTES];
    for (off_t left = size - TRAILER_BYTES; left > 0;) {
        size_t n = (size_t)FM_MIN(left, (off_t)sizeof buf);
        if (fread(buf, 1, n, src->f) != n) return fm_hash_end(h), fm_fail(src->err, FM_ERR_IO, "%s: read failed", src->path);
        fm_hash_bytes(buf, n, h), left -= (off_t)n;
    }
    uint64_t expected = fm_hash_end(h);
    if (fread(trailer, 1, sizeof trailer, src->f) != sizeof trailer || get_u64(trailer) != expected)
        return damaged(src, "checksum mismatch");
    rewind(src->f);
    return FM_OK;
}

/* Magic and version, then the checksum of the whole file, then the header's fields. */
static fm_status read_header(source *src, header *h)
{
    unsigned char b[HEADER_BYTES];
    if (fread(b, 1, sizeof b, src->f) != sizeof b || memcmp(b, MAGIC, 8) != 0)
        return fm_fail(src->err, FM_ERR_INPUT, "%s: not a flockmorph checkpoint", src->path);
    h->version = get_u32(b + 8);
    if (h->version != CHECKPOINT_VERSION)
        return fm_fail(src->err, FM_ERR_INPUT, "%s: checkpoint version %u; this flockmorph reads version %d: "
                       "finish the run with the flockmorph that started it, or run again without --resume",
                       src->path, h->version, CHECKPOINT_VERSION);
    fm_status st = verify_checksum(src);
    if (st == FM_OK) st = get(src, b, sizeof b);
    h->members = get_u32(b + 12);
    h->scene_hash = get_u64(b + 16), h->model_hash = get_u64(b + 24);
    h->agents = get_u64(b + 32), h->frames = get_u64(b + 40), h->layout_hash = get_u64(b + 48);
    uint64_t room = (uint64_t)(src->size - HEADER_BYTES - TRAILER_BYTES) / 8; /* the stats take frames + 2 */
    if (st == FM_OK && (h->frames < 1 || h->frames > UINT32_MAX || h->frames + 2 > room))
        return damaged(src, "impossible frame count");
    return st;
}

static fm_status check_scene(const source *src, const header *h, const fm_scene_def *def)
{
    if (h->scene_hash == scene_hash(def)) return FM_OK;
    return fm_fail(src->err, FM_ERR_INPUT, "%s: written for a different scene: the parameters of %s differ from "
                   "the run it saved; resume with the same scene file, or run again without --resume",
                   src->path, def->scene_path[0] ? def->scene_path : "this scene");
}

static fm_status open_checked(source *src, header *h, const fm_scene_def *def, const fm_store_member *members,
                              int count)
{
    struct stat file;
    fm_status checked = stat(src->path, &file) == 0 ? fm_check_input_file(src->path, "checkpoint", src->err) : FM_OK;
    if (checked != FM_OK) return checked; /* a FIFO or device there would block or never end */
    errno = 0;
    src->f = fopen(src->path, "rb");
    if (!src->f)
        return fm_fail(src->err, errno == ENOENT ? FM_ERR_INPUT : FM_ERR_IO, "%s: cannot open the checkpoint: %s%s",
                       src->path, strerror(errno), errno == ENOENT ? " (nothing to resume)" : "");
    fm_status st = read_header(src, h);
    if (st == FM_OK) st = check_scene(src, h, def); /* first: the other mode's file is another scene's */
    if (st == FM_OK && (h->members != (uint32_t)count || h->layout_hash != layout_hash(members, count)))
        return fm_fail(src->err, FM_ERR_INPUT, "%s: written by a flockmorph whose agent store differs from this "
                       "one; finish the run with that build, or run again without --resume", src->path);
    return st;
}

fm_status fm_ckpt_check(const char *path, const fm_scene_def *def, const fm_store_member *members, int count,
                        fm_error *err)
{
    source src = {NULL, path, err, 0};
    header h;
    fm_status st = open_checked(&src, &h, def, members, count);
    if (src.f) fclose(src.f);
    return st;
}

static fm_status read_stats(const source *src, const header *h, const fm_ckpt_store *c)
{
    fm_status st = FM_OK;
    for (int i = 0; i < c->stats_count && st == FM_OK; i++) st = get(src, (char *)c->run_stats + c->stats[i].offset, c->stats[i].bytes);
    if (st != FM_OK || !c->per_frame) return st;
    size_t count = (size_t)c->per_frame_width * (size_t)(h->frames - 1);
    *c->per_frame = malloc(sizeof(double) * (count ? count : 1));
    if (!*c->per_frame) return fm_fail(src->err, FM_ERR_MEMORY, "out of memory for the per-frame statistics");
    return get(src, *c->per_frame, sizeof(double) * count);
}

static fm_status read_members(const source *src, const fm_ckpt_store *c)
{
    for (int i = 0; i < c->member_count; i++) {
        const fm_store_member *mb = &c->members[i];
        uint64_t want, bytes;
        void *data = member_data(c->state, c->n, mb, &want);
        uint32_t len;
        char name[NAME_MAX_BYTES];
        fm_status st = get(src, &len, 4);
        if (st == FM_OK && len >= sizeof name) return damaged(src, "member name too long");
        if (st == FM_OK) st = get(src, name, len);
        if (st == FM_OK) st = get(src, &bytes, 8);
        if (st != FM_OK) return st;
        name[len] = 0;
        if (strcmp(name, mb->name) != 0 || bytes != want) return damaged(src, "unexpected member");
        if (bytes && (st = get(src, data, (size_t)bytes)) != FM_OK) return st;
    }
    return ftello(src->f) == src->size - TRAILER_BYTES ? FM_OK : damaged(src, "unexpected bytes after the state");
}

fm_status fm_ckpt_load(const char *path, fm_ckpt_store *c, int64_t *frames, fm_error *err)
{
    source src = {NULL, path, err, 0};
    header h = {0};
    fm_status st = open_checked(&src, &h, c->def, c->members, c->member_count);
    if (st == FM_OK && (h.agents != (uint64_t)c->n || h.model_hash != c->model_hash))
        st = fm_fail(err, FM_ERR_INPUT, "%s: written for a different model: %s differ from the run it saved (another "
                     "mesh file or TetGen version?); run again without --resume", path, c->model_what);
    if (st == FM_OK) st = read_stats(&src, &h, c);
    if (st == FM_OK) st = read_members(&src, c);
    const char *bad = st == FM_OK ? c->check(c->state) : NULL;
    if (bad) st = damaged(&src, bad);
    if (src.f) fclose(src.f);
    *frames = (int64_t)h.frames;
    return st;
}

