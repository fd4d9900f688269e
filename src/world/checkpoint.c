/* Checkpoints: the state of a run at a frame boundary, so a killed or interrupted run can resume
 * and finish with the same bytes as an uninterrupted one (docs/resume.md specifies the file).
 *
 *   header   64 bytes: "FMCHKPT\0", version, member count, scene hash, model hash, agents,
 *            frames written, layout hash, 0
 *   stats    inverted_tet_frames (i64), simulate_seconds, output_seconds (f64), then the MDE
 *            fraction of frames 1 .. frames-1 (f64 each)
 *   members  for each entry of fm_state_members, in order: name length (u32), name, byte count
 *            (u64), the bytes (a per-agent array: agents x element size)
 *   trailer  XXH3-64 of every byte before it
 * Little-endian, like the cache. Hashes are XXH3-64 (libxxhash): the scene hash of the canonical
 * parameter bytes (fm_scene_def_feed), the model hash of every array the step reads from the model
 * (the tets after TetGen and subdivision, the path, the obstacle distance grids), so a resume with
 * other meshes, another TetGen or other parameters is refused instead of producing a different
 * animation.
 *
 * Both modes write this file: the tetra morph saves fm_state_members and its fm_run_stats, the shape
 * flock fm_flock_state_members and its fm_flock_run_stats (a ckpt_store says which); the scene hash
 * covers the mode, so one mode's checkpoint is refused by the other. */
#define _POSIX_C_SOURCE 200809L
#include "flock.h"
#include "sim.h"

#include <xxhash.h>

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum { CHECKPOINT_VERSION = 1, HEADER_BYTES = 64, TRAILER_BYTES = 8, NAME_MAX_BYTES = 64 };
static const char MAGIC[8] = {'F', 'M', 'C', 'H', 'K', 'P', 'T', 0};

typedef struct header {
    uint32_t version, members;
    uint64_t scene_hash, model_hash, agents, frames, layout_hash;
} header;

static void put_u32(unsigned char *p, uint32_t x) { memcpy(p, &x, 4); }
static void put_u64(unsigned char *p, uint64_t x) { memcpy(p, &x, 8); }
static uint32_t get_u32(const unsigned char *p) { uint32_t x; memcpy(&x, p, 4); return x; }
static uint64_t get_u64(const unsigned char *p) { uint64_t x; memcpy(&x, p, 8); return x; }

/* What one mode's checkpoint holds besides its header: the run's statistics (the scalars of the
 * `stats` table, then frames - 1 doubles per frame, if any) and the store's members. */
typedef struct ckpt_store {
    const fm_state_member *members;
    int member_count;
    void *state;                 /* the fm_state or fm_flock_state the members are offsets into */
    int64_t n;
    const fm_state_member *stats; /* scalars of the run's statistics, offsets into run_stats */
    int stats_count;
    void *run_stats;
    double **per_frame;          /* NULL, or the statistics' per-frame array (malloc'ed on load) */
    const fm_scene_def *def;
    uint64_t model_hash;
    int64_t frames;              /* frames written, frame 0 included */
} ckpt_store;

#define STAT(type, member) {#member, offsetof(type, member), sizeof(((type *)0)->member), 0}
/* The tetra morph's statistics (the MDE fractions follow per frame). */
static const fm_state_member RUN_STATS[] = {
    STAT(fm_run_stats, inverted_tet_frames), STAT(fm_run_stats, simulate_seconds), STAT(fm_run_stats, output_seconds),
};
static const fm_state_member FLOCK_RUN_STATS[] = {
    STAT(fm_flock_run_stats, simulate_seconds), STAT(fm_flock_run_stats, output_seconds),
    STAT(fm_flock_run_stats, tracking_frames),
};
#undef STAT

/* ---------------------------------------------------------------- hashes */

static void hash_bytes(const void *bytes, size_t n, void *state)
{
    if (n) XXH3_64bits_update((XXH3_state_t *)state, bytes, n);
}

static XXH3_state_t *hash_begin(void)
{
    XXH3_state_t *h = XXH3_createState();
    if (h) XXH3_64bits_reset(h);
    return h;
}

static uint64_t hash_end(XXH3_state_t *h)
{
    uint64_t x = XXH3_64bits_digest(h);
    XXH3_freeState(h);
    return x;
}

static uint64_t scene_hash(const fm_scene_def *def)
{
    XXH3_state_t *h = hash_begin();
    if (!h) return 0;
    fm_scene_def_feed(def, hash_bytes, h);
    return hash_end(h);
}

static void hash_sdf(XXH3_state_t *h, const fm_obstacles *o)
{
    if (!o) return hash_bytes("none", 4, h);
    fm_sdf_view v = fm_obstacles_sdf(o);
    hash_bytes(v.n, sizeof v.n, h), hash_bytes(v.origin, sizeof v.origin, h);
    hash_bytes(&v.voxel, sizeof v.voxel, h), hash_bytes(&v.far, sizeof v.far, h);
    hash_bytes(v.d, sizeof(float) * (size_t)v.n[0] * (size_t)v.n[1] * (size_t)v.n[2], h);
}

/* Everything of the model the step reads: if TetGen, the subdivision or an obstacle mesh came out
 * differently, the resumed frames would not continue the saved ones. */
static uint64_t model_hash(const fm_model *m)
{
    XXH3_state_t *h = hash_begin();
    if (!h) return 0;
    size_t n = (size_t)m->n, keys = (size_t)m->key_count;
    hash_bytes(&m->n, sizeof m->n, h);
    hash_bytes(m->src_rel, sizeof(float) * 12 * n, h);
    hash_bytes(m->tgt, sizeof(double) * 12 * n, h);
    hash_bytes(m->src_radius, sizeof(float) * n, h);
    for (int k = 0; k < 3; k++) {
        hash_bytes(m->src_c[k], sizeof(float) * n, h), hash_bytes(m->tgt_c[k], sizeof(float) * n, h);
        hash_bytes(m->key_q[k], sizeof(float) * keys, h), hash_bytes(m->key_f[k], sizeof(float) * keys, h);
    }
    hash_bytes(m->sphere_c, sizeof m->sphere_c, h), hash_bytes(&m->sphere_r, sizeof m->sphere_r, h);
    hash_bytes(m->scene_lo, sizeof m->scene_lo, h), hash_bytes(m->scene_hi, sizeof m->scene_hi, h);
    hash_bytes(&m->dt, sizeof m->dt, h), hash_bytes(&m->steps_per_frame, sizeof m->steps_per_frame, h);
    hash_bytes(&m->launch_rate, sizeof m->launch_rate, h);
    hash_sdf(h, m->obstacles), hash_sdf(h, m->target_sdf);
    return hash_end(h);
}

/* The saved members' names and sizes: a build whose store differs cannot read the file. */
static uint64_t layout_hash(const fm_state_member *members, int count)
{
    XXH3_state_t *h = hash_begin();
    if (!h) return 0;
    for (int i = 0; i < count; i++) {
        const fm_state_member *mb = &members[i];
        uint64_t bytes = mb->bytes, per_agent = (uint64_t)mb->per_agent;
        hash_bytes(mb->name, strlen(mb->name) + 1, h);
        hash_bytes(&bytes, sizeof bytes, h), hash_bytes(&per_agent, sizeof per_agent, h);
    }
    return hash_end(h);
}

/* Where a member's bytes are: the array a pointer member points at, or the member itself. */
static void *member_data(void *base, int64_t n, const fm_state_member *mb, uint64_t *bytes)
{
    char *field = (char *)base + mb->offset;
    *bytes = mb->per_agent ? (uint64_t)mb->bytes * (uint64_t)n : mb->bytes;
    if (!mb->per_agent) return field;
    void *array;
    memcpy(&array, field, sizeof array);
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
    hash_bytes(bytes, n, k->hash);
}

static void put_header(sink *k, const ckpt_store *c)
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

static void put_stats(sink *k, const ckpt_store *c)
{
    for (int i = 0; i < c->stats_count; i++) put(k, (const char *)c->run_stats + c->stats[i].offset, c->stats[i].bytes);
    if (c->per_frame) put(k, *c->per_frame, sizeof(double) * (size_t)(c->frames - 1));
}

static void put_members(sink *k, const ckpt_store *c)
{
    for (int i = 0; i < c->member_count; i++) {
        const fm_state_member *mb = &c->members[i];
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

static fm_status save_store(const char *path, const ckpt_store *c, fm_error *err)
{
    if (c->frames < 1) return fm_fail(err, FM_ERR_INTERNAL, "%s: a checkpoint needs at least frame 0", path);
    fm_output_file out;
    fm_status st = fm_output_open(&out, path, err);
    if (st != FM_OK) return st;
    sink k = {out.f, hash_begin()};
    if (!k.hash) return fm_output_discard(&out), fm_fail(err, FM_ERR_MEMORY, "out of memory");
    setvbuf(out.f, NULL, _IOFBF, 1 << 20);
    put_header(&k, c);
    put_stats(&k, c);
    put_members(&k, c);
    unsigned char trailer[TRAILER_BYTES];
    put_u64(trailer, hash_end(k.hash));
    fwrite(trailer, 1, sizeof trailer, out.f);
    st = fm_output_commit(&out, NULL, err); /* fflush, fsync, rename */
    if (st == FM_OK) sync_directory(path);
    return st;
}

/* The tetra morph's store and statistics (per-frame MDE fractions included). */
static ckpt_store tetra_store(const fm_model *m, const fm_state *s, const fm_run_stats *stats)
{
    return (ckpt_store){fm_state_members, fm_state_member_count, (void *)s, s->n, RUN_STATS,
                        (int)(sizeof RUN_STATS / sizeof RUN_STATS[0]), (void *)stats, (double **)&stats->mde_fraction,
                        &m->def, model_hash(m), stats->frames};
}

static uint64_t flock_model_hash(const fm_flock_model *m);

static ckpt_store flock_store(const fm_flock_model *m, const fm_flock_state *s, const fm_flock_run_stats *stats)
{
    return (ckpt_store){fm_flock_state_members, fm_flock_state_member_count, (void *)s, s->n, FLOCK_RUN_STATS,
                        (int)(sizeof FLOCK_RUN_STATS / sizeof FLOCK_RUN_STATS[0]), (void *)stats, NULL, &m->def,
                        flock_model_hash(m), stats->frames};
}

fm_status fm_checkpoint_save(const char *path, const fm_model *m, const fm_state *s, const fm_run_stats *stats,
                             fm_error *err)
{
    const ckpt_store c = tetra_store(m, s, stats);
    return save_store(path, &c, err);
}

fm_status fm_flock_checkpoint_save(const char *path, const fm_flock_model *m, const fm_flock_state *s,
                                   const fm_flock_run_stats *stats, fm_error *err)
{
    const ckpt_store c = flock_store(m, s, stats);
    return save_store(path, &c, err);
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
    XXH3_state_t *h = hash_begin();
    if (!h) return fm_fail(src->err, FM_ERR_MEMORY, "out of memory");
    unsigned char buf[1 << 16], trailer[TRAILER_BYTES];
    for (off_t left = size - TRAILER_BYTES; left > 0;) {
        size_t n = (size_t)FM_MIN(left, (off_t)sizeof buf);
        if (fread(buf, 1, n, src->f) != n) return hash_end(h), fm_fail(src->err, FM_ERR_IO, "%s: read failed", src->path);
        hash_bytes(buf, n, h), left -= (off_t)n;
    }
    uint64_t expected = hash_end(h);
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

/* The member table of the scene's mode. */
static const fm_state_member *mode_members(const fm_scene_def *def, int *count)
{
    int flock = def->mode == FM_MODE_SHAPE_FLOCK;
    *count = flock ? fm_flock_state_member_count : fm_state_member_count;
    return flock ? fm_flock_state_members : fm_state_members;
}

static fm_status open_checked(source *src, header *h, const fm_scene_def *def)
{
    errno = 0;
    src->f = fopen(src->path, "rb");
    if (!src->f)
        return fm_fail(src->err, errno == ENOENT ? FM_ERR_INPUT : FM_ERR_IO, "%s: cannot open the checkpoint: %s%s",
                       src->path, strerror(errno), errno == ENOENT ? " (nothing to resume)" : "");
    fm_status st = read_header(src, h);
    if (st == FM_OK) st = check_scene(src, h, def); /* first: the other mode's file is another scene's */
    int count;
    const fm_state_member *members = mode_members(def, &count);
    if (st == FM_OK && (h->members != (uint32_t)count || h->layout_hash != layout_hash(members, count)))
        return fm_fail(src->err, FM_ERR_INPUT, "%s: written by a flockmorph whose agent store differs from this "
                       "one; finish the run with that build, or run again without --resume", src->path);
    return st;
}

fm_status fm_checkpoint_check(const char *path, const fm_scene_def *def, fm_error *err)
{
    source src = {NULL, path, err, 0};
    header h;
    fm_status st = open_checked(&src, &h, def);
    if (src.f) fclose(src.f);
    return st;
}

static fm_status read_stats(const source *src, const header *h, const ckpt_store *c)
{
    fm_status st = FM_OK;
    for (int i = 0; i < c->stats_count && st == FM_OK; i++) st = get(src, (char *)c->run_stats + c->stats[i].offset, c->stats[i].bytes);
    if (st != FM_OK || !c->per_frame) return st;
    size_t count = (size_t)(h->frames - 1);
    *c->per_frame = malloc(sizeof(double) * (count ? count : 1));
    if (!*c->per_frame) return fm_fail(src->err, FM_ERR_MEMORY, "out of memory for the per-frame statistics");
    return get(src, *c->per_frame, sizeof(double) * count);
}

static fm_status read_members(const source *src, const ckpt_store *c)
{
    for (int i = 0; i < c->member_count; i++) {
        const fm_state_member *mb = &c->members[i];
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
        if ((st = get(src, data, (size_t)bytes)) != FM_OK) return st;
    }
    return ftello(src->f) == src->size - TRAILER_BYTES ? FM_OK : damaged(src, "unexpected bytes after the state");
}

/* The restored values that index arrays must be in range (a checksum proves the file is as
 * written, not that the writer was sound). */
static fm_status check_state(const source *src, const void *state)
{
    const fm_state *s = state;
    int64_t n = s->n, count[4] = {0, 0, 0, 0};
    for (int64_t a = 0; a < n; a++) {
        if (s->phase[a] > FM_PHASE_ARRIVED || s->perm[a] >= 12 || s->target[a] < -1 || s->target[a] >= n ||
            s->id[a] < 0 || s->id[a] >= n)
            return damaged(src, "agent values out of range");
        count[s->phase[a]]++;
    }
    if (memcmp(count, s->count, sizeof count) != 0 || s->launched < 0 || s->launched > n || s->next_slot < 0 ||
        s->next_slot > n || s->step < 0)
        return damaged(src, "counters inconsistent with the agents");
    return FM_OK;
}

/* The shape flock's restored values: phases in range and counted, a step and time that fit. */
static fm_status check_flock_state(const source *src, const void *state)
{
    const fm_flock_state *s = state;
    int64_t count[4] = {0, 0, 0, 0};
    for (int64_t a = 0; a < s->n; a++) {
        if (s->phase[a] > FM_PHASE_ARRIVED) return damaged(src, "agent values out of range");
        count[s->phase[a]]++;
    }
    if (memcmp(count, s->count, sizeof count) != 0 || s->step < 0 || !(s->time >= 0))
        return damaged(src, "counters inconsistent with the agents");
    return FM_OK;
}

/* Restores c (its state fresh from the mode's create) after the header, scene and model checks;
 * `check` vets the restored values. */
static fm_status load_store(const char *path, ckpt_store *c, fm_status (*check)(const source *, const void *),
                            int64_t *frames, fm_error *err)
{
    source src = {NULL, path, err, 0};
    header h = {0};
    fm_status st = open_checked(&src, &h, c->def);
    if (st == FM_OK && (h.agents != (uint64_t)c->n || h.model_hash != c->model_hash))
        st = fm_fail(err, FM_ERR_INPUT, "%s: written for a different model: %s differ from the run it saved (another "
                     "mesh file or TetGen version?); run again without --resume", path,
                     c->def->mode == FM_MODE_SHAPE_FLOCK ? "the samples, the path (or the obstacles)"
                                                         : "the tets after TetGen and subdivision (or the obstacles)");
    if (st == FM_OK) st = read_stats(&src, &h, c);
    if (st == FM_OK) st = read_members(&src, c);
    if (st == FM_OK) st = check(&src, c->state);
    if (src.f) fclose(src.f);
    *frames = (int64_t)h.frames;
    return st;
}

fm_status fm_checkpoint_load(const char *path, const fm_model *m, fm_state *s, fm_run_stats *stats, fm_error *err)
{
    memset(stats, 0, sizeof *stats);
    ckpt_store c = tetra_store(m, s, stats);
    fm_status st = load_store(path, &c, check_state, &stats->frames, err);
    if (st == FM_OK) fm_state_fill_rest(m, s); /* derived from id[], which check_state vouched for */
    if (st != FM_OK) fm_run_stats_free(stats);
    return st;
}

fm_status fm_flock_checkpoint_load(const char *path, const fm_flock_model *m, fm_flock_state *s,
                                   fm_flock_run_stats *stats, fm_error *err)
{
    memset(stats, 0, sizeof *stats);
    ckpt_store c = flock_store(m, s, stats);
    return load_store(path, &c, check_flock_state, &stats->frames, err);
}

/* ---------------------------------------------------------------- the shape flock's model */

static void hash_floats3(XXH3_state_t *h, float *const a[3], size_t n)
{
    for (int k = 0; k < 3; k++) hash_bytes(a[k], sizeof(float) * n, h);
}

/* Everything of the flock model the step reads: the samples (start, destination and its triangle
 * and barycentrics), each agent's parameters, the target's meshes, the path and the obstacles. */
static uint64_t flock_model_hash(const fm_flock_model *m)
{
    XXH3_state_t *h = hash_begin();
    if (!h) return 0;
    const size_t n = (size_t)m->n, nv = (size_t)m->target.mesh.nv;
    const fm_samples *d = &m->target.dest;
    hash_bytes(&m->n, sizeof m->n, h);
    hash_floats3(h, m->start, n), hash_floats3(h, m->dest0, n);
    hash_floats3(h, m->radius, n), hash_floats3(h, m->cos_half, n), hash_floats3(h, m->weight, n);
    hash_bytes(m->max_speed, sizeof(float) * n, h), hash_bytes(m->max_force, sizeof(float) * n, h);
    hash_bytes(d->p, sizeof(float) * 3 * n, h), hash_bytes(d->bary, sizeof(float) * 3 * n, h);
    hash_bytes(d->tri, sizeof(int32_t) * n, h);
    hash_bytes(m->target.mesh.v, sizeof(double) * 3 * nv, h);
    hash_bytes(m->target.mesh.tri, sizeof(int32_t) * 3 * (size_t)m->target.mesh.nt, h);
    if (m->target.frames) hash_bytes(m->target.frames, sizeof(double) * 3 * nv * (size_t)m->def.flock.deform_frames, h);
    if (m->path.ctrl) hash_bytes(m->path.ctrl, sizeof(double) * 3 * ((size_t)m->path.count + 2), h);
    hash_bytes(&m->path.length, sizeof m->path.length, h);
    hash_bytes(m->o1, sizeof m->o1, h), hash_bytes(m->o2, sizeof m->o2, h);
    hash_bytes(&m->path_time, sizeof m->path_time, h), hash_bytes(&m->dt, sizeof m->dt, h);
    hash_bytes(&m->steps_per_frame, sizeof m->steps_per_frame, h), hash_bytes(&m->max_radius, sizeof m->max_radius, h);
    hash_bytes(m->scene_lo, sizeof m->scene_lo, h), hash_bytes(m->scene_hi, sizeof m->scene_hi, h);
    hash_sdf(h, m->obstacles);
    return hash_end(h);
}
