/* flockmorph previews (docs/render.md): an Embree ray-cast renderer of tets and points, PNG files
 * and H.264 video through ffmpeg. */
#ifndef FLOCKMORPH_RENDER_H
#define FLOCKMORPH_RENDER_H

#include "flockmorph/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The preview renderer (docs/render.md): Embree ray casting of tets (4 triangles each) or points
 * (spheres) and of obstacle triangles (fm_renderer_set_obstacles), Lambert shading with one key light and hard shadows, a ground plane under the bounds,
 * a colour per agent (by default from a gradient over agent index; fm_render_colours), sRGB output. Every pixel is computed by one
 * thread from fixed rays, so the image does not depend on the thread count. */
typedef struct fm_render_opts {
    int width, height;      /* pixels, 1..16384 */
    double view_dir[3];     /* direction the camera looks along (any length) */
    double up[3];           /* the image's up direction (projected onto the image plane) */
    int perspective;        /* 0: orthographic; 1: perspective from a distance set by fov_deg */
    double fov_deg;         /* perspective: the bounding sphere fills this angle (default 40) */
    double margin;          /* fraction of the image left around the fitted bounds, [0, 0.5) */
    const double *bounds;   /* optional fixed [minx miny minz maxx maxy maxz] that the camera and
                               ground are fitted to (e.g. the whole animation's); NULL: the frame's */
    double world_up[3];     /* the ground lies under the bounds across world_up */
    double light_dir[3];    /* towards the key light (any length); zero: high above, from the camera's left */
    int ground;             /* 1: draw the ground plane (default), 0: background only */
    double point_radius;    /* points: sphere radius in world units; 0: fm_render_point_radius() */
    int samples;            /* samples per pixel along each axis, 1..8 (1: one ray per pixel) */
    int threads;            /* OpenMP threads; <= 0: OpenMP's default */
} fm_render_opts;

/* 960x540, the "persp" view, world up +Z, ground on, margin 0.05, 1 sample, automatic radius. */
fm_render_opts fm_default_render_opts(void);

/* Sets view_dir, up and perspective for a named view: "persp" (a 3/4 perspective view from the
 * front left, above), "front" (orthographic along +Y), "top" (along -Z) or "side" (along -X).
 * An unknown name is a usage error. */
fm_status fm_render_set_view(fm_render_opts *opts, const char *name, fm_error *err);

/* A sphere radius for points: 0.45 x the median distance from a sample of the points to their
 * nearest neighbour (so neighbouring spheres nearly touch). Non-finite points are ignored. */
double fm_render_point_radius(const float *positions, size_t n);

/* A renderer keeps its options and Embree device across frames (a video's frames share them). */
typedef struct fm_renderer fm_renderer;

fm_renderer *fm_renderer_create(const fm_render_opts *opts, fm_error *err);
void fm_renderer_destroy(fm_renderer *r);

/* Changes the bounds the camera and the ground are fitted to (as fm_render_opts.bounds; NULL: each
 * frame's own), e.g. for each frame of a video whose camera follows the flock. Bounds that are
 * not finite or not ordered are a usage error and leave the renderer as it was. */
fm_status fm_renderer_set_bounds(fm_renderer *r, const double *bounds, fm_error *err);

/* Static triangles drawn with every frame after this call: the scene's obstacles, in world space
 * (`flockmorph run` writes them to OUTDIR/obstacles.ply). verts: nv x 3 floats; tris: nt x 3
 * vertex indices. They are drawn in a light warm grey that no agent colour takes, Lambert shaded,
 * casting shadows on the agents and the ground and receiving theirs. They do not move the camera:
 * it is fitted to the bounds (fm_render_opts.bounds, or without them to the frame's agents, or
 * to the obstacles when no agent is drawn); the ground's rectangle reaches under them. The renderer
 * keeps its own copy; nt = 0 removes them.
 * A vertex that is not finite or an index >= nv is a usage error (the obstacles are unchanged). */
fm_status fm_renderer_set_obstacles(fm_renderer *r, const float *verts, size_t nv,
                                    const uint32_t *tris, size_t nt, fm_error *err);

/* Render tets (n x 12 floats) or points (n x 3 floats) into rgb: width x height x 3 bytes, rows top
 * to bottom, sRGB. Agent i (its index) gets colour i / (n - 1) of the gradient. Tets or points
 * with a non-finite coordinate are skipped. */
fm_status fm_renderer_draw_tets(fm_renderer *r, const float *verts, size_t n, unsigned char *rgb,
                                fm_error *err);
fm_status fm_renderer_draw_points(fm_renderer *r, const float *positions, size_t n,
                                  unsigned char *rgb, fm_error *err);

/* How the agents of one drawing are coloured (docs/render.md, "Colour"). A zeroed struct is
 * FM_COLOUR_INDEX, what fm_renderer_draw_tets and _points do. */
typedef enum fm_render_colour_mode {
    FM_COLOUR_INDEX = 0, /* agent i of n: i / (n - 1) of the gradient blue, teal, green, amber, coral */
    FM_COLOUR_VALUE = 1, /* values[i] on the colormap (fm_render_colormap): lo its first colour, hi its
                            last, values outside [lo, hi] clamped, NaN grey */
    FM_COLOUR_RGB = 2    /* rgb[3i .. 3i + 2]: agent i's sRGB colour, each channel in [0, 1] (clamped) */
} fm_render_colour_mode;

typedef struct fm_render_colours {
    fm_render_colour_mode mode;
    const float *values; /* FM_COLOUR_VALUE: n values, one per agent */
    double lo, hi;       /* FM_COLOUR_VALUE: the range, finite, lo < hi; keep it fixed across the
                            frames of a video so that a colour means one value throughout */
    const float *rgb;    /* FM_COLOUR_RGB: n x 3 sRGB */
} fm_render_colours;

/* As fm_renderer_draw_tets and _points, with the agents coloured as c says (NULL: by index). A
 * mode other than the three, missing values or rgb (n > 0), or a range that is not finite with
 * lo < hi is a usage error. The image does not depend on the thread count in any mode. */
fm_status fm_renderer_draw_tets_coloured(fm_renderer *r, const float *verts, size_t n,
                                         const fm_render_colours *c, unsigned char *rgb,
                                         fm_error *err);
fm_status fm_renderer_draw_points_coloured(fm_renderer *r, const float *positions, size_t n,
                                           const fm_render_colours *c, unsigned char *rgb,
                                           fm_error *err);

/* The sequential colormap of FM_COLOUR_VALUE: viridis (matplotlib's, CC0), 33 of its 256 entries
 * interpolated linearly in sRGB. u in [0, 1] (clamped; NaN gives the grey of a NaN value) from
 * dark blue-violet (0) through blue and teal to yellow (1); srgb in [0, 1]. */
void fm_render_colormap(double u, float srgb[3]);

/* The palette of `flockmorph render --color phase`: fm_phase 0 waiting blue, 1 flying orange,
 * 2 homing reddish purple, 3 arrived bluish green (Okabe and Ito's colours); any other value grey.
 * srgb in [0, 1]. */
void fm_render_phase_colour(unsigned phase, float srgb[3]);

/* Writes an 8-bit RGB image (rows top to bottom) as PNG through PATH.partial and rename(). */
fm_status fm_write_png(const unsigned char *rgb, int width, int height, const char *path,
                       fm_error *err);

/* One-call forms: create a renderer, draw, write the PNG. */
fm_status fm_render_tets_png(const float *verts, size_t n, const fm_render_opts *opts,
                             const char *path, fm_error *err);
fm_status fm_render_points_png(const float *positions, size_t n, const fm_render_opts *opts,
                               const char *path, fm_error *err);

/* Video through the ffmpeg program (Debian package ffmpeg), H.264 in MP4: raw RGB frames are piped
 * to `ffmpeg -f rawvideo -pix_fmt rgb24 -s WxH -r FPS -i - -c:v libx264 -pix_fmt yuv420p`, which
 * writes PATH.partial; finish() waits for it and renames the file to PATH. A missing ffmpeg or
 * one that fails is an I/O error that quotes its stderr; no file is left under PATH then. */
typedef struct fm_video_writer fm_video_writer;

/* width and height must be even (yuv420p); fps > 0. */
fm_video_writer *fm_video_open(const char *path, int width, int height, double fps, fm_error *err);
/* rgb: width x height x 3 bytes. */
fm_status fm_video_add_frame(fm_video_writer *v, const unsigned char *rgb, fm_error *err);
fm_status fm_video_finish(fm_video_writer *v, fm_error *err); /* frees v */
void fm_video_abort(fm_video_writer *v);                       /* frees v, removes the partial file */

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_RENDER_H */
