/* The camera of `flockmorph render` (cli_render_camera.c, docs/render.md "Camera"): the bounds the
 * renderer fits its camera and ground to, for each frame of a cache. */
#ifndef FM_CLI_RENDER_CAMERA_H
#define FM_CLI_RENDER_CAMERA_H

#include <stddef.h>
#include <stdint.h>

typedef enum cli_camera_mode {
    CLI_CAMERA_FRAME = 0,     /* each frame's own content, smoothed over about a second of frames */
    CLI_CAMERA_ANIMATION = 1, /* one box: every agent of every frame (the camera before issue 14) */
    CLI_CAMERA_SHOT = 2       /* one box: every agent of every frame and the obstacles near them */
} cli_camera_mode;

/* Static triangles (the obstacles): nv x 3 floats and nt x 3 indices. */
typedef struct cli_triangles {
    float *verts;
    uint32_t *tris;
    size_t nv, nt;
} cli_triangles;

typedef struct cli_camera {
    cli_camera_mode mode;
    uint32_t frames;
    int half_window;     /* frames on each side of the one drawn that its camera averages over */
    double (*agents)[6]; /* per frame: the finite agents' [lo hi], lo > hi when there is none */
    double (*framed)[6]; /* per frame: what the camera frames (cli_camera_finish) */
    double animation[6];
    int have_animation;  /* some frame has a finite agent */
} cli_camera;

/* For `frames` frames at frame_rate (which sets the window; not finite or <= 0: 24 frames/s). 0, or
 * an exit status (out of memory). */
int cli_camera_init(cli_camera *c, cli_camera_mode mode, uint32_t frames, double frame_rate);
void cli_camera_free(cli_camera *c);
/* Frame f's agents: count points (x y z each) of which those not finite are left out. */
void cli_camera_add_frame(cli_camera *c, uint32_t f, const float *xyz, size_t count);
/* After every frame is added: pads the agents' boxes by pad (a point cache's sphere radius) and
 * computes each frame's framed box, with the obstacles near the agents (NULL: none). */
void cli_camera_finish(cli_camera *c, double pad, const cli_triangles *obstacles);
/* The bounds of frame f's camera, or NULL when no frame has an agent to frame. */
const double *cli_camera_bounds(const cli_camera *c, uint32_t f);

#endif
