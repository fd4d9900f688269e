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
    if (m->motion) fm_morph_motion_hash(m->motion, h); /* the sequence's meshes and the binding */
    return fm_hash_end(h);
}

/* The restored values of slots [0, count) that index arrays must be in range (a checksum proves the
 * file is as written, not that the writer was sound), their phases counted into count_out. */
static const char *check_agents(const fm_morph_state *s, int64_t count, int64_t count_out[4])
{
    const int64_t n = s->n;
    for (int64_t a = 0; a < count; a++) {
        if (s->phase[a] > FM_PHASE_ARRIVED || s->perm[a] >= 12 || s->target[a] < -1 || s->target[a] >= n ||
            s->id[a] < 0 || s->id[a] >= n)
            return "agent values out of range";
        count_out[s->phase[a]]++;
    }
    return NULL;
}

/* The counters against every agent's phase (count: summed over the ranks' shares on P ranks). */
static const char *check_counters(const fm_morph_state *s, const int64_t count[4])
{
    if (memcmp(count, s->count, sizeof s->count) != 0 || s->launched < 0 || s->launched > s->n || s->next_slot < 0 ||
        s->next_slot > s->n || s->step < 0 || s->active_begin < 0 || s->active_begin > s->active_end ||
        s->active_end > s->launched)
        return "counters inconsistent with the agents";
    return NULL;
}

static const char *check_state(const void *state)
{
    const fm_morph_state *s = state;
    int64_t count[4] = {0, 0, 0, 0};
    const char *bad = check_agents(s, s->n, count);
    return bad ? bad : check_counters(s, count);
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

/* On P ranks: every rank reads the file, keeping its share of the slots (fm_ckpt_share, as the ranks
 * wrote them) in slots [0, share); the phases are counted over every rank's share, and the launched
 * agents go to the ranks whose slabs hold them (fm_morph_dist_adopt). */
static fm_status load_share(const char *path, const fm_morph_model *m, fm_morph_state *s, fm_morph_run_stats *stats,
                            int64_t *frames, fm_error *err)
{
    fm_ckpt_part part = fm_ckpt_share(s->n, m->def.cache_piece_agents, fm_dist_rank(s->dist), fm_dist_size(s->dist));
    part.at = 0; /* the share's first slot to slot 0 */
    fm_ckpt_store c = tetra_store(m, s, stats, 0);
    c.parts[0] = part, c.part_count = 1, c.check = NULL; /* the share's check is below: it needs every rank */
    fm_status st = fm_morph_state_reserve(s, part.count, err);
    if (st == FM_OK) st = fm_ckpt_load(path, &c, frames, err);
    int64_t count[4] = {0, 0, 0, 0};
    const char *bad = st == FM_OK ? check_agents(s, part.count, count) : NULL;
    if ((st = fm_dist_agree(s->dist, bad ? fm_ckpt_damaged(path, bad, err) : st, err)) != FM_OK) return st;
    fm_dist_sum_i64(s->dist, count, 4); /* every rank then knows the same */
    if ((bad = check_counters(s, count))) return fm_ckpt_damaged(path, bad, err);
    return fm_morph_dist_adopt(m, s, part.first, part.count, err);
}

/* The file into the store: on one process all of it; on P ranks this rank's slab's agents. */
static fm_status load_store(const char *path, const fm_morph_model *m, fm_morph_state *s, fm_morph_run_stats *stats,
                            int64_t *frames, fm_error *err)
{
    if (s->dist) return load_share(path, m, s, stats, frames, err);
    fm_ckpt_store c = tetra_store(m, s, stats, 0);
    fm_status st = fm_ckpt_load(path, &c, frames, err);
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

