/* The tetra morph's checkpoint (docs/resume.md): its store's members (fm_morph_state_members), its
 * statistics with the per-frame MDE fractions, the hash of its model and the checks of restored
 * values, handed to the checkpoint writer (world/checkpoint.h). */
#include "checkpoint.h"
#include "morph.h"

#include <string.h>

/* The tetra morph's statistics (the MDE fractions follow per frame). */
static const fm_store_member RUN_STATS[] = {
    FM_STORE_SCALAR(fm_morph_run_stats, inverted_tet_frames), FM_STORE_SCALAR(fm_morph_run_stats, run.simulate_seconds), FM_STORE_SCALAR(fm_morph_run_stats, run.output_seconds),
    FM_STORE_SCALAR(fm_morph_run_stats, min_vertex_clearance),
};

/* Everything of the model the step reads: if TetGen, the subdivision or an obstacle mesh came out
 * differently, the resumed frames would not continue the saved ones. */
static uint64_t model_hash(const fm_morph_model *m)
{
    fm_hash *h = fm_hash_begin();
    if (!h) return 0;
    size_t n = (size_t)m->n, keys = (size_t)m->key_count;
    fm_hash_bytes(&m->n, sizeof m->n, h);
    fm_hash_bytes(m->src_rel, sizeof(float) * 12 * n, h);
    fm_hash_bytes(m->tgt_f, sizeof(float) * 12 * n, h);
    fm_hash_bytes(m->src_radius, sizeof(float) * n, h);
    for (int k = 0; k < 3; k++) {
        fm_hash_bytes(m->src_c[k], sizeof(float) * n, h), fm_hash_bytes(m->tgt_c[k], sizeof(float) * n, h);
        fm_hash_bytes(m->key_q[k], sizeof(float) * keys, h), fm_hash_bytes(m->key_f[k], sizeof(float) * keys, h);
    }
    fm_hash_bytes(m->sphere_c, sizeof m->sphere_c, h), fm_hash_bytes(&m->sphere_r, sizeof m->sphere_r, h);
    fm_hash_bytes(m->scene_lo, sizeof m->scene_lo, h), fm_hash_bytes(m->scene_hi, sizeof m->scene_hi, h);
    fm_hash_bytes(&m->dt, sizeof m->dt, h), fm_hash_bytes(&m->steps_per_frame, sizeof m->steps_per_frame, h);
    fm_hash_bytes(&m->launch_rate, sizeof m->launch_rate, h);
    fm_hash_sdf(h, m->obstacles), fm_hash_sdf(h, m->target_sdf);
    return fm_hash_end(h);
}

/* The restored values that index arrays must be in range (a checksum proves the file is as
 * written, not that the writer was sound). */
static const char *check_state(const void *state)
{
    const fm_morph_state *s = state;
    int64_t n = s->n, count[4] = {0, 0, 0, 0};
    for (int64_t a = 0; a < n; a++) {
        if (s->phase[a] > FM_PHASE_ARRIVED || s->perm[a] >= 12 || s->target[a] < -1 || s->target[a] >= n ||
            s->id[a] < 0 || s->id[a] >= n)
            return "agent values out of range";
        count[s->phase[a]]++;
    }
    if (memcmp(count, s->count, sizeof count) != 0 || s->launched < 0 || s->launched > n || s->next_slot < 0 ||
        s->next_slot > n || s->step < 0)
        return "counters inconsistent with the agents";
    return NULL;
}

/* The tetra morph's store and statistics (per-frame MDE fractions included) at `frames` frames;
 * a shot's group has no statistics of its own (stats NULL: the shot's file holds them). */
static fm_ckpt_store tetra_store(const fm_morph_model *m, const fm_morph_state *s, const fm_morph_run_stats *stats,
                                 int64_t frames)
{
    return (fm_ckpt_store){.members = fm_morph_state_members, .member_count = fm_morph_state_member_count,
                           .state = (void *)s, .n = s->n, .stats = stats ? RUN_STATS : NULL,
                           .stats_count = stats ? (int)(sizeof RUN_STATS / sizeof RUN_STATS[0]) : 0,
                           .run_stats = (void *)stats, .per_frame = stats ? (double **)&stats->mde_fraction : NULL,
                           .per_frame_width = 1, .def = &m->def, .model_hash = model_hash(m),
                           .model_what = "the tets after TetGen and subdivision (or the obstacles)",
                           .check = check_state, .frames = frames, .piece_agents = m->def.cache_piece_agents};
}

fm_status fm_morph_checkpoint_save(const char *path, const fm_morph_model *m, const fm_morph_state *s, const fm_morph_run_stats *stats,
                             fm_error *err)
{
    const fm_ckpt_store c = tetra_store(m, s, stats, stats->run.frames);
    return fm_ckpt_save(path, &c, err);
}

/* On P ranks (every rank calls it): this rank writes its agents' parts, rank 0 the rest. */
fm_status fm_morph_checkpoint_write(const char *path, const fm_morph_model *m, const fm_morph_state *s,
                                    const fm_morph_run_stats *stats, int64_t frames, const fm_ckpt_part *parts,
                                    int part_count, fm_error *err)
{
    const fm_ckpt_store c = fm_ckpt_on_ranks(tetra_store(m, s, stats, frames), s->dist, parts, part_count);
    return fm_ckpt_save(path, &c, err);
}

/* Every rank reads the whole store (on P ranks the next reserve or adopt makes it the rank's). */
static fm_status load_store(const char *path, const fm_morph_model *m, fm_morph_state *s, fm_morph_run_stats *stats,
                            int64_t *frames, fm_error *err)
{
    fm_status st = fm_morph_state_hold_all(s, err);
    fm_ckpt_store c = tetra_store(m, s, stats, 0);
    if (st == FM_OK) st = fm_ckpt_load(path, &c, frames, err);
    if (st == FM_OK) fm_morph_state_fill_rest(m, s); /* derived from id[], which check_state vouched for */
    return st;
}

fm_status fm_morph_checkpoint_load(const char *path, const fm_morph_model *m, fm_morph_state *s, fm_morph_run_stats *stats, fm_error *err)
{
    memset(stats, 0, sizeof *stats);
    fm_status st = load_store(path, m, s, stats, &stats->run.frames, err);
    if (st != FM_OK) fm_morph_run_stats_free(stats);
    return st;
}

fm_status fm_morph_group_checkpoint_save(const char *path, const fm_morph_model *m, fm_morph_state *s, int64_t frames,
                                         fm_error *err)
{
    if (s->dist) return fm_morph_dist_checkpoint_save(path, m, s, NULL, frames, err);
    const fm_ckpt_store c = tetra_store(m, s, NULL, frames);
    return fm_ckpt_save(path, &c, err);
}

fm_status fm_morph_group_checkpoint_load(const char *path, const fm_morph_model *m, fm_morph_state *s, int64_t *frames,
                                         fm_error *err)
{
    return load_store(path, m, s, NULL, frames, err);
}

