/* Obstacle avoidance (FM §5.3, eqs 7-8) over a signed distance grid, refined near the surface by
 * an exact distance callback (Embree in the engine). */
#ifndef FM_KERNEL_AVOID_H
#define FM_KERNEL_AVOID_H

#include "kernel_sdf.h"

#include <stdint.h>

typedef struct fm_obstacle_view {
    fm_sdf_view sdf;      /* d_t: signed distance to the obstacles, negative inside */
    float k_a;            /* influence range of eq 7 */
    float speed0;
    /* Exact signed distance and outward normal, used where |d_t| < exact_band (the grid is too
     * coarse there); NULL to use the grid everywhere. Must be thread-safe. */
    double (*exact)(const void *ctx, const double p[3], double normal[3]);
    const void *exact_ctx;
    float exact_band;
    float up[3];          /* the scene's unit up direction: head-on agents are turned round an
                             obstacle in the plane normal to it */
} fm_obstacle_view;

/* The tets' bounding radius R_X at a given moment: rest radius times the launch shrink. */
typedef struct fm_radius_view {
    const float *rest;    /* per store slot: the largest distance from the tet's centroid to a vertex, at rest */
    const int32_t *id;    /* agent id of each store slot (the store is re-sorted): its launch time */
    float shrink;         /* FM §6 shrink factor and its duration */
    float shrink_time;
    double launch_rate;   /* agent id i launched at i / launch_rate */
} fm_radius_view;

/* Per-agent scratch that fm_kernel_avoid fills for fm_kernel_contact in the same step (the agents
 * have not moved in between): the grid's d_t at the centroid and R_X. */
typedef struct fm_obstacle_scratch {
    float *d_grid;
    float *radius;
} fm_obstacle_scratch;

/* d_t and its unit gradient at (x, y, z): the grid, or the exact callback near the surface. */
float fm_obstacle_distance(const fm_obstacle_view *o, float x, float y, float z, float g[3]);

/* FM eq 8 for agents a in [begin, end) with phase[a] == phase_sel: with V_grn = v(a), if
 * d_t(x + V_grn dt) < R_X the velocity becomes V_oa of eq 7, else it stays V_grn. Returns the
 * smallest clearance d_t(x) - R_X over those agents (INFINITY if none). */
float fm_kernel_avoid(const fm_obstacle_view *o, const fm_radius_view *r, const float *const p[3],
                      float *const v[3], const uint8_t *phase, uint8_t phase_sel, int64_t begin,
                      int64_t end, double time, float dt, fm_obstacle_scratch scratch);
/* The scalar reference twin: the look-ahead sampled for every agent, however far from the
 * obstacles (fm_kernel_avoid skips it where it cannot collide; tests compare the two). */
float fm_kernel_avoid_ref(const fm_obstacle_view *o, const fm_radius_view *r, const float *const p[3],
                          float *const v[3], const uint8_t *phase, uint8_t phase_sel, int64_t begin,
                          int64_t end, double time, float dt);

/* Contact (beyond the paper): after V_la is added (eq 8), an agent whose tet would end the step
 * inside an obstacle (d_t(x + v dt) < R_X) is turned so that it ends the step at d_t = R_X,
 * along grad d_t at that end point (up to three times, for concave corners), and if that does
 * not clear it, its step is shortened (down to none: it is clear where it stands). Eq 7 slides along the surface
 * at the agent's position, which a concave corner or an MDE push can still carry into the
 * obstacle. */
void fm_kernel_contact(const fm_obstacle_view *o, fm_obstacle_scratch scratch, const float *const p[3],
                       float *const v[3], const uint8_t *phase, uint8_t phase_sel, int64_t begin,
                       int64_t end, float dt);

#endif
