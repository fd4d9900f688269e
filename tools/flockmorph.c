/* flockmorph: the command line.
 *
 *   flockmorph run SCENE.json -o OUTDIR [--threads N] [--quiet]
 *   flockmorph export CACHE -o FILE.ply|FILE.obj [--frame K]
 *   flockmorph render CACHE -o FILE.png [--frame K] [--size WxH] [--view front|top|side]
 *   flockmorph info CACHE
 *
 * Exit status: 0 success, 1 usage, 2 bad input, 3 I/O, 4 memory, 5 internal. */
#define _POSIX_C_SOURCE 200809L
#include "flockmorph/flockmorph.h"
#include "fm_internal.h"

#include <jansson.h>
#include <omp.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static const char *USAGE_MAIN =
    "usage: flockmorph <command> [options]\n"
    "\n"
    "Turns one 3D shape into another as a flock of tetrahedra and caches every frame.\n"
    "\n"
    "commands:\n"
    "  run      simulate a scene file and write the frame cache and stats.json\n"
    "  export   write one frame of a cache as PLY or OBJ\n"
    "  render   render one frame of a cache to a PNG preview\n"
    "  info     print a cache's agent and frame counts\n"
    "\n"
    "'flockmorph <command> --help' describes each command. docs/ has the scene file reference.\n";

static const char *USAGE_RUN =
    "usage: flockmorph run SCENE.json -o OUTDIR [--threads N] [--quiet]\n"
    "\n"
    "Reads the scene (docs/scene.md), tetrahedralizes and subdivides the meshes, simulates until\n"
    "every agent has arrived (or the scene's frame limit), and writes OUTDIR/<output.cache>\n"
    "(default frames.fmc, docs/cache-format.md) and OUTDIR/stats.json. OUTDIR is created if needed.\n"
    "\n"
    "  -o, --output DIR   output directory (required)\n"
    "  --threads N        worker threads (default: all cores); results do not depend on N\n"
    "  --quiet            no progress display (it is shown only on a terminal anyway)\n";

static const char *USAGE_EXPORT =
    "usage: flockmorph export CACHE -o FILE.ply|FILE.obj [--frame K]\n"
    "\n"
    "Writes frame K (default: the last; negative counts from the end) as a triangle mesh with\n"
    "four triangles per tet.\n";

static const char *USAGE_RENDER =
    "usage: flockmorph render CACHE -o FILE.png [--frame K] [--size WxH] [--view front|top|side]\n"
    "\n"
    "Renders frame K (default: the last; negative counts from the end) with an orthographic\n"
    "camera fitted to the whole animation's bounds (front looks along +Y, top along -Z, side\n"
    "along -X; default front, 960x540).\n";

static const char *USAGE_INFO = "usage: flockmorph info CACHE\n\nPrints the cache's agents, frames and frame rate.\n";

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int usage_error(const char *usage, const char *fmt, const char *arg)
{
    fprintf(stderr, "flockmorph: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\n\n%s", usage);
    return FM_ERR_USAGE;
}

static int report(const fm_error *err)
{
    fprintf(stderr, "flockmorph: error: %s\n", err->message);
    return err->status ? (int)err->status : FM_ERR_INTERNAL;
}

static int wants_help(int argc, char **argv)
{
    for (int i = 0; i < argc; i++)
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) return 1;
    return 0;
}

static int parse_int(const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi) return -1;
    *out = v;
    return 0;
}

/* ---------------------------------------------------------------- run */

typedef struct run_options {
    const char *scene, *outdir;
    int threads, quiet;
} run_options;

static int parse_run(int argc, char **argv, run_options *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        long v;
        if ((!strcmp(a, "-o") || !strcmp(a, "--output")) && i + 1 < argc) o->outdir = argv[++i];
        else if (!strcmp(a, "--threads") && i + 1 < argc) {
            if (parse_int(argv[++i], 1, 1024, &v)) return usage_error(USAGE_RUN, "--threads wants a whole number from 1 to 1024, not '%s'", argv[i]);
            o->threads = (int)v;
        } else if (!strcmp(a, "--quiet") || !strcmp(a, "-q")) o->quiet = 1;
        else if (a[0] == '-') return usage_error(USAGE_RUN, "unknown or incomplete option '%s'", a);
        else if (!o->scene) o->scene = a;
        else return usage_error(USAGE_RUN, "unexpected argument '%s'", a);
    }
    if (!o->scene) return usage_error(USAGE_RUN, "%s", "no scene file given");
    if (!o->outdir) return usage_error(USAGE_RUN, "%s", "no output directory given (-o OUTDIR)");
    return 0;
}

/* mkdir -p: creates dir and any missing parents. */
static int make_dirs(const char *dir)
{
    char path[FM_PATH_MAX];
    if (snprintf(path, sizeof path, "%s", dir) >= (int)sizeof path) return errno = ENAMETOOLONG, -1;
    for (char *p = path + 1; *p; p++) {
        if (*p != '/') continue;
        *p = 0;
        if (mkdir(path, 0777) != 0 && errno != EEXIST) return -1;
        *p = '/';
    }
    return mkdir(path, 0777) != 0 && errno != EEXIST ? -1 : 0;
}

static int make_outdir(const char *dir, fm_error *err)
{
    struct stat st;
    if (stat(dir, &st) == 0) {
        if (!S_ISDIR(st.st_mode)) return fprintf(stderr, "flockmorph: error: %s exists and is not a directory\n", dir), FM_ERR_IO;
    } else if (make_dirs(dir) != 0) {
        fprintf(stderr, "flockmorph: error: cannot create the output directory %s: %s\n", dir, strerror(errno));
        return FM_ERR_IO;
    }
    if (access(dir, W_OK) != 0) {
        fprintf(stderr, "flockmorph: error: cannot write to the output directory %s: %s\n", dir, strerror(errno));
        return FM_ERR_IO;
    }
    (void)err;
    return 0;
}

static void prep_progress(const char *stage, double fraction, void *user)
{
    if (*(const int *)user) fprintf(stderr, "\r\033[K  preprocessing: %-24s %3.0f%%", stage, 100 * fraction);
}

typedef struct run_progress {
    int show;
    int64_t agents;
    double start;
} run_progress;

static void frame_progress(const fm_state_info *info, int64_t frame, void *user)
{
    const run_progress *p = user;
    if (!p->show) return;
    double done = (double)info->count[FM_PHASE_ARRIVED] / (double)p->agents;
    fprintf(stderr, "\r\033[K  frame %lld  t = %.2f s  waiting %lld  flying %lld  homing %lld  arrived %.1f%%  (%.0f s)",
            (long long)frame, info->time, (long long)info->count[0], (long long)info->count[1],
            (long long)info->count[2], 100 * done, now_seconds() - p->start);
}

static json_t *vec3_json(const double v[3])
{
    return json_pack("[fff]", v[0], v[1], v[2]);
}

/* The velocity-model settings of the run (FM Table I's parameters, grid and style columns). */
static json_t *velocity_json(const fm_scene_def *def)
{
    static const char *const kinds[] = {"curl_noise", "wind", "gravity", "vortex"};
    json_t *fields = json_array();
    for (int i = 0; i < def->field_count; i++) {
        const fm_field_def *f = &def->fields[i];
        json_t *o = json_pack("{ss}", "type", kinds[f->kind]);
        if (f->kind == FM_FIELD_CURL_NOISE) json_object_set_new(o, "gain", json_real(f->gain)), json_object_set_new(o, "scale", json_real(f->scale));
        if (f->kind == FM_FIELD_WIND || f->kind == FM_FIELD_GRAVITY)
            json_object_set_new(o, "direction", vec3_json(f->direction)), json_object_set_new(o, "speed", json_real(f->speed));
        if (f->kind == FM_FIELD_WIND)
            json_object_set_new(o, "turbulence", json_real(f->turbulence)), json_object_set_new(o, "scale", json_real(f->scale)),
            json_object_set_new(o, "period", json_real(f->period));
        if (f->kind == FM_FIELD_VORTEX)
            json_object_set_new(o, "center", vec3_json(f->center)), json_object_set_new(o, "axis", vec3_json(f->axis)),
            json_object_set_new(o, "strength", json_real(f->strength));
        json_array_append_new(fields, o);
    }
    json_t *grid = def->field_grid[0] > 0 ? json_pack("[iii]", def->field_grid[0], def->field_grid[1], def->field_grid[2]) : json_null();
    return json_pack("{sfsfsosososisfsfsbsfsfsfsfss}", "omega1", def->omega1, "omega2", def->omega2, "fields", fields,
                     "field_grid", grid, "field_evaluation", json_string(def->field_grid[0] > 0 ? "baked" : "direct"),
                     "obstacles", def->obstacle_count, "k_a", def->k_a, "obstacle_voxel", def->obstacle_voxel,
                     "avoid_in_phase2", def->avoid_in_phase2 != 0, "d_min", def->d_min, "mde_speed", def->mde_speed,
                     "path_width", def->path_width, "path_attraction", def->path_attraction,
                     "phase_switch", def->phase_switch == FM_SWITCH_DISTANCE ? "distance" : "sphere");
}

static json_t *mde_frames_json(const fm_run_stats *rs)
{
    json_t *a = json_array();
    for (int64_t f = 0; f + 1 < rs->frames; f++)
        json_array_append_new(a, isnan(rs->mde_fraction[f]) ? json_null() : json_real(rs->mde_fraction[f]));
    return a;
}

static int write_stats(const char *path, const fm_scene_def *def, const fm_model_info *mi, const fm_run_stats *rs,
                       int threads, double preprocess_seconds, const char *cache_path)
{
    json_t *j = json_object();
    json_object_set_new(j, "agents", json_integer(mi->agents));
    json_object_set_new(j, "source_tets", json_integer(mi->source_tets));
    json_object_set_new(j, "target_tets", json_integer(mi->target_tets));
    json_object_set_new(j, "frames", json_integer(rs->frames));
    json_object_set_new(j, "steps", json_integer(rs->steps));
    json_object_set_new(j, "time_step", json_real(mi->time_step));
    json_object_set_new(j, "frame_rate", json_real(def->frame_rate));
    json_object_set_new(j, "launch_rate", json_real(mi->launch_rate));
    json_object_set_new(j, "preprocess_seconds", json_real(preprocess_seconds));
    json_object_set_new(j, "simulate_seconds", json_real(rs->simulate_seconds));
    json_object_set_new(j, "output_seconds", json_real(rs->output_seconds));
    double rate = rs->simulate_seconds > 0 ? (double)mi->agents * (double)rs->steps / rs->simulate_seconds : 0;
    json_object_set_new(j, "agent_steps_per_second", json_real(rate));
    json_object_set_new(j, "all_arrived", json_boolean(rs->all_arrived));
    json_object_set_new(j, "stopped_at_frame_limit", json_boolean(rs->stopped_at_frame_limit));
    json_object_set_new(j, "final_max_vertex_error", rs->all_arrived ? json_real(rs->final_max_vertex_error) : json_null());
    json_object_set_new(j, "target_tets_filled_once", json_boolean(rs->target_tets_filled_once));
    json_object_set_new(j, "inverted_tet_frames", json_integer(rs->inverted_tet_frames));
    json_object_set_new(j, "morph_fallbacks", json_integer(rs->morph_fallbacks));
    json_object_set_new(j, "mde_fraction_mean", json_real(rs->mde_fraction_mean));
    json_object_set_new(j, "mde_fraction_per_frame", mde_frames_json(rs));
    json_object_set_new(j, "min_obstacle_clearance",
                        isinf(rs->min_obstacle_clearance) ? json_null() : json_real(rs->min_obstacle_clearance));
    json_object_set_new(j, "velocity_model", velocity_json(def));
    json_object_set_new(j, "source_volume", json_real(mi->source_volume));
    json_object_set_new(j, "target_volume", json_real(mi->target_volume));
    json_object_set_new(j, "target_sphere_radius", json_real(mi->sphere_radius));
    json_object_set_new(j, "threads", json_integer(threads));
    json_object_set_new(j, "seed", json_integer((json_int_t)def->seed));
    json_object_set_new(j, "cache", json_string(cache_path));
    fm_output_file out;
    fm_error err = {0};
    fm_status st = fm_output_open(&out, path, &err);
    if (st == FM_OK) {
        if (json_dumpf(j, out.f, JSON_INDENT(2) | JSON_REAL_PRECISION(10)) == 0 && fputc('\n', out.f) != EOF)
            st = fm_output_commit(&out, NULL, &err);
        else
            fm_output_discard(&out), st = fm_fail(&err, FM_ERR_IO, "cannot write '%s'", path);
    }
    json_decref(j);
    return st == FM_OK ? 0 : report(&err);
}

static int simulate(const run_options *o, const fm_scene_def *def, fm_model *model, double prep_seconds)
{
    fm_error err = {0};
    int show = !o->quiet && isatty(STDERR_FILENO);
    fm_model_info mi = fm_model_get_info(model);
    fm_state *state = fm_state_create(model, o->threads, &err);
    if (!state) return report(&err);
    int threads = o->threads > 0 ? o->threads : omp_get_max_threads();
    char cache_path[FM_PATH_MAX + 300], stats_path[FM_PATH_MAX + 16];
    snprintf(cache_path, sizeof cache_path, "%s/%s", o->outdir, def->cache_name);
    snprintf(stats_path, sizeof stats_path, "%s/stats.json", o->outdir);
    fm_cache_writer *cache = fm_cache_writer_create(cache_path, (uint64_t)mi.agents, def->frame_rate, def->compression_level, &err);
    if (!cache) return fm_state_destroy(state), report(&err);
    run_progress rp = {show, mi.agents, now_seconds()};
    fm_run_stats rs;
    fm_status st = fm_run(model, state, cache, frame_progress, &rp, &rs, &err);
    if (show) fprintf(stderr, "\n");
    int64_t still_flying = mi.agents - fm_state_get_info(state).count[FM_PHASE_ARRIVED];
    fm_state_destroy(state);
    if (st != FM_OK) return fm_cache_writer_abort(cache), fm_run_stats_free(&rs), report(&err);
    if (fm_cache_writer_finish(cache, &err) != FM_OK) return fm_run_stats_free(&rs), report(&err);
    int rc = write_stats(stats_path, def, &mi, &rs, threads, prep_seconds, cache_path);
    fm_run_stats_free(&rs);
    if (rc) return rc;
    printf("agents %lld, frames %lld, steps %lld, %.3g agent-steps/s\n", (long long)mi.agents, (long long)rs.frames,
           (long long)rs.steps, rs.simulate_seconds > 0 ? (double)mi.agents * (double)rs.steps / rs.simulate_seconds : 0.0);
    if (!rs.all_arrived)
        fprintf(stderr, "flockmorph: warning: stopped at the frame limit (%d frames) with %lld agents not yet arrived; "
                "raise time.frame_limit in the scene\n", def->frame_limit, (long long)still_flying);
    printf("cache: %s\nstats: %s\n", cache_path, stats_path);
    return 0;
}

static int cmd_run(int argc, char **argv)
{
    if (wants_help(argc, argv)) return printf("%s", USAGE_RUN), 0;
    run_options o;
    int rc = parse_run(argc, argv, &o);
    if (rc) return rc;
    fm_error err = {0};
    fm_scene_def def;
    if (fm_scene_load(o.scene, &def, &err) != FM_OK) return report(&err);
    if ((rc = make_outdir(o.outdir, &err))) return rc;
    int show = !o.quiet && isatty(STDERR_FILENO);
    double t0 = now_seconds();
    fm_model *model = fm_model_build(&def, prep_progress, &show, &err);
    double prep_seconds = now_seconds() - t0;
    if (show) fprintf(stderr, "\n");
    if (!model) return report(&err);
    rc = simulate(&o, &def, model, prep_seconds);
    fm_model_destroy(model);
    return rc;
}

/* ---------------------------------------------------------------- export, render, info */

typedef struct frame_options {
    const char *cache, *out, *view;
    long frame;
    int has_frame, width, height;
} frame_options;

static int parse_frame_options(int argc, char **argv, const char *usage, frame_options *o)
{
    memset(o, 0, sizeof *o);
    o->width = 960, o->height = 540, o->view = "front";
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if ((!strcmp(a, "-o") || !strcmp(a, "--output")) && i + 1 < argc) o->out = argv[++i];
        else if (!strcmp(a, "--frame") && i + 1 < argc) {
            if (parse_int(argv[++i], -2000000000L, 2000000000L, &o->frame)) return usage_error(usage, "--frame wants a whole number, not '%s'", argv[i]);
            o->has_frame = 1;
        } else if (!strcmp(a, "--size") && i + 1 < argc) {
            if (sscanf(argv[++i], "%dx%d", &o->width, &o->height) != 2 || o->width < 16 || o->height < 16 || o->width > 16384 || o->height > 16384)
                return usage_error(usage, "--size wants WIDTHxHEIGHT between 16 and 16384, not '%s'", argv[i]);
        } else if (!strcmp(a, "--view") && i + 1 < argc) o->view = argv[++i];
        else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown or incomplete option '%s'", a);
        else if (!o->cache) o->cache = a;
        else return usage_error(usage, "unexpected argument '%s'", a);
    }
    if (!o->cache) return usage_error(usage, "%s", "no cache file given");
    if (!o->out && usage != USAGE_INFO) return usage_error(usage, "%s", "no output file given (-o FILE)");
    return 0;
}

/* Opens the cache and reads the chosen frame (default last). */
static int load_frame(const frame_options *o, fm_cache_reader **reader, float **verts, uint32_t *frame)
{
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(o->cache, &err);
    if (!r) return report(&err);
    if (fm_cache_warning(r)[0]) fprintf(stderr, "flockmorph: warning: %s\n", fm_cache_warning(r));
    long frames = (long)fm_cache_frames(r), k = o->has_frame ? o->frame : -1;
    if (k < 0) k += frames;
    if (k < 0 || k >= frames) {
        fprintf(stderr, "flockmorph: error: %s has %ld frames (0..%ld); there is no frame %ld\n", o->cache, frames, frames - 1, o->frame);
        fm_cache_close(r);
        return FM_ERR_USAGE;
    }
    *verts = malloc(sizeof(float) * 12 * (fm_cache_agents(r) ? fm_cache_agents(r) : 1));
    if (!*verts) return fm_cache_close(r), fprintf(stderr, "flockmorph: error: out of memory\n"), FM_ERR_MEMORY;
    if (fm_cache_read_frame(r, (uint32_t)k, *verts, &err) != FM_OK) {
        free(*verts);
        fm_cache_close(r);
        return report(&err);
    }
    *reader = r;
    *frame = (uint32_t)k;
    return 0;
}

static int cmd_export(int argc, char **argv)
{
    if (wants_help(argc, argv)) return printf("%s", USAGE_EXPORT), 0;
    frame_options o;
    int rc = parse_frame_options(argc, argv, USAGE_EXPORT, &o);
    if (rc) return rc;
    fm_cache_reader *r;
    float *verts;
    uint32_t frame;
    if ((rc = load_frame(&o, &r, &verts, &frame))) return rc;
    fm_error err = {0};
    if (fm_export_tets(verts, fm_cache_agents(r), o.out, &err) != FM_OK) rc = report(&err);
    else printf("frame %u of %s -> %s\n", frame, o.cache, o.out);
    free(verts);
    fm_cache_close(r);
    return rc;
}

/* Bounds of every frame of the cache, so a sequence of renders shares one camera. */
static int animation_bounds(fm_cache_reader *r, double b[6])
{
    size_t n = fm_cache_agents(r);
    float *v = malloc(sizeof(float) * 12 * (n ? n : 1));
    fm_error err = {0};
    if (!v) return -1;
    for (int k = 0; k < 3; k++) b[k] = 1e300, b[3 + k] = -1e300;
    for (uint32_t f = 0; f < fm_cache_frames(r); f++) {
        if (fm_cache_read_frame(r, f, v, &err) != FM_OK) return free(v), report(&err);
        for (size_t i = 0; i < 4 * n; i++)
            for (int k = 0; k < 3; k++) {
                double x = v[3 * i + k];
                if (x < b[k]) b[k] = x;
                if (x > b[3 + k]) b[3 + k] = x;
            }
    }
    free(v);
    return 0;
}

static int set_view(const char *view, fm_render_opts *ro)
{
    static const struct { const char *name; double dir[3], up[3]; } views[] = {
        {"front", {0, 1, 0}, {0, 0, 1}}, {"top", {0, 0, -1}, {0, 1, 0}}, {"side", {-1, 0, 0}, {0, 0, 1}}};
    for (size_t i = 0; i < sizeof views / sizeof views[0]; i++)
        if (!strcmp(view, views[i].name)) {
            memcpy(ro->view_dir, views[i].dir, sizeof ro->view_dir);
            memcpy(ro->up, views[i].up, sizeof ro->up);
            return 0;
        }
    return -1;
}

static int cmd_render(int argc, char **argv)
{
    if (wants_help(argc, argv)) return printf("%s", USAGE_RENDER), 0;
    frame_options o;
    int rc = parse_frame_options(argc, argv, USAGE_RENDER, &o);
    if (rc) return rc;
    fm_render_opts ro = fm_default_render_opts();
    if (set_view(o.view, &ro)) return usage_error(USAGE_RENDER, "--view is front, top or side, not '%s'", o.view);
    ro.width = o.width, ro.height = o.height;
    fm_cache_reader *r;
    float *verts;
    uint32_t frame;
    if ((rc = load_frame(&o, &r, &verts, &frame))) return rc;
    double bounds[6];
    fm_error err = {0};
    if ((rc = animation_bounds(r, bounds)) == 0) {
        ro.bounds = bounds;
        if (fm_render_tets_png(verts, fm_cache_agents(r), &ro, o.out, &err) != FM_OK) rc = report(&err);
        else printf("frame %u of %s -> %s\n", frame, o.cache, o.out);
    }
    free(verts);
    fm_cache_close(r);
    return rc;
}

static int cmd_info(int argc, char **argv)
{
    if (wants_help(argc, argv)) return printf("%s", USAGE_INFO), 0;
    frame_options o;
    int rc = parse_frame_options(argc, argv, USAGE_INFO, &o);
    if (rc) return rc;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(o.cache, &err);
    if (!r) return report(&err);
    if (fm_cache_warning(r)[0]) fprintf(stderr, "flockmorph: warning: %s\n", fm_cache_warning(r));
    printf("{\"agents\": %llu, \"frames\": %u, \"frame_rate\": %g, \"complete\": %s}\n",
           (unsigned long long)fm_cache_agents(r), fm_cache_frames(r), fm_cache_frame_rate(r),
           fm_cache_warning(r)[0] ? "false" : "true");
    fm_cache_close(r);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 2) return fprintf(stderr, "%s", USAGE_MAIN), FM_ERR_USAGE;
    const char *cmd = argv[1];
    if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || !strcmp(cmd, "help")) return printf("%s", USAGE_MAIN), 0;
    if (!strcmp(cmd, "--version")) return printf("flockmorph %s\n", FM_VERSION_STRING), 0;
    if (!strcmp(cmd, "run")) return cmd_run(argc - 2, argv + 2);
    if (!strcmp(cmd, "export")) return cmd_export(argc - 2, argv + 2);
    if (!strcmp(cmd, "render")) return cmd_render(argc - 2, argv + 2);
    if (!strcmp(cmd, "info")) return cmd_info(argc - 2, argv + 2);
    fprintf(stderr, "flockmorph: unknown command '%s'\n\n%s", cmd, USAGE_MAIN);
    return FM_ERR_USAGE;
}
