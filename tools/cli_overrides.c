/* A run's overrides, the wedge's then --set's, as the scene loader takes them (fm_scene_override),
 * the seed of a wedge that sets none, and the manifest OUTDIR/wedge.json (docs/wedges.md). */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"
#include "scene_override.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>


/* Keeps s to be freed with ov; NULL stays NULL. */
static char *keep(cli_overrides *ov, char *s)
{
    if (s) ov->owned[ov->owned_count++] = s;
    return s;
}

static int add_override(cli_overrides *ov, const char *key, const char *value, const char *origin)
{
    if (!key || !value) return fprintf(stderr, "flockmorph: error: out of memory\n"), FM_ERR_MEMORY;
    if (ov->count == FM_MAX_OVERRIDES)
        return fprintf(stderr, "flockmorph: error: more than %d overrides (--set and the wedge's)\n", FM_MAX_OVERRIDES),
               FM_ERR_USAGE;
    ov->set[ov->count++] = (fm_scene_override){key, value, origin};
    return 0;
}

int cli_overrides_add_wedge(const cli_wedges *w, long index, cli_overrides *ov)
{
    ov->wedge = cli_wedge_overrides(w, index);
    ov->wedge_count = w->count;
    snprintf(ov->origin, sizeof ov->origin, "%s: wedge %ld", w->path, index);
    const char *key;
    json_t *value;
    json_object_foreach(ov->wedge, key, value) {
        int rc = add_override(ov, key, keep(ov, cli_json_text(value)), ov->origin);
        if (rc) return rc;
    }
    return 0;
}

/* The wedge file, the index, the wedge's overrides. */
static int add_wedge(cli_run_options *o, cli_overrides *ov)
{
    int rc = cli_wedges_load(o->wedge_file, &ov->wedges);
    if (!rc) rc = cli_wedge_index(o, ov->wedges.count);
    return rc ? rc : cli_overrides_add_wedge(&ov->wedges, o->wedge, ov);
}

int cli_overrides_prepare(cli_run_options *o, cli_overrides *ov)
{
    memset(ov, 0, sizeof *ov);
    snprintf(ov->start_time, sizeof ov->start_time, "%s", o->start_time);
    int rc = o->wedge_file ? add_wedge(o, ov) : 0;
    for (int i = 0; i < o->set_count && !rc; i++) { /* KEY=VALUE, checked by parse_run */
        const char *arg = o->sets[i], *eq = strchr(arg, '=');
        rc = add_override(ov, keep(ov, strndup(arg, (size_t)(eq - arg))), eq + 1, NULL);
    }
    return rc;
}

void cli_overrides_free(cli_overrides *ov)
{
    for (int i = 0; i < ov->owned_count; i++) free(ov->owned[i]);
    json_decref(ov->wedge);
    cli_wedges_free(&ov->wedges);
    memset(ov, 0, sizeof *ov);
}

static int sets_seed(const cli_overrides *ov)
{
    for (int i = 0; i < ov->count; i++)
        if (!strcmp(ov->set[i].key, "seed")) return 1;
    return 0;
}

int cli_overrides_load(const cli_run_options *o, cli_overrides *ov, fm_scene_def *def)
{
    fm_error err = {0};
    if (fm_scene_load_overridden(o->scene, ov->set, ov->count, def, &err) != FM_OK) return cli_report(&err);
    ov->base_seed = def->seed;
    ov->seed_derived = o->wedge_file && !sets_seed(ov); /* so that wedges differ, each reproducibly */
    if (ov->seed_derived) def->seed = cli_wedge_seed(def->seed, o->wedge);
    return 0;
}

/* Every key the run overrode with its final value (a later override replaces an earlier one). */
static json_t *final_overrides(const cli_overrides *ov)
{
    json_t *j = json_object();
    for (int i = 0; i < ov->count; i++) json_object_set_new(j, ov->set[i].key, fm_override_value(ov->set[i].value));
    return j;
}

static json_t *wedge_json(const cli_run_options *o, const cli_overrides *ov)
{
    if (!o->wedge_file) return json_null();
    return json_pack("{sosIsIsssO}", "file", cli_json_string(o->wedge_file), "index", (json_int_t)o->wedge, "count",
                     (json_int_t)ov->wedge_count, "index_from", o->wedge_from, "overrides", ov->wedge);
}

static json_t *strings_json(const char *const *s, int n)
{
    json_t *a = json_array();
    for (int i = 0; i < n; i++) json_array_append_new(a, cli_json_string(s[i])); /* not UTF-8: kept as \xNN */
    return a;
}

static const char *status_name(int exit_status)
{
    return exit_status < 0 ? "running" : exit_status == 0 ? "finished" : exit_status > 128 ? "interrupted" : "failed";
}

int cli_write_manifest(const cli_run_options *o, const cli_overrides *ov, const fm_scene_def *def, int exit_status)
{
    char path[FM_PATH_MAX + 32], now[32], host[256] = "";
    snprintf(path, sizeof path, "%s/" FM_OUTPUT_MANIFEST, o->outdir);
    if (!o->wedge_file && !o->set_count) { /* a plain run: an earlier run's manifest would pass for its own */
        if (exit_status < 0) remove(path);
        return 0;
    }
    cli_utc_now(now, sizeof now);
    gethostname(host, sizeof host - 1);
    json_t *j = json_object();
    json_object_set_new(j, "version", json_string(FM_VERSION_STRING));
    json_object_set_new(j, "scene", cli_json_string(o->scene));
    json_object_set_new(j, "output", cli_json_string(o->outdir));
    json_object_set_new(j, "wedge", wedge_json(o, ov));
    json_object_set_new(j, "set", strings_json(o->sets, o->set_count));
    json_object_set_new(j, "overrides", final_overrides(ov));
    json_object_set_new(j, "seed", json_integer((json_int_t)def->seed));
    json_object_set_new(j, "seed_derived", json_boolean(ov->seed_derived));
    json_object_set_new(j, "base_seed", ov->seed_derived ? json_integer((json_int_t)ov->base_seed) : json_null());
    json_object_set_new(j, "resumed", json_boolean(o->resume));
    json_object_set_new(j, "arguments", strings_json((const char *const *)o->argv, o->argc));
    json_object_set_new(j, "host", json_string(host));
    json_object_set_new(j, "start_time", json_string(ov->start_time));
    json_object_set_new(j, "end_time", exit_status < 0 ? json_null() : json_string(now));
    json_object_set_new(j, "status", json_string(status_name(exit_status)));
    json_object_set_new(j, "exit_status", exit_status < 0 ? json_null() : json_integer(exit_status));
    return cli_write_json(path, j);
}
