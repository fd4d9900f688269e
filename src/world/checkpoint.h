/* Checkpoints (checkpoint.c, docs/resume.md): the file that lets a run resume at a frame boundary
 * with the bytes of an uninterrupted one. The writer knows no mode: a mode hands it an
 * fm_ckpt_store with its store's member table, its statistics table, its model hash and the checks
 * of the restored values. */
#ifndef FM_CHECKPOINT_H
#define FM_CHECKPOINT_H

#include "dist.h"
#include "obstacles.h"

#include <stddef.h>
#include <stdint.h>

/* One member of a mode's agent store (or of its run statistics) that a step changes and a later
 * step reads. A per-agent array (the member is a pointer) holds n elements of `bytes` each; a
 * scalar member is `bytes` bytes of the struct itself. */
typedef struct fm_store_member {
    const char *name;
    size_t offset;   /* offsetof(the struct, member) */
    size_t bytes;    /* per agent for an array, in all for a scalar */
    int per_agent;
} fm_store_member;

/* A scalar member of struct `type`. */
#define FM_STORE_SCALAR(type, member) {#member, offsetof(type, member), sizeof(((type *)0)->member), 0}

/* Agents first … first + count − 1 of the file, taken from element `at` of the store's arrays. */
typedef struct fm_ckpt_part {
    int64_t first, count, at;
} fm_ckpt_part;

/* What one mode's checkpoint holds besides its header: the run's statistics (the scalars of the
 * `stats` table, then frames - 1 doubles per frame, if any) and the store's members. On P ranks
 * each rank writes the agents of its parts, rank 0 everything else (its statistics and scalars). */
typedef struct fm_ckpt_store {
    const fm_store_member *members;
    int member_count;
    void *state;                  /* the mode's store the members are offsets into */
    int64_t n;
    const fm_store_member *stats; /* scalars of the run's statistics, offsets into run_stats */
    int stats_count;
    void *run_stats;
    double **per_frame;           /* NULL, or the statistics' per-frame array (malloc'ed on load) */
    int per_frame_width;          /* its doubles per frame */
    const fm_scene_def *def;
    uint64_t model_hash;          /* of every model array the step reads (fm_hash_*) */
    const char *model_what;       /* what differs when the model hash does not match, for the message */
    const char *(*check)(const void *state); /* after a load: NULL, or what is out of range (none: NULL) */
    int64_t frames;               /* frames written, frame 0 included */
    int64_t piece_agents;         /* agents per checksummed piece (output.piece_agents) */
    const fm_dist *dist;          /* P ranks (every rank calls fm_ckpt_save), or NULL */
    fm_ckpt_part parts[2];        /* this rank's agents; with part_count 0, all n from element 0 */
    int part_count;
} fm_ckpt_store;

/* Writes c to `path` (as PATH.partial, fsync'ed, then renamed; the directory synced). Collective
 * on c->dist's ranks: each writes its parts' bytes at their offsets (MPI-IO), rank 0 the rest. */
fm_status fm_ckpt_save(const char *path, const fm_ckpt_store *c, fm_error *err);
/* c written by P ranks: this rank's parts (at most 2). */
fm_ckpt_store fm_ckpt_on_ranks(fm_ckpt_store c, const fm_dist *dist, const fm_ckpt_part *parts, int part_count);
/* Rank `rank`'s share of n agents cut into pieces of `piece`: the pieces [J r / P, J (r + 1) / P)
 * (as the cache's frames are shared), one part from element `first` of id-indexed arrays. */
fm_ckpt_part fm_ckpt_share(int64_t n, int64_t piece, int rank, int ranks);
/* Restores c's state and statistics (the state fresh from the mode's create) after the checks of
 * fm_ckpt_check, a check of the agent count and model hash, and c->check; *frames gets the frame
 * count the file states. With c->part_count 1 only the agents of c->parts[0] are kept (from its
 * element `at`): a rank's share; the whole file is read and checked all the same. */
fm_status fm_ckpt_load(const char *path, fm_ckpt_store *c, int64_t *frames, fm_error *err);
/* The refusal of a damaged checkpoint, `what` saying what is wrong (exit 2): for the modes' checks
 * that need every rank's share. */
fm_status fm_ckpt_damaged(const char *path, const char *what, fm_error *err);
/* Readable, undamaged (checksum), this version, the same scene parameters, the same member table. */
fm_status fm_ckpt_check(const char *path, const fm_scene_def *def, const fm_store_member *members, int count,
                        fm_error *err);

/* XXH3-64 over a mode's model arrays: begin, feed, end (NULL from begin: out of memory). */
typedef struct XXH3_state_s fm_hash;
fm_hash *fm_hash_begin(void);
void fm_hash_bytes(const void *bytes, size_t n, void *hash);
uint64_t fm_hash_end(fm_hash *hash);
void fm_hash_sdf(fm_hash *hash, const fm_obstacles *o); /* a distance grid, or "none" */

#endif
