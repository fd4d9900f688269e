/* The camera of `flockmorph render` (docs/render.md, "Camera").
 *
 * --camera shot (the default, issue 41): one camera for the whole shot, the box of every agent of
 * every frame grown by the obstacles near it (as below), so the travel from source to target that
 * the shot is about is seen whole, and every frame of a video is seen from the same place.
 *
 * --camera frame (issue 14): frame K's camera is fitted to what frame K shows, its agents' box
 * grown by the parts of the obstacles that lie within a quarter of the box's largest extent of it.
 * So the obstacle the flock is passing is in the picture, while a far one, or a floor larger than
 * the scene, adds at most that margin; and the box changes continuously as the flock moves (a
 * clipped box does), without jumps when an obstacle comes near.
 *
 * A box fitted to each frame alone would make the camera jitter as agents come and go at the
 * edges, so it is smoothed over the frames within about half a second on each side: the mean of
 * their boxes' centres and, on each axis, the largest of their half-extents. The window stays
 * centred: near the first and the last frame it narrows to the frames left on that side, so the
 * mean follows a flock in steady flight exactly and the first and last frames are framed as they
 * are. The largest half-extent rather than the mean keeps the box from being smaller than that
 * of any frame in the window, and the box is widened further where the frame's own agents would
 * still reach out of it (a flock that speeds up), so every agent is always in the picture. It
 * depends on the per-frame boxes alone: a PNG of frame K gets the camera frame K has in a video or
 * a sequence, whatever the range rendered.
 *
 * --camera animation: one box, every finite agent of every frame, as before issue 14. */
#include "cli_render_camera.h"
#include "flockmorph/core.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NEAR_FRACTION 0.25 /* obstacles within this fraction of the agents' largest extent are framed */

static void set_empty(double b[6])
{
    for (int k = 0; k < 3; k++) b[k] = INFINITY, b[3 + k] = -INFINITY;
}

static int is_empty(const double b[6]) { return !(b[0] <= b[3]); }

static void grow_point(double b[6], const float p[3])
{
    for (int k = 0; k < 3; k++) b[k] = fmin(b[k], p[k]), b[3 + k] = fmax(b[3 + k], p[k]);
}

int cli_camera_init(cli_camera *c, cli_camera_mode mode, uint32_t frames, double frame_rate)
{
    memset(c, 0, sizeof *c);
    c->mode = mode, c->frames = frames;
    double rate = isfinite(frame_rate) && frame_rate > 0.0 ? frame_rate : 24.0;
    c->half_window = (int)lround(fmin(0.5 * rate, 1e6));
    c->agents = malloc(sizeof *c->agents * (frames ? frames : 1));
    c->framed = malloc(sizeof *c->framed * (frames ? frames : 1));
    if (!c->agents || !c->framed)
        return fprintf(stderr, "flockmorph: error: out of memory for the camera of %u frames\n", frames), FM_ERR_MEMORY;
    for (uint32_t f = 0; f < frames; f++) set_empty(c->agents[f]), set_empty(c->framed[f]);
    set_empty(c->animation);
    return 0;
}

void cli_camera_free(cli_camera *c)
{
    free(c->agents);
    free(c->framed);
    memset(c, 0, sizeof *c);
}

void cli_camera_add_frame(cli_camera *c, uint32_t f, const float *xyz, size_t count)
{
    for (size_t i = 0; i < count; i++) {
        const float *p = xyz + 3 * i;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) continue;
        grow_point(c->agents[f], p);
        grow_point(c->animation, p);
        c->have_animation = 1;
    }
}

static void pad_box(double b[6], double pad)
{
    for (int k = 0; k < 3; k++) b[k] -= pad, b[3 + k] += pad;
}

/* Grows box by each obstacle triangle's box clipped to box padded by NEAR_FRACTION of its largest
 * extent. */
static void add_near_obstacles(double box[6], const cli_triangles *ob)
{
    double extent = 0.0, near[6], grown[6];
    for (int k = 0; k < 3; k++) extent = fmax(extent, box[3 + k] - box[k]);
    memcpy(near, box, sizeof near), memcpy(grown, box, sizeof grown);
    pad_box(near, NEAR_FRACTION * extent);
    for (size_t t = 0; t < ob->nt; t++) {
        double tri[6];
        set_empty(tri);
        for (int j = 0; j < 3; j++) grow_point(tri, ob->verts + 3 * (size_t)ob->tris[3 * t + j]);
        int inside = 1;
        for (int k = 0; k < 3; k++) {
            tri[k] = fmax(tri[k], near[k]), tri[3 + k] = fmin(tri[3 + k], near[3 + k]);
            inside &= tri[k] <= tri[3 + k];
        }
        for (int k = 0; inside && k < 3; k++) grown[k] = fmin(grown[k], tri[k]), grown[3 + k] = fmax(grown[3 + k], tri[3 + k]);
    }
    memcpy(box, grown, sizeof grown);
}

/* Frame f's framed box: the mean centre and the largest half-extents of the boxes of the centred
 * window, widened to hold frame f's own box; the animation's box when no frame in the window has
 * an agent. */
static void smooth(const cli_camera *c, uint32_t f, double out[6])
{
    double centre[3] = {0, 0, 0}, half[3] = {0, 0, 0};
    long side = c->half_window, count = 0;
    side = side < (long)f ? side : (long)f;
    side = side < (long)c->frames - 1 - (long)f ? side : (long)c->frames - 1 - (long)f;
    for (long g = (long)f - side; g <= (long)f + side; g++) {
        const double *b = c->agents[g];
        if (is_empty(b)) continue;
        for (int k = 0; k < 3; k++) centre[k] += 0.5 * (b[k] + b[3 + k]), half[k] = fmax(half[k], 0.5 * (b[3 + k] - b[k]));
        count++;
    }
    if (!count) return (void)memcpy(out, c->animation, 6 * sizeof(double));
    const double *own = c->agents[f];
    for (int k = 0; k < 3; k++) {
        double mid = centre[k] / (double)count, h = half[k];
        if (!is_empty(own)) h = fmax(h, fmax(own[3 + k] - mid, mid - own[k]));
        out[k] = mid - h, out[3 + k] = mid + h;
    }
}

void cli_camera_finish(cli_camera *c, double pad, const cli_triangles *obstacles)
{
    if (c->have_animation) pad_box(c->animation, pad);
    if (c->mode == CLI_CAMERA_SHOT && c->have_animation && obstacles && obstacles->nt)
        add_near_obstacles(c->animation, obstacles);
    if (c->mode != CLI_CAMERA_FRAME) return;
    for (uint32_t f = 0; f < c->frames; f++) {
        if (is_empty(c->agents[f])) continue;
        pad_box(c->agents[f], pad);
        if (obstacles && obstacles->nt) add_near_obstacles(c->agents[f], obstacles);
    }
    for (uint32_t f = 0; f < c->frames; f++) smooth(c, f, c->framed[f]);
}

const double *cli_camera_bounds(const cli_camera *c, uint32_t f)
{
    if (c->mode != CLI_CAMERA_FRAME || f >= c->frames) return c->have_animation ? c->animation : NULL;
    return is_empty(c->framed[f]) ? NULL : c->framed[f];
}
