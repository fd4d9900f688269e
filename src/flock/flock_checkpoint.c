/* The shape flock's checkpoint: the same file as the tetra morph's (docs/resume.md) with the
 * flock's store (fm_flock_state_members), its statistics, the hash of its model and the checks of
 * restored values, handed to the checkpoint writer (world/checkpoint.h). */
#include "checkpoint.h"
#include "flock.h"

#include <string.h>

static const fm_store_member FLOCK_RUN_STATS[] = {
    FM_STORE_SCALAR(fm_flock_run_stats, run.simulate_seconds), FM_STORE_SCALAR(fm_flock_run_stats, run.output_seconds),
    FM_STORE_SCALAR(fm_flock_run_stats, tracking_frames),
};

static void hash_floats3(fm_hash *h, float *const a[3], size_t n)
{
    for (int k = 0; k < 3; k++) fm_hash_bytes(a[k], sizeof(float) * n, h);
}

/* Everything of the flock model the step reads: the samples (start, destination and its triangle
 * and barycentrics), each agent's parameters, the target's meshes, the path and the obstacles. */
static uint64_t flock_model_hash(const fm_flock_model *m)
{
    fm_hash *h = fm_hash_begin();
    if (!h) return 0;
    const size_t n = (size_t)m->n, nv = (size_t)m->target.mesh.nv;
    const fm_samples *d = &m->target.dest;
    fm_hash_bytes(&m->n, sizeof m->n, h);
    hash_floats3(h, m->start, n), hash_floats3(h, m->dest0, n);
    hash_floats3(h, m->radius, n), hash_floats3(h, m->cos_half, n), hash_floats3(h, m->weight, n);
    fm_hash_bytes(m->max_speed, sizeof(float) * n, h), fm_hash_bytes(m->max_force, sizeof(float) * n, h);
    fm_hash_bytes(d->p, sizeof(float) * 3 * n, h), fm_hash_bytes(d->bary, sizeof(float) * 3 * n, h);
    fm_hash_bytes(d->tri, sizeof(int32_t) * n, h);
    fm_hash_bytes(m->target.mesh.v, sizeof(double) * 3 * nv, h);
    fm_hash_bytes(m->target.mesh.tri, sizeof(int32_t) * 3 * (size_t)m->target.mesh.nt, h);
    if (m->target.frames) fm_hash_bytes(m->target.frames, sizeof(double) * 3 * nv * (size_t)m->def.flock.deform_frames, h);
    if (m->path.ctrl) fm_hash_bytes(m->path.ctrl, sizeof(double) * 3 * ((size_t)m->path.count + 2), h);
    fm_hash_bytes(&m->path.length, sizeof m->path.length, h);
    fm_hash_bytes(m->o1, sizeof m->o1, h), fm_hash_bytes(m->o2, sizeof m->o2, h);
    fm_hash_bytes(&m->path_time, sizeof m->path_time, h), fm_hash_bytes(&m->dt, sizeof m->dt, h);
    fm_hash_bytes(&m->steps_per_frame, sizeof m->steps_per_frame, h), fm_hash_bytes(&m->max_radius, sizeof m->max_radius, h);
    fm_hash_bytes(m->scene_lo, sizeof m->scene_lo, h), fm_hash_bytes(m->scene_hi, sizeof m->scene_hi, h);
    fm_hash_sdf(h, m->obstacles);
    return fm_hash_end(h);
}

/* The shape flock's restored values: phases in range and counted (a share of the agents, on P ranks,
 * is counted by fm_flock_dist_checkpoint_load over every rank's), a step and time that fit. */
static const char *check_state(const void *state)
{
    const fm_flock_state *s = state;
    int64_t count[4] = {0, 0, 0, 0};
    for (int64_t a = 0; a < s->slots; a++) {
        if (s->phase[a] > FM_PHASE_ARRIVED) return "agent values out of range";
        count[s->phase[a]]++;
    }
    if ((s->slots == s->n && memcmp(count, s->count, sizeof count) != 0) || s->step < 0 || !(s->time >= 0))
        return "counters inconsistent with the agents";
    return NULL;
}

/* The flock's store and statistics at `frames` frames; a shot's group has no statistics of its own
 * (stats NULL: the shot's file holds them). */
static fm_ckpt_store flock_store(const fm_flock_model *m, const fm_flock_state *s, const fm_flock_run_stats *stats,
                                 int64_t frames)
{
    return (fm_ckpt_store){.members = fm_flock_state_members, .member_count = fm_flock_state_member_count,
                           .state = (void *)s, .n = s->n, .stats = stats ? FLOCK_RUN_STATS : NULL,
                           .stats_count = stats ? (int)(sizeof FLOCK_RUN_STATS / sizeof FLOCK_RUN_STATS[0]) : 0,
                           .run_stats = (void *)stats, .per_frame = stats ? (double **)&stats->measures : NULL,
                           .per_frame_width = FM_FLOCK_MEASURES, .def = &m->def, .model_hash = flock_model_hash(m),
                           .model_what = "the samples, the path (or the obstacles)", .check = check_state,
                           .frames = frames, .piece_agents = m->def.cache_piece_agents};
}

/* The store's members as a checkpoint saves them, in id order (docs/resume.md: the file does not
 * depend on the store's order): a re-sorted store on one process is put in id order for the save
 * and back in its order after it, so the state (const) is as it was and the run goes on as one
 * that did not save. */
static fm_status save_in_id_order(const char *path, const fm_ckpt_store *c, const fm_flock_state *s, fm_error *err)
{
    fm_flock_state *moved = (fm_flock_state *)s; /* the slots move and come back */
    const int begun = fm_flock_state_id_order_begin(moved);
    const fm_status st = fm_ckpt_save(path, c, err);
    fm_flock_state_id_order_end(moved, begun);
    return st;
}

fm_status fm_flock_checkpoint_save(const char *path, const fm_flock_model *m, const fm_flock_state *s,
                                   const fm_flock_run_stats *stats, fm_error *err)
{
    const fm_ckpt_store c = flock_store(m, s, stats, stats->run.frames);
    return save_in_id_order(path, &c, s, err);
}

/* On P ranks (every rank calls it): this rank writes its agents' parts, rank 0 the rest. */
fm_status fm_flock_checkpoint_write(const char *path, const fm_flock_model *m, const fm_flock_state *s,
                                    const fm_dist *dist, const fm_flock_run_stats *stats, int64_t frames,
                                    const fm_ckpt_part *parts, int part_count, fm_error *err)
{
    const fm_ckpt_store c = fm_ckpt_on_ranks(flock_store(m, s, stats, frames), dist, parts, part_count);
    return fm_ckpt_save(path, &c, err);
}

/* What a load reads into a store: the file, the model, and the statistics or the frames. */
typedef struct flock_load {
    const char *path;
    const fm_flock_model *m;
    fm_flock_run_stats *stats; /* NULL: a shot's group */
    int64_t *frames;
    fm_error *err;
} flock_load;

/* The file into s, or with a part (P ranks) that share of the agents into s, a share's view. */
static fm_status load_into(fm_flock_state *s, const fm_ckpt_part *part, void *arg)
{
    const flock_load *l = arg;
    fm_ckpt_store c = flock_store(l->m, s, l->stats, 0);
    if (part) c.parts[0] = *part, c.part_count = 1;
    return fm_ckpt_load(l->path, &c, l->stats ? &l->stats->run.frames : l->frames, l->err);
}

/* On P ranks every rank reads its share of the agents and they go to their slabs' ranks
 * (flock_dist.c). */
static fm_status load(fm_flock_state *s, flock_load *l)
{
    if (s->dist) return fm_flock_dist_checkpoint_load(s, l->m, load_into, l, l->path, l->err);
    fm_flock_state_in_id_order(s); /* the file's agents in id order, into slots in id order with their parameters */
    return load_into(s, NULL, l);
}

fm_status fm_flock_checkpoint_load(const char *path, const fm_flock_model *m, fm_flock_state *s,
                                   fm_flock_run_stats *stats, fm_error *err)
{
    memset(stats, 0, sizeof *stats);
    flock_load l = {path, m, stats, NULL, err};
    fm_status st = load(s, &l);
    if (st != FM_OK) fm_flock_run_stats_free(stats);
    return st;
}

fm_status fm_flock_group_checkpoint_save(const char *path, const fm_flock_model *m, fm_flock_state *s, int64_t frames,
                                         fm_error *err)
{
    if (s->dist) return fm_flock_dist_checkpoint_save(path, m, s, NULL, frames, err);
    const fm_ckpt_store c = flock_store(m, s, NULL, frames);
    return save_in_id_order(path, &c, s, err);
}

fm_status fm_flock_group_checkpoint_load(const char *path, const fm_flock_model *m, fm_flock_state *s, int64_t *frames,
                                         fm_error *err)
{
    flock_load l = {path, m, NULL, frames, err};
    return load(s, &l);
}

