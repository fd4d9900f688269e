/* The command line's shared helpers; each command lives in tools/cli_<command>.c. */
#ifndef FM_CLI_H
#define FM_CLI_H

#include "flockmorph/flockmorph.h"
#include "fm_internal.h"
#include "dist.h"
#include "slabs.h"

#include <jansson.h>
#include <signal.h>
#include <stdint.h>

/* Commands: argc/argv start after the command's name. Each returns the process exit status. */
int cli_run(int argc, char **argv);
int cli_export(int argc, char **argv);
int cli_render(int argc, char **argv);
int cli_inspect(int argc, char **argv);
int cli_info(int argc, char **argv); /* inspect --json */
int cli_wedge(int argc, char **argv); /* wedge list | count (cli_wedge.c) */
int cli_studio(int argc, char **argv); /* the browser studio (cli_studio.c, docs/studio.md) */

double cli_seconds(void);
/* Prints "flockmorph: <fmt with arg>" and "see 'flockmorph help CMD'" (CMD from the usage text's
 * first line) instead of the whole usage; returns FM_ERR_USAGE. */
int cli_usage_error(const char *usage, const char *fmt, const char *arg);
/* Prints the error; returns its status as the exit code. */
int cli_report(const fm_error *err);
/* A model build's failure: cli_report, but a build the studio cancelled (FM_STOPPED: an edit
 * supersedes its run) returns FM_STOPPED and prints nothing. */
int cli_report_build(const fm_error *err);
/* The message cli_report last printed on this thread ("" before any): the studio's worker shows a
 * failed run's reason on the page. */
extern _Thread_local char cli_last_error[2048];
/* A message that starts with a bare scene key ("shape_flock.deform.sequence: ..."; the shape flock's
 * meshes are named that way) gets the key's FILE:LINE:COL in front, as the scene's own errors have. */
void cli_locate_key(const fm_scene_def *def, fm_error *err);
/* The cache writer's quantisation failure names output.quantum, where the scene sets it, and the fix. */
void cli_locate_quantum(const fm_scene_def *def, fm_error *err);
/* stats.json and the manifest record the output paths as JSON text, which is UTF-8: a path that is
 * not (bytes from another locale) is refused up front with exit 1 ("-o DIR: ... not UTF-8").
 * cli_json_string never loses a value: text that is not UTF-8 is kept with each bad byte as \xNN. */
int cli_check_json_path(const char *option, const char *path);
json_t *cli_json_string(const char *text);
int cli_wants_help(int argc, char **argv);
/* Parses a whole number in [lo, hi]; -1 if it is not one. */
int cli_parse_int(const char *s, long lo, long hi, long *out);
/* Parses a finite number > 0; -1 if it is not one. */
int cli_parse_positive(const char *s, double *out);
/* A finite number that fills s: 0, or -1 if s is not one. */
int cli_parse_number(const char *s, double *out);
/* A frame-number pattern (frames.%04d.ply): exactly one integer conversion %d, %i or %u with an
 * optional 0 flag and a width of at most 2 digits, and %% for a literal %; 0 if it is one, -1
 * otherwise. cli_frame_name prints it with the frame number (the pattern was checked). */
int cli_check_frame_pattern(const char *pattern);
int cli_frame_name(char *out, size_t size, const char *pattern, long frame);
/* Creates dir (and parents) if needed and checks that it is writable and that none of the output
 * file names (nor their .partial) is taken by a directory; 0, or FM_ERR_USAGE with a message. */
int cli_make_outdir(const char *dir, const char *const *names, int count);
/* The obstacles that go with a cache (cli_obstacles.c): the mesh FILE of --obstacles (given), or
 * else obstacles.ply beside the cache, which `run` writes, when it is there; path gets the file read
 * ("" for none). 0 (out->nt is 0 when there are none), or the input error naming the file that
 * cannot be read (exit 2, printed; beside the cache it says that --no-obstacles leaves it out). */
struct fm_mesh;
int cli_cache_obstacles(const char *cache, const char *given, struct fm_mesh *out, char path[FM_PATH_MAX + 32]);
/* --up, --scale and --preset (cli_axes.c, docs/export.md#axes): the axes and units of the files
 * written for other tools, which `export` and `run` take alike. */
typedef struct cli_preset {
    const char *name;
    int up_y;
    int four_digit_names; /* export: --name '<cache name>.%04d.<ext>' (Houdini's $F4, Maya's ####) */
    long start;           /* export: --start */
} cli_preset;
typedef struct cli_axes_options {
    int up_y, has_up;         /* --up y; has_up: --up was given, which wins over a preset's */
    double scale;             /* --scale; 0 when not given (1) */
    const cli_preset *preset; /* --preset, or NULL */
} cli_axes_options;
/* A convention: the engine's Z-up turned to Y-up or not, then a scale; {0, 1} is the engine's own. */
typedef struct cli_axes {
    int up_y;
    double scale;
} cli_axes;
/* When option is --up, --scale or --preset: value parsed into o, and 0 or the usage error's status
 * (printed, naming the option); 1 for any other option. */
int cli_axes_parse(const char *usage, const char *option, const char *value, cli_axes_options *o);
/* The convention the options choose: --up, else the preset's, else z; --scale, else 1. */
cli_axes cli_axes_chosen(const cli_axes_options *o);
/* n vectors from the engine's axes and units into a's: --up y, then --scale. */
void cli_axes_to(const cli_axes *a, float *xyz, size_t n);
/* A mesh's vertices as frames are converted: to float, then cli_axes_to. 0, or FM_ERR_MEMORY printed. */
int cli_axes_mesh_to(const cli_axes *a, struct fm_mesh *m);
/* The header line that names a file's convention ("flockmorph axes: up y, scale 2.5", the scale in
 * the fewest digits that read back exactly): every obstacle file flockmorph writes has it. */
void cli_axes_comment(const cli_axes *a, char *out, size_t size);
/* The convention a mesh file's header names (a PLY comment, or an OBJ's leading # line, as
 * cli_axes_comment writes it): 1 and *a, 0 when it names none (the engine's axes), -1 when the
 * line is malformed; line (size bytes) gets the last header line read, for a message. */
int cli_axes_of_file(const char *path, cli_axes *a, char *line, size_t size);
/* Undoes cli_axes_mesh_to on the vertices (exact for the turn, and for the scale where no two floats
 * land on one: a power of two, say). */
void cli_axes_mesh_from(const cli_axes *a, struct fm_mesh *m);
/* stats.json's "axes": {"up": "z"|"y", "scale": S, "preset": NAME or null}, the convention chosen. */
json_t *cli_axes_json(const cli_axes_options *o);
/* The scene file's name without its folder and its .json, or the folder's name for a file named
 * scene.json (examples/words/scene.json is "words"): -o's {scene}, render's burn-in. */
void cli_scene_stem(const char *scene, char *out, size_t size);
/* Takes the output directory for this run until cli_unlock_outdir or the process's exit (an
 * exclusive flock on dir/.flockmorph.lock); 0, or FM_ERR_USAGE with a message when another run
 * holds it. cli_unlock_outdir removes the lock file, still held, and releases it. */
int cli_lock_outdir(const char *dir);
void cli_unlock_outdir(void);
/* FM_ERR_USAGE with a message if dir holds a finished run's results (the cache or stats.json
 * under their final names), which a new run would replace: --overwrite says that is meant. */
int cli_refuse_earlier_results(const char *dir, const char *cache_name);

/* `run`: its options (cli_run.c). */
typedef struct cli_run_options {
    const char *scene, *outdir;
    int threads, quiet, resume;
    int overwrite;         /* --overwrite: replace a finished run's results in OUTDIR */
    long checkpoint_every; /* -1: by wall time (the default) */
    long stop_after_frame; /* -1: none */
    double log_every;      /* seconds between the plain progress lines when stderr is not a terminal */
    char start_time[32];   /* UTC, ISO 8601, when the command started (cli_utc_now) */
    const char *sets[FM_MAX_OVERRIDES]; /* --set KEY=VALUE, in order */
    int set_count;
    const char *wedge_file;             /* --wedge-file W, or NULL */
    long wedge;                         /* --wedge I; -1 until chosen (cli_wedge_index) */
    const char *wedge_from;             /* where the index came from: "--wedge", "SLURM_ARRAY_TASK_ID" ... */
    char outdir_buf[FM_PATH_MAX];       /* -o with its {wedge} and {scene} filled in (outdir points here) */
    int argc;
    char **argv;                        /* as typed, for the manifest */
    cli_axes_options axes;              /* --up, --scale, --preset: obstacles.ply's axes and units */
} cli_run_options;

/* `flockmorph studio` runs a scene through run's one path (cli_run.c), so that the frames it shows
 * are the frames `run` writes: in OUTDIR (made by the caller), with the studio's stop flag instead
 * of the signals' and no checkpoints; cache_ready gets the cache writer before frame 0 (to tap the
 * frames: fm_cache_writer_set_tap). Returns run's exit status, or FM_STOPPED when stopped. */
typedef struct cli_model_keep cli_model_keep;
typedef struct cli_run_hooks {
    volatile sig_atomic_t *stop;
    void (*cache_ready)(fm_cache_writer *cache, void *user);
    void *user;
    cli_model_keep *keep; /* NULL, or what the model build keeps for the next run (below) */
    const char *scene_text; /* NULL, or the scene's text as edited: a shot's groups are read from it,
                               not from the file (the studio's edits of a shot) */
} cli_run_hooks;

/* The studio's runs keep the costly part of the model (TetGen's tets and the tets at n, or the
 * shape flock's samples and match) for the next run of an edited scene, which reuses it where its
 * inputs are unchanged (fm_morph_model_build_keeping, fm_flock_model_build_keeping; docs/studio.md,
 * "An edit and the model"); a shot keeps each group's the same way (fm_shot_build_keeping,
 * fm_flock_shot_build_keeping). Both modes keep their obstacles' grids and routed paths too. */
struct cli_model_keep {
    struct fm_morph_keep *morph; /* FM_MAX_GROUPS of each, made at the first build of its mode: a scene's */
    struct fm_flock_keep *flock; /* in [0], a shot's group g's in [g] */
    int reused;                  /* the last build reused the costly part (a shot: of every group) */
    int groups_reused;           /* ... of how many groups (a scene: 0 or 1) */
    int grids_reused;            /* of how many groups the obstacles' distance grid was kept */
    int routes_reused;           /* ... and the routed path (the tetra morph: with its navigation function) */
    volatile sig_atomic_t *cancel; /* the studio's stop flag: every keep's (cli_morph_keeps, cli_flock_keeps) */
    double build_seconds;        /* the last build's wall time */
};
void cli_model_keep_free(cli_model_keep *keep);
/* The keeps of its mode, made at the first call (cli_mode_morph.c, cli_mode_flock.c): NULL, printed,
 * when out of memory. */
struct fm_morph_keep *cli_morph_keeps(cli_model_keep *keep);
struct fm_flock_keep *cli_flock_keeps(cli_model_keep *keep);
void cli_morph_keep_free(cli_model_keep *keep); /* its morph part (cli_mode_morph.c) */
void cli_flock_keep_free(cli_model_keep *keep); /* its flock part (cli_mode_flock.c) */
int cli_run_scene_hooked(const cli_run_options *o, const fm_scene_def *def, const cli_run_hooks *hooks);

/* A wedge file (docs/wedges.md): a list of override sets ({"wedges": [{KEY: VALUE, ...}, ...]}) or
 * the product of value lists and ranges ({"product": {KEY: [v, ...] or {"from", "to", "count"}}},
 * the last key varying fastest). */
typedef struct cli_wedges {
    const char *path;
    json_t *list;  /* "wedges": the array of objects; "product": an object of KEY: [values] */
    int product;
    long count;
} cli_wedges;
/* Reads and checks a wedge file; 0 or an exit status (the error printed). */
int cli_wedges_load(const char *path, cli_wedges *w);
void cli_wedges_free(cli_wedges *w);
/* Wedge `index`'s overrides, {KEY: VALUE, ...} in the file's order (a new reference). */
json_t *cli_wedge_overrides(const cli_wedges *w, long index);
/* o->wedge from --wedge, else SLURM_ARRAY_TASK_ID, PDG_INDEX or CUE_IFRAME (o->wedge_from says
 * which), checked against the count; 0 or FM_ERR_USAGE with a message. */
int cli_wedge_index(cli_run_options *o, long count);
/* The seed of a wedge that sets none (docs/wedges.md): 63 bits of fm_random_bits(base, stream
 * "WEDGE", index). */
uint64_t cli_wedge_seed(uint64_t base, long index);
/* VALUE as --set takes it: JSON text, reals in the fewest digits that read back exactly (a new
 * malloc'ed string, or NULL). */
char *cli_json_text(const json_t *v);
/* o->outdir from the -o template: {wedge} is the index as 4 digits or more (0003), {scene} the
 * scene file's name without its folder and .json (its folder's name for a scene.json); 0 or
 * FM_ERR_USAGE with a message. */
int cli_expand_outdir(cli_run_options *o);

/* The run's overrides: the wedge's, then --set's (a later one wins), as the scene loader takes
 * them, and what the manifest records (cli_overrides.c). */
typedef struct cli_overrides {
    fm_scene_override set[FM_MAX_OVERRIDES];
    char *owned[2 * FM_MAX_OVERRIDES]; /* the keys and values this struct allocated */
    int count, owned_count;
    cli_wedges wedges;                 /* with --wedge-file (cli_overrides_prepare) */
    json_t *wedge;                     /* the wedge's {KEY: VALUE}, or NULL */
    long wedge_count;                  /* of its file */
    char origin[FM_PATH_MAX + 32];     /* "W.json: wedge 3", how errors name the wedge's values */
    uint64_t base_seed;
    int seed_derived;                  /* the wedge and --set gave no seed: cli_wedge_seed */
    char start_time[32];
} cli_overrides;
/* Reads the wedge file, picks the wedge and builds the override list; 0 or an exit status. */
int cli_overrides_prepare(cli_run_options *o, cli_overrides *ov);
/* Adds wedge `index` of w (which ov does not own) to ov's overrides. */
int cli_overrides_add_wedge(const cli_wedges *w, long index, cli_overrides *ov);
/* Loads the scene with the overrides and gives a wedge that sets no seed its derived one. */
int cli_overrides_load(const cli_run_options *o, cli_overrides *ov, fm_scene_def *def);
/* OUTDIR/wedge.json (with --set or a wedge): at the start (exit_status < 0: "running") and at the
 * end; a plain run removes an earlier run's at its start. */
int cli_write_manifest(const cli_run_options *o, const cli_overrides *ov, const fm_scene_def *def, int exit_status);
void cli_overrides_free(cli_overrides *ov);
/* Where a run writes (OUTDIR/<output.cache>, OUTDIR/stats.json, OUTDIR/checkpoint.fmck,
 * OUTDIR/obstacles.ply) and with how many threads. */
typedef struct cli_outputs {
    char cache[FM_PATH_MAX + 300];
    char stats[FM_PATH_MAX + 16];
    char checkpoint[FM_PATH_MAX + 32];
    char obstacles[FM_PATH_MAX + 32];
    int threads;
} cli_outputs;
void cli_run_outputs(const cli_run_options *o, const fm_scene_def *def, cli_outputs *out);
/* The checkpoint's frames (--checkpoint-every K: K; by default none: cli_checkpoint_seconds). */
int64_t cli_checkpoint_every(const cli_run_options *o);
double cli_checkpoint_seconds(const cli_run_options *o);
/* A new run (not --resume): warns if an interrupted run's checkpoint is in the way, and removes it
 * with the previous run's cache, stats.json and obstacles.ply. */
void cli_start_over(const cli_outputs *out);
void cli_remove_checkpoint(const cli_outputs *out); /* and its .partial, and a shot's groups' files */
/* --resume: the checkpoint checked against the scene (fm_checkpoint_check), before preprocessing. */
int cli_check_checkpoint(const cli_run_options *o, const fm_scene_def *def);
/* After a planned stop (--stop-after-frame): the partial cache kept, how to continue; returns 0. */
int cli_report_stopped_as_asked(const cli_run_options *o, fm_cache_writer *cache, int64_t frames);
/* After a stop (FM_STOPPED: the checkpoint is written): keeps the cache's frames as .partial for
 * --resume and prints how to resume; returns 128 + the signal. */
int cli_report_interrupted(const cli_run_options *o, fm_cache_writer *cache, int64_t frames);
/* After a failed run: with a checkpoint, keeps it and the partial cache and prints how to resume
 * once the cause is fixed; without, as cli_fail_keeping_partial_cache. Returns the exit status. */
int cli_report_failed(const cli_run_options *o, const cli_outputs *out, fm_cache_writer *cache, const fm_error *err);
/* The frame progress's state: a line redrawn on a terminal (show 1), or a plain line every
 * log_every seconds when stderr is not one (show 2, a farm's log); none with --quiet (show 0). */
typedef struct cli_progress {
    int show;
    int64_t agents, frame_limit;
    double start, log_every, last_log;
    const char *const *phase_labels; /* the mode's (cli_mode) */
    double first_fraction, first_time; /* at the first frame of this session (ETA of a resumed run) */
    int64_t first_frame;               /* -1 until then */
    double frame_done;                 /* when the last frame was handed over (a checkpoint follows it) */
} cli_progress;
/* Preprocessing progress on stderr when *(int *)user (an fm_progress_fn). */
void cli_prep_progress(const char *stage, double fraction, void *user);
/* The scene's output.* cache options. */
fm_cache_options cli_cache_options(const fm_scene_def *def);
/* stats.json's keys that both modes write: mode, agents, frames, steps, timings and rates, threads,
 * seed and cache. The caller adds its own and passes j to cli_write_json. */
typedef struct cli_run_record {
    const char *mode;
    int64_t agents, frames, steps;
    double time_step, preprocess_seconds, simulate_seconds, output_seconds;
    int threads;
    const char *cache;
    const cli_run_options *options; /* the scene, the command line, the start time */
} cli_run_record;
json_t *cli_stats_json(const fm_scene_def *def, const cli_run_record *r);
/* stats.json's schema number (docs/stats.md): raised when a key changes meaning or goes away. */
#define CLI_STATS_SCHEMA 1
/* schema, commit, scene, scene_absolute, scene_xxh64, command_line, working_directory, start_time,
 * machine (cli_stats.c). */
void cli_stats_provenance(json_t *j, const cli_run_options *o);
/* The absolute form of path: realpath where it exists, else the working directory joined to it. */
json_t *cli_absolute_path(const char *path);
/* "cache" as given and "cache_absolute". */
void cli_stats_cache_path(json_t *j, const char *cache);
/* stats.json's "meshes": every mesh file the scenes (one, or a shot's groups) read, with its XXH64. */
json_t *cli_meshes_json(const fm_scene_def *defs, int count);
/* What made the cache at `cache` (of `agents` and `frames`): the provenance keys of the stats.json
 * beside it, when that stats.json names a cache of this file name, agents and frames; json null
 * otherwise (inspect --json). */
json_t *cli_cache_provenance(const char *cache, int64_t agents, int64_t frames);
/* Now, UTC, ISO 8601: 2026-12-02T08:05:46Z. */
void cli_utc_now(char *out, size_t size);
double cli_agent_steps_per_second(const cli_run_record *r);

/* What the run path reads of a mode's run context: its first member, set by build(). */
typedef struct cli_mode_run {
    int64_t agents;
    double time_step;
    const fm_run_totals *totals; /* the run statistics' frames, steps and seconds */
    cli_model_keep *keep;        /* set before build(): the studio's keep, or NULL */
    const char *scene_text;      /* set before build(): the hooks' scene_text, or NULL */
} cli_mode_run;

/* One simulation mode as `run` drives it: cli_run.c holds the one run path, and each mode fills a
 * table (cli_mode_morph.c, cli_mode_flock.c). `run` is the mode's context (a cli_mode_run first):
 * `size` bytes, zeroed, owned by the run path; close() frees what the others made. Each
 * int-returning call gives 0 or an exit status (after printing the error). */
typedef struct cli_mode {
    const char *name;             /* stats.json "mode" */
    const char *phase_labels[4];  /* the progress line's label of each fm_phase count (NULL: not
                                     shown); the last, ARRIVED, as a percentage */
    size_t size;
    int (*build)(void *run, const fm_scene_def *def, int *show_progress); /* the model, its warnings */
    fm_status (*create_state)(void *run, int threads, fm_error *err);
    /* A new run's cache with the mode's attributes and the scene's options. */
    fm_cache_writer *(*create_cache)(void *run, const fm_scene_def *def, const char *path, fm_error *err);
    /* --resume: the checkpoint's state and statistics (after create_state). */
    fm_status (*load_checkpoint)(void *run, const char *path, fm_error *err);
    fm_status (*simulate)(void *run, fm_cache_writer *cache, const fm_run_control *control, fm_error *err);
    int (*write_stats)(void *run, const fm_scene_def *def, const char *path, const cli_run_record *record);
    /* The rest of the summary line ("; ..." and the newline) and any warning that follows it. */
    void (*summary)(const void *run, const fm_scene_def *def);
    void (*close)(void *run);
} cli_mode;
extern const cli_mode cli_mode_morph, cli_mode_flock, cli_mode_shot, cli_mode_flock_shot;
/* The run's overrides, which the shot mode reads each group with, and the seed the file gave and the
 * run's (a wedge's derived one), which the groups that keep the file's take (cli_mode_shot.c). */
void cli_shot_use_overrides(const fm_scene_override *set, int count, uint64_t file_seed, uint64_t run_seed);
/* A shot's checkpoint against its first group's scene (with the run's overrides and seed), before the
 * model build: 0, or the reported exit status. */
int cli_check_shot_checkpoint(const char *path, const fm_scene_def *def);
/* Every group of the shot read with the overrides as the run reads it (cli_shot_use_overrides
 * first): 0, or the first group's error printed and its status. */
int cli_shot_check_groups(const fm_scene_def *def);
/* Writes j (indented) to path through fm_output_*, then frees it; 0 or an exit status. */
int cli_write_json(const char *path, json_t *j);
/* A new run first removes the previous run's cache and stats.json, so that should this one fail,
 * the old results cannot pass for its own. */
void cli_remove_previous_results(const char *cache, const char *stats);
/* A run that failed while writing (disk full, file-size limit): prints err, keeps the cache's frames
 * so far as CACHE.partial (cache may already be gone: NULL), says how many complete frames it holds
 * (or removes it when it holds none) and that no stats.json was written; returns the exit status. */
int cli_fail_keeping_partial_cache(const fm_error *err, fm_cache_writer *cache, const char *cache_path);
/* SIGINT / SIGTERM while catching (cli_catch_stop_signals(1)): the first sets cli_stop_signal to
 * the signal's number, which both modes' runs read at every frame boundary (the exit status is then
 * 128 + it); a second one ends the process at once. cli_catch_stop_signals(0) restores the default. */
extern volatile sig_atomic_t cli_stop_signal;

/* The ranks of a run under mpirun (flockmorph.c; NULL without one: dist.h's P = 1). Rank 0 alone
 * touches the output directory and prints; every rank simulates its share. */
extern fm_dist *cli_dist;
static inline int cli_is_root(void) { return fm_dist_rank(cli_dist) == 0; }
/* The ranks agree on an exit code (the worst); rank 0 has printed its own reason, and prints
 * err's when another rank's was worse (err may be NULL: nothing to tell). */
int cli_agree(int rc, fm_error *err);
/* Starts and ends `threads` - 1 threads as OpenMP will: 0, or the reported exit status (4 when
 * their stacks do not fit) instead of libgomp's exit 1 in the first parallel region. */
int cli_threads_fit(int threads);
/* Collective, called by every rank whatever its rc (the exit status so far: its command line, its
 * scene): the ranks agree on the worst rc, then that they run the same job (the scene as loaded, -o,
 * --resume, --stop-after-frame, --checkpoint-every, the version, the FM_ environment; cli_ranks.c).
 * A difference is exit 1, naming the rank and what differs; 0 when every rank runs rank 0's job. */
int cli_ranks_agree(int rc, const cli_run_options *o, const cli_overrides *ov, const fm_scene_def *def);
/* On P ranks (docs/scale-out.md): what the decomposition cost, every rank's sends together, and
 * its stats.json object. These depend on P, as the timings do; everything else does not. */
fm_dist_totals cli_sum_totals(fm_dist_totals mine);
json_t *cli_scale_out_json(const fm_dist_totals *t);
void cli_catch_stop_signals(int catch);
/* While the model is built (no frame yet): SIGINT / SIGTERM print why and end the process at once
 * with 128 + the signal; 0 restores the default action. */
void cli_end_on_stop_signals(int end);

typedef struct cli_frame_options {
    const char *cache, *out, *view;
    long frame;
    int has_frame, width, height;
} cli_frame_options;

/* CACHE -o OUT [--frame K] [--size WxH] [--view V]; -o may be omitted when optional_out. */
int cli_parse_frame_options(int argc, char **argv, const char *usage, int optional_out, cli_frame_options *o);
/* Opens a cache and prints its recovery warning, if any; 0 or an exit status. */
int cli_open_cache(const char *path, fm_cache_reader **reader);
/* Frame k of a cache with `frames` frames (k < 0 counts from the end); 0, or FM_ERR_USAGE with a
 * message naming the frame count. */
int cli_pick_frame(const char *cache, uint32_t frames, long k, uint32_t *frame);

/* A frame range as typed: "A:B" (inclusive), "A:", ":B", ":" or a single "K", each optionally
 * with ":S", every S-th frame (S >= 1); negative numbers count from the end. */
typedef struct cli_frame_range {
    long first, last, step;
    int has_first, has_last;
} cli_frame_range;

/* -1 if spec is not a range. */
int cli_parse_frame_range(const char *spec, cli_frame_range *range);
/* The range's frames of a cache (open ends: its first and last; last moved down onto the stride);
 * 0 or FM_ERR_USAGE with a message. */
int cli_resolve_frame_range(const char *cache, uint32_t frames, const cli_frame_range *range, uint32_t *first, uint32_t *last);
/* Opens the cache and reads the chosen frame (default last) into a malloc'ed array. */
int cli_load_frame(const cli_frame_options *o, fm_cache_reader **reader, float **verts, uint32_t *frame);

#endif
