/* The global detour (issue 38, beyond FM §5.3): eq 7 slides a tet along an obstacle, but a tet held
 * in a concave pocket, or square against a wall, makes no progress along the path for good. A tet
 * near an obstacle whose navigation value u (the length still to go round the obstacles, onto the
 * path and along it: path_route.c) has not fallen by `progress` for `wait` seconds takes the
 * detour: its V_g becomes speed * -grad u / |grad u| instead of eq 3's f_i, until it is back on
 * the path (g < join) where the path leads on. Eqs 7-8 and the contact step still act on top, so no vertex enters an
 * obstacle. Per agent and in its own slots only: any thread count gives the same bits. Scalar
 * only: it runs for the few agents near an obstacle, the rest cost a compare. */
#ifndef FM_KERNEL_DETOUR_H
#define FM_KERNEL_DETOUR_H

#include "kernel_avoid.h"
#include "kernels.h"

#include <stdint.h>

typedef struct fm_detour_view {
    fm_sdf_view u;      /* the navigation function: length to go round the obstacles to C_T */
    fm_sdf_view g;      /* its part off the path: length onto the key-point polyline */
    fm_sdf_view d;      /* the obstacles' d_t: a detour also backs away from the surface */
    float wait;         /* seconds without progress before a detour (obstacles.detour_time) */
    float progress;     /* the fall in u that counts as progress (a grid cell) */
    float join;         /* g below which a detouring agent is back on the path */
    float near;         /* clearance d_t - R_X below which an agent is watched (k_a) */
    float speed;        /* omega1 speed0: V_g's speed */
} fm_detour_view;

/* The per-agent detour state (store slots): the smallest u since the clock was last reset (INFINITY:
 * not watched), the time it was reached, and whether the agent is on a detour. */
typedef struct fm_detour_store {
    float *best;
    float *since;
    uint8_t *on;
} fm_detour_store;

/* Flying agents on a detour: V_g = speed * the unit of -grad u / |grad u| + w grad d_t / |grad d_t|,
 * w = 1 - d_t / near (0 beyond near): the grid of u is coarse beside a concave pocket, and eq 7 takes
 * the outward part off a velocity that would collide, so a tet in contact backs away from the
 * surface as it follows u. Kept (eq 3) where both gradients vanish. */
void fm_kernel_detour_velocity(const fm_detour_view *dv, const float *const p[3], const uint8_t *phase,
                               fm_detour_store st, int64_t begin, int64_t end, float *const v[3]);

/* The clock of the flying agents, after fm_kernel_avoid filled the scratch (d_t and R_X at the start
 * of the step): an agent farther than `near` and not on a detour is not watched; a watched one whose
 * u falls by `progress` restarts its clock, and one whose clock runs past `wait` starts a detour; a
 * detour ends back on the path (g < join) where eq 3's f_i of `path` leads within 45 degrees of
 * -grad u (not where the path runs into the obstacle), or when it too makes no progress for 2 wait
 * (the path is tried again). Returns the agents on a detour after the update. */
int64_t fm_kernel_detour_track(const fm_detour_view *dv, const fm_path_view *path, fm_obstacle_scratch sc,
                               const float *const p[3], const uint8_t *phase, fm_detour_store st, int64_t begin,
                               int64_t end, double time);

#endif
