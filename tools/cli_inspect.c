/* flockmorph inspect: what a cache holds, how it was written, how well it compressed, and the
 * bounds of its geometry over all frames. `info` is `inspect --json`. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"

#include <jansson.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const USAGE_INSPECT =
    "usage: flockmorph inspect CACHE [--json]\n"
    "\n"
    "Prints the cache's format version, agents, frames (and, from format 3, the frame count its\n"
    "header states), frame rate and duration, attributes, the options it was written with, file\n"
    "size, raw and compressed bytes, compression ratio, chunk sizes per frame, the bounds of its\n"
    "positions and tet vertices over all frames, and whether it is complete or was recovered from a\n"
    "run that did not finish (with a warning). docs/cache-format.md#inspecting-a-cache lists the\n"
    "JSON keys.\n"
    "\n"
    "  --json   one JSON object instead of text (`flockmorph info CACHE` is the same)\n";

static const char *scalar_name(fm_cache_scalar s)
{
    return s == FM_SCALAR_F32 ? "f32" : s == FM_SCALAR_U32 ? "u32" : "u8";
}

static json_t *attributes_json(const fm_cache_reader *r)
{
    json_t *list = json_array();
    for (int i = 0; i < fm_cache_attr_count(r); i++) {
        const fm_cache_attr_info *a = fm_cache_attr_at(r, i);
        json_array_append_new(list, json_pack("{s:s, s:i, s:s}", "name", a->name, "components", a->components,
                                              "type", scalar_name(a->scalar)));
    }
    return list;
}

static json_t *options_json(const fm_cache_reader *r)
{
    fm_cache_options o = fm_cache_get_options(r);
    json_t *j = json_pack("{s:i, s:b, s:i, s:f}", "compression_level", o.compression_level, "delta", o.delta,
                          "key_interval", o.key_interval, "quantum", o.quantum);
    if (o.piece_agents > 0) json_object_set_new(j, "piece_agents", json_integer(o.piece_agents)); /* format 4 */
    return j;
}

static json_t *frame_bytes_json(const fm_cache_reader *r)
{
    uint32_t frames = fm_cache_frames(r);
    if (frames == 0) return json_null();
    uint64_t lo = UINT64_MAX, hi = 0;
    for (uint32_t k = 0; k < frames; k++) {
        uint64_t b = fm_cache_frame_bytes(r, k);
        lo = b < lo ? b : lo, hi = b > hi ? b : hi;
    }
    return json_pack("{s:I, s:f, s:I}", "min", (json_int_t)lo, "mean", (double)fm_cache_compressed_bytes(r) / frames,
                     "max", (json_int_t)hi);
}

/* Bounds of an xyz attribute (tet vertices: 4 points per agent) over every frame; NULL with
 * *status set if a frame cannot be read, json null if the cache has no frames. */
static json_t *bounds_json(fm_cache_reader *r, fm_cache_attr attr, fm_error *err, fm_status *status)
{
    const fm_cache_attr_info *a = fm_cache_attr_describe(attr);
    size_t floats = (size_t)fm_cache_agents(r) * (size_t)a->components;
    float *buf = malloc(sizeof(float) * (floats ? floats : 1));
    if (!buf) return *status = fm_fail(err, FM_ERR_MEMORY, "out of memory for a frame"), NULL;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    json_int_t non_finite = 0, first_frame = -1; /* a run that ran away: counted, kept out of the bounds */
    *status = FM_OK;
    for (uint32_t k = 0; k < fm_cache_frames(r) && *status == FM_OK; k++) {
        if ((*status = fm_cache_read_attr(r, k, attr, buf, err)) != FM_OK) break;
        for (size_t j = 0; j < floats; j++) {
            if (!isfinite(buf[j])) {
                if (!non_finite++) first_frame = k;
                continue;
            }
            lo[j % 3] = fmin(lo[j % 3], buf[j]), hi[j % 3] = fmax(hi[j % 3], buf[j]);
        }
    }
    free(buf);
    if (*status != FM_OK) return NULL;
    json_t *first = first_frame >= 0 ? json_integer(first_frame) : json_null();
    if (!(lo[0] <= hi[0])) /* no frames, no agents, or nothing finite */
        return non_finite ? json_pack("{s:n, s:n, s:I, s:o}", "min", "max", "non_finite_values", non_finite,
                                      "first_non_finite_frame", first)
                          : (json_decref(first), json_null());
    return json_pack("{s:[fff], s:[fff], s:I, s:o}", "min", lo[0], lo[1], lo[2], "max", hi[0], hi[1], hi[2],
                     "non_finite_values", non_finite, "first_non_finite_frame", first);
}

/* Everything inspect reports, as one JSON object; NULL on a read error. */
static json_t *inspect_json(fm_cache_reader *r, const char *path, fm_error *err)
{
    uint32_t frames = fm_cache_frames(r);
    double rate = fm_cache_frame_rate(r);
    uint64_t raw = fm_cache_raw_bytes(r), packed = fm_cache_compressed_bytes(r);
    json_t *bounds = json_object();
    const fm_cache_attr geometric[] = {FM_ATTR_TET_VERTICES, FM_ATTR_POSITION};
    for (int i = 0; i < 2; i++) {
        if (!fm_cache_has_attr(r, geometric[i])) continue;
        fm_status st;
        json_t *b = bounds_json(r, geometric[i], err, &st);
        if (!b) return json_decref(bounds), NULL;
        json_object_set_new(bounds, fm_cache_attr_describe(geometric[i])->name, b);
    }
    const char *warning = fm_cache_warning(r);
    /* formats 1 and 2 have no frame count in the header */
    json_t *header_frames = fm_cache_version(r) >= 3 ? json_integer(fm_cache_header_frames(r)) : json_null();
    return json_pack("{s:s, s:o, s:i, s:I, s:I, s:o, s:f, s:f, s:o, s:o, s:I, s:I, s:I, s:o, s:o, s:o, s:b, s:o, "
                     "s:o}",
                     "path", path, "path_absolute", cli_absolute_path(path), "format_version", (int)fm_cache_version(r),
                     "agents", (json_int_t)fm_cache_agents(r), "frames", (json_int_t)frames,
                     "header_frames", header_frames, "frame_rate", rate,
                     "duration_seconds", frames > 1 && rate > 0 ? (frames - 1) / rate : 0.0,
                     "attributes", attributes_json(r), "options", options_json(r),
                     "file_bytes", (json_int_t)fm_cache_file_bytes(r), "raw_bytes", (json_int_t)raw,
                     "compressed_bytes", (json_int_t)packed,
                     "compression_ratio", packed ? json_real((double)raw / (double)packed) : json_null(),
                     "frame_bytes", frame_bytes_json(r), "bounds", bounds, "complete", !warning[0],
                     "warning", warning[0] ? json_string(warning) : json_null(),
                     "provenance", cli_cache_provenance(path, (int64_t)fm_cache_agents(r), (int64_t)frames));
}

static void print_bounds(const char *name, json_t *b)
{
    if (!json_is_object(b)) return (void)printf("bounds        %s: none (no frames)\n", name);
    json_t *lo = json_object_get(b, "min"), *hi = json_object_get(b, "max");
    json_int_t bad = json_integer_value(json_object_get(b, "non_finite_values"));
    if (json_is_array(lo))
        printf("bounds        %s: [%.6g %.6g %.6g] .. [%.6g %.6g %.6g]", name, json_real_value(json_array_get(lo, 0)),
               json_real_value(json_array_get(lo, 1)), json_real_value(json_array_get(lo, 2)),
               json_real_value(json_array_get(hi, 0)), json_real_value(json_array_get(hi, 1)),
               json_real_value(json_array_get(hi, 2)));
    else printf("bounds        %s: none finite", name);
    if (bad)
        printf("; %lld values not finite, the first in frame %lld (the run ran away)", (long long)bad,
               (long long)json_integer_value(json_object_get(b, "first_non_finite_frame")));
    printf("\n");
}

static json_int_t num(json_t *j, const char *key) { return json_integer_value(json_object_get(j, key)); }

static void print_human(json_t *j)
{
    json_t *o = json_object_get(j, "options"), *fb = json_object_get(j, "frame_bytes"), *ratio = json_object_get(j, "compression_ratio");
    printf("cache         %s\n", json_string_value(json_object_get(j, "path")));
    printf("status        %s\n", json_is_true(json_object_get(j, "complete")) ? "complete" : "recovered (no valid index; see the warning)");
    printf("format        %lld\n", (long long)num(j, "format_version"));
    printf("agents        %lld\n", (long long)num(j, "agents"));
    printf("frames        %lld", (long long)num(j, "frames"));
    json_t *header_frames = json_object_get(j, "header_frames");
    if (json_is_integer(header_frames))
        printf(" (the header states %lld%s)", (long long)json_integer_value(header_frames),
               json_integer_value(header_frames) || json_is_true(json_object_get(j, "complete")) ? "" : ": the writer did not finish");
    printf("\n");
    printf("frame rate    %g fps, duration %.4g s (first to last frame)\n", json_real_value(json_object_get(j, "frame_rate")),
           json_real_value(json_object_get(j, "duration_seconds")));
    printf("attributes    ");
    json_t *a;
    size_t i;
    json_array_foreach(json_object_get(j, "attributes"), i, a)
        printf("%s%s (%lld x %s)", i ? ", " : "", json_string_value(json_object_get(a, "name")),
               (long long)num(a, "components"), json_string_value(json_object_get(a, "type")));
    printf("\noptions       zstd level %lld, delta %s, key interval %lld, quantum %g%s\n", (long long)num(o, "compression_level"),
           json_is_true(json_object_get(o, "delta")) ? "on" : "off", (long long)num(o, "key_interval"),
           json_real_value(json_object_get(o, "quantum")), json_real_value(json_object_get(o, "quantum")) > 0 ? "" : " (lossless)");
    if (json_is_integer(json_object_get(o, "piece_agents")))
        printf("pieces        %lld agents each\n", (long long)num(o, "piece_agents"));
    printf("file size     %lld bytes\n", (long long)num(j, "file_bytes"));
    printf("raw bytes     %lld\n", (long long)num(j, "raw_bytes"));
    printf("compressed    %lld bytes", (long long)num(j, "compressed_bytes"));
    if (json_is_real(ratio)) printf(", ratio %.3f", json_real_value(ratio));
    if (json_is_object(fb))
        printf("\nper frame     min %lld, mean %.1f, max %lld bytes", (long long)num(fb, "min"),
               json_real_value(json_object_get(fb, "mean")), (long long)num(fb, "max"));
    printf("\n");
    const char *name;
    json_object_foreach(json_object_get(j, "bounds"), name, a) print_bounds(name, a);
}

static int inspect(int argc, char **argv, int force_json, const char *usage)
{
    const char *path = NULL;
    int as_json = force_json;
    for (int i = 0; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) as_json = 1;
        else if (argv[i][0] == '-') return cli_usage_error(usage, "unknown option '%s'", argv[i]);
        else if (!path) path = argv[i];
        else return cli_usage_error(usage, "unexpected argument '%s'", argv[i]);
    }
    if (!path) return cli_usage_error(usage, "%s", "no cache file given");
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    if (!r) return cli_report(&err);
    if (fm_cache_warning(r)[0]) fprintf(stderr, "flockmorph: warning: %s\n", fm_cache_warning(r));
    json_t *j = inspect_json(r, path, &err);
    fm_cache_close(r);
    if (!j) return cli_report(&err);
    if (as_json) {
        char *text = json_dumps(j, JSON_INDENT(2) | JSON_REAL_PRECISION(10));
        printf("%s\n", text);
        free(text);
    } else {
        print_human(j);
    }
    json_decref(j);
    return 0;
}

int cli_inspect(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_INSPECT), 0;
    return inspect(argc, argv, 0, USAGE_INSPECT);
}

int cli_info(int argc, char **argv)
{
    static const char *const usage = "usage: flockmorph info CACHE\n\nThe same as 'flockmorph inspect CACHE --json'.\n";
    if (cli_wants_help(argc, argv)) return printf("%s", usage), 0;
    return inspect(argc, argv, 1, usage);
}
