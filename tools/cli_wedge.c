/* Wedges (docs/wedges.md): a wedge file's override sets, the index a farm task runs, its seed and
 * output folder, and `flockmorph wedge list | count`. */
#define _DEFAULT_SOURCE /* realpath */
#include "cli.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CLI_MAX_WEDGES 1000000L /* one farm task each: more is not a wedge, it is a mistake */
/* The file of that many wedges, each setting a few keys; a larger one is not read to its end. */
#define CLI_WEDGE_FILE_MAX_BYTES ((size_t)256 << 20)

static int wedge_error(const char *path, const char *key, const char *what)
{
    fprintf(stderr, "flockmorph: error: %s: %s%s%s\n", path, key, key[0] ? ": " : "", what);
    return FM_ERR_INPUT;
}

/* A value rounded to 15 significant digits, so that 0.02 + 3 * 0.02 is written 0.08. */
static double round15(double x)
{
    char text[32];
    snprintf(text, sizeof text, "%.15g", x);
    return strtod(text, NULL);
}

/* An integer that a double does not hold exactly (beyond 2^53 - 1 either way). */
static int beyond_doubles(const json_t *v)
{
    json_int_t i = json_integer_value(v);
    return json_is_integer(v) && (i > (json_int_t)FM_SEED_MAX || i < -(json_int_t)FM_SEED_MAX);
}

/* {"from": a, "to": b, "count": n}: n values evenly spaced from a to b, integers when a and b are
 * and every step is whole (seeds, counts). */
static json_t *range_values(const char *path, const char *key, const json_t *r)
{
    const json_t *from = json_object_get(r, "from"), *to = json_object_get(r, "to"), *count = json_object_get(r, "count");
    if (json_object_size(r) != 3 || !json_is_number(from) || !json_is_number(to) || !json_is_integer(count))
        return wedge_error(path, key, "a range is {\"from\": NUMBER, \"to\": NUMBER, \"count\": WHOLE NUMBER}"), NULL;
    json_int_t n = json_integer_value(count);
    if (n < 1 || n > CLI_MAX_WEDGES) return wedge_error(path, key, "a range's count must be 1 to 1000000"), NULL;
    if (beyond_doubles(from) || beyond_doubles(to))
        return wedge_error(path, key, "a range's from and to must lie within -9007199254740991 ... 9007199254740991 "
                           "(2^53 - 1): its values are counted in doubles, and a seed must be at most that"), NULL;
    double a = json_number_value(from), b = json_number_value(to);
    int whole = json_is_integer(from) && json_is_integer(to) && (n == 1 || fmod(b - a, (double)(n - 1)) == 0);
    json_t *values = json_array();
    for (json_int_t k = 0; k < n; k++) {
        double x = n == 1 ? a : a + (b - a) * (double)k / (double)(n - 1);
        json_array_append_new(values, whole ? json_integer((json_int_t)llround(x)) : json_real(round15(x)));
    }
    return values;
}

/* "product": every axis as an array of values, and their count. */
static int load_product(cli_wedges *w, const json_t *axes)
{
    if (!json_is_object(axes) || json_object_size(axes) == 0 || json_object_size(axes) > FM_MAX_OVERRIDES)
        return wedge_error(w->path, "product", "expected an object of 1 to 64 KEY: [values] or KEY: {\"from\", \"to\", "
                           "\"count\"}");
    const char *key;
    json_t *axis;
    w->list = json_object();
    w->count = 1;
    json_object_foreach((json_t *)axes, key, axis) {
        char label[256];
        snprintf(label, sizeof label, "product.%s", key);
        json_t *values = NULL;
        if (json_is_array(axis)) values = json_incref(axis);
        else if (!json_is_object(axis))
            return wedge_error(w->path, label, "expected a list of values or a range {\"from\", \"to\", \"count\"}");
        else if (!(values = range_values(w->path, label, axis))) return FM_ERR_INPUT;
        json_object_set_new(w->list, key, values);
        if (json_array_size(values) == 0) return wedge_error(w->path, label, "the list of values is empty");
        if ((w->count *= (long)json_array_size(values)) > CLI_MAX_WEDGES)
            return wedge_error(w->path, "product", "more than 1000000 wedges");
    }
    return 0;
}

/* "wedges": a list of objects of overrides ({} runs the scene as it is). */
static int load_list(cli_wedges *w, const json_t *list)
{
    if (!json_is_array(list) || json_array_size(list) == 0)
        return wedge_error(w->path, "wedges", "expected a non-empty list of objects {KEY: VALUE, ...}");
    if (json_array_size(list) > (size_t)CLI_MAX_WEDGES) return wedge_error(w->path, "wedges", "more than 1000000 wedges");
    for (size_t i = 0; i < json_array_size(list); i++)
        if (!json_is_object(json_array_get(list, i)) || json_object_size(json_array_get(list, i)) > FM_MAX_OVERRIDES) {
            char label[64];
            snprintf(label, sizeof label, "wedges[%zu]", i);
            return wedge_error(w->path, label, "expected an object of at most 64 overrides {KEY: VALUE, ...}");
        }
    w->list = json_incref((json_t *)list);
    w->count = (long)json_array_size(list);
    return 0;
}

int cli_wedges_load(const char *path, cli_wedges *w)
{
    memset(w, 0, sizeof *w);
    w->path = path;
    fm_error err = {0};
    fm_status st;
    size_t len;
    char *text = fm_read_text_file(path, "wedge file", CLI_WEDGE_FILE_MAX_BYTES, &len, &st, &err);
    if (!text) return cli_report(&err);
    json_error_t jerr;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES, &jerr);
    free(text);
    if (!root) return fprintf(stderr, "flockmorph: error: %s:%d:%d: %s\n", path, jerr.line, jerr.column, jerr.text), FM_ERR_INPUT;
    const json_t *list = json_object_get(root, "wedges"), *product = json_object_get(root, "product");
    int rc;
    if (!json_is_object(root) || json_object_size(root) != 1 || (!list && !product))
        rc = wedge_error(path, "", "a wedge file is {\"wedges\": [...]} or {\"product\": {...}} (docs/wedges.md)");
    else if ((w->product = product != NULL)) rc = load_product(w, product);
    else rc = load_list(w, list);
    json_decref(root);
    if (rc) cli_wedges_free(w);
    return rc;
}

void cli_wedges_free(cli_wedges *w)
{
    json_decref(w->list);
    w->list = NULL;
}

json_t *cli_wedge_overrides(const cli_wedges *w, long index)
{
    if (!w->product) return json_incref(json_array_get(w->list, (size_t)index));
    const char *keys[FM_MAX_OVERRIDES], *key;
    json_t *axes[FM_MAX_OVERRIDES], *values, *out = json_object();
    size_t n = 0, digit[FM_MAX_OVERRIDES];
    json_object_foreach(w->list, key, values) keys[n] = key, axes[n++] = values;
    /* mixed radix, the last key fastest: index = (d0 * n1 + d1) * n2 + d2 ... */
    size_t rest = (size_t)index;
    for (size_t k = n; k-- > 0; rest /= json_array_size(axes[k])) digit[k] = rest % json_array_size(axes[k]);
    for (size_t k = 0; k < n; k++) json_object_set(out, keys[k], json_array_get(axes[k], digit[k]));
    return out;
}

/* The farm's index variables, in the order they are read: Slurm job arrays, Houdini PDG's
 * schedulers (the work item's index; PDG_ITEM_ID is its id, unique in the graph, not an index),
 * OpenCue (the frame number of a layer whose frames are the wedges). */
static const char *const INDEX_VARIABLES[] = {"SLURM_ARRAY_TASK_ID", "PDG_INDEX", "CUE_IFRAME"};

static int no_wedge_index(const cli_run_options *o, long count)
{
    fprintf(stderr, "flockmorph: error: no wedge index: give --wedge I, or run as a Slurm array task "
            "(SLURM_ARRAY_TASK_ID), a Houdini PDG work item (PDG_INDEX) or an OpenCue frame (CUE_IFRAME); "
            "%s has %ld wedges (0 ... %ld)%s\n", o->wedge_file, count, count - 1,
            getenv("PDG_ITEM_ID") ? "; PDG_ITEM_ID is set, but it is a work item's id, not its index: give "
            "the TOP's command --wedge `@pdg_index`" : "");
    return FM_ERR_USAGE;
}

int cli_wedge_index(cli_run_options *o, long count)
{
    for (size_t i = 0; o->wedge < 0 && i < sizeof INDEX_VARIABLES / sizeof INDEX_VARIABLES[0]; i++) {
        const char *v = getenv(INDEX_VARIABLES[i]);
        if (!v || !v[0]) continue;
        if (cli_parse_int(v, 0, 2000000000L, &o->wedge))
            return fprintf(stderr, "flockmorph: error: %s is '%s', not a wedge index (a whole number >= 0)\n",
                           INDEX_VARIABLES[i], v), FM_ERR_USAGE;
        o->wedge_from = INDEX_VARIABLES[i];
    }
    if (o->wedge < 0) return no_wedge_index(o, count);
    if (o->wedge >= count)
        return fprintf(stderr, "flockmorph: error: wedge %ld (from %s) is out of range: %s has %ld wedges (0 ... %ld)\n",
                       o->wedge, o->wedge_from, o->wedge_file, count, count - 1), FM_ERR_USAGE;
    return 0;
}

#define WEDGE_SEED_STREAM 0x5745444745ull /* "WEDGE" in ASCII */

uint64_t cli_wedge_seed(uint64_t base, long index)
{
    return fm_random_bits(base, WEDGE_SEED_STREAM, (uint64_t)index) >> 11; /* 53 bits: the scene's 0 ... FM_SEED_MAX */
}

/* A real in the fewest digits (15, 16 or 17) that read back to the same double. */
static char *real_text(double x)
{
    char text[40];
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(text, sizeof text, "%.*g", digits, x);
        if (strtod(text, NULL) == x) break;
    }
    if (!strpbrk(text, ".eEn")) strcat(text, ".0"); /* a real stays a real: "2.0", not the integer 2 */
    return strdup(text);
}

char *cli_json_text(const json_t *v)
{
    if (json_is_real(v)) return real_text(json_real_value(v));
    return json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(17));
}

/* The last part of the real path of the scene's folder ("scene" for the root): what "." or ".."
 * stands for in ./scene.json and ../scene.json, so that {scene} never names the runs folder itself
 * or the one above it. */
static void real_folder_name(const char *scene, char *out, size_t size)
{
    char dir[FM_PATH_MAX], real[PATH_MAX];
    const char *slash = strrchr(scene, '/');
    snprintf(dir, sizeof dir, "%.*s", slash ? (int)(slash - scene) : 1, slash ? scene : ".");
    const char *name = realpath(dir[0] ? dir : "/", real) ? strrchr(real, '/') + 1 : "";
    snprintf(out, size, "%s", name[0] ? name : "scene");
}

static int names_no_folder(const char *stem) { return !stem[0] || !strcmp(stem, ".") || !strcmp(stem, ".."); }

/* The scene file's name without its folder and its .json, or the folder's name for a file named
 * scene.json (examples/words/scene.json is "words"). */
static void scene_name(const char *scene, char *out, size_t size)
{
    const char *slash = strrchr(scene, '/'), *name = slash ? slash + 1 : scene;
    size_t len = strlen(name);
    if (len > 5 && !strcmp(name + len - 5, ".json")) len -= 5;
    if (slash && len == 5 && !strncmp(name, "scene", 5)) {
        const char *end = slash;
        while (end > scene && end[-1] == '/') end--;
        const char *start = end;
        while (start > scene && start[-1] != '/') start--;
        if (end > start) name = start, len = (size_t)(end - start);
    }
    snprintf(out, size, "%.*s", (int)len, name);
}

/* scene_name, never "", "." or ".." (./scene.json: the current folder's real name): -o's {scene},
 * render's burn-in (cli.h). */
void cli_scene_stem(const char *scene, char *out, size_t size)
{
    scene_name(scene, out, size);
    if (names_no_folder(out)) real_folder_name(scene, out, size);
}

/* Appends placeholder `name` ("wedge", "scene") of -o; -1 if it is not one. */
static int put_placeholder(const cli_run_options *o, const char *name, size_t len, char *out, size_t size)
{
    size_t used = strlen(out);
    char stem[FM_PATH_MAX];
    if (len == 5 && !strncmp(name, "wedge", 5) && o->wedge_file) snprintf(out + used, size - used, "%04ld", o->wedge);
    else if (len == 5 && !strncmp(name, "scene", 5)) cli_scene_stem(o->scene, stem, sizeof stem), snprintf(out + used, size - used, "%s", stem);
    else return -1;
    return 0;
}

static int outdir_too_long(const cli_run_options *o)
{
    fprintf(stderr, "flockmorph: error: -o %s: the path is too long: the directory and the files the run writes in it "
            "must fit in %d bytes\n", o->outdir, FM_PATH_MAX - 1);
    return FM_ERR_USAGE;
}

int cli_expand_outdir(cli_run_options *o)
{
    char *out = o->outdir_buf;
    const size_t size = sizeof o->outdir_buf;
    int placeholders = 0;
    out[0] = 0;
    for (const char *s = o->outdir; *s;) {
        const char *close = *s == '{' ? strchr(s, '}') : NULL;
        size_t used = strlen(out);
        if (used + 1 >= size) /* full: what follows, or a placeholder's value, was cut */
            return outdir_too_long(o);
        if (!close) {
            out[used] = *s++, out[used + 1] = 0;
            continue;
        }
        if (put_placeholder(o, s + 1, (size_t)(close - s - 1), out, size))
            return fprintf(stderr, "flockmorph: error: -o %s: unknown placeholder %.*s (-o takes {scene}, and {wedge} with "
                           "--wedge-file)\n", o->outdir, (int)(close - s + 1), s), FM_ERR_USAGE;
        placeholders = 1;
        s = close + 1;
    }
    if (strlen(out) + 1 >= size) /* the last placeholder's value was cut */
        return outdir_too_long(o);
    for (size_t n = strlen(out); placeholders && n > 1 && out[n - 1] == '/'; n--) out[n - 1] = 0; /* out/{wedge}/ */
    o->outdir = out;
    return 0;
}

/* ---------------------------------------------------------------- flockmorph wedge */

static const char *const USAGE_WEDGE =
    "usage: flockmorph wedge list WEDGES.json [--scene SCENE.json] [--json]\n"
    "       flockmorph wedge count WEDGES.json\n"
    "\n"
    "A wedge file lists variants of a scene: {\"wedges\": [{KEY: VALUE, ...}, ...]}, or the product\n"
    "{\"product\": {KEY: [VALUE, ...] or {\"from\": A, \"to\": B, \"count\": N}, ...}}, whose last key\n"
    "varies fastest. 'list' prints every wedge with its index, 'count' how many there are (an array\n"
    "job runs indices 0 ... count-1). 'flockmorph run SCENE --wedge-file WEDGES.json --wedge I -o\n"
    "out/{wedge}' runs one; docs/wedges.md has the details and farm examples.\n"
    "\n"
    "  --scene SCENE  also read every wedge with the scene, as run would (keys, types, ranges; not\n"
    "                 the meshes), and give the seed it runs with; exit 2 if any is wrong\n"
    "  --json         list as JSON: {\"file\", \"count\", \"wedges\": [{\"index\", \"overrides\"\n"
    "                 (, \"seed\" with --scene)}, ...]}\n";

typedef struct wedge_args {
    const char *command, *file, *scene;
    int json;
} wedge_args;

static int parse_wedge(int argc, char **argv, wedge_args *a)
{
    memset(a, 0, sizeof *a);
    for (int i = 0; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) a->json = 1;
        else if (!strcmp(argv[i], "--scene") && i + 1 < argc) a->scene = argv[++i];
        else if (argv[i][0] == '-') return cli_usage_error(USAGE_WEDGE, "unknown or incomplete option '%s'", argv[i]);
        else if (!a->command) a->command = argv[i];
        else if (!a->file) a->file = argv[i];
        else return cli_usage_error(USAGE_WEDGE, "unexpected argument '%s'", argv[i]);
    }
    int list = a->command && !strcmp(a->command, "list"), count = a->command && !strcmp(a->command, "count");
    if (!a->file || !(list || count) || (count && (a->json || a->scene)))
        return cli_usage_error(USAGE_WEDGE, "%s", "wedge wants 'list WEDGES.json [--scene SCENE.json] [--json]' or "
                               "'count WEDGES.json'");
    return 0;
}

/* Wedge i read with the scene as run reads it (its errors printed); its seed. */
static int wedge_seed(const cli_wedges *w, long i, const char *scene, uint64_t *seed)
{
    cli_run_options o = {.scene = scene, .wedge_file = w->path, .wedge = i, .wedge_from = "--wedge"};
    cli_overrides ov = {0};
    fm_scene_def *def = malloc(sizeof *def);
    int rc = def ? cli_overrides_add_wedge(w, i, &ov) : FM_ERR_MEMORY;
    if (!rc) rc = cli_overrides_load(&o, &ov, def);
    if (!rc) cli_shot_use_overrides(ov.set, ov.count, ov.base_seed, def->seed);
    if (!rc && def->group_count > 0) rc = cli_shot_check_groups(def); /* as run reads a shot's groups */
    if (!rc) *seed = def->seed;
    cli_overrides_free(&ov);
    free(def);
    return rc;
}

/* One line of 'list': the index, KEY=VALUE ..., and with --scene the seed. */
static int print_wedge_line(const cli_wedges *w, long i, const char *scene)
{
    json_t *set = cli_wedge_overrides(w, i);
    const char *key;
    json_t *value;
    uint64_t seed = 0;
    int rc = scene ? wedge_seed(w, i, scene, &seed) : 0;
    printf("%6ld ", i);
    json_object_foreach(set, key, value) {
        char *text = cli_json_text(value);
        printf(" %s=%s", key, text ? text : "?");
        free(text);
    }
    printf("%s", json_object_size(set) ? "" : " (the scene as it is)");
    if (scene) rc ? printf("  (wrong: see above)") : printf("  (seed %llu)", (unsigned long long)seed);
    printf("\n");
    fflush(stdout); /* each line after its error, if any */
    json_decref(set);
    return rc;
}

static int print_wedges_json(const cli_wedges *w, const char *scene)
{
    json_t *list = json_array();
    int wrong = 0;
    for (long i = 0; i < w->count; i++) {
        json_t *e = json_pack("{sIso}", "index", (json_int_t)i, "overrides", cli_wedge_overrides(w, i));
        uint64_t seed = 0;
        int rc = scene ? wedge_seed(w, i, scene, &seed) : 0;
        if (scene) json_object_set_new(e, "seed", rc ? json_null() : json_integer((json_int_t)seed));
        wrong += rc != 0;
        json_array_append_new(list, e);
    }
    json_t *j = json_pack("{sssIso}", "file", w->path, "count", (json_int_t)w->count, "wedges", list);
    json_dumpf(j, stdout, JSON_INDENT(2) | JSON_REAL_PRECISION(17));
    printf("\n");
    json_decref(j);
    return wrong;
}

static int print_wedges(const cli_wedges *w, const char *scene)
{
    int wrong = 0;
    printf("%s: %ld wedge%s%s\n", w->path, w->count, w->count == 1 ? "" : "s",
           w->product ? " (a product: the last key varies fastest)" : "");
    for (long i = 0; i < w->count; i++) wrong += print_wedge_line(w, i, scene) != 0;
    return wrong;
}

int cli_wedge(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_WEDGE), 0;
    wedge_args a;
    cli_wedges w;
    int rc = parse_wedge(argc, argv, &a);
    if (!rc) rc = cli_wedges_load(a.file, &w);
    if (rc) return rc;
    int wrong = 0;
    if (!strcmp(a.command, "count")) printf("%ld\n", w.count);
    else wrong = a.json ? print_wedges_json(&w, a.scene) : print_wedges(&w, a.scene);
    if (wrong) fprintf(stderr, "flockmorph: error: %d of the %ld wedges of %s are wrong for %s\n", wrong, w.count, w.path, a.scene);
    cli_wedges_free(&w);
    return wrong ? FM_ERR_INPUT : 0;
}
