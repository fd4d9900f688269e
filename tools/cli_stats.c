/* stats.json's provenance (docs/stats.md): the schema number, the scene file and its XXH64, the
 * command line, the start time and the machine, so a result found later says what made it. */
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
    json_object_set_new(j, "scene", cli_json_string(o->scene));
    json_object_set_new(j, "scene_absolute", realpath(o->scene, absolute) ? json_string(absolute) : json_null());
    json_object_set_new(j, "scene_xxh64", file_xxh64(o->scene));
    json_object_set_new(j, "command_line", command_line(o));
    json_object_set_new(j, "start_time", json_string(o->start_time));
    json_object_set_new(j, "machine", machine_json());
}
