/* fm_step: one time step of the tetra flock morph (FM §5).
 *
 * The pipeline, in order:
 *   1. launch       agents whose launch time has come leave the source, in D1 order (eq 4)
 *   2. velocities   phase 1: V_grn = omega1 * V_g (eqs 3, 6)
 *                   [the velocity-model issue adds here: style fields V_l (eqs 5-6), the obstacle
 *                    velocity V_oa with the look-ahead test (eqs 7-8) and MDE V_la (§5.4) on a
 *                    neighbour grid rebuilt before this stage]
 *   3. integrate    phase 1 agents move; those now inside the target's bounding sphere are flagged
 *   4. homing       phase 2 agents move on their straight line (eq 9) and may arrive
 *   5. hand-out     flagged agents take the next target tet in D2 order, in agent-id order (serial)
 *   6. morph setup  each new phase-2 agent gets its correspondence and A = RS (§6)
 * Stages 2-4 and 6 run over fixed blocks of agents on OpenMP threads; every agent writes only
 * its own entries and per-block counts are combined in block order, so the result is the same
 * for any thread count. */
#include "sim.h"
#include "kernels.h"

#include <math.h>

static void launch_due_agents(const fm_model *m, fm_state *s)
{
    int64_t due = (int64_t)floor(m->launch_rate * s->time) + 1; /* agent a launches at a / rate */
    if (due > s->n) due = s->n;
    for (int64_t a = s->launched; a < due; a++) s->phase[a] = FM_PHASE_FLYING;
    s->count[FM_PHASE_WAITING] -= due - s->launched;
    s->count[FM_PHASE_FLYING] += due - s->launched;
    s->launched = FM_MAX(s->launched, due);
}

static void move_block(const fm_model *m, fm_state *s, int64_t begin, int64_t end, double t_end,
                       block_counts *bc)
{
    const fm_path_view path = {{m->key_q[0], m->key_q[1], m->key_q[2]},
                               {m->key_f[0], m->key_f[1], m->key_f[2]}, m->key_count};
    const fm_sphere_view sphere = {{m->sphere_c[0], m->sphere_c[1], m->sphere_c[2]}, m->sphere_r};
    const float speed = (float)(m->def.omega1 * m->def.speed0);
    fm_kernel_global_velocity(&path, (const float *const *)s->p, s->phase, begin, end, speed, s->v);
    bc->entered = fm_kernel_integrate_flying(s->p, (const float *const *)s->v, s->phase, begin, end,
                                             (float)m->dt, sphere, s->entered);
    bc->arrived = fm_kernel_homing(s->p, s->v, s->phase, s->target, (const float *const *)m->tgt_c,
                                   (const float *const *)s->p2, s->t2, s->tf, begin, end, t_end);
}

/* Stage 5 (FM §5.5): the k-th agent to enter phase 2 takes target slot k (D2 order). */
static void hand_out_targets(const fm_model *m, fm_state *s, const block_counts *bc, int64_t blocks,
                             double t_end)
{
    for (int64_t b = 0; b < blocks; b++) {
        if (bc[b].entered == 0) continue;
        int64_t end = FM_MIN((b + 1) * FM_BLOCK, s->n);
        for (int64_t a = b * FM_BLOCK; a < end; a++) {
            if (!s->entered[a]) continue;
            int64_t slot = s->next_slot++;
            s->target[a] = slot;
            s->phase[a] = FM_PHASE_HOMING;
            s->t2[a] = (float)t_end;
            double d2 = 0;
            for (int k = 0; k < 3; k++) {
                s->p2[k][a] = s->p[k][a];
                double d = (double)m->tgt_c[k][slot] - s->p[k][a];
                d2 += d * d;
            }
            s->tf[a] = (float)(sqrt(d2) / m->def.speed0); /* eq 9 */
        }
    }
}

static int64_t setup_morphs(const fm_model *m, fm_state *s, int64_t begin, int64_t end)
{
    int64_t fallbacks = 0;
    for (int64_t a = begin; a < end; a++) {
        if (!s->entered[a]) continue;
        const int64_t slot = s->target[a];
        float dst[12];
        for (int i = 0; i < 12; i++) dst[i] = m->tgt_f[12 * slot + i] - m->tgt_c[i % 3][slot];
        s->morph_safe[a] = (uint8_t)fm_morph_setup(m->src_rel + 12 * a, dst,
                                                   s->morph + FM_MORPH_FLOATS * a, &s->perm[a]);
        fallbacks += s->morph_safe[a];
    }
    return fallbacks;
}

void fm_step(const fm_model *m, fm_state *s)
{
    const double t_end = (double)(s->step + 1) * m->dt; /* no drift from summing dt */
    const int64_t blocks = (s->n + FM_BLOCK - 1) / FM_BLOCK;
    block_counts *bc = s->blocks;
    launch_due_agents(m, s);
#pragma omp parallel for num_threads(s->threads) schedule(static)
    for (int64_t b = 0; b < blocks; b++) {
        bc[b] = (block_counts){0, 0, 0};
        move_block(m, s, b * FM_BLOCK, FM_MIN((b + 1) * FM_BLOCK, s->n), t_end, &bc[b]);
    }
    hand_out_targets(m, s, bc, blocks, t_end);
#pragma omp parallel for num_threads(s->threads) schedule(dynamic, 1)
    for (int64_t b = 0; b < blocks; b++)
        if (bc[b].entered) bc[b].fallbacks = setup_morphs(m, s, b * FM_BLOCK, FM_MIN((b + 1) * FM_BLOCK, s->n));
    for (int64_t b = 0; b < blocks; b++) { /* combine in block order */
        s->count[FM_PHASE_FLYING] -= bc[b].entered;
        s->count[FM_PHASE_HOMING] += bc[b].entered - bc[b].arrived;
        s->count[FM_PHASE_ARRIVED] += bc[b].arrived;
        s->morph_fallbacks += bc[b].fallbacks;
    }
    s->time = t_end;
    s->step++;
}
