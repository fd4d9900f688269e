/* flockmorph run: simulate a scene, write the cache and stats.json. One run path for both modes;
 * what differs is in each mode's cli_mode (cli_mode_morph.c, cli_mode_flock.c). */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "export.h"
#include "geom.h"
#include "obstacles.h"

#include <jansson.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *const USAGE_RUN =
    "usage: flockmorph run SCENE.json -o OUTDIR [--threads N] [--quiet] [--checkpoint-every K] [--resume]\n"
    "                      [--overwrite] [--stop-after-frame F] [--set KEY=VALUE ...]\n"
    "                      [--wedge-file WEDGES.json [--wedge I]] [--up z|y] [--scale S] [--preset P]\n"
    "\n"
    "Reads the scene (docs/scene.md) and runs its mode: the tetra morph tetrahedralizes and\n"
    "subdivides the meshes and simulates until every agent has arrived; the shape flock\n"
    "(\"mode\": \"shape_flock\", docs/shape-flock.md) samples the surfaces and simulates until every\n"
    "agent is bound; both stop at the scene's frame limit. Writes OUTDIR/<output.cache> (default\n"
    "frames.fmc, docs/cache-format.md) and OUTDIR/stats.json, and with obstacles their placed\n"
    "meshes in OUTDIR/obstacles.ply (render draws them). OUTDIR is created if needed.\n"
    "\n"
    "  -o, --output DIR      output directory (required)\n"
    "  --threads N           worker threads (default: all cores; under MPI, the machine's cores\n"
    "                        over its ranks); results do not depend on N\n"
    "  --quiet               no progress (on a terminal a line redrawn every frame; otherwise,\n"
    "                        as in a farm's log, a plain line every --log-every seconds)\n"
    "  --log-every S         seconds between those plain lines (default 10; 0: every frame)\n"
    "  --checkpoint-every K  save the run to OUTDIR/checkpoint.fmck every K frames; 0: only when\n"
    "                        interrupted (default: every 60 s of wall time)\n"
    "  --resume              continue the run saved in OUTDIR/checkpoint.fmck (same scene;\n"
    "                        either mode)\n"
    "  --stop-after-frame F  write frames up to F, save the checkpoint and exit 0 (a run split\n"
    "                        into segments under a farm's time limit: the next one --resume's)\n"
    "  --overwrite           replace the results of a finished run in OUTDIR (without it such a\n"
    "                        folder is refused)\n"
    "  --set KEY=VALUE       change the scene: KEY dotted (mde.d_min, obstacles.meshes.0.scale),\n"
    "                        VALUE JSON (0.05, true, [1, 2, 3]) or else a string; checked as the\n"
    "                        file is. Repeatable; applied after the wedge's\n"
    "  --wedge-file W        run one wedge of W (docs/wedges.md; 'flockmorph wedge list W')\n"
    "  --wedge I             which one (0 ...); default: $SLURM_ARRAY_TASK_ID, $PDG_INDEX or\n"
    "                        $CUE_IFRAME. -o may hold {wedge} (0003) and {scene}; OUTDIR/wedge.json\n"
    "                        records what ran\n"
    "  --up z|y              the axes of obstacles.ply: y turns Z-up into Y-up (Houdini, Maya),\n"
    "                        (x, y, z) -> (x, z, -y); default z. The cache keeps the engine's axes\n"
    "  --scale S             obstacles.ply's vertices times S (1e-6 to 1e6, after --up; default 1)\n"
    "  --preset P            houdini or maya: --up y; blender: --up z (a flag given wins). Export\n"
    "                        the frames with the same flags (docs/export.md), and they and the\n"
    "                        obstacles meet; render and export read obstacles.ply back into the\n"
    "                        cache's axes, as its header says\n"
    "\n"
    "SIGINT (Ctrl-C) or SIGTERM saves a checkpoint at the end of the current frame and exits with\n"
    "status 130 or 143; a second signal ends the run at once. docs/resume.md has the details.\n"
    "\n"
    "Under MPI, 'mpirun -np P flockmorph run ...' runs either mode on P ranks of --threads N\n"
    "threads each, with the same cache bytes as one process (docs/scale-out.md). Every rank must\n"
    "be started with the same scene, options and FM_ variables, or every rank stops with exit 1.\n";

/* --set KEY=VALUE: a key before the first '=' (what it names is the scene loader's to check). */
static int parse_set(const char *arg, cli_run_options *o)
{
    const char *eq = strchr(arg, '=');
    if (!eq || eq == arg || o->set_count == FM_MAX_OVERRIDES) return -1;
    o->sets[o->set_count++] = arg;
    return 0;
}

static int parse_run(int argc, char **argv, cli_run_options *o)
{
    memset(o, 0, sizeof *o);
    o->checkpoint_every = -1;
    o->stop_after_frame = -1;
    o->log_every = 10;
    cli_utc_now(o->start_time, sizeof o->start_time);
    o->wedge = -1;
    o->argc = argc, o->argv = argv;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        long v;
        int rc;
        if ((!strcmp(a, "-o") || !strcmp(a, "--output")) && i + 1 < argc) o->outdir = argv[++i];
        else if (!strcmp(a, "--threads") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 1, 1024, &v)) return cli_usage_error(USAGE_RUN, "--threads wants a whole number from 1 to 1024, not '%s'", argv[i]);
            o->threads = (int)v;
        } else if (!strcmp(a, "--checkpoint-every") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 0, 2000000000L, &o->checkpoint_every))
                return cli_usage_error(USAGE_RUN, "--checkpoint-every wants a whole number of frames >= 0, not '%s'", argv[i]);
        } else if (!strcmp(a, "--stop-after-frame") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 0, 2000000000L, &o->stop_after_frame))
                return cli_usage_error(USAGE_RUN, "--stop-after-frame wants a frame number >= 0, not '%s'", argv[i]);
        } else if (!strcmp(a, "--set") && i + 1 < argc) {
            if (parse_set(argv[++i], o)) return cli_usage_error(USAGE_RUN, "--set wants KEY=VALUE (mde.d_min=0.05) and at most 64 of them, not '%s'", argv[i]);
        } else if (!strcmp(a, "--wedge-file") && i + 1 < argc) o->wedge_file = argv[++i];
        else if (!strcmp(a, "--wedge") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 0, 2000000000L, &o->wedge)) return cli_usage_error(USAGE_RUN, "--wedge wants a wedge index (0, 1, ...), not '%s'", argv[i]);
            o->wedge_from = "--wedge";
        } else if (!strcmp(a, "--resume")) o->resume = 1;
        else if (!strcmp(a, "--overwrite")) o->overwrite = 1;
        else if (!strcmp(a, "--quiet") || !strcmp(a, "-q")) o->quiet = 1;
        else if (!strcmp(a, "--log-every") && i + 1 < argc) {
            if (cli_parse_int(argv[++i], 0, 86400, &v)) return cli_usage_error(USAGE_RUN, "--log-every wants whole seconds from 0 to 86400, not '%s'", argv[i]);
            o->log_every = (double)v;
        } else if (i + 1 < argc && (rc = cli_axes_parse(USAGE_RUN, a, argv[i + 1], &o->axes)) != 1) {
            if (rc) return rc;
            i++;
        }
        else if (a[0] == '-') return cli_usage_error(USAGE_RUN, "unknown or incomplete option '%s'", a);
        else if (!o->scene) o->scene = a;
        else return cli_usage_error(USAGE_RUN, "unexpected argument '%s'", a);
    }
    if (!o->scene) return cli_usage_error(USAGE_RUN, "%s", "no scene file given");
    if (!o->outdir) return cli_usage_error(USAGE_RUN, "%s", "no output directory given (-o OUTDIR)");
    if (o->wedge >= 0 && !o->wedge_file) return cli_usage_error(USAGE_RUN, "%s", "--wedge needs --wedge-file");
    if (o->resume && o->overwrite)
        return cli_usage_error(USAGE_RUN, "%s", "--resume continues the run in OUTDIR and --overwrite replaces it: give one");
    return 0;
}

/* How far the run is, 0 ... 1: it ends when every agent has arrived or at the frame limit, so the
 * larger of the two fractions (frames written of the limit, agents arrived) is how much of the
 * longest it can still take is done. */
static double run_fraction(const cli_progress *p, const fm_run_info *info, int64_t frame)
{
    double by_frames = (double)(frame + 1) / (double)p->frame_limit;
    double by_agents = p->agents > 0 ? (double)info->count[FM_PHASE_ARRIVED] / (double)p->agents : 0.0;
    return fmin(1.0, fmax(by_frames, by_agents));
}

/* Seconds left at this session's pace so far; negative when not yet known. */
static double eta_seconds(const cli_progress *p, double fraction, double now)
{
    double done = fraction - p->first_fraction, spent = now - p->first_time;
    return done > 0 && spent > 0 ? spent * (1.0 - fraction) / done : -1.0;
}

/* frame F of at most L, the time, each phase the mode labels, the percentage and the ETA. */
static void format_progress(const cli_progress *p, const fm_run_info *info, int64_t frame, double fraction,
                            double now, char *out, size_t size)
{
    size_t n = (size_t)snprintf(out, size, "frame %lld of at most %lld  t = %.2f s", (long long)frame,
                                (long long)p->frame_limit - 1, info->time);
    for (int k = 0; k < FM_PHASE_ARRIVED && n < size; k++)
        if (p->phase_labels[k]) n += (size_t)snprintf(out + n, size - n, "  %s %lld", p->phase_labels[k], (long long)info->count[k]);
    double eta = eta_seconds(p, fraction, now);
    if (n < size)
        n += (size_t)snprintf(out + n, size - n, "  %s %.1f%%  done %.1f%%  %.0f s", p->phase_labels[FM_PHASE_ARRIVED],
                              100.0 * (double)info->count[FM_PHASE_ARRIVED] / (double)p->agents, 100.0 * fraction,
                              now - p->start);
    if (n < size) snprintf(out + n, size - n, eta >= 0 ? "  eta %.0f s" : "  eta ?", eta);
}

static void frame_progress(const fm_run_info *info, int64_t frame, void *user)
{
    cli_progress *p = user;
    p->frame_done = cli_seconds();
    if (!p->show) return;
    double now = p->frame_done, fraction = run_fraction(p, info, frame);
    if (p->first_frame < 0) p->first_frame = frame, p->first_fraction = fraction, p->first_time = now;
    char line[512];
    if (p->show == 2 && now - p->last_log < p->log_every) return;
    format_progress(p, info, frame, fraction, now, line, sizeof line);
    if (p->show == 1) return (void)fprintf(stderr, "\r\033[K  %s", line);
    char utc[32];
    cli_utc_now(utc, sizeof utc);
    fprintf(stderr, "%s flockmorph: progress: %s\n", utc, line), p->last_log = now;
}

/* A farm's log says when a checkpoint was written and what it cost (the cache's flush and the
 * save: they follow the last frame's progress). */
static fm_status checkpoint_logged(int64_t frames, void *user, fm_error *err)
{
    (void)err;
    const cli_progress *p = user;
    char utc[32];
    cli_utc_now(utc, sizeof utc);
    if (p->show == 2)
        fprintf(stderr, "%s flockmorph: checkpoint at frame %lld written (%.2f s)\n", utc, (long long)frames - 1,
                cli_seconds() - p->frame_done);
    return FM_OK;
}

static fm_run_control run_control(const cli_run_options *o, const cli_outputs *files, cli_progress *progress,
                                  const cli_run_hooks *hooks)
{
    fm_run_control c = fm_default_run_control();
    c.progress = frame_progress, c.progress_user = progress;
    c.resume = o->resume;
    c.checkpoint_path = files->checkpoint;
    c.checkpoint = checkpoint_logged, c.checkpoint_user = progress;
    c.checkpoint_every = cli_checkpoint_every(o);
    c.checkpoint_seconds = cli_checkpoint_seconds(o);
    c.stop = &cli_stop_signal;
    c.stop_frames = o->stop_after_frame + 1; /* 0 without one */
    if (hooks) { /* the studio's runs: cancelled by its next edit, never resumed (docs/studio.md) */
        c.stop = hooks->stop;
        c.checkpoint_path = NULL, c.checkpoint = NULL;
    }
    return c;
}

/* The state, and a new run's cache, or the interrupted run's state and the frames its cache
 * already holds. */
static int open_run(const cli_mode *mode, void *run, const cli_run_options *o, const fm_scene_def *def,
                    const cli_outputs *files, fm_cache_writer **cache)
{
    fm_error err = {0};
    const cli_mode_run *common = run;
    fm_status st = mode->create_state(run, o->threads, &err);
    if ((st = fm_dist_agree(cli_dist, st, &err)) != FM_OK) return cli_is_root() ? cli_report(&err) : (int)st;
    if (!o->resume) { /* on P ranks rank 0 writes the cache */
        if (cli_is_root()) cli_start_over(files);
        if (cli_is_root()) *cache = mode->create_cache(run, def, files->cache, &err);
        int rc = cli_is_root() && !*cache ? cli_report(&err) : 0;
        return cli_agree(rc, NULL);
    }
    st = fm_dist_agree(cli_dist, mode->load_checkpoint(run, files->checkpoint, &err), &err); /* every rank reads it */
    if (st != FM_OK) return cli_is_root() ? cli_report(&err) : (int)st;
    if (cli_is_root()) *cache = fm_cache_writer_resume(files->cache, (uint32_t)common->totals->frames, &err);
    return cli_agree(cli_is_root() && !*cache ? cli_report(&err) : 0, NULL);
}

/* A rank but 0 after the run: the exit status rank 0 gives for the same outcome (the ranks agreed
 * on it), without the messages. */
static int rank_exit_status(fm_status st, int planned)
{
    if (planned) return 0;
    if (st == FM_STOPPED) return 128 + (cli_stop_signal ? cli_stop_signal : SIGTERM);
    return (int)st;
}

/* OUTDIR/obstacles.ply: the scene's obstacle meshes placed in the world, loaded as the modes load
 * them (fm_obstacle_mesh_load), so that `render` can draw them and Blender or Houdini import them
 * beside the cache; in the axes and units --up, --scale and --preset choose (converted as `export`
 * converts frames), which its header names for render and export to read them back. Nothing is
 * written for a scene without obstacles. */
static int write_obstacles(const fm_scene_def *def, const cli_axes *axes, const char *path)
{
    if (def->obstacle_count == 0) return 0;
    fm_error err = {0};
    fm_mesh meshes[FM_MAX_OBSTACLES];
    fm_ply_mesh views[FM_MAX_OBSTACLES];
    char names[FM_MAX_OBSTACLES][FM_PATH_MAX + 32], comment[64];
    fm_status st = FM_OK;
    int loaded = 0, rc = 0;
    for (; loaded < def->obstacle_count && st == FM_OK && !rc; loaded++) {
        st = fm_obstacle_mesh_load(def, loaded, NULL, NULL, &meshes[loaded], &err);
        if (st == FM_OK) rc = cli_axes_mesh_to(axes, &meshes[loaded]);
        snprintf(names[loaded], sizeof names[loaded], "obstacles.meshes[%d] %s", loaded, def->obstacles[loaded].path);
        views[loaded] = (fm_ply_mesh){names[loaded], meshes[loaded].v, meshes[loaded].nv, meshes[loaded].tri,
                                      meshes[loaded].nt};
    }
    cli_axes_comment(axes, comment, sizeof comment);
    if (st == FM_OK && !rc) st = fm_export_ply_meshes(views, def->obstacle_count, comment, path, &err);
    for (int i = 0; i < loaded; i++) fm_mesh_free(&meshes[i]);
    return rc ? rc : st == FM_OK ? 0 : cli_report(&err);
}

/* The run after the model build: the cache (new, or the interrupted run's), the simulation with
 * checkpoints and the stop signals, then the finished cache, stats.json and the summary; the
 * checkpoint of a complete run is removed. */
static int simulate(const cli_mode *mode, void *run, const cli_run_options *o, const fm_scene_def *def,
                    double prep_seconds, const cli_run_hooks *hooks)
{
    fm_error err = {0};
    cli_outputs files;
    cli_run_outputs(o, def, &files);
    fm_cache_writer *cache = NULL;
    int rc = open_run(mode, run, o, def, &files, &cache);
    if (rc) return rc;
    if (hooks && cache) hooks->cache_ready(cache, hooks->user);
    const cli_mode_run *common = run;
    const int64_t agents = common->agents;
    cli_progress progress = {.show = o->quiet || !cli_is_root() ? 0 : isatty(STDERR_FILENO) ? 1 : 2, .agents = agents,
                             .frame_limit = def->frame_limit, .start = cli_seconds(), .log_every = o->log_every,
                             .last_log = -INFINITY, .phase_labels = mode->phase_labels, .first_frame = -1};
    const fm_run_control control = run_control(o, &files, &progress, hooks);
    if (!hooks) cli_catch_stop_signals(1); /* the run checkpoints and stops at the end of the frame */
    fm_status st = mode->simulate(run, cache, &control, &err);
    if (!hooks) cli_catch_stop_signals(0);
    if (hooks && st == FM_STOPPED) return fm_cache_writer_close_partial(cache), FM_STOPPED; /* cancelled */
    if (progress.show == 1) fprintf(stderr, "\n");
    const int planned = st == FM_STOPPED && !cli_stop_signal; /* --stop-after-frame, not a signal */
    if (!cli_is_root()) return rank_exit_status(st, planned);
    const fm_run_totals *t = common->totals;
    if (planned) return cli_report_stopped_as_asked(o, cache, t->frames);
    if (st == FM_STOPPED) return cli_report_interrupted(o, cache, t->frames);
    if (st != FM_OK) cli_locate_quantum(def, &err);
    if (st != FM_OK) return cli_report_failed(o, &files, cache, &err);
    if (fm_cache_writer_finish(cache, &err) != FM_OK) { /* finish keeps PATH.partial on failure */
        cli_locate_quantum(def, &err);
        return cli_fail_keeping_partial_cache(&err, NULL, files.cache);
    }
    const cli_run_record record = {mode->name, agents, t->frames, t->steps, common->time_step, prep_seconds,
                                   t->simulate_seconds, t->output_seconds, files.threads, files.cache, o};
    const cli_axes axes = cli_axes_chosen(&o->axes);
    if ((rc = write_obstacles(def, &axes, files.obstacles))) return rc;
    if ((rc = mode->write_stats(run, def, files.stats, &record))) return rc;
    cli_remove_checkpoint(&files);
    printf("agents %lld, frames %lld, steps %lld, %.3g agent-steps/s", (long long)agents, (long long)record.frames,
           (long long)record.steps, cli_agent_steps_per_second(&record));
    mode->summary(run, def);
    printf("cache: %s\nstats: %s\n", files.cache, files.stats);
    if (def->obstacle_count > 0) printf("obstacles: %s\n", files.obstacles);
    return 0;
}

/* The scene's mode: the CLI's one choice by mode. */
static const cli_mode *scene_mode(const fm_scene_def *def)
{
    if (def->group_count > 0) return def->mode == FM_MODE_SHAPE_FLOCK ? &cli_mode_flock_shot : &cli_mode_shot;
    return def->mode == FM_MODE_SHAPE_FLOCK ? &cli_mode_flock : &cli_mode_morph;
}

static int run_scene(const cli_run_options *o, const fm_scene_def *def, const cli_run_hooks *hooks)
{
    const cli_mode *mode = scene_mode(def);
    void *run = calloc(1, mode->size);
    if (!run) return fprintf(stderr, "flockmorph: out of memory\n"), FM_ERR_MEMORY;
    int show = !o->quiet && isatty(STDERR_FILENO);
    cli_model_keep *keep = hooks ? hooks->keep : NULL;
    ((cli_mode_run *)run)->keep = keep;
    ((cli_mode_run *)run)->scene_text = hooks ? hooks->scene_text : NULL;
    if (keep) keep->reused = keep->groups_reused = keep->grids_reused = keep->routes_reused = 0;
    if (keep) keep->cancel = hooks->stop; /* an edit stops the build at its next stage boundary */
    double t0 = cli_seconds();
    if (!hooks) cli_end_on_stop_signals(1); /* the build cannot stop halfway; a signal ends it, saying so */
    int rc = mode->build(run, def, &show);
    if (!hooks) cli_end_on_stop_signals(0);
    rc = cli_agree(rc, NULL); /* the same model on every rank */
    double prep_seconds = cli_seconds() - t0;
    if (keep) keep->build_seconds = prep_seconds;
    if (show) fprintf(stderr, "\n"); /* after the preparation's progress line */
    if (!rc && hooks && *hooks->stop) rc = FM_STOPPED; /* cancelled while the model was built */
    if (!rc) rc = simulate(mode, run, o, def, prep_seconds, hooks);
    mode->close(run);
    free(run);
    return rc;
}

/* The output directory, taken (by rank 0 on P ranks), and the manifest's first version. */
static int take_outdir(const cli_run_options *o, const cli_overrides *ov, const fm_scene_def *def)
{
    const char *outputs[] = {def->cache_name, FM_OUTPUT_STATS, FM_OUTPUT_MANIFEST, FM_OUTPUT_OBSTACLES};
    int rc = cli_check_json_path("-o", o->outdir);
    if (!rc) rc = cli_make_outdir(o->outdir, outputs, 4);
    if (!rc) rc = cli_lock_outdir(o->outdir); /* before anything there is removed or read */
    if (!rc && !o->resume && !o->overwrite) rc = cli_refuse_earlier_results(o->outdir, def->cache_name);
    if (!rc && o->resume) rc = cli_check_checkpoint(o, def); /* before the long preprocessing */
    if (!rc) rc = cli_write_manifest(o, ov, def, -1);
    return rc;
}

/* The output directory, taken, and the manifest's first version; then the run and its last. */
static int run_in_outdir(const cli_run_options *o, const cli_overrides *ov, const fm_scene_def *def)
{
    int rc = cli_agree(cli_is_root() ? take_outdir(o, ov, def) : 0, NULL);
    if (rc) return cli_unlock_outdir(), rc;
    rc = run_scene(o, def, NULL);
    int manifest = cli_is_root() ? cli_write_manifest(o, ov, def, rc) : 0;
    cli_unlock_outdir(); /* the run is over: the next may take the folder */
    return rc ? rc : manifest;
}

int cli_run_scene_hooked(const cli_run_options *o, const fm_scene_def *def, const cli_run_hooks *hooks)
{
    return run_scene(o, def, hooks);
}

void cli_model_keep_free(cli_model_keep *keep)
{
    cli_morph_keep_free(keep); /* each beside its mode: the engine's headers of the two modes */
    cli_flock_keep_free(keep);
    *keep = (cli_model_keep){0};
}

int cli_run(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_RUN), 0;
    cli_run_options o;
    cli_overrides ov;
    memset(&ov, 0, sizeof ov);
    fm_scene_def def;
    int rc = parse_run(argc, argv, &o);
    if (!rc) rc = cli_threads_fit(fm_threads(o.threads));
    if (!rc) rc = cli_overrides_prepare(&o, &ov); /* the wedge's index is chosen here */
    if (!rc) rc = cli_expand_outdir(&o);
    if (!rc) rc = cli_overrides_load(&o, &ov, &def);
    rc = cli_ranks_agree(rc, &o, &ov, &def); /* every rank, whatever its rc: no rank waits for one that left */
    if (!rc) cli_shot_use_overrides(ov.set, ov.count, ov.base_seed, def.seed);
    if (!rc) rc = run_in_outdir(&o, &ov, &def);
    cli_overrides_free(&ov);
    return rc;
}
