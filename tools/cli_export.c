/* flockmorph export: frames of a cache as PLY, OBJ, VTK (.vtu + .pvd) or OpenVDB points, one file
 * per frame, or as one point cache (PC2, MDD) holding them all (docs/export.md). Frames are
 * written in parallel, each thread a contiguous block of frames with its own cache reader; every
 * file depends only on its frame, not on the threads. A point cache is written in frame order by
 * one thread. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "export.h"
#include "geom.h"

#include <limits.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *const USAGE_EXPORT =
    "usage: flockmorph export CACHE --format ply|obj|vtk|vdb [--frames A:B[:S]] -o DIR [options]\n"
    "       flockmorph export CACHE -o FILE.ply|FILE.obj|FILE.vtu|FILE.vdb [--frame K] [options]\n"
    "       flockmorph export CACHE [--format pc2|mdd] -o FILE.pc2|FILE.mdd [--frames A:B[:S]]\n"
    "\n"
    "The first form writes one file per frame, DIR/<cache name>_<frame, 5 digits>.<ext>\n"
    "(frames_00012.ply; ext is vtu for vtk), and for vtk also DIR/<cache name>.pvd, which lists\n"
    "the frames with their times for ParaView. The second writes frame K (default: the last;\n"
    "negative counts from the end) to FILE in the format of its extension. The third writes\n"
    "every frame of the range into one point cache for Blender's Mesh Cache modifier, Maya,\n"
    "3ds Max or Cinema 4D: a tet's 4 vertices, or a flock's agent positions, per frame.\n"
    "\n"
    "Tets become 4 triangles each (PLY: per vertex its velocity v and an id unique to it, 4 x the\n"
    "tet's id + the vertex; per face the tet's agent_id and phase), VTK_TETRA cells with cell data\n"
    "agent_id, velocity and phase and point data id (VTK), or points at their centroids (VDB).\n"
    "Points carry Houdini's attributes v, orient (x, y, z, w), pscale, age, id and phase in PLY\n"
    "and VDB, and id, velocity, orient and phase in VTK. A shot's cache adds group to each. VTK's\n"
    "data are zlib-compressed as VTK writes them.\n"
    "\n"
    "options:\n"
    "  --frames A:B   frames A to B inclusive; A: to the last, :B from the first, K just one;\n"
    "                 negative numbers count from the end (-1 is the last); default: every frame;\n"
    "                 A:B:S every S-th frame from A (::2 every other frame)\n"
    "  --voxel SIZE   VDB voxel size in the file's units (default: from the point density)\n"
    "  --up z|y       y: turn Z-up into Y-up (Houdini, Maya): (x, y, z) -> (x, z, -y), also the\n"
    "                 velocities and orientations; default z (flockmorph's and Blender's axes)\n"
    "  --scale S      multiply positions, tet vertices, velocities, pscale and the obstacles by S\n"
    "                 (1e-6 to 1e6, after --up; default 1)\n"
    "  --preset P     houdini: --up y --name '<cache name>.%04d.<ext>' --start 1001;\n"
    "                 maya: --up y --name '<cache name>.%04d.<ext>' --start 1;\n"
    "                 blender: --up z --start 1. A flag given as well wins over the preset's\n"
    "  --name PAT     sequence file names from a pattern with one %d (frames.%04d.ply)\n"
    "  --start N      number the first exported frame N in file names (and PC2's start frame),\n"
    "                 the others N + (frame - first); default: the cache's frame numbers\n"
    "  --pscale R     points' pscale in the file's units (default: 0.45 x their median spacing in\n"
    "                 the cache's last frame, the radius render draws, times --scale); tets: each\n"
    "                 tet's radius\n"
    "  --threads N    frames written at once (default: one per core); the files do not change\n"
    "  --obstacles F  the obstacle mesh to write with the frames (default: obstacles.ply beside the\n"
    "                 cache, which run writes, if it is there): to <cache name>_obstacles.ply in\n"
    "                 DIR, or FILE's name with _obstacles.ply, in the frames' axes and scale (.obj\n"
    "                 for OBJ frames)\n"
    "  --no-obstacles write no obstacles\n"
    "  --quiet        no progress display (it is shown only on a terminal anyway)\n"
    "\n"
    "docs/export.md says how Blender, Houdini and ParaView import each format.\n";

/* ---------------------------------------------------------------- options */

typedef struct export_options {
    const char *cache, *out, *format_name, *frames, *name, *obstacles;
    long frame, start;
    int has_frame, has_start, threads, quiet, no_obstacles;
    double voxel, pscale;
    cli_axes_options axes; /* --up, --scale, --preset */
} export_options;

static int parse_option(int argc, char **argv, int *i, export_options *o)
{
    const char *a = argv[*i], *value = *i + 1 < argc ? argv[*i + 1] : NULL;
    long v;
    if (!value) return cli_usage_error(USAGE_EXPORT, "unknown or incomplete option '%s'", a);
    ++*i;
    int rc = cli_axes_parse(USAGE_EXPORT, a, value, &o->axes);
    if (rc != 1) return rc;
    if (!strcmp(a, "-o") || !strcmp(a, "--output")) o->out = value;
    else if (!strcmp(a, "--format")) o->format_name = value;
    else if (!strcmp(a, "--frames")) o->frames = value;
    else if (!strcmp(a, "--frame")) {
        if (cli_parse_int(value, -2000000000L, 2000000000L, &o->frame))
            return cli_usage_error(USAGE_EXPORT, "--frame wants a whole number, not '%s'", value);
        o->has_frame = 1;
    } else if (!strcmp(a, "--voxel")) {
        if (cli_parse_positive(value, &o->voxel))
            return cli_usage_error(USAGE_EXPORT, "--voxel wants a positive size in world units, not '%s'", value);
    } else if (!strcmp(a, "--obstacles")) o->obstacles = value;
    else if (!strcmp(a, "--name")) {
        if (cli_check_frame_pattern(value) || strchr(value, '/'))
            return cli_usage_error(USAGE_EXPORT, "--name wants a file name with exactly one integer conversion "
                                   "(%%d, %%04d; %%%% for a literal %%) and no '/', not '%s'", value);
        o->name = value;
    } else if (!strcmp(a, "--start")) {
        if (cli_parse_int(value, 0, 1000000000L, &o->start))
            return cli_usage_error(USAGE_EXPORT, "--start wants a whole number from 0 to 1000000000, not '%s'", value);
        o->has_start = 1;
    } else if (!strcmp(a, "--pscale")) {
        if (cli_parse_positive(value, &o->pscale))
            return cli_usage_error(USAGE_EXPORT, "--pscale wants a positive radius in world units, not '%s'", value);
    } else if (!strcmp(a, "--threads")) {
        if (cli_parse_int(value, 1, 1024, &v))
            return cli_usage_error(USAGE_EXPORT, "--threads wants a whole number from 1 to 1024, not '%s'", value);
        o->threads = (int)v;
    } else return cli_usage_error(USAGE_EXPORT, "unknown or incomplete option '%s'", a);
    return 0;
}

static int is_point_cache(fm_export_format f) { return f == FM_EXPORT_PC2 || f == FM_EXPORT_MDD; }

static int parse_options(int argc, char **argv, export_options *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 0; i < argc; i++) {
        int rc;
        if (!strcmp(argv[i], "--quiet") || !strcmp(argv[i], "-q")) o->quiet = 1;
        else if (!strcmp(argv[i], "--no-obstacles")) o->no_obstacles = 1;
        else if (argv[i][0] == '-' && argv[i][1]) {
            if ((rc = parse_option(argc, argv, &i, o))) return rc;
        } else if (!o->cache) o->cache = argv[i];
        else return cli_usage_error(USAGE_EXPORT, "unexpected argument '%s'", argv[i]);
    }
    if (!o->cache) return cli_usage_error(USAGE_EXPORT, "%s", "no cache file given");
    if (o->obstacles && o->no_obstacles)
        return cli_usage_error(USAGE_EXPORT, "%s", "--obstacles FILE and --no-obstacles contradict each other: give one");
    if (!o->out) return cli_usage_error(USAGE_EXPORT, "%s", "no output given (-o DIR with --format, or -o FILE)");
    if (o->has_frame && (o->frames || o->format_name))
        return cli_usage_error(USAGE_EXPORT, "%s", "--frame K names one frame for -o FILE; with --format "
                               "use --frames K (or A:B)");
    if (o->frames && !o->format_name && !is_point_cache(fm_export_format_of_path(o->out)))
        return cli_usage_error(USAGE_EXPORT, "--frames %s writes a sequence into a directory: give "
                               "--format ply|obj|vtk|vdb", o->frames);
    return 0;
}

/* ---------------------------------------------------------------- frame ranges */

/* A:B, A:, :B, : or K, each optionally followed by :S; each end a whole number, negative from
 * the end, S a positive stride. option and text are what the user wrote, for messages. */
typedef struct frame_range {
    long first, last, step;
    int has_first, has_last;
    const char *option;
    char text[64];
} frame_range;

static int parse_end(const char *s, size_t len, long *v, int *has)
{
    char buf[32];
    *has = len > 0;
    if (!len) return 0;
    if (len >= sizeof buf) return -1;
    memcpy(buf, s, len);
    buf[len] = '\0';
    return cli_parse_int(buf, -2000000000L, 2000000000L, v);
}

static int parse_range(const char *spec, frame_range *r)
{
    const char *colon = strchr(spec, ':'), *second = colon ? strchr(colon + 1, ':') : NULL;
    r->step = 1;
    if (!colon) {
        r->has_first = r->has_last = 1;
        return cli_parse_int(spec, -2000000000L, 2000000000L, &r->first) ? -1 : (r->last = r->first, 0);
    }
    if (second && (strchr(second + 1, ':') || cli_parse_int(second + 1, 1, 2000000000L, &r->step))) return -1;
    size_t last_len = second ? (size_t)(second - colon - 1) : strlen(colon + 1);
    return parse_end(spec, (size_t)(colon - spec), &r->first, &r->has_first) ||
                   parse_end(colon + 1, last_len, &r->last, &r->has_last)
               ? -1 : 0;
}

/* Resolves the range against the cache's frame count; prints an error naming the option. */
static int resolve_range(const frame_range *r, const char *cache, uint32_t frames, uint32_t *first,
                         uint32_t *last, uint32_t *step)
{
    const char *option = r->option, *spec = r->text;
    long n = (long)frames, a = r->has_first ? r->first : 0, b = r->has_last ? r->last : -1;
    if (a < 0) a += n;
    if (b < 0) b += n;
    if (n > 0 && a >= 0 && b < n && a <= b) {
        *step = (uint32_t)r->step;
        *first = (uint32_t)a, *last = (uint32_t)(a + (b - a) / r->step * r->step); /* on the stride */
        return 0;
    }
    if (n == 0) fprintf(stderr, "flockmorph: error: %s %s: %s has no frames\n", option, spec, cache);
    else
        fprintf(stderr, "flockmorph: error: %s %s: %s has %ld frames (0..%ld, or -%ld..-1 from the end), "
                "and %s names %s\n", option, spec, cache, n, n - 1, n, spec,
                a <= b ? "frames outside them" : "an empty range (its start is after its end)");
    return FM_ERR_USAGE;
}

/* ---------------------------------------------------------------- the cache's contents */

/* What every thread needs to export its frames: read-only once set up. */
typedef struct export_job {
    const char *cache, *out_file; /* out_file: one frame to one file; NULL: a sequence into dir */
    char dir[FM_PATH_MAX], stem[256]; /* stem: the cache's name, cut to 255 bytes */
    fm_export_format format;
    fm_export_options opts;
    uint32_t first, last, step, frames; /* frames first, first + step, ... last of the cache's */
    double frame_rate;
    size_t agents;
    int points;                   /* a point flock (positions) rather than tets */
    int need_velocity;            /* VDB and VTK always (tets: the centroids'), tet PLY (the vertices'); point
                                     flocks in every format */
    int vertex_velocity;          /* tet PLY: each vertex's own velocity rather than its centroid's */
    int cache_velocity, cache_ids, cache_phases, cache_groups, cache_orientation;
    int houdini;                  /* PLY and VDB: orient, pscale, age (and ids for tet PLY) */
    cli_axes axes;                /* --up y: every vector turned from Z-up to Y-up; --scale: every
                                     position, vertex, velocity and pscale times it */
    const char *name_pattern;     /* --name; NULL: <stem>_%05d.<ext> */
    char preset_name[300];        /* the name pattern a --preset stands for */
    long start;                   /* --start (or the preset's), when has_start */
    int has_start;
    long number_offset;           /* a frame's number in names: k + number_offset (--start) */
    float pscale;                 /* points: the pscale of every agent */
} export_job;

/* Points' pscale: the radius render draws them with, from the cache's last frame (where a flock
 * has taken its shape), so every frame and range gets the same value. */
static int default_pscale(fm_cache_reader *r, export_job *job)
{
    fm_error err = {0};
    float *p = malloc(sizeof(float) * 3 * (job->agents ? job->agents : 1));
    fm_status st = !p ? fm_fail(&err, FM_ERR_MEMORY, "out of memory for %zu positions", job->agents)
                   : job->frames ? fm_cache_read_attr(r, job->frames - 1, FM_ATTR_POSITION, p, &err) : FM_OK;
    if (st == FM_OK) job->pscale = (float)(job->axes.scale * fm_render_point_radius(p, job->frames ? job->agents : 0));
    free(p);
    return st == FM_OK ? 0 : cli_report(&err);
}

static int describe_cache(fm_cache_reader *r, export_job *job)
{
    job->frames = fm_cache_frames(r);
    job->frame_rate = fm_cache_frame_rate(r);
    job->agents = (size_t)fm_cache_agents(r);
    job->points = !fm_cache_has_attr(r, FM_ATTR_TET_VERTICES) && fm_cache_has_attr(r, FM_ATTR_POSITION);
    if (!job->points && !fm_cache_has_attr(r, FM_ATTR_TET_VERTICES)) {
        fprintf(stderr, "flockmorph: error: %s has neither tet vertices nor positions to export\n", job->cache);
        return FM_ERR_INPUT;
    }
    job->vertex_velocity = !job->points && job->format == FM_EXPORT_PLY;
    job->need_velocity = job->format == FM_EXPORT_VDB || job->format == FM_EXPORT_VTK || job->points ||
                         job->vertex_velocity;
    if (job->need_velocity && !(job->frame_rate > 0 && isfinite(job->frame_rate))) { /* VTK: and the .pvd's times */
        fprintf(stderr, "flockmorph: error: %s has frame rate %g; velocities and timesteps need a "
                "positive one\n", job->cache, job->frame_rate);
        return FM_ERR_INPUT;
    }
    job->cache_velocity = job->points && fm_cache_has_attr(r, FM_ATTR_VELOCITY);
    job->cache_ids = fm_cache_has_attr(r, FM_ATTR_ID);
    job->houdini = job->format == FM_EXPORT_PLY || job->format == FM_EXPORT_VDB;
    job->cache_phases = (job->format == FM_EXPORT_VTK || job->houdini) && fm_cache_has_attr(r, FM_ATTR_PHASE);
    job->cache_groups = (job->format == FM_EXPORT_VTK || job->houdini) && fm_cache_has_attr(r, FM_ATTR_GROUP);
    job->cache_orientation = (job->houdini || job->format == FM_EXPORT_VTK) && job->points &&
                             fm_cache_has_attr(r, FM_ATTR_ORIENTATION);
    return job->houdini && job->points && !(job->pscale > 0) ? default_pscale(r, job) : 0;
}

/* The points velocities are taken at: a flock's agents, a tet PLY's vertices (4 a tet), or else the
 * tets' centroids. */
static size_t velocity_points(const export_job *job) { return (job->vertex_velocity ? 4 : 1) * job->agents; }

/* How many frames the range exports, and the i-th of them. */
static uint32_t frame_count(const export_job *job) { return (job->last - job->first) / job->step + 1; }
static uint32_t frame_at(const export_job *job, uint32_t i) { return job->first + i * job->step; }

/* ---------------------------------------------------------------- one thread's frames */

enum { POSITION_SLOTS = 3 }; /* frames k - 1, k, k + 1 for the finite difference */

/* A thread's reader and buffers. Positions (a point flock's, or tet centroids) are kept for the
 * last three frames read, so a contiguous block of frames reads each frame once. */
typedef struct frame_source {
    fm_cache_reader *r;
    float *tets, *velocity, *slot[POSITION_SLOTS];
    long slot_frame[POSITION_SLOTS];
    uint32_t *ids;
    uint8_t *phases, *groups;
    float *orientation;           /* points: PLY, VDB and VTK */
    float *pscales, *ages;        /* Houdini's attributes (PLY and VDB) */
} frame_source;

static void source_close(frame_source *s)
{
    if (s->r) fm_cache_close(s->r);
    free(s->tets), free(s->velocity), free(s->ids), free(s->phases), free(s->groups);
    free(s->orientation), free(s->pscales), free(s->ages);
    for (int i = 0; i < POSITION_SLOTS; i++) free(s->slot[i]);
    memset(s, 0, sizeof *s);
}

static void *alloc_or_flag(size_t bytes, int *failed)
{
    void *p = malloc(bytes ? bytes : 1);
    if (!p) *failed = 1;
    return p;
}

static fm_status source_open(frame_source *s, const export_job *job, fm_error *err)
{
    memset(s, 0, sizeof *s);
    if (!(s->r = fm_cache_open(job->cache, err))) return err->status;
    size_t n = job->agents;
    int failed = 0;
    if (!job->points) s->tets = alloc_or_flag(sizeof(float) * 12 * n, &failed);
    if (job->need_velocity) s->velocity = alloc_or_flag(sizeof(float) * 3 * velocity_points(job), &failed);
    if (job->cache_ids || job->houdini) s->ids = alloc_or_flag(sizeof(uint32_t) * n, &failed);
    if (job->cache_phases) s->phases = alloc_or_flag(n, &failed);
    if (job->cache_groups) s->groups = alloc_or_flag(n, &failed);
    if (job->cache_orientation) s->orientation = alloc_or_flag(sizeof(float) * 4 * n, &failed);
    if (job->houdini) s->pscales = alloc_or_flag(sizeof(float) * n, &failed);
    if (job->houdini) s->ages = alloc_or_flag(sizeof(float) * n, &failed);
    for (int i = 0; i < POSITION_SLOTS; i++) { /* positions: points, or tet vertices or centroids for velocities */
        if (job->need_velocity) s->slot[i] = alloc_or_flag(sizeof(float) * 3 * velocity_points(job), &failed);
        s->slot_frame[i] = -1;
    }
    if (!failed) return FM_OK;
    source_close(s);
    return fm_fail(err, FM_ERR_MEMORY, "out of memory for the buffers of %zu agents", n);
}

/* An attribute of 3-vectors (position, velocity) of frame k, in the export's axes and units. */
static fm_status read_vectors(frame_source *s, const export_job *job, uint32_t k, fm_cache_attr attr, float *out,
                              fm_error *err)
{
    fm_status st = fm_cache_read_attr(s->r, k, attr, out, err);
    if (st == FM_OK) cli_axes_to(&job->axes, out, job->agents);
    return st;
}

/* Frame k's tet vertices into s->tets, in the export's axes and units. */
static fm_status read_tets(frame_source *s, const export_job *job, uint32_t k, fm_error *err)
{
    fm_status st = fm_cache_read_frame(s->r, k, s->tets, err);
    if (st == FM_OK) cli_axes_to(&job->axes, s->tets, 4 * job->agents);
    return st;
}

/* Frame k's positions (a point flock's own, or its tets' vertices or centroids, velocity_points)
 * while frame `center` is exported: k is center or a neighbour, and the slots of the three stay. */
static fm_status positions(frame_source *s, const export_job *job, uint32_t k, uint32_t center,
                           const float **out, fm_error *err)
{
    int free_slot = 0;
    for (int i = 0; i < POSITION_SLOTS; i++) {
        if (s->slot_frame[i] == (long)k) return *out = s->slot[i], FM_OK;
        long f = s->slot_frame[i];
        if (f < 0 || f + 1 < (long)center || f > (long)center + 1) free_slot = i;
    }
    float *p = s->slot[free_slot];
    s->slot_frame[free_slot] = -1;
    fm_status st = job->points ? read_vectors(s, job, k, FM_ATTR_POSITION, p, err) : read_tets(s, job, k, err);
    if (st != FM_OK) return st;
    if (job->vertex_velocity) memcpy(p, s->tets, sizeof(float) * 12 * job->agents);
    else if (!job->points) fm_tet_centroids(s->tets, job->agents, p);
    s->slot_frame[free_slot] = (long)k;
    *out = p;
    return FM_OK;
}

/* Velocity by finite difference over the cache's frames: central inside, one-sided at frame 0
 * and the last frame (so a frame's velocity does not depend on the range exported). */
static fm_status difference_velocity(frame_source *s, const export_job *job, uint32_t k, fm_error *err)
{
    uint32_t before = k > 0 ? k - 1 : k, after = k + 1 < job->frames ? k + 1 : k;
    const float *a, *b;
    if (before == after) { /* a single frame: nothing moves */
        memset(s->velocity, 0, sizeof(float) * 3 * velocity_points(job));
        return FM_OK;
    }
    fm_status st = positions(s, job, before, k, &a, err);
    if (st == FM_OK) st = positions(s, job, after, k, &b, err);
    double dt = (double)(after - before) / job->frame_rate;
    if (st == FM_OK) fm_finite_difference(a, b, velocity_points(job), dt, s->velocity);
    return st;
}

/* Each tet's radius: the largest distance from its centroid to a vertex (the engine's R_X). */
static void tet_radii(const float *tets, size_t n, float *out)
{
    for (size_t t = 0; t < n; t++) {
        float c[3];
        double r2 = 0;
        fm_tet_centroids(tets + 12 * t, 1, c);
        for (int j = 0; j < 4; j++) {
            const float *v = tets + 12 * t + 3 * j;
            double d2 = 0;
            for (int k = 0; k < 3; k++) d2 += ((double)v[k] - c[k]) * ((double)v[k] - c[k]);
            r2 = fmax(r2, d2);
        }
        out[t] = (float)sqrt(r2);
    }
}

/* Frame k's orientations (turned with --up y). */
static fm_status read_orientation(frame_source *s, const export_job *job, uint32_t k, fm_export_frame *f,
                                  fm_error *err)
{
    fm_status st = fm_cache_read_attr(s->r, k, FM_ATTR_ORIENTATION, s->orientation, err);
    if (st == FM_OK && job->axes.up_y) fm_export_up_y_quaternions(s->orientation, job->agents);
    if (st == FM_OK) f->orientations = s->orientation;
    return st;
}

/* Houdini's attributes of frame k (PLY and VDB) besides orient: pscale, age (every agent exists
 * from frame 0, so its age is the frame's time), and ids 0 .. n-1 when the cache has none, so
 * tet PLY carry them too. s->tets holds frame k for tets. */
static void houdini_attrs(frame_source *s, const export_job *job, uint32_t k, fm_export_frame *f)
{
    size_t n = job->agents;
    for (size_t i = 0; i < n; i++) s->ages[i] = (float)(k / job->frame_rate);
    if (job->points)
        for (size_t i = 0; i < n; i++) s->pscales[i] = job->pscale;
    else tet_radii(s->tets, n, s->pscales);
    for (size_t i = 0; !job->cache_ids && i < n; i++) s->ids[i] = (uint32_t)i;
    f->ages = s->ages, f->pscales = s->pscales, f->ids = s->ids;
}

/* Frame k as the exporters take it. */
static fm_status load_frame(frame_source *s, const export_job *job, uint32_t k, fm_export_frame *f,
                            fm_error *err)
{
    memset(f, 0, sizeof *f);
    f->n = job->agents;
    fm_status st = FM_OK;
    /* first: for tets (VDB, VTK) the difference reads the neighbours' tets into s->tets, which
     * read_tets then fills with frame k's */
    if (job->need_velocity) {
        st = job->cache_velocity ? read_vectors(s, job, k, FM_ATTR_VELOCITY, s->velocity, err)
                                 : difference_velocity(s, job, k, err);
        if (job->vertex_velocity) f->vertex_velocities = s->velocity;
        else f->velocities = s->velocity;
    }
    if (st == FM_OK && !job->points) st = read_tets(s, job, k, err);
    if (st == FM_OK && (job->points || job->format == FM_EXPORT_VDB)) /* VDB writes tets as their centroids */
        st = positions(s, job, k, k, &f->positions, err);
    if (!job->points && job->format != FM_EXPORT_VDB) f->tet_vertices = s->tets;
    if (st == FM_OK && job->cache_ids) {
        st = fm_cache_read_attr(s->r, k, FM_ATTR_ID, s->ids, err);
        f->ids = s->ids;
    }
    if (st == FM_OK && job->cache_phases) {
        st = fm_cache_read_attr(s->r, k, FM_ATTR_PHASE, s->phases, err);
        f->phases = s->phases;
    }
    if (st == FM_OK && job->cache_groups) {
        st = fm_cache_read_attr(s->r, k, FM_ATTR_GROUP, s->groups, err);
        f->groups = s->groups;
    }
    if (st == FM_OK && job->cache_orientation) st = read_orientation(s, job, k, f, err);
    if (st == FM_OK && job->houdini) houdini_attrs(s, job, k, f);
    return st;
}

/* Room for any <stem>_<frame>.<ext>, and for DIR/ before it; paths of FM_PATH_MAX bytes or more
 * are refused. */
#define CLI_NAME_BUF 288
#define CLI_PATH_BUF (FM_PATH_MAX + CLI_NAME_BUF)

/* <stem>_<frame, 5 digits>.<ext>, or the --name pattern with the frame's number: the name the
 * .pvd lists (relative to DIR); -1 if it is too long. */
static int frame_name(const export_job *job, uint32_t k, char name[CLI_NAME_BUF])
{
    long number = (long)k + job->number_offset;
    if (job->name_pattern) return cli_frame_name(name, CLI_NAME_BUF, job->name_pattern, number);
    snprintf(name, CLI_NAME_BUF, "%s_%05ld.%s", job->stem, number, fm_export_extension(job->format));
    return 0;
}

/* DIR/<name>; -1 if it is too long. */
static int frame_path(const export_job *job, uint32_t k, char path[CLI_PATH_BUF])
{
    char name[CLI_NAME_BUF];
    if (frame_name(job, k, name)) return -1;
    int len = snprintf(path, CLI_PATH_BUF, "%s/%s", job->dir, name);
    return len < 0 || len >= FM_PATH_MAX ? -1 : 0;
}

static fm_status export_one(frame_source *s, const export_job *job, uint32_t k, fm_error *err)
{
    char path[CLI_PATH_BUF];
    if (job->out_file) snprintf(path, sizeof path, "%s", job->out_file);
    else if (frame_path(job, k, path))
        return fm_fail(err, FM_ERR_USAGE, "the output path for frame %u is longer than %d bytes",
                       (unsigned)k, FM_PATH_MAX - 1);
    fm_export_frame frame;
    fm_status st = load_frame(s, job, k, &frame, err);
    return st == FM_OK ? fm_export_frame_write(&frame, job->format, &job->opts, path, err) : st;
}

/* ---------------------------------------------------------------- all frames, in parallel */

typedef struct export_progress {
    int show;
    double start;
    uint32_t done, total;
    int failed;                   /* set once any frame failed: the others stop */
    uint32_t error_frame;         /* the lowest frame that failed, and why */
    fm_error error;
} export_progress;

static void note_result(export_progress *p, uint32_t k, fm_status st, const fm_error *err)
{
#pragma omp critical(export_progress)
    {
        if (st != FM_OK && (!p->failed || k < p->error_frame)) p->error = *err, p->error_frame = k;
        if (st != FM_OK) {
#pragma omp atomic write
            p->failed = 1;
        } else p->done++;
        if (p->show && st == FM_OK)
            fprintf(stderr, "\r\033[K  export: %u of %u frames  (%.0f s)", p->done, p->total,
                    cli_seconds() - p->start);
    }
}

static int failed_so_far(export_progress *p)
{
    int failed;
#pragma omp atomic read
    failed = p->failed;
    return failed;
}

static void export_block(const export_job *job, export_progress *p)
{
    frame_source s;
    fm_error err = {0};
    fm_status st = source_open(&s, job, &err);
    /* schedule(static) without a chunk size: each thread one contiguous block of frames */
#pragma omp for schedule(static)
    for (long i = 0; i < (long)frame_count(job); i++) {
        uint32_t k = frame_at(job, (uint32_t)i);
        if (failed_so_far(p)) continue;
        if (st == FM_OK) {
            fm_error frame_err = {0};
            note_result(p, k, export_one(&s, job, k, &frame_err), &frame_err);
        } else note_result(p, k, st, &err);
    }
    if (st == FM_OK) source_close(&s);
}

static int export_frames(const export_job *job, int threads, int quiet)
{
    export_progress p = {.show = !quiet && isatty(STDERR_FILENO), .start = cli_seconds(),
                         .total = frame_count(job)};
    int team = fm_threads(threads);
    if ((uint32_t)team > p.total) team = (int)p.total;
#pragma omp parallel num_threads(team)
    export_block(job, &p);
    if (p.show) fprintf(stderr, "\r\033[K");
    return p.failed ? cli_report(&p.error) : 0;
}

/* The .pvd: every frame at timestep frame / frame rate (seconds of animation time). */
static int write_pvd(const export_job *job, char pvd[CLI_PATH_BUF])
{
    size_t count = frame_count(job);
    char (*names)[CLI_NAME_BUF] = malloc(sizeof *names * count);
    const char **files = malloc(sizeof *files * count);
    double *times = malloc(sizeof *times * count);
    fm_error err = {0};
    fm_status st = names && files && times ? FM_OK : fm_fail(&err, FM_ERR_MEMORY, "out of memory for the .pvd");
    for (size_t i = 0; st == FM_OK && i < count; i++) {
        uint32_t k = frame_at(job, (uint32_t)i);
        if (frame_name(job, k, names[i])) st = fm_fail(&err, FM_ERR_USAGE, "frame %u's file name is too long", (unsigned)k);
        files[i] = names[i];
        times[i] = job->frame_rate > 0 ? k / job->frame_rate : (double)k;
    }
    if (st == FM_OK && snprintf(pvd, CLI_PATH_BUF, "%s/%s.pvd", job->dir, job->stem) >= FM_PATH_MAX)
        st = fm_fail(&err, FM_ERR_USAGE, "the .pvd path is longer than %d bytes", FM_PATH_MAX - 1);
    if (st == FM_OK) st = fm_export_pvd(pvd, files, times, count, &err);
    free(names), free(files), free(times);
    return st == FM_OK ? 0 : cli_report(&err);
}

/* ---------------------------------------------------------------- point caches */

/* Frame k's points as a point cache holds them: a tet's 4 vertices, or a flock's positions. */
static fm_status point_cache_frame(fm_cache_reader *r, const export_job *job, uint32_t k, float *xyz,
                                   fm_error *err)
{
    fm_status st = job->points ? fm_cache_read_attr(r, k, FM_ATTR_POSITION, xyz, err) : fm_cache_read_frame(r, k, xyz, err);
    if (st == FM_OK) cli_axes_to(&job->axes, xyz, job->points ? job->agents : 4 * job->agents);
    return st;
}

/* Every frame of the range into one PC2 or MDD file, in order. PC2's start frame and MDD's
 * times are the frames' numbers (the cache's, or from --start; MDD: over the frame rate); the
 * step is the stride. */
static int export_point_cache(const export_job *job, int quiet)
{
    fm_pointcache_options pc = {.format = job->format, .points = job->points ? job->agents : 4 * job->agents,
                                .frames = frame_count(job), .start_frame = (double)job->first + job->number_offset,
                                .frame_step = job->step, .frame_rate = job->frame_rate};
    export_progress p = {.show = !quiet && isatty(STDERR_FILENO), .start = cli_seconds(), .total = frame_count(job)};
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(job->cache, &err);
    float *xyz = r ? malloc(sizeof(float) * 3 * (pc.points ? pc.points : 1)) : NULL;
    fm_pointcache_writer *w = xyz ? fm_pointcache_create(job->out_file, &pc, &err) : NULL;
    fm_status st = w ? FM_OK : r && !xyz ? fm_fail(&err, FM_ERR_MEMORY, "out of memory for a frame") : err.status;
    for (uint32_t i = 0; st == FM_OK && i < pc.frames; i++) {
        st = point_cache_frame(r, job, frame_at(job, i), xyz, &err);
        if (st == FM_OK) st = fm_pointcache_add(w, xyz, &err);
        note_result(&p, frame_at(job, i), st, &err);
    }
    if (st == FM_OK) st = fm_pointcache_finish(w, &err);
    else fm_pointcache_abort(w);
    if (p.show) fprintf(stderr, "\r\033[K");
    free(xyz);
    if (r) fm_cache_close(r);
    return st == FM_OK ? 0 : cli_report(&err);
}

/* ---------------------------------------------------------------- obstacles */

/* Where the obstacles go: DIR/<stem>_obstacles.ply for a sequence; for one file or a point cache,
 * its path without the extension and _obstacles.ply. .obj when the frames are OBJ. -1 if too long. */
static int obstacles_path(const export_job *job, char out[CLI_PATH_BUF])
{
    const char *ext = job->format == FM_EXPORT_OBJ ? "obj" : "ply";
    int len;
    if (!job->out_file) len = snprintf(out, CLI_PATH_BUF, "%s/%s_obstacles.%s", job->dir, job->stem, ext);
    else {
        const char *slash = strrchr(job->out_file, '/'), *dot = strrchr(job->out_file, '.');
        int keep = dot && (slash ? dot > slash + 1 : dot > job->out_file) ? (int)(dot - job->out_file)
                                                                          : (int)strlen(job->out_file);
        len = snprintf(out, CLI_PATH_BUF, "%.*s_obstacles.%s", keep, job->out_file, ext);
    }
    return len < 0 || len >= FM_PATH_MAX ? -1 : 0;
}

/* The cache's obstacles (--obstacles FILE, or obstacles.ply beside it, which run writes; read back
 * into the cache's axes) in the frames' axes and units, so that they stand where the flock flies
 * round them in the tool that reads the export; its header names them. written gets the file ("" for
 * none). */
static int export_obstacles(const export_options *o, const export_job *job, char written[CLI_PATH_BUF])
{
    written[0] = 0;
    if (o->no_obstacles) return 0;
    fm_mesh m;
    char source[FM_PATH_MAX + 32], name[FM_PATH_MAX + 96], axes[64];
    int rc = cli_cache_obstacles(o->cache, o->obstacles, &m, source);
    if (!rc && source[0] && obstacles_path(job, written))
        rc = cli_usage_error(USAGE_EXPORT, "-o %s: the obstacles' path would be too long", o->out);
    if (!rc && source[0]) rc = cli_axes_mesh_to(&job->axes, &m);
    if (!rc && source[0]) {
        snprintf(name, sizeof name, "obstacles from %s, up %s, scale %.9g", source, job->axes.up_y ? "y" : "z", job->axes.scale);
        cli_axes_comment(&job->axes, axes, sizeof axes);
        fm_ply_mesh view = {name, m.v, m.nv, m.tri, m.nt};
        fm_error err = {0};
        fm_status st = job->format == FM_EXPORT_OBJ ? fm_export_obj_meshes(&view, 1, axes, written, &err)
                                                     : fm_export_ply_meshes(&view, 1, axes, written, &err);
        if (st != FM_OK) rc = cli_report(&err);
    }
    fm_mesh_free(&m);
    if (rc || !source[0]) written[0] = 0;
    return rc;
}

/* ---------------------------------------------------------------- the command */

/* The cache's file name without its extension: frames.fmc -> frames. */
static void cache_stem(const char *cache, char *stem, size_t size)
{
    const char *slash = strrchr(cache, '/'), *base = slash ? slash + 1 : cache;
    const char *dot = strrchr(base, '.');
    size_t len = dot && dot > base ? (size_t)(dot - base) : strlen(base);
    snprintf(stem, size, "%.*s", (int)FM_MIN(len, size - 1), base);
}

/* The names and start --preset stands for (its up is cli_axes_chosen's), where none was given and
 * the form takes them. */
static void apply_preset(const export_options *o, export_job *job)
{
    const cli_preset *p = o->axes.preset;
    if (!o->has_start && (!job->out_file || is_point_cache(job->format))) job->has_start = 1, job->start = p->start;
    if (o->name || job->out_file || !p->four_digit_names) return;
    size_t n = 0; /* <stem>.%04d.<ext>, a '%' of the stem doubled */
    for (const char *c = job->stem; *c && n + 2 < sizeof job->preset_name - 16; c++) {
        if (*c == '%') job->preset_name[n++] = '%';
        job->preset_name[n++] = *c;
    }
    snprintf(job->preset_name + n, sizeof job->preset_name - n, ".%%04d.%s", fm_export_extension(job->format));
    job->name_pattern = job->preset_name;
}

/* Format, output and frames from the options, before the cache is opened. */
static int plan_job(const export_options *o, export_job *job, frame_range *range)
{
    memset(job, 0, sizeof *job);
    job->cache = o->cache;
    job->opts = fm_default_export_options();
    job->opts.voxel_size = o->voxel;
    job->axes = cli_axes_chosen(&o->axes), job->name_pattern = o->name, job->pscale = (float)o->pscale;
    job->has_start = o->has_start, job->start = o->start;
    if (o->format_name) {
        job->format = fm_export_format_named(o->format_name);
        if (job->format == FM_EXPORT_UNKNOWN)
            return cli_usage_error(USAGE_EXPORT, "--format wants ply, obj, vtk, vdb, pc2 or mdd, not '%s'",
                                   o->format_name);
    }
    if (o->format_name && !is_point_cache(job->format)) {
        if (snprintf(job->dir, sizeof job->dir, "%s", o->out) >= (int)sizeof job->dir)
            return cli_usage_error(USAGE_EXPORT, "-o %s: the path is too long", o->out);
        cache_stem(o->cache, job->stem, sizeof job->stem);
    } else {
        if (!o->format_name) job->format = fm_export_format_of_path(o->out);
        if (job->format == FM_EXPORT_UNKNOWN)
            return cli_usage_error(USAGE_EXPORT, "-o %s: unknown extension; give FILE.ply, .obj, .vtu, .vdb, "
                                   ".pc2 or .mdd, or --format ply|obj|vtk|vdb with -o DIR for a sequence", o->out);
        job->out_file = o->out;
    }
    if (o->name && job->out_file)
        return cli_usage_error(USAGE_EXPORT, "--name %s names the files of a sequence: give --format "
                               "ply|obj|vtk|vdb and -o DIR", o->name);
    if (o->has_start && job->out_file && !is_point_cache(job->format))
        return cli_usage_error(USAGE_EXPORT, "%s", "--start numbers a sequence or a point cache, not one file");
    if (o->axes.preset) apply_preset(o, job);
    memset(range, 0, sizeof *range);
    range->option = o->frames ? "--frames" : "--frame";
    if (o->has_frame) snprintf(range->text, sizeof range->text, "%ld", o->frame);
    else snprintf(range->text, sizeof range->text, "%s",
                  o->frames ? o->frames : job->out_file && !is_point_cache(job->format) ? "-1" : ":");
    if (o->has_frame && is_point_cache(job->format))
        return cli_usage_error(USAGE_EXPORT, "%s", "a point cache holds a range of frames: give --frames A:B "
                               "(or K), not --frame");
    if (parse_range(range->text, range) || (o->frames && strlen(o->frames) >= sizeof range->text))
        return cli_usage_error(USAGE_EXPORT, "--frames wants A:B, A:, :B or K, optionally with :S (whole "
                               "numbers, negative from the end; S a positive stride), not '%s'", o->frames);
    return 0;
}

static void print_summary(const export_job *job, const char *pvd)
{
    if (job->out_file && is_point_cache(job->format)) {
        printf("frames %u..%u step %u of %s -> %s (%u frames of %zu points)\n", (unsigned)job->first,
               (unsigned)job->last, (unsigned)job->step, job->cache, job->out_file, (unsigned)frame_count(job),
               job->points ? job->agents : 4 * job->agents);
        return;
    }
    if (job->out_file) {
        printf("frame %u of %s -> %s\n", (unsigned)job->first, job->cache, job->out_file);
        return;
    }
    char first[CLI_PATH_BUF], last[CLI_PATH_BUF];
    frame_path(job, job->first, first);
    frame_path(job, job->last, last);
    printf("frames %u..%u of %s -> %s%s%s (%u files)\n", (unsigned)job->first, (unsigned)job->last,
           job->cache, first, job->last > job->first ? " .. " : "", job->last > job->first ? last : "",
           (unsigned)frame_count(job));
    if (pvd[0]) printf("collection -> %s\n", pvd);
}

int cli_export(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_EXPORT), 0;
    export_options o;
    export_job job;
    frame_range range;
    int rc = parse_options(argc, argv, &o);
    if (!rc) rc = plan_job(&o, &job, &range);
    if (rc) return rc;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(o.cache, &err);
    if (!r) return cli_report(&err);
    if (fm_cache_warning(r)[0]) fprintf(stderr, "flockmorph: warning: %s\n", fm_cache_warning(r));
    rc = describe_cache(r, &job);
    fm_cache_close(r);
    if (!rc) rc = resolve_range(&range, o.cache, job.frames, &job.first, &job.last, &job.step);
    if (!rc && job.has_start) job.number_offset = job.start - (long)job.first;
    if (!rc && !job.out_file) rc = cli_make_outdir(job.dir, NULL, 0);
    char pvd[CLI_PATH_BUF] = "", obstacles[CLI_PATH_BUF] = "";
    if (!rc) rc = export_obstacles(&o, &job, obstacles); /* first: a mesh that cannot be read stops it all */
    if (!rc) rc = is_point_cache(job.format) ? export_point_cache(&job, o.quiet) : export_frames(&job, o.threads, o.quiet);
    if (!rc && !job.out_file && job.format == FM_EXPORT_VTK) rc = write_pvd(&job, pvd);
    if (!rc) print_summary(&job, pvd);
    if (!rc && obstacles[0]) printf("obstacles -> %s\n", obstacles);
    return rc;
}
