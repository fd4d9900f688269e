/* flockmorph render: a frame of a cache to a PNG, or a range of frames to an MP4 through ffmpeg. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "cli_colour.h"
#include "cli_render_burnin.h"
#include "cli_render_camera.h"
#include "geom.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

static const char *const USAGE_RENDER =
    "usage: flockmorph render CACHE -o FILE.png [--frame K] [options]\n"
    "       flockmorph render CACHE -o FILE.mp4 [--frames A:B[:S]] [--fps F] [options]\n"
    "       flockmorph render CACHE -o NAME.%04d.png [--frames A:B[:S]] [options]\n"
    "\n"
    "Ray casts the tets (or, for a point cache, spheres) with Embree: a key light with hard shadows,\n"
    "a ground plane, a colour per agent (--color), and the scene's obstacles (obstacles.ply beside\n"
    "the cache, which 'flockmorph run' writes) in a light warm grey. The camera frames the whole\n"
    "shot, every agent of every frame from source to target and the obstacles near them (--camera).\n"
    "The output's extension picks the format: .png renders frame K (default: the last; negative\n"
    "counts from the end); .mp4 renders frames A to B inclusive (default: all; A:, :B and a single\n"
    "K work too; A:B:S every S-th) into H.264 with the ffmpeg program, at F frames per second\n"
    "(default: the cache's frame rate).\n"
    "A .png name with one integer conversion (%d, %04d) renders the frames into a numbered PNG\n"
    "sequence, each file named with its cache frame number (out/f.0012.png).\n"
    "\n"
    "options:\n"
    "  --size WxH      image size (default 960x540; even numbers for .mp4)\n"
    "  --view V        persp (default, a 3/4 perspective view from the front left), or the\n"
    "                  orthographic front (along +Y), top (along -Z) or side (along -X)\n"
    "  --samples N     N x N rays per pixel for smoother edges (1..8, default 1)\n"
    "  --radius R      sphere radius of a point cache's agents (default: from their spacing)\n"
    "  --no-ground     leave out the ground plane\n"
    "  --camera C      shot (default): one camera fitted to every agent of every frame and the\n"
    "                  obstacles near them; frame: fitted to each frame's agents and the obstacles\n"
    "                  near them, smoothed over about a second of frames (the default before);\n"
    "                  animation: one camera fitted to every agent of every frame\n"
    "  --burn-in       write the scene's name, the frame and its time into the bottom-left corner\n"
    "  --obstacles F   draw the triangle mesh F as the obstacles (default: obstacles.ply beside\n"
    "                  the cache, if it is there)\n"
    "  --no-obstacles  leave the obstacles out\n"
    "  --color MODE    speed (default): each agent's speed on the viridis map, dark violet (slow)\n"
    "                  to yellow (fast), |velocity| or a tet centroid's motion between frames;\n"
    "                  phase: 0 waiting blue, 1 flying orange, 2 homing purple, 3 arrived green;\n"
    "                  id: a gradient over the agent id, blue (first) to coral (last)\n"
    "  --color-range LO:HI  the speeds (units/s) at the two ends of the map, one scale for all\n"
    "                  frames (default: 0 to the 99th percentile of the speeds in the frames\n"
    "                  rendered, at most 64 of them evenly spread); speeds outside are clamped\n"
    "  --threads N     rendering threads (default: all cores; the image does not depend on it)\n";

/* Options only render has; the shared parser takes CACHE, -o, --frame and --size. */
typedef struct render_args {
    cli_frame_options o;
    const char *view, *frames, *fps, *color, *color_range, *camera, *obstacles;
    long samples, threads;
    double radius;
    int no_ground, no_obstacles, burn_in;
} render_args;

static const char *const RENDER_ONLY[] = {"--view",    "--frames", "--fps",         "--samples",
                                          "--radius",  "--threads", "--color",      "--color-range",
                                          "--camera",  "--obstacles"};

static int is_render_only(const char *opt)
{
    for (size_t i = 0; i < sizeof RENDER_ONLY / sizeof RENDER_ONLY[0]; i++)
        if (!strcmp(opt, RENDER_ONLY[i])) return 1;
    return 0;
}

static int set_render_only(render_args *a, const char *opt, const char *val)
{
    if (!strcmp(opt, "--view")) a->view = val;
    else if (!strcmp(opt, "--frames")) a->frames = val;
    else if (!strcmp(opt, "--fps")) a->fps = val;
    else if (!strcmp(opt, "--color")) a->color = val;
    else if (!strcmp(opt, "--color-range")) a->color_range = val;
    else if (!strcmp(opt, "--camera")) a->camera = val;
    else if (!strcmp(opt, "--obstacles")) a->obstacles = val;
    else if (!strcmp(opt, "--samples") && cli_parse_int(val, 1, 8, &a->samples))
        return cli_usage_error(USAGE_RENDER, "--samples wants a whole number in 1..8, not '%s'", val);
    else if (!strcmp(opt, "--threads") && cli_parse_int(val, 1, 1024, &a->threads))
        return cli_usage_error(USAGE_RENDER, "--threads wants a whole number in 1..1024, not '%s'", val);
    else if (!strcmp(opt, "--radius") && cli_parse_positive(val, &a->radius))
        return cli_usage_error(USAGE_RENDER, "--radius wants a positive number, not '%s'", val);
    return 0;
}

/* Takes the render-only options out of argv and hands the rest to cli_parse_frame_options. */
static int parse_args(int argc, char **argv, render_args *a)
{
    memset(a, 0, sizeof *a);
    a->view = "persp", a->samples = 1;
    char **rest = malloc(sizeof(char *) * (size_t)(argc + 1));
    if (!rest) return fprintf(stderr, "flockmorph: error: out of memory\n"), FM_ERR_MEMORY;
    int n = 0, rc = 0;
    for (int i = 0; i < argc && !rc; i++) {
        if (!strcmp(argv[i], "--no-ground")) a->no_ground = 1;
        else if (!strcmp(argv[i], "--no-obstacles")) a->no_obstacles = 1;
        else if (!strcmp(argv[i], "--burn-in")) a->burn_in = 1;
        else if (is_render_only(argv[i]) && i + 1 < argc) rc = set_render_only(a, argv[i], argv[i + 1]), i++;
        else rest[n++] = argv[i];
    }
    rest[n] = NULL;
    if (!rc) rc = cli_parse_frame_options(n, rest, USAGE_RENDER, 0, &a->o);
    free(rest);
    if (!rc && a->camera && strcmp(a->camera, "shot") && strcmp(a->camera, "frame") && strcmp(a->camera, "animation"))
        rc = cli_usage_error(USAGE_RENDER, "--camera is shot, frame or animation, not '%s'", a->camera);
    if (!rc && a->obstacles && a->no_obstacles)
        rc = cli_usage_error(USAGE_RENDER, "%s", "--obstacles FILE and --no-obstacles contradict each other: give one");
    return rc;
}

typedef enum out_format { OUT_PNG, OUT_MP4, OUT_PNG_SEQUENCE } out_format;

/* The format from the output's extension, checked against the options that only one of them takes. */
static int check_format(const render_args *a, out_format *fmt)
{
    const char *dot = strrchr(a->o.out, '.'), *slash = strrchr(a->o.out, '/');
    const char *name = slash ? slash + 1 : a->o.out;
    if (dot && (!slash || dot > slash) && !strcasecmp(dot, ".png")) *fmt = strchr(name, '%') ? OUT_PNG_SEQUENCE : OUT_PNG;
    else if (dot && (!slash || dot > slash) && !strcasecmp(dot, ".mp4")) *fmt = OUT_MP4;
    else return cli_usage_error(USAGE_RENDER, "the output's extension picks the format, .png or .mp4: '%s' has neither", a->o.out);
    if (*fmt == OUT_PNG_SEQUENCE && cli_check_frame_pattern(name))
        return cli_usage_error(USAGE_RENDER, "a numbered PNG sequence wants a file name with exactly one integer "
                               "conversion (%%d, %%04d; %%%% for a literal %%), not '%s'", name);
    if (*fmt == OUT_PNG_SEQUENCE && (a->o.has_frame || a->fps))
        return cli_usage_error(USAGE_RENDER, "%s is a numbered sequence: it takes --frames A:B[:S], not --frame or --fps", a->o.out);
    if (*fmt == OUT_PNG && (a->frames || a->fps))
        return cli_usage_error(USAGE_RENDER, "%s renders one frame (--frame K); --frames and --fps are for .mp4", a->o.out);
    if (*fmt == OUT_MP4 && a->o.has_frame)
        return cli_usage_error(USAGE_RENDER, "%s takes a range of frames: --frames A:B, not --frame", a->o.out);
    if (*fmt == OUT_MP4 && (a->o.width % 2 || a->o.height % 2))
        return cli_usage_error(USAGE_RENDER, "an .mp4 (H.264, 4:2:0) needs an even width and height, not %s", a->o.width % 2 ? "an odd width" : "an odd height");
    return 0;
}

static int render_options(const render_args *a, fm_render_opts *ro)
{
    fm_error err = {0};
    *ro = fm_default_render_opts();
    if (fm_render_set_view(ro, a->view, &err) != FM_OK)
        return cli_usage_error(USAGE_RENDER, "--view is persp, front, top or side, not '%s'", a->view);
    ro->width = a->o.width, ro->height = a->o.height;
    ro->samples = (int)a->samples;
    ro->threads = (int)a->threads;
    ro->point_radius = a->radius;
    ro->ground = !a->no_ground;
    return 0;
}

/* ---------------------------------------------------------------- frames of the cache */

typedef struct frame_source {
    fm_cache_reader *r;
    const char *path;
    int points;   /* 1: the cache's position attribute; 0: its tet vertices */
    size_t n;
    float *data;  /* one frame: n x 12 (tets) or n x 3 (points) floats */
    uint32_t frame; /* the frame data holds */
    cli_colouring colour;
    fm_render_colours colours; /* of that frame (source_load) */
    cli_camera camera;         /* each frame's bounds (fix_camera) */
    const char *burn_in;       /* --burn-in: the scene's name; NULL without it */
    int width, height;
} frame_source;

static int is_point_cache(fm_cache_reader *r)
{
    return fm_cache_has_attr(r, FM_ATTR_POSITION) && !fm_cache_has_attr(r, FM_ATTR_TET_VERTICES);
}

static int source_open(const char *path, const cli_colour_options *colour, frame_source *s)
{
    memset(s, 0, sizeof *s);
    s->path = path;
    int rc = cli_open_cache(path, &s->r);
    if (rc) return rc;
    s->points = is_point_cache(s->r);
    s->n = fm_cache_agents(s->r);
    s->data = malloc(sizeof(float) * (s->points ? 3 : 12) * (s->n ? s->n : 1));
    if (!s->data) return fprintf(stderr, "flockmorph: error: out of memory for %zu agents\n", s->n), FM_ERR_MEMORY;
    return cli_colour_open(&s->colour, colour, s->r, path, s->points);
}

static void source_close(frame_source *s)
{
    cli_camera_free(&s->camera);
    cli_colour_free(&s->colour);
    if (s->r) fm_cache_close(s->r);
    free(s->data);
}

static int source_read(frame_source *s, uint32_t frame)
{
    fm_error err = {0};
    fm_status st = s->points ? fm_cache_read_attr(s->r, frame, FM_ATTR_POSITION, s->data, &err)
                             : fm_cache_read_frame(s->r, frame, s->data, &err);
    s->frame = frame;
    return st == FM_OK ? 0 : cli_report(&err);
}

/* A frame with a value that is not finite is refused (exit 2): it shows a simulation that ran away,
 * and a picture of what is left would hide that (issue 15). */
static int refuse_non_finite(const frame_source *s)
{
    const size_t floats = (s->points ? 3 : 12), values = floats * s->n;
    size_t bad = 0, first = 0;
    for (size_t i = 0; i < values; i++)
        if (!isfinite(s->data[i]) && !bad++) first = i;
    if (!bad) return 0;
    fprintf(stderr, "flockmorph: error: %s: frame %u holds %zu values that are not finite, the first of agent %zu: the "
            "simulation that wrote it ran away; render cannot show it (flockmorph inspect counts them)\n", s->path,
            s->frame, bad, first / floats);
    return FM_ERR_INPUT;
}

/* A frame to draw: its colours (which may read the frame before it), then its coordinates. */
static int source_load(frame_source *s, uint32_t frame)
{
    int rc = cli_colour_frame(&s->colour, frame, &s->colours);
    return rc ? rc : source_read(s, frame);
}

/* --burn-in: "<scene>  frame K  T s", T the frame's time at the cache's frame rate. */
static void burn_in(const frame_source *s, unsigned char *rgb)
{
    char text[320];
    double rate = fm_cache_frame_rate(s->r);
    int n = snprintf(text, sizeof text, "%.200s  frame %u", s->burn_in, s->frame);
    if (rate > 0 && isfinite(rate)) snprintf(text + n, sizeof text - (size_t)n, "  %.2f s", s->frame / rate);
    cli_burn_in(rgb, s->width, s->height, text);
}

/* Draws the frame source_load read, coloured as --color says, with that frame's camera. */
static int source_draw(frame_source *s, fm_renderer *rr, unsigned char *rgb)
{
    int rc = refuse_non_finite(s);
    if (rc) return rc;
    fm_error err = {0};
    if (fm_renderer_set_bounds(rr, cli_camera_bounds(&s->camera, s->frame), &err) != FM_OK) return cli_report(&err);
    fm_status st = s->points ? fm_renderer_draw_points_coloured(rr, s->data, s->n, &s->colours, rgb, &err)
                             : fm_renderer_draw_tets_coloured(rr, s->data, s->n, &s->colours, rgb, &err);
    if (st == FM_OK && s->burn_in) burn_in(s, rgb);
    return st == FM_OK ? 0 : cli_report(&err);
}

/* The cameras of every frame (cli_render_camera.c) from every frame's agents, and for points one
 * sphere radius for all frames. */
static int fix_camera(frame_source *s, const render_args *a, const cli_triangles *obstacles, fm_render_opts *ro)
{
    cli_camera_mode mode = !a->camera || !strcmp(a->camera, "shot") ? CLI_CAMERA_SHOT
                           : !strcmp(a->camera, "animation") ? CLI_CAMERA_ANIMATION : CLI_CAMERA_FRAME;
    uint32_t frames = fm_cache_frames(s->r);
    int rc = cli_camera_init(&s->camera, mode, frames, fm_cache_frame_rate(s->r));
    for (uint32_t f = 0; f < frames && !rc; f++)
        if (!(rc = source_read(s, f))) cli_camera_add_frame(&s->camera, f, s->data, (s->points ? 1 : 4) * s->n);
    if (rc || !s->camera.have_animation) return rc;
    if (s->points && !(ro->point_radius > 0.0)) {
        if ((rc = source_read(s, frames - 1))) return rc; /* the formed shape */
        ro->point_radius = fm_render_point_radius(s->data, s->n);
    }
    cli_camera_finish(&s->camera, s->points ? ro->point_radius : 0.0, obstacles);
    return 0;
}

/* ---------------------------------------------------------------- obstacles */

/* The mesh as the renderer's triangles (floats, unsigned indices). */
static int take_triangles(const fm_mesh *m, cli_triangles *t)
{
    t->verts = malloc(3 * sizeof(float) * (size_t)(m->nv ? m->nv : 1));
    t->tris = malloc(3 * sizeof(uint32_t) * (size_t)(m->nt ? m->nt : 1));
    if (!t->verts || !t->tris) return fprintf(stderr, "flockmorph: error: out of memory for the obstacles\n"), FM_ERR_MEMORY;
    for (int64_t i = 0; i < 3 * m->nv; i++) t->verts[i] = (float)m->v[i];
    for (int64_t i = 0; i < 3 * m->nt; i++) t->tris[i] = (uint32_t)m->tri[i];
    t->nv = (size_t)m->nv, t->nt = (size_t)m->nt;
    return 0;
}

/* The obstacles to draw: --obstacles FILE, or else obstacles.ply beside the cache when it is
 * there (a cache without one draws none, silently); none with --no-obstacles. A file that cannot
 * be read is an input error naming it (exit 2). */
static int load_obstacles(const render_args *a, cli_triangles *t)
{
    memset(t, 0, sizeof *t);
    if (a->no_obstacles) return 0;
    fm_mesh m;
    char path[FM_PATH_MAX + 32];
    int rc = cli_cache_obstacles(a->o.cache, a->obstacles, &m, path);
    if (!rc && path[0]) rc = take_triangles(&m, t);
    fm_mesh_free(&m);
    return rc;
}

static void free_triangles(cli_triangles *t)
{
    free(t->verts);
    free(t->tris);
}

/* ---------------------------------------------------------------- PNG and MP4 */

static int render_png(frame_source *s, fm_renderer *rr, const render_args *a, unsigned char *rgb)
{
    uint32_t frame;
    int rc = cli_pick_frame(s->path, fm_cache_frames(s->r), a->o.has_frame ? a->o.frame : -1, &frame);
    if (!rc) rc = cli_colour_fix_scale(&s->colour, frame, frame, 1);
    if (!rc) rc = source_load(s, frame);
    double t0 = cli_seconds();
    if (!rc) rc = source_draw(s, rr, rgb);
    double ms = 1e3 * (cli_seconds() - t0);
    fm_error err = {0};
    if (!rc && fm_write_png(rgb, a->o.width, a->o.height, a->o.out, &err) != FM_OK) rc = cli_report(&err);
    if (!rc) printf("frame %u of %s -> %s (%.0f ms)\n", frame, s->path, a->o.out, ms);
    return rc;
}

static int frames_per_second(const render_args *a, const frame_source *s, double *fps)
{
    *fps = fm_cache_frame_rate(s->r);
    if (a->fps && cli_parse_positive(a->fps, fps))
        return cli_usage_error(USAGE_RENDER, "--fps wants a positive number, not '%s'", a->fps);
    if (!(*fps > 0.0 && *fps <= 1000.0)) {
        fprintf(stderr, "flockmorph: error: %g frames per second is outside (0, 1000]; give --fps\n", *fps);
        return FM_ERR_USAGE;
    }
    return 0;
}

/* Where render_frames puts each image: the video, or a PNG named by the pattern. */
typedef struct frame_sink {
    fm_video_writer *video;
    const char *pattern; /* PNG sequence: -o with its frame conversion */
    int width, height;
} frame_sink;

static int sink_add(const frame_sink *k, uint32_t frame, const unsigned char *rgb)
{
    fm_error err = {0};
    char path[FM_PATH_MAX];
    if (k->video) return fm_video_add_frame(k->video, rgb, &err) == FM_OK ? 0 : cli_report(&err);
    if (cli_frame_name(path, sizeof path, k->pattern, (long)frame))
        return fprintf(stderr, "flockmorph: error: -o %s: the name of frame %u is too long\n", k->pattern, frame), FM_ERR_USAGE;
    return fm_write_png(rgb, k->width, k->height, path, &err) == FM_OK ? 0 : cli_report(&err);
}

/* Frames first, first + step, ... last into the sink, with progress on a terminal; *drawing the
 * seconds spent ray casting. */
static int render_frames(frame_source *s, fm_renderer *rr, const frame_sink *k, uint32_t first, uint32_t last,
                         uint32_t step, unsigned char *rgb, double *drawing)
{
    int rc = 0, progress = isatty(STDERR_FILENO);
    uint32_t count = (last - first) / step + 1;
    *drawing = 0.0;
    if ((rc = cli_colour_fix_scale(&s->colour, first, last, step))) return rc;
    for (uint32_t i = 0; i < count && !rc; i++) {
        uint32_t f = first + i * step;
        if (progress) fprintf(stderr, "\rrender: frame %u (%u of %u)", f, i + 1, count);
        double t = cli_seconds();
        if (!(rc = source_load(s, f)) && !(rc = source_draw(s, rr, rgb))) {
            *drawing += cli_seconds() - t;
            rc = sink_add(k, f, rgb);
        }
    }
    if (progress) fprintf(stderr, "\n");
    return rc;
}

/* --frames (default every frame) against the cache. */
static int frame_range(const render_args *a, const frame_source *s, uint32_t *first, uint32_t *last, uint32_t *step)
{
    cli_frame_range range;
    if (cli_parse_frame_range(a->frames ? a->frames : ":", &range))
        return cli_usage_error(USAGE_RENDER, "--frames wants A:B, A:, :B or K (whole numbers), optionally with "
                               ":S (a stride of at least 1), not '%s'", a->frames);
    *step = (uint32_t)range.step;
    return cli_resolve_frame_range(s->path, fm_cache_frames(s->r), &range, first, last);
}

static int render_png_sequence(frame_source *s, fm_renderer *rr, const render_args *a, unsigned char *rgb)
{
    uint32_t first = 0, last = 0, step = 1;
    double drawing, t0 = cli_seconds();
    frame_sink k = {NULL, a->o.out, a->o.width, a->o.height};
    int rc = frame_range(a, s, &first, &last, &step);
    if (!rc) rc = render_frames(s, rr, &k, first, last, step, rgb, &drawing);
    if (rc) return rc;
    uint32_t count = (last - first) / step + 1;
    char name[FM_PATH_MAX];
    cli_frame_name(name, sizeof name, a->o.out, (long)first);
    printf("frames %u..%u step %u of %s -> %s ... (%u PNGs; %.0f ms per frame rendering, %.1f s in all)\n", first, last,
           step, s->path, name, count, 1e3 * drawing / count, cli_seconds() - t0);
    return 0;
}

static int render_mp4(frame_source *s, fm_renderer *rr, const render_args *a, unsigned char *rgb)
{
    uint32_t first = 0, last = 0, step = 1;
    double fps, drawing, t0 = cli_seconds();
    int rc = frame_range(a, s, &first, &last, &step);
    if (!rc) rc = frames_per_second(a, s, &fps);
    if (rc) return rc;
    fm_error err = {0};
    frame_sink k = {fm_video_open(a->o.out, a->o.width, a->o.height, fps, &err), NULL, 0, 0};
    if (!k.video) return cli_report(&err);
    rc = render_frames(s, rr, &k, first, last, step, rgb, &drawing);
    if (rc) return fm_video_abort(k.video), rc;
    if (fm_video_finish(k.video, &err) != FM_OK) return cli_report(&err);
    uint32_t count = (last - first) / step + 1;
    printf("frames %u..%u of %s -> %s (%u frames at %g fps; %.0f ms per frame rendering, %.1f s in all)\n",
           first, last, s->path, a->o.out, count, fps, 1e3 * drawing / count, cli_seconds() - t0);
    return 0;
}

int cli_render(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_RENDER), 0;
    render_args a;
    out_format fmt = OUT_PNG;
    fm_render_opts ro;
    cli_colour_options colour;
    int rc = parse_args(argc, argv, &a);
    if (!rc) rc = cli_colour_parse(a.color, a.color_range, USAGE_RENDER, &colour);
    if (!rc) rc = check_format(&a, &fmt);
    if (!rc) rc = render_options(&a, &ro);
    if (rc) return rc;

    frame_source s = {0};
    cli_triangles obstacles = {0};
    fm_error err = {0};
    fm_renderer *rr = NULL;
    unsigned char *rgb = malloc(3 * (size_t)ro.width * (size_t)ro.height);
    if (!rgb) rc = (fprintf(stderr, "flockmorph: error: out of memory for the image\n"), FM_ERR_MEMORY);
    if (!rc) rc = source_open(a.o.cache, &colour, &s);
    char scene[256];
    if (!rc && a.burn_in) cli_burn_in_scene(a.o.cache, scene, sizeof scene), s.burn_in = scene;
    s.width = ro.width, s.height = ro.height;
    if (!rc) rc = load_obstacles(&a, &obstacles);
    if (!rc) rc = fix_camera(&s, &a, &obstacles, &ro);
    if (!rc && !(rr = fm_renderer_create(&ro, &err))) rc = cli_report(&err);
    if (!rc && fm_renderer_set_obstacles(rr, obstacles.verts, obstacles.nv, obstacles.tris, obstacles.nt, &err) != FM_OK)
        rc = cli_report(&err);
    if (!rc) rc = fmt == OUT_PNG ? render_png(&s, rr, &a, rgb)
                  : fmt == OUT_MP4 ? render_mp4(&s, rr, &a, rgb) : render_png_sequence(&s, rr, &a, rgb);
    fm_renderer_destroy(rr);
    source_close(&s);
    free_triangles(&obstacles);
    free(rgb);
    return rc;
}
