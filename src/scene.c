/* Scene files (JSON through jansson) and parameter validation.
 *
 * One table lists every numeric and string parameter with its key, type, range and place in
 * fm_scene_def; the loader and fm_scene_validate both walk it, so a range is written once.
 * Errors name FILE:LINE:COLUMN (found by json_locate.c, since jansson keeps no positions after
 * parsing) and the key. */
#define _POSIX_C_SOURCE 200809L
#include "fm_internal.h"
#include "json_locate.h"

#include <jansson.h>

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

fm_scene_def fm_default_scene_def(void)
{
    fm_scene_def d;
    memset(&d, 0, sizeof d);
    d.source.scale = d.target.scale = 1.0;
    d.tet_quality = 2.0;
    d.speed0 = 10.0;
    d.omega1 = 1.0;
    d.frame_rate = 24.0;
    d.frame_limit = 10000;
    d.path_key_points = 32;
    d.path_curve = FM_CURVE_POLYLINE;
    d.shrink = 0.5;
    d.shrink_time = 0.25;
    d.morph_fraction = 0.75;
    d.seed = 1;
    d.compression_level = 1; /* zstd level 1: twice as fast as 3 on frames, about 10 % larger */
    d.omega2 = 1.0;
    d.k_a = 1.0;
    d.path_attraction = 1.0;
    strcpy(d.cache_name, "frames.fmc");
    return d;
}

typedef enum param_type {
    P_DOUBLE, P_INT32, P_INT64, P_UINT64, P_BOOL, P_VEC3, P_INT3, P_MESH, P_NAME, P_CURVE, P_SWITCH,
    P_FIELD_KIND, P_POINTS, P_FIELDS, P_OBSTACLES
} param_type;

enum { OPEN_MIN = 1, OPEN_MAX = 2 };

typedef struct param {
    const char *key;    /* dotted: "time.frame_rate" */
    param_type type;
    size_t offset;
    double min, max;
    int open;           /* OPEN_MIN / OPEN_MAX: that bound itself is excluded */
} param;

#define OFF(field) offsetof(fm_scene_def, field)
static const param PARAMS[] = {
    {"source.mesh", P_MESH, OFF(source.path), 0, 0, 0},
    {"source.translate", P_VEC3, OFF(source.translate), -1e9, 1e9, 0},
    {"source.scale", P_DOUBLE, OFF(source.scale), 0, 1e9, 1},
    {"source.rotate_deg", P_VEC3, OFF(source.rotate_deg), -3600, 3600, 0},
    {"target.mesh", P_MESH, OFF(target.path), 0, 0, 0},
    {"target.translate", P_VEC3, OFF(target.translate), -1e9, 1e9, 0},
    {"target.scale", P_DOUBLE, OFF(target.scale), 0, 1e9, 1},
    {"target.rotate_deg", P_VEC3, OFF(target.rotate_deg), -3600, 3600, 0},
    {"n", P_INT64, OFF(n), 0, 1e9, 0},
    {"tetgen.quality", P_DOUBLE, OFF(tet_quality), 1.1, 100, 0},
    {"tetgen.max_volume", P_DOUBLE, OFF(tet_max_volume), 0, 1e30, 0},
    {"speed0", P_DOUBLE, OFF(speed0), 0, 1e9, 1},
    {"omega1", P_DOUBLE, OFF(omega1), 0, 1e3, 1},
    {"time.frame_rate", P_DOUBLE, OFF(frame_rate), 0, 1e4, 1},
    {"time.time_step", P_DOUBLE, OFF(time_step), 0, 1e3, 0},
    {"time.frame_limit", P_INT32, OFF(frame_limit), 1, 1e7, 0},
    {"path.points", P_POINTS, OFF(path_points), -1e9, 1e9, 0},
    {"path.key_points", P_INT32, OFF(path_key_points), 1, 1e5, 0},
    {"path.curve", P_CURVE, OFF(path_curve), 0, 0, 0},
    {"launch_rate", P_DOUBLE, OFF(launch_rate), 0, 1e12, 0},
    {"morph.shrink", P_DOUBLE, OFF(shrink), 0, 1, 1},
    {"morph.shrink_time", P_DOUBLE, OFF(shrink_time), 0, 1e6, 0},
    {"morph.morph_fraction", P_DOUBLE, OFF(morph_fraction), 0, 1, OPEN_MIN | OPEN_MAX},
    {"seed", P_UINT64, OFF(seed), 0, 0, 0},
    {"output.cache", P_NAME, OFF(cache_name), 0, 0, 0},
    {"output.compression_level", P_INT32, OFF(compression_level), 1, 19, 0},
    {"style.omega2", P_DOUBLE, OFF(omega2), 0, 1e3, 0},
    {"style.grid", P_INT3, OFF(field_grid), 0, 2048, 0},
    {"style.fields", P_FIELDS, OFF(fields), 0, 0, 0},
    {"obstacles.meshes", P_OBSTACLES, OFF(obstacles), 0, 0, 0},
    {"obstacles.k_a", P_DOUBLE, OFF(k_a), 0, 1e9, OPEN_MIN},
    {"obstacles.voxel", P_DOUBLE, OFF(obstacle_voxel), 0, 1e9, 0},
    {"obstacles.in_phase2", P_BOOL, OFF(avoid_in_phase2), 0, 0, 0},
    {"mde.d_min", P_DOUBLE, OFF(d_min), 0, 1e9, 0},
    {"mde.speed", P_DOUBLE, OFF(mde_speed), 0, 1e9, 0},
    {"path.width", P_DOUBLE, OFF(path_width), 0, 1e9, 0},
    {"path.attraction", P_DOUBLE, OFF(path_attraction), 0, 1e6, 0},
    {"phase2.switch", P_SWITCH, OFF(phase_switch), 0, 0, 0},
    {"phase2.switch_distance", P_DOUBLE, OFF(switch_distance), -1e9, 1e9, 0},
};
#define PARAM_COUNT (sizeof PARAMS / sizeof PARAMS[0])

/* The keys of one element of obstacles.meshes (source and target share the ranges above). */
#define MOFF(field) offsetof(fm_mesh_ref, field)
static const param MESH_PARAMS[] = {
    {"mesh", P_MESH, MOFF(path), 0, 0, 0},
    {"translate", P_VEC3, MOFF(translate), -1e9, 1e9, 0},
    {"scale", P_DOUBLE, MOFF(scale), 0, 1e9, 1},
    {"rotate_deg", P_VEC3, MOFF(rotate_deg), -3600, 3600, 0},
};

/* The keys of one element of style.fields; FIELD_KEYS says which apply to each kind. */
#define FOFF(field) offsetof(fm_field_def, field)
static const param FIELD_PARAMS[] = {
    {"type", P_FIELD_KIND, FOFF(kind), 0, 0, 0},
    {"gain", P_DOUBLE, FOFF(gain), 0, 1e6, 0},
    {"scale", P_DOUBLE, FOFF(scale), 0, 1e9, OPEN_MIN},
    {"direction", P_VEC3, FOFF(direction), -1e9, 1e9, 0},
    {"speed", P_DOUBLE, FOFF(speed), 0, 1e9, 0},
    {"turbulence", P_DOUBLE, FOFF(turbulence), 0, 1e6, 0},
    {"period", P_DOUBLE, FOFF(period), 0, 1e9, 0},
    {"center", P_VEC3, FOFF(center), -1e9, 1e9, 0},
    {"axis", P_VEC3, FOFF(axis), -1e9, 1e9, 0},
    {"strength", P_DOUBLE, FOFF(strength), -1e6, 1e6, 0},
};
static const char *const FIELD_NAMES[] = {"curl_noise", "wind", "gravity", "vortex"};
static const char *const FIELD_KEYS[] = {" type gain scale ", " type direction speed turbulence scale period ",
                                         " type direction speed ", " type center axis strength "};

fm_field_def fm_default_field_def(fm_field_kind kind)
{
    fm_field_def f = {.kind = kind, .gain = 1, .scale = 1, .speed = 1, .period = 1, .strength = 1};
    f.direction[kind == FM_FIELD_GRAVITY ? 2 : 0] = kind == FM_FIELD_GRAVITY ? -1 : 1;
    f.axis[1] = 1;
    return f;
}

/* Where an error points: the scene text and a JSON path. */
typedef struct where {
    const char *file;
    const char *text;       /* NULL when validating a definition built in code */
    fm_error *err;
    fm_json_step steps[8];
    char names[8][64];
    int depth;
    int at_key;             /* point at the key rather than the value */
    char label[160];        /* the key named in messages inside list elements ("style.fields[1].gain") */
} where;

#define KEY(w, p) ((w)->label[0] ? (w)->label : (p)->key)

static void where_set_key(where *w, const char *dotted)
{
    w->depth = 0;
    w->at_key = 0;
    const char *s = dotted;
    while (*s && w->depth < 8) {
        size_t len = strcspn(s, ".");
        snprintf(w->names[w->depth], sizeof w->names[0], "%.*s", (int)len, s);
        w->steps[w->depth] = (fm_json_step){w->names[w->depth], 0};
        w->depth++;
        s += len + (s[len] == '.');
    }
}

/* The error message: "FILE:LINE:COL: key: what" (FILE: key: what without a text). */
static fm_status fail_at(const where *w, const char *key, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static fm_status fail_at(const where *w, const char *key, const char *fmt, ...)
{
    char what[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    int line = 0, col = 0;
    if (w->text) fm_json_locate(w->text, w->steps, w->depth, w->at_key, &line, &col);
    const char *file = w->file && w->file[0] ? w->file : "scene";
    if (line > 0) return fm_fail(w->err, FM_ERR_INPUT, "%s:%d:%d: %s: %s", file, line, col, key, what);
    return fm_fail(w->err, FM_ERR_INPUT, "%s: %s: %s", file, key, what);
}

static const char *json_type_name(const json_t *v)
{
    switch (json_typeof(v)) {
    case JSON_OBJECT: return "an object";
    case JSON_ARRAY: return "an array";
    case JSON_STRING: return "a string";
    case JSON_INTEGER: return "an integer";
    case JSON_REAL: return "a number";
    case JSON_TRUE: case JSON_FALSE: return "a boolean";
    default: return "null";
    }
}

static fm_status check_range(const where *w, const param *p, double x)
{
    if (!isfinite(x)) return fail_at(w, KEY(w, p), "must be a finite number");
    int open_min = p->open & OPEN_MIN, open_max = p->open & OPEN_MAX;
    if (open_min ? !(x > p->min) : !(x >= p->min))
        return fail_at(w, KEY(w, p), "%g is out of range: must be %s %g", x, open_min ? ">" : ">=", p->min);
    if (open_max ? !(x < p->max) : !(x <= p->max))
        return fail_at(w, KEY(w, p), "%g is out of range: must be %s %g", x, open_max ? "<" : "<=", p->max);
    return FM_OK;
}

static fm_status read_number(const where *w, const param *p, const json_t *v, double *out)
{
    if (!json_is_number(v)) return fail_at(w, KEY(w, p), "expected a number, got %s", json_type_name(v));
    *out = json_number_value(v);
    return check_range(w, p, *out);
}

static fm_status read_integer(const where *w, const param *p, const json_t *v, int64_t *out)
{
    if (!json_is_integer(v)) return fail_at(w, KEY(w, p), "expected an integer, got %s", json_type_name(v));
    *out = json_integer_value(v);
    if (p->type == P_UINT64) {
        if (*out < 0) return fail_at(w, KEY(w, p), "must be >= 0");
        return FM_OK;
    }
    return check_range(w, p, (double)*out);
}

/* [x, y, z] with each component in range; w points at the array and is extended per element. */
static fm_status read_vec3(where *w, const param *p, const json_t *v, double *out)
{
    if (!json_is_array(v) || json_array_size(v) != 3)
        return fail_at(w, KEY(w, p), "expected an array of 3 numbers, got %s%s", json_type_name(v),
                       json_is_array(v) ? " of another length" : "");
    for (int k = 0; k < 3; k++) {
        w->steps[w->depth++] = (fm_json_step){NULL, k};
        fm_status st = read_number(w, p, json_array_get(v, (size_t)k), &out[k]);
        w->depth--;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

static fm_status read_points(where *w, const param *p, const json_t *v, fm_scene_def *def)
{
    if (!json_is_array(v)) return fail_at(w, KEY(w, p), "expected an array of [x, y, z] points, got %s", json_type_name(v));
    if (json_array_size(v) > FM_MAX_PATH_POINTS)
        return fail_at(w, KEY(w, p), "%zu points is more than the %d supported", json_array_size(v), FM_MAX_PATH_POINTS);
    def->path_point_count = (int32_t)json_array_size(v);
    for (int32_t i = 0; i < def->path_point_count; i++) {
        w->steps[w->depth++] = (fm_json_step){NULL, i};
        fm_status st = read_vec3(w, p, json_array_get(v, (size_t)i), def->path_points[i]);
        w->depth--;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

/* A mesh path, resolved against the scene file's directory when relative. */
static fm_status read_mesh_path(const where *w, const param *p, const json_t *v, char *out)
{
    if (!json_is_string(v)) return fail_at(w, KEY(w, p), "expected a file name, got %s", json_type_name(v));
    const char *name = json_string_value(v);
    if (!name[0]) return fail_at(w, KEY(w, p), "the mesh file name is empty");
    const char *slash = strrchr(w->file, '/');
    int dir_len = (name[0] != '/' && slash) ? (int)(slash - w->file + 1) : 0;
    if ((size_t)dir_len + strlen(name) + 1 > FM_PATH_MAX) return fail_at(w, KEY(w, p), "the path is too long");
    snprintf(out, FM_PATH_MAX, "%.*s%s", dir_len, w->file, name);
    return FM_OK;
}

static fm_status read_name(const where *w, const param *p, const json_t *v, char *out)
{
    if (!json_is_string(v)) return fail_at(w, KEY(w, p), "expected a file name, got %s", json_type_name(v));
    const char *name = json_string_value(v);
    if (!name[0] || strchr(name, '/') || strlen(name) >= 256 || !strcmp(name, ".") || !strcmp(name, ".."))
        return fail_at(w, KEY(w, p), "'%s' is not a plain file name (no '/', at most 255 bytes)", name);
    strcpy(out, name);
    return FM_OK;
}

/* One of `count` names; *out = its index. */
static fm_status read_enum(const where *w, const param *p, const json_t *v, const char *const *names, int count, int *out)
{
    const char *s = json_is_string(v) ? json_string_value(v) : "";
    for (int i = 0; i < count; i++)
        if (!strcmp(s, names[i])) return *out = i, FM_OK;
    char list[256] = "";
    for (int i = 0; i < count; i++)
        snprintf(list + strlen(list), sizeof list - strlen(list), "%s\"%s\"", i ? (i + 1 == count ? " or " : ", ") : "", names[i]);
    return fail_at(w, KEY(w, p), "expected %s", list);
}

static fm_status read_bool(const where *w, const param *p, const json_t *v, int32_t *out)
{
    if (!json_is_boolean(v)) return fail_at(w, KEY(w, p), "expected true or false, got %s", json_type_name(v));
    *out = json_is_true(v);
    return FM_OK;
}

/* [nx, ny, nz] integers in range. */
static fm_status read_int3(where *w, const param *p, const json_t *v, int32_t *out)
{
    if (!json_is_array(v) || json_array_size(v) != 3)
        return fail_at(w, KEY(w, p), "expected an array of 3 integers, got %s", json_type_name(v));
    for (int k = 0; k < 3; k++) {
        int64_t x = 0;
        w->steps[w->depth++] = (fm_json_step){NULL, k};
        fm_status st = read_integer(w, p, json_array_get(v, (size_t)k), &x);
        w->depth--;
        if (st != FM_OK) return st;
        out[k] = (int32_t)x;
    }
    return FM_OK;
}

static fm_status read_param(where *w, const param *p, const json_t *v, void *base, fm_scene_def *def);

/* Reads member p->key of a list element, naming it "<label>.<key>" in messages. */
static fm_status read_member(where *w, const char *label, const param *p, const json_t *v, void *base,
                             fm_scene_def *def)
{
    w->steps[w->depth++] = (fm_json_step){p->key, 0};
    snprintf(w->label, sizeof w->label, "%s.%s", label, p->key);
    fm_status st = read_param(w, p, v, base, def);
    w->label[0] = 0;
    w->depth--;
    return st;
}

/* Reads the keys of one list element (an object) into base through its table; unknown keys, and
 * keys not in `allowed` (" key key ... ", NULL = all), are errors. */
static fm_status read_element(where *w, const json_t *obj, const param *table, int count, void *base,
                              const char *label, const char *allowed, fm_scene_def *def)
{
    if (!json_is_object(obj)) return fail_at(w, label, "expected an object, got %s", json_type_name(obj));
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)obj, key, value) {
        char spaced[80];
        snprintf(spaced, sizeof spaced, " %s ", key);
        int known = 0;
        for (int i = 0; i < count; i++) known |= !strcmp(table[i].key, key);
        if (known && (!allowed || strstr(allowed, spaced))) continue;
        w->steps[w->depth++] = (fm_json_step){key, 0};
        w->at_key = 1;
        snprintf(w->label, sizeof w->label, "%s.%s", label, key);
        fm_status st = fail_at(w, w->label, known ? "does not apply here (this element takes:%s)" : "unknown key%s",
                               known ? allowed : " (docs/scene.md lists the keys)");
        w->label[0] = 0;
        return st;
    }
    for (int i = 0; i < count; i++) {
        const json_t *v = json_object_get(obj, table[i].key);
        fm_status st = v ? read_member(w, label, &table[i], v, base, def) : FM_OK;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

typedef fm_status (*element_reader)(where *w, const json_t *e, int32_t i, const char *label, fm_scene_def *def);

/* A list of objects (style.fields, obstacles.meshes): each element read by read_one, with
 * messages naming "<key>[i]". */
static fm_status read_list(where *w, const param *p, const json_t *v, int max, int32_t *count,
                           element_reader read_one, fm_scene_def *def)
{
    if (!json_is_array(v)) return fail_at(w, p->key, "expected an array of objects, got %s", json_type_name(v));
    if (json_array_size(v) > (size_t)max) return fail_at(w, p->key, "at most %d entries", max);
    *count = (int32_t)json_array_size(v);
    for (int32_t i = 0; i < *count; i++) {
        char label[64];
        snprintf(label, sizeof label, "%s[%d]", p->key, i);
        w->steps[w->depth++] = (fm_json_step){NULL, i};
        fm_status st = read_one(w, json_array_get(v, (size_t)i), i, label, def);
        w->depth--;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

/* One style field: {"type": "curl_noise", ...}, starting from its kind's defaults. */
static fm_status read_field(where *w, const json_t *e, int32_t i, const char *label, fm_scene_def *def)
{
    const json_t *type = json_is_object(e) ? json_object_get(e, "type") : NULL;
    if (json_is_object(e) && !type) return fail_at(w, label, "every field needs a \"type\"");
    fm_field_def probe = {.kind = FM_FIELD_CURL_NOISE};
    fm_status st = type ? read_member(w, label, &FIELD_PARAMS[0], type, &probe, def) : FM_OK;
    if (st != FM_OK) return st;
    def->fields[i] = fm_default_field_def(probe.kind);
    return read_element(w, e, FIELD_PARAMS, (int)(sizeof FIELD_PARAMS / sizeof FIELD_PARAMS[0]), &def->fields[i],
                        label, FIELD_KEYS[probe.kind], def);
}

/* One obstacle: {"mesh": "king.obj", "translate": [...], ...}. */
static fm_status read_obstacle(where *w, const json_t *e, int32_t i, const char *label, fm_scene_def *def)
{
    fm_mesh_ref *ref = &def->obstacles[i];
    memset(ref, 0, sizeof *ref);
    ref->scale = 1;
    fm_status st = read_element(w, e, MESH_PARAMS, (int)(sizeof MESH_PARAMS / sizeof MESH_PARAMS[0]), ref, label, NULL, def);
    if (st == FM_OK && !ref->path[0]) st = fail_at(w, label, "every obstacle needs a \"mesh\"");
    return st;
}

static const char *const CURVE_NAMES[] = {"polyline", "catmull_rom"};
static const char *const SWITCH_NAMES[] = {"sphere", "distance"};

/* Reads one value into the field at base + p->offset (base: the scene, or a list element). */
static fm_status read_param(where *w, const param *p, const json_t *v, void *base, fm_scene_def *def)
{
    char *field = (char *)base + p->offset;
    int64_t i = 0;
    int e = 0;
    fm_status st;
    switch (p->type) {
    case P_DOUBLE: return read_number(w, p, v, (double *)field);
    case P_INT32: st = read_integer(w, p, v, &i); *(int32_t *)field = (int32_t)i; return st;
    case P_INT64: return read_integer(w, p, v, (int64_t *)field);
    case P_UINT64: st = read_integer(w, p, v, &i); *(uint64_t *)field = (uint64_t)i; return st;
    case P_VEC3: return read_vec3(w, p, v, (double *)field);
    case P_MESH: return read_mesh_path(w, p, v, field);
    case P_NAME: return read_name(w, p, v, field);
    case P_CURVE: st = read_enum(w, p, v, CURVE_NAMES, 2, &e); *(fm_curve *)field = (fm_curve)e; return st;
    case P_SWITCH: st = read_enum(w, p, v, SWITCH_NAMES, 2, &e); *(fm_phase_switch *)field = (fm_phase_switch)e; return st;
    case P_FIELD_KIND: st = read_enum(w, p, v, FIELD_NAMES, 4, &e); *(fm_field_kind *)field = (fm_field_kind)e; return st;
    case P_BOOL: return read_bool(w, p, v, (int32_t *)field);
    case P_INT3: return read_int3(w, p, v, (int32_t *)field);
    case P_POINTS: return read_points(w, p, v, def);
    case P_FIELDS: return read_list(w, p, v, FM_MAX_FIELDS, &def->field_count, read_field, def);
    case P_OBSTACLES: return read_list(w, p, v, FM_MAX_OBSTACLES, &def->obstacle_count, read_obstacle, def);
    }
    return FM_OK;
}

/* The value at a dotted key, or NULL. A group that is not an object is an error. */
static fm_status lookup(where *w, const json_t *root, const char *dotted, const json_t **out)
{
    *out = NULL;
    where_set_key(w, dotted);
    const json_t *v = root;
    for (int d = 0; d < w->depth; d++) {
        if (!json_is_object(v)) {
            int depth = w->depth;
            w->depth = d;
            fm_status st = fail_at(w, w->names[d - 1], "expected an object, got %s", json_type_name(v));
            w->depth = depth;
            return st;
        }
        v = json_object_get(v, w->names[d]);
        if (!v) return FM_OK;
    }
    *out = v;
    return FM_OK;
}

/* Is `key` (inside group `prefix`, "" for the top) a parameter or a group of parameters? */
static int known_key(const char *prefix, const char *key)
{
    if (strchr(key, '.')) return 0; /* "time.frame_rate" must be written as a nested object */
    char full[160];
    snprintf(full, sizeof full, "%s%s%s", prefix, prefix[0] ? "." : "", key);
    size_t len = strlen(full);
    for (size_t i = 0; i < PARAM_COUNT; i++)
        if (!strncmp(PARAMS[i].key, full, len) && (PARAMS[i].key[len] == 0 || PARAMS[i].key[len] == '.')) return 1;
    return 0;
}

static fm_status check_unknown_keys(where *w, const json_t *obj, const char *prefix)
{
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)obj, key, value) {
        char full[160];
        snprintf(full, sizeof full, "%s%s%s", prefix, prefix[0] ? "." : "", key);
        if (!known_key(prefix, key)) {
            where_set_key(w, prefix);
            if (!prefix[0]) w->depth = 0;
            w->steps[w->depth++] = (fm_json_step){key, 0};
            w->at_key = 1;
            return fail_at(w, full, "unknown key (docs/scene.md lists the keys)");
        }
        if (json_is_object(value)) {
            fm_status st = check_unknown_keys(w, value, full);
            if (st != FM_OK) return st;
        }
    }
    return FM_OK;
}

static fm_status read_scene(where *w, const json_t *root, fm_scene_def *def)
{
    if (!json_is_object(root)) {
        w->depth = 0;
        return fail_at(w, "scene", "the scene must be a JSON object");
    }
    fm_status st = check_unknown_keys(w, root, "");
    for (size_t i = 0; i < PARAM_COUNT && st == FM_OK; i++) {
        const json_t *v;
        st = lookup(w, root, PARAMS[i].key, &v);
        if (st == FM_OK && v) st = read_param(w, &PARAMS[i], v, def, def);
        else if (st == FM_OK && PARAMS[i].type == P_MESH) {
            where_set_key(w, PARAMS[i].key);
            w->depth = 0;
            st = fail_at(w, PARAMS[i].key, "required key is missing");
        }
    }
    return st;
}

/* Checks that span several parameters. */
static fm_status check_consistency(where *w, const fm_scene_def *def)
{
    if (def->time_step > 0) {
        double steps = (1.0 / def->frame_rate) / def->time_step;
        if (steps < 0.999999 || fabs(steps - floor(steps + 0.5)) > 1e-6 * steps) {
            where_set_key(w, "time.time_step");
            return fail_at(w, "time.time_step", "%g s does not divide the frame interval 1/%g s "
                           "into whole steps", def->time_step, def->frame_rate);
        }
    }
    return FM_OK;
}

/* Range checks of every numeric entry of a table over the struct at base. */
static fm_status check_table(where *w, const param *table, size_t count, const void *base, const char *prefix)
{
    for (size_t i = 0; i < count; i++) {
        const param *p = &table[i];
        const char *field = (const char *)base + p->offset;
        if (prefix) snprintf(w->label, sizeof w->label, "%s.%s", prefix, p->key);
        fm_status st = FM_OK;
        if (p->type == P_DOUBLE) st = check_range(w, p, *(const double *)field);
        else if (p->type == P_INT32) st = check_range(w, p, *(const int32_t *)field);
        else if (p->type == P_INT64) st = check_range(w, p, (double)*(const int64_t *)field);
        else if (p->type == P_VEC3 || p->type == P_INT3)
            for (int k = 0; k < 3 && st == FM_OK; k++)
                st = check_range(w, p, p->type == P_VEC3 ? ((const double *)field)[k] : ((const int32_t *)field)[k]);
        w->label[0] = 0;
        if (st != FM_OK) return st;
    }
    return FM_OK;
}

/* The list parameters of a definition built in code. */
static fm_status check_lists(where *w, const fm_scene_def *def)
{
    if (def->field_count < 0 || def->field_count > FM_MAX_FIELDS)
        return fail_at(w, "style.fields", "between 0 and %d fields", FM_MAX_FIELDS);
    if (def->obstacle_count < 0 || def->obstacle_count > FM_MAX_OBSTACLES)
        return fail_at(w, "obstacles.meshes", "between 0 and %d obstacles", FM_MAX_OBSTACLES);
    char label[64];
    for (int32_t i = 0; i < def->field_count; i++) {
        snprintf(label, sizeof label, "style.fields[%d]", i);
        if ((unsigned)def->fields[i].kind > FM_FIELD_VORTEX) return fail_at(w, label, "unknown field type");
        fm_status st = check_table(w, FIELD_PARAMS, sizeof FIELD_PARAMS / sizeof FIELD_PARAMS[0], &def->fields[i], label);
        if (st != FM_OK) return st;
    }
    for (int32_t i = 0; i < def->obstacle_count; i++) {
        snprintf(label, sizeof label, "obstacles.meshes[%d]", i);
        if (!def->obstacles[i].path[0]) return fail_at(w, label, "no mesh given");
        fm_status st = check_table(w, MESH_PARAMS, sizeof MESH_PARAMS / sizeof MESH_PARAMS[0], &def->obstacles[i], label);
        if (st != FM_OK) return st;
    }
    if ((unsigned)def->phase_switch > FM_SWITCH_DISTANCE) return fail_at(w, "phase2.switch", "unknown switch");
    return FM_OK;
}

fm_status fm_scene_validate(const fm_scene_def *def, fm_error *err)
{
    where w = {def->scene_path, NULL, err, {{0}}, {{0}}, 0, 0, ""};
    if (!def->source.path[0] || !def->target.path[0])
        return fail_at(&w, def->source.path[0] ? "target.mesh" : "source.mesh", "no mesh given");
    fm_status st = check_table(&w, PARAMS, PARAM_COUNT, def, NULL);
    if (st == FM_OK) st = check_lists(&w, def);
    if (st != FM_OK) return st;
    if (def->path_point_count < 0 || def->path_point_count > FM_MAX_PATH_POINTS)
        return fail_at(&w, "path.points", "between 0 and %d points", FM_MAX_PATH_POINTS);
    if (def->path_curve != FM_CURVE_POLYLINE && def->path_curve != FM_CURVE_CATMULL_ROM)
        return fail_at(&w, "path.curve", "unknown curve %d", (int)def->path_curve);
    if (!def->cache_name[0] || strchr(def->cache_name, '/') || !strcmp(def->cache_name, ".") || !strcmp(def->cache_name, ".."))
        return fail_at(&w, "output.cache", "'%s' is not a plain file name", def->cache_name);
    return check_consistency(&w, def);
}

static char *read_text(const char *path, size_t *out_len, fm_status *st, fm_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        *st = fm_fail(err, errno == ENOENT || errno == ENOTDIR ? FM_ERR_INPUT : FM_ERR_IO,
                      "%s: cannot open the scene file: %s", path, strerror(errno));
        return NULL;
    }
    size_t cap = 1 << 16, len = 0;
    char *text = malloc(cap);
    while (text) {
        len += fread(text + len, 1, cap - len - 1, f);
        if (len < cap - 1) break;
        char *bigger = realloc(text, cap *= 2);
        if (!bigger) free(text);
        text = bigger;
    }
    int bad = ferror(f);
    fclose(f);
    if (!text || bad) {
        free(text);
        *st = fm_fail(err, bad ? FM_ERR_IO : FM_ERR_MEMORY, "%s: cannot read the scene file", path);
        return NULL;
    }
    text[len] = 0;
    *out_len = len;
    return text;
}

fm_status fm_scene_parse(const char *text, size_t len, const char *name, fm_scene_def *def, fm_error *err)
{
    *def = fm_default_scene_def();
    snprintf(def->scene_path, sizeof def->scene_path, "%s", name ? name : "");
    const char *file = def->scene_path[0] ? def->scene_path : "scene";
    /* json_locate walks a NUL-terminated text; jansson rejects embedded NULs itself. */
    char *copy = malloc(len + 1);
    if (!copy) return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory for the scene text", file);
    memcpy(copy, text, len);
    copy[len] = 0;
    json_error_t jerr;
    fm_status st;
    json_t *root = json_loadb(copy, len, JSON_REJECT_DUPLICATES, &jerr);
    if (!root) {
        st = fm_fail(err, FM_ERR_INPUT, "%s:%d:%d: %s", file, jerr.line, jerr.column, jerr.text);
    } else {
        where w = {def->scene_path, copy, err, {{0}}, {{0}}, 0, 0, ""};
        st = read_scene(&w, root, def);
        if (st == FM_OK) st = check_consistency(&w, def);
        json_decref(root);
    }
    free(copy);
    return st;
}

fm_status fm_scene_load(const char *path, fm_scene_def *def, fm_error *err)
{
    *def = fm_default_scene_def();
    snprintf(def->scene_path, sizeof def->scene_path, "%s", path);
    size_t len = 0;
    fm_status st = FM_OK;
    char *text = read_text(path, &len, &st, err);
    if (!text) return st;
    st = fm_scene_parse(text, len, path, def, err);
    free(text);
    return st;
}
