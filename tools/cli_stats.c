/* stats.json's provenance (docs/stats.md): the schema number, the build's commit, the scene file and
 * its XXH64, every mesh file the scene read and its XXH64, the command line, the working directory,
 * the start time and the machine, so a result found later says what made it. `inspect --json`
 * gives the same for a cache with its stats.json beside it. */
#define _DEFAULT_SOURCE /* realpath, gethostname */
#include "cli.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define XXH_INLINE_ALL /* header-only: the CLI needs no link to libxxhash for one hash */
#include <xxhash.h>

#include "fm_build_commit.h" /* FM_BUILD_COMMIT, written at build time (cmake/build_commit.cmake) */

void cli_utc_now(char *out, size_t size)
{
    time_t t = time(NULL);
    struct tm tm;
    gmtime_r(&t, &tm);
    strftime(out, size, "%Y-%m-%dT%H:%M:%SZ", &tm);
}

/* XXH64 (seed 0, what `xxhsum` prints) of the file's bytes as 16 hex digits; null if unreadable. */
static json_t *file_xxh64(const char *path)
{
    FILE *f = fopen(path, "rb");
    XXH64_state_t state;
    unsigned char buf[1 << 14];
    size_t n;
    if (!f) return json_null();
    XXH64_reset(&state, 0);
    while ((n = fread(buf, 1, sizeof buf, f)) > 0) XXH64_update(&state, buf, n);
    int bad = ferror(f);
    fclose(f);
    char hex[17];
    snprintf(hex, sizeof hex, "%016llx", (unsigned long long)XXH64_digest(&state));
    return bad ? json_null() : json_string(hex);
}

/* The "model name" line of /proc/cpuinfo (x86; other machines name it otherwise): null if none. */
static json_t *cpu_model(void)
{
    FILE *f = fopen("/proc/cpuinfo", "r");
    char line[512];
    json_t *model = NULL;
    while (f && !model && fgets(line, sizeof line, f)) {
        char *colon = strchr(line, ':');
        if (strncmp(line, "model name", 10) || !colon) continue;
        colon += 1 + (colon[1] == ' ');
        colon[strcspn(colon, "\n")] = 0;
        model = json_string(colon);
    }
    if (f) fclose(f);
    return model ? model : json_null();
}

static json_t *machine_json(void)
{
    char host[256] = "";
    if (gethostname(host, sizeof host) != 0) host[0] = 0;
    host[sizeof host - 1] = 0;
    return json_pack("{s:o, s:o, s:I}", "hostname", host[0] ? json_string(host) : json_null(), "cpu_model",
                     cpu_model(), "cores", (json_int_t)sysconf(_SC_NPROCESSORS_ONLN));
}

/* The absolute form of path: realpath where it exists, else the working directory joined to it. */
json_t *cli_absolute_path(const char *path)
{
    char absolute[PATH_MAX], cwd[PATH_MAX];
    if (realpath(path, absolute)) return cli_json_string(absolute);
    if (path[0] == '/' || !getcwd(cwd, sizeof cwd)) return cli_json_string(path);
    json_t *joined = json_sprintf("%s/%s", cwd, path);
    return joined ? joined : json_null();
}

static json_t *working_directory(void)
{
    char cwd[PATH_MAX];
    return getcwd(cwd, sizeof cwd) ? cli_json_string(cwd) : json_null();
}

/* The mesh files of a run, each once (by absolute path): the first key that names it, the path,
 * its XXH64. */
typedef struct mesh_files {
    json_t *list, *seen;
} mesh_files;

static void add_mesh(mesh_files *m, const char *key, const char *path)
{
    if (!path[0]) return;
    json_t *where = cli_absolute_path(path);
    const char *text = json_string_value(where);
    if (text && !json_object_get(m->seen, text)) {
        json_object_set_new(m->seen, text, json_true());
        json_array_append_new(m->list, json_pack("{s:s, s:O, s:o}", "key", key, "path", where, "xxh64", file_xxh64(path)));
    }
    json_decref(where);
}

/* A printf pattern's files 0 .. frames - 1 (shape_flock.deform.sequence, target_motion.sequence). */
static void add_sequence(mesh_files *m, const char *prefix, const char *key, const char *pattern, int32_t frames)
{
    char path[FM_PATH_MAX + 32], label[320];
    for (int32_t i = 0; pattern[0] && i < frames; i++) {
        snprintf(path, sizeof path, pattern, i);
        snprintf(label, sizeof label, "%s%s[%d]", prefix, key, (int)i);
        add_mesh(m, label, path);
    }
}

static void add_scene_meshes(mesh_files *m, const fm_scene_def *def, const char *prefix)
{
    char key[320];
    snprintf(key, sizeof key, "%ssource.mesh", prefix);
    add_mesh(m, key, def->source.path);
    snprintf(key, sizeof key, "%starget.mesh", prefix);
    add_mesh(m, key, def->target.path);
    for (int32_t i = 0; i < def->obstacle_count; i++) {
        snprintf(key, sizeof key, "%sobstacles.meshes[%d].mesh", prefix, (int)i);
        add_mesh(m, key, def->obstacles[i].path);
    }
    add_sequence(m, prefix, "shape_flock.deform.sequence", def->flock.deform_sequence, def->flock.deform_frames);
    add_sequence(m, prefix, "target_motion.sequence", def->target_motion.sequence, def->target_motion.frames);
}

json_t *cli_meshes_json(const fm_scene_def *defs, int count)
{
    mesh_files m = {json_array(), json_object()};
    char prefix[32] = "";
    for (int g = 0; g < count; g++) {
        if (defs[g].group_index >= 0) snprintf(prefix, sizeof prefix, "groups[%d].", (int)defs[g].group_index);
        add_scene_meshes(&m, &defs[g], prefix);
    }
    json_decref(m.seen);
    return m.list;
}

static json_t *command_line(const cli_run_options *o)
{
    json_t *a = json_pack("[ss]", "flockmorph", "run");
    for (int i = 0; i < o->argc; i++) json_array_append_new(a, cli_json_string(o->argv[i])); /* not UTF-8: \xNN */
    return a;
}

void cli_stats_provenance(json_t *j, const cli_run_options *o)
{
    char absolute[PATH_MAX];
    json_object_set_new(j, "schema", json_integer(CLI_STATS_SCHEMA));
    json_object_set_new(j, "commit", json_string(FM_BUILD_COMMIT));
    json_object_set_new(j, "scene", cli_json_string(o->scene));
    json_object_set_new(j, "scene_absolute", realpath(o->scene, absolute) ? json_string(absolute) : json_null());
    json_object_set_new(j, "scene_xxh64", file_xxh64(o->scene));
    json_object_set_new(j, "command_line", command_line(o));
    json_object_set_new(j, "working_directory", working_directory());
    json_object_set_new(j, "start_time", json_string(o->start_time));
    json_object_set_new(j, "machine", machine_json());
}

void cli_stats_cache_path(json_t *j, const char *cache)
{
    json_object_set_new(j, "cache", cli_json_string(cache));
    json_object_set_new(j, "cache_absolute", cli_absolute_path(cache));
}

/* The keys of stats.json that say what made a cache, for `inspect --json`. */
static const char *const PROVENANCE_KEYS[] = {"version", "commit", "scene_absolute", "scene_xxh64", "meshes",
                                               "cache_absolute", "working_directory", "command_line", "start_time",
                                               "axes"};

static const char *file_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

/* stats.json describes this cache: the same file name (the folder may have moved, with both in
 * it), agents and frames. A cache copied in from another run fails one of them, in all likelihood. */
static int stats_of(const json_t *run, const char *cache, int64_t agents, int64_t frames)
{
    const char *named = json_string_value(json_object_get(run, "cache"));
    return named && !strcmp(file_name(named), file_name(cache)) &&
           json_integer_value(json_object_get(run, "agents")) == agents &&
           json_integer_value(json_object_get(run, "frames")) == frames;
}

json_t *cli_cache_provenance(const char *cache, int64_t agents, int64_t frames)
{
    char stats[PATH_MAX + 16];
    snprintf(stats, sizeof stats, "%.*s" FM_OUTPUT_STATS, (int)(file_name(cache) - cache), cache);
    json_t *run = json_load_file(stats, 0, NULL), *out = json_null();
    if (run && stats_of(run, cache, agents, frames)) {
        out = json_object();
        for (size_t i = 0; i < sizeof PROVENANCE_KEYS / sizeof PROVENANCE_KEYS[0]; i++) {
            json_t *v = json_object_get(run, PROVENANCE_KEYS[i]);
            json_object_set(out, PROVENANCE_KEYS[i], v ? v : json_null());
        }
        json_object_set_new(out, "stats", cli_json_string(stats));
    }
    json_decref(run);
    return out;
}
