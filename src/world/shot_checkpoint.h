/* A shot's checkpoint (docs/resume.md "Shots"): the shot's own file at PATH, a checkpoint of no
 * agents holding the shot's clock (its step, which groups started, arrived and write) and its
 * statistics, and each group's store in PATH.f<F>.g<G>, F the frames the checkpoint counts, in the
 * format of a single run's checkpoint without statistics. The group files are written first and
 * the shot's file last (each under its final name only once complete), so the shot's file always
 * names a complete set: a save cut short leaves the previous set and its file in place. */
#ifndef FM_SHOT_CHECKPOINT_H
#define FM_SHOT_CHECKPOINT_H

#include "checkpoint.h"

typedef struct fm_shot_ckpt {
    fm_ckpt_store shot; /* the shot's members and statistics (n = 0; on P ranks dist set) */
    int groups;
    void *user;         /* the shot, for the group callbacks */
    fm_status (*save_group)(void *user, int g, const char *path, int64_t frames, fm_error *err); /* collective */
    fm_status (*load_group)(void *user, int g, const char *path, int64_t *frames, fm_error *err); /* this rank */
} fm_shot_ckpt;

/* The group files, then the shot's; on success rank 0 removes the set of *saved (the frames of the
 * previous checkpoint, 0: none), which becomes c->shot.frames. Collective on P ranks. */
fm_status fm_shot_ckpt_save(const char *path, const fm_shot_ckpt *c, int64_t *saved, fm_error *err);
/* The shot's file, then each group's at the frames it names (checked to hold as many); this rank
 * alone, so the caller agrees on the outcome before any collective. */
fm_status fm_shot_ckpt_load(const char *path, fm_shot_ckpt *c, int64_t *frames, fm_error *err);
/* Every group file beside PATH (PATH.f*.g*, and their .partial), whatever its frame: after a
 * complete run, or when a new run starts over. */
void fm_shot_ckpt_remove_groups(const char *path);
/* A restored shot clock's check: NULL, or what is out of range (for fm_ckpt_store.check). ended[g]:
 * the group arrived (or bound all), at end_step[g]. */
const char *fm_shot_ckpt_check_clock(int groups, int64_t step, const int *started, const int *ended, const int *writes,
                                     const int64_t *start_step, const int64_t *end_step);
/* The shot file's model hash: the groups' parameters and agent counts. */
uint64_t fm_shot_ckpt_groups_hash(const fm_scene_def *defs, const int64_t *agents, int count);

#endif
