/* The ranks of a run (docs/scale-out.md): the engine's one door to MPI.
 *
 * A run launched by mpirun (or srun) has one fm_dist per process, naming its rank among P; every
 * other run has none (NULL), and every call below then acts as for P = 1: a reduction returns its
 * input, a gather copies. So the engine has no #ifdef: built without MPI (FM_MPI=OFF), dist.c has
 * the P = 1 bodies only.
 *
 * Every function is collective: all ranks call it, in the same order, or the run hangs. The
 * engine calls them only from code every rank runs in step (the step, the frame, the end). */
#ifndef FM_DIST_H
#define FM_DIST_H

#include "fm_internal.h"

#include <stdint.h>

typedef struct fm_dist fm_dist;

/* 1 when this process was started by an MPI launcher (mpirun, srun: their environment variables)
 * and the build has MPI; such a process calls fm_dist_init before anything else. */
int fm_dist_launched(void);
/* MPI_Init (threads: funneled, the OpenMP regions make no MPI calls). NULL, with err set, on
 * failure; the world communicator otherwise, also for P = 1. */
fm_dist *fm_dist_init(int *argc, char ***argv, fm_error *err);
void fm_dist_finalize(fm_dist *d);
/* Ends every rank now with `code` (a rank that cannot reach the others' next collective). */
void fm_dist_abort(const fm_dist *d, int code);

int fm_dist_rank(const fm_dist *d); /* 0 for NULL */
int fm_dist_size(const fm_dist *d); /* 1 for NULL */
int fm_dist_size_here(const fm_dist *d); /* the ranks on this machine, sharing its memory; 1 for NULL */
int fm_dist_first_here(const fm_dist *d); /* 1 on the first rank of each machine (and for NULL) */
/* Collective over this machine's ranks: the first one's `bytes` at `data` to the others (< 2 GiB). */
void fm_dist_bcast_here(const fm_dist *d, void *data, size_t bytes);

/* Memory the ranks on one machine share (POSIX shared memory, /dev/shm): read-only data that the
 * machine's first rank fills once instead of every rank holding its own copy (the model,
 * docs/scale-out.md). Collective over every rank: one segment per machine of the `bytes` its first
 * rank asks for (the others' `bytes` is ignored), its address, 64-byte aligned, in *base on each of
 * the machine's ranks (mapped read-only but on the first). A rank alone on its machine (or NULL)
 * gets a plain allocation. NULL on every rank, with the same err, when any machine's failed (a full
 * /dev/shm, a file-size limit). */
typedef struct fm_dist_shared fm_dist_shared;
fm_dist_shared *fm_dist_shared_create(const fm_dist *d, size_t bytes, void **base, fm_error *err);
/* A model's `count` arrays, at *p[i] of bytes[i] each, put in one segment the machine's ranks share:
 * the machine's first rank copies its arrays in and frees them (fm_free); every rank's *p[i] then
 * points into the segment (each 64-byte aligned). Collective as fm_dist_shared_create. On failure
 * (NULL on every rank) the first rank keeps its own arrays and the others' *p[i] are NULL. */
fm_dist_shared *fm_dist_share_arrays(const fm_dist *d, void **const *p, const size_t *bytes, int count, fm_error *err);
/* A mode's model built once a machine (fm_dist_build_shared): its struct, how to build it, and its
 * parts. */
enum { FM_DIST_MAX_ARRAYS = 32 };
typedef struct fm_dist_model_ops {
    size_t size;          /* of the model's struct, broadcast whole to the machine's other ranks */
    size_t shared_offset; /* of its fm_dist_shared * member, the segment */
    /* one process's; context: what fm_dist_build_shared was given (a shot's group: the group it
     * starts from) */
    void *(*build)(const fm_scene_def *def, const void *context, fm_progress_fn progress, void *user, fm_error *err);
    /* on the other ranks, over the broadcast struct: their own scene, the first rank's objects
     * (pointers other than the arrays) cleared */
    void (*take_scalars)(void *model, const fm_scene_def *def);
    int (*arrays)(void *model, void **p[FM_DIST_MAX_ARRAYS], size_t bytes[FM_DIST_MAX_ARRAYS]); /* of n: shared */
    fm_status (*build_replicated)(void *model, fm_error *err); /* the other ranks: their own objects */
    void (*destroy)(void *model);
} fm_dist_model_ops;
/* On P ranks: the first rank of each machine builds the model (the preparation's peak: TetGen, the
 * sampling) and puts its arrays of n in the machine's segment (fm_dist_share_arrays); the others
 * take its scalars and build only what each rank holds for itself (distance grids, paths). Where no
 * segment can be made, every rank builds its own model (rank 0 warns on stderr). Collective; a
 * failure on any rank is every rank's (the same err). One process (d NULL or P = 1): ops->build.
 * docs/scale-out.md, "One model a machine". */
void *fm_dist_build_shared(const fm_dist *d, const fm_dist_model_ops *ops, const fm_scene_def *def, const void *context,
                           fm_progress_fn progress, void *user, fm_error *err);
/* This rank's mapping (the memory goes once every rank of the machine unmapped it); NULL-safe. */
void fm_dist_shared_free(fm_dist_shared *s);

/* Element-wise sums, maxima and minima over the ranks, in place (integers: exact for any P;
 * the float min and max are exact too). */
void fm_dist_sum_i64(const fm_dist *d, int64_t *v, int count);
void fm_dist_max_i64(const fm_dist *d, int64_t *v, int count);
void fm_dist_max_f64(const fm_dist *d, double *v, int count);
void fm_dist_sum_f64(const fm_dist *d, double *v, int count); /* in MPI's order: for what no result depends on */
void fm_dist_min_f32(const fm_dist *d, float *v, int count);
void fm_dist_bcast(const fm_dist *d, void *data, size_t bytes, int root); /* a value or a path (< 2 GiB) */

/* The ranks agree on one outcome: the worst status (the largest fm_status) and, with it, err's
 * message from the lowest rank that had it, so every rank returns the same status and rank 0 can
 * print what another rank met. Returns that status (FM_OK when every rank had FM_OK). */
fm_status fm_dist_agree(const fm_dist *d, fm_status st, fm_error *err);

/* Every rank's `count` records of `size` bytes, concatenated in rank order, in *all (fm_alloc'd;
 * NULL when the total is 0) with the total in *total, on every rank. */
fm_status fm_dist_allgather(const fm_dist *d, const void *mine, int64_t count, size_t size, void **all, int64_t *total,
                            fm_error *err);
static inline fm_status fm_dist_allgather_i32(const fm_dist *d, const int32_t *mine, int64_t count, int32_t **all,
                                              int64_t *total, fm_error *err)
{
    return fm_dist_allgather(d, mine, count, sizeof(int32_t), (void **)all, total, err);
}

/* Personalised all-to-all of records of `size` bytes: send holds send_count[r] records for rank r,
 * rank after rank. *recv (fm_alloc'd, NULL when empty) gets every rank's records for this one, in
 * rank order, *recv_count of them. */
fm_status fm_dist_exchange(const fm_dist *d, const void *send, const int64_t *send_count, size_t size, void **recv,
                           int64_t *recv_count, fm_error *err);

/* Rank 0 gets every rank's records of `size` bytes, in rank order (*all fm_alloc'd there, NULL on
 * the other ranks); the other ranks' *total is 0. */
fm_status fm_dist_gather(const fm_dist *d, const void *mine, int64_t count, size_t size, void **all, int64_t *total,
                         fm_error *err);

/* A file the ranks write at once, each its own byte ranges (checkpoints: docs/resume.md): written
 * as PATH.partial with MPI-IO on P ranks (pwrite on one process) and renamed to PATH by rank 0
 * once every rank's writes reached the disk, so a file under its final name is never partial. */
typedef struct fm_dist_file fm_dist_file;
/* Collective: creates (truncates) PATH.partial. NULL on every rank, with the same err, on failure. */
fm_dist_file *fm_dist_file_open(const fm_dist *d, const char *path, fm_error *err);
/* This rank alone: n bytes at `offset`. A failure is kept for fm_dist_file_commit (and returned). */
fm_status fm_dist_file_write_at(fm_dist_file *f, uint64_t offset, const void *bytes, size_t n, fm_error *err);
/* Collective: with every rank's `st` and writes FM_OK, syncs, closes and renames PATH.partial to
 * PATH (the directory synced); otherwise removes PATH.partial. Every rank returns the same status
 * and message. Frees f. */
fm_status fm_dist_file_commit(fm_dist_file *f, fm_status st, fm_error *err);
/* Collective: the existing file at `path` (rank 0's cache, which it created) opened by every rank
 * for writes at offsets, nothing truncated or renamed. NULL on every rank, with err, on failure. */
fm_dist_file *fm_dist_file_attach(const fm_dist *d, const char *path, fm_error *err);
/* Collective: every rank's writes so far on disk (MPI_File_sync); any rank's failure, agreed. */
fm_status fm_dist_file_sync(fm_dist_file *f, fm_error *err);
/* Collective: closes an attached file (after a sync); frees f. */
fm_status fm_dist_file_detach(fm_dist_file *f, fm_error *err);

#endif
