/* --set KEY=VALUE on a scene's JSON (docs/wedges.md). The key walks the document, objects by member
 * name and lists by index, creating missing groups; the value replaces what is there. The changed
 * document is then read by scene.c exactly as a file is, and its errors blame the override
 * (fm_override_blame) rather than a line of the file, which does not hold the value. */
#define _POSIX_C_SOURCE 200809L
#include "scene_override.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *fm_json_type_name(const json_t *v)
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

/* One part of a key: a member name, or a list index, written "[2]" (bracketed) or ".2". */
typedef struct key_part {
    char name[64];
    int bracketed;
} key_part;

enum { MAX_KEY_PARTS = 16 };

static int is_index(const char *s)
{
    size_t len = strlen(s);
    return len > 0 && len <= 9 && strspn(s, "0123456789") == len;
}

/* "a.b[2].c" or "a.b.2.c" into parts; -1 for an empty part, a bad index or too many parts. */
static int split_key(const char *key, key_part *parts)
{
    int n = 0;
    for (const char *s = key; *s;) {
        if (n == MAX_KEY_PARTS) return -1;
        key_part *p = &parts[n++];
        p->bracketed = *s == '[';
        const char *start = s + p->bracketed;
        size_t len = p->bracketed ? strcspn(start, "]") : strcspn(start, ".[");
        if (len == 0 || len >= sizeof p->name) return -1;
        memcpy(p->name, start, len);
        p->name[len] = 0;
        s = start + len;
        if (p->bracketed && (*s++ != ']' || !is_index(p->name))) return -1;
        if (*s == '.' && (!s[1] || s[1] == '.' || s[1] == '[')) return -1;
        if (*s && *s != '.' && *s != '[') return -1;
        s += *s == '.';
    }
    return n;
}

json_t *fm_override_value(const char *text)
{
    json_t *v = json_loads(text, JSON_DECODE_ANY | JSON_REJECT_DUPLICATES, NULL);
    return v ? v : json_string(text);
}

static fm_status fail_override(const fm_scene_override_note *note, fm_error *err, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static fm_status fail_override(const fm_scene_override_note *note, fm_error *err, const char *fmt, ...)
{
    char what[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return fm_fail(err, FM_ERR_INPUT, "%s: %s", note->label, what);
}

/* Appends the part to the note's path as messages write keys ("obstacles.meshes[0].scale"). */
static void extend_path(fm_scene_override_note *note, const json_t *node, const key_part *p)
{
    char part[sizeof p->name + 2];
    size_t len = strlen(note->path);
    if (json_is_array(node)) snprintf(part, sizeof part, "[%.63s]", p->name);
    else snprintf(part, sizeof part, "%s%.63s", len ? "." : "", p->name);
    strncat(note->path, part, sizeof note->path - len - 1);
}

/* Checks that the part can name a member or element of node; *index is the element's. */
static fm_status check_part(const json_t *node, const key_part *p, const char *parent,
                            const fm_scene_override_note *note, size_t *index, fm_error *err)
{
    if (json_is_object(node) && !p->bracketed) return FM_OK;
    if (!json_is_array(node))
        return fail_override(note, err, "%s is %s, not %s", parent[0] ? parent : "the scene", fm_json_type_name(node),
                             p->bracketed ? "a list" : "a group of keys");
    if (!is_index(p->name))
        return fail_override(note, err, "%s is a list: name an element by its index (%s.0)", parent, parent);
    *index = (size_t)strtol(p->name, NULL, 10);
    if (*index >= json_array_size(node))
        return fail_override(note, err, "%s has %zu element%s; there is no element %zu (set the whole list to add one)",
                             parent, json_array_size(node), json_array_size(node) == 1 ? "" : "s", *index);
    return FM_OK;
}

/* Moves *node to its member or element p, creating a missing member as an empty object; but a
 * missing member whose `next` part is an index is a list the scene lacks, whose elements cannot
 * be set one by one. */
static fm_status descend(json_t **node, const key_part *p, const key_part *next, fm_scene_override_note *note,
                         fm_error *err)
{
    char parent[sizeof note->path];
    size_t index = 0;
    snprintf(parent, sizeof parent, "%s", note->path);
    fm_status st = check_part(*node, p, parent, note, &index, err);
    if (st != FM_OK) return st;
    extend_path(note, *node, p);
    if (json_is_array(*node)) return *node = json_array_get(*node, index), FM_OK;
    json_t *child = json_object_get(*node, p->name);
    if (!child && (next->bracketed || is_index(next->name)))
        return fail_override(note, err, "element %s is out of range: the scene has no %s list (set the whole list to "
                             "add one: --set '%s=[...]')", next->name, note->path, note->path);
    if (!child && json_object_set_new(*node, p->name, child = json_object()) != 0)
        return fm_fail(err, FM_ERR_MEMORY, "%s: out of memory", note->label);
    *node = child;
    return FM_OK;
}

/* Sets (or, for null, removes) member or element p of node to value. */
static fm_status assign(json_t *node, const key_part *p, json_t *value, fm_scene_override_note *note, fm_error *err)
{
    char parent[sizeof note->path];
    size_t index = 0;
    snprintf(parent, sizeof parent, "%s", note->path);
    fm_status st = check_part(node, p, parent, note, &index, err);
    if (st != FM_OK) return st;
    extend_path(note, node, p);
    if (json_is_array(node) && json_is_null(value))
        return fail_override(note, err, "null removes a key, not a list element: set the whole list %s instead", parent);
    if (json_is_null(value)) return json_object_del(node, p->name), FM_OK; /* a missing key is already removed */
    int rc = json_is_array(node) ? json_array_set(node, index, value) : json_object_set(node, p->name, value);
    return rc == 0 ? FM_OK : fm_fail(err, FM_ERR_MEMORY, "%s: out of memory", note->label);
}

/* "--set KEY=VALUE" or "ORIGIN: KEY=VALUE", a long value cut short. */
static void make_label(const fm_scene_override *o, fm_scene_override_note *note)
{
    const int max = 96;
    int cut = (int)strlen(o->value) > max;
    snprintf(note->label, sizeof note->label, "%s%s%s=%.*s%s", o->origin ? o->origin : "--set", o->origin ? ": " : " ",
             o->key, cut ? max - 3 : max, o->value, cut ? "..." : "");
}

static fm_status apply_one(json_t *root, const fm_scene_override *o, fm_scene_override_note *note, fm_error *err)
{
    key_part parts[MAX_KEY_PARTS];
    make_label(o, note);
    note->path[0] = 0;
    int n = split_key(o->key, parts);
    if (n <= 0)
        return fail_override(note, err, "'%s' is not a key: groups and keys joined by dots, list elements by index "
                             "(mde.d_min, obstacles.meshes.0.scale)", o->key);
    json_t *value = fm_override_value(o->value), *node = root;
    if (!value) return fail_override(note, err, "the value is not UTF-8 text");
    fm_status st = FM_OK;
    for (int i = 0; i + 1 < n && st == FM_OK; i++) st = descend(&node, &parts[i], &parts[i + 1], note, err);
    if (st == FM_OK) st = assign(node, &parts[n - 1], value, note, err);
    json_decref(value);
    return st;
}

fm_status fm_overrides_apply(json_t *root, const fm_scene_override *set, int count, fm_scene_def *def,
                             fm_error *err)
{
    if (count > FM_MAX_OVERRIDES)
        return fm_fail(err, FM_ERR_INPUT, "%d overrides (--set and the wedge's) are more than the %d supported", count,
                       FM_MAX_OVERRIDES);
    def->override_count = 0;
    for (int i = 0; i < count; i++) {
        fm_status st = apply_one(root, &set[i], &def->overrides[i], err);
        if (st != FM_OK) return st;
        def->override_count = i + 1;
    }
    return FM_OK;
}

/* Is a the key b, or a group above it ("source" of "source.mesh", "style.fields" of
 * "style.fields[1]")? */
static int on_path(const char *a, const char *b)
{
    size_t n = strlen(a);
    return n > 0 && !strncmp(a, b, n) && (b[n] == 0 || b[n] == '.' || b[n] == '[');
}

const fm_scene_override_note *fm_override_blame(const fm_scene_def *def, const char *path)
{
    for (int i = def->override_count - 1; i >= 0; i--)
        if (on_path(def->overrides[i].path, path) || on_path(path, def->overrides[i].path)) return &def->overrides[i];
    return NULL;
}

int fm_override_shadowed(const json_t *item, const char *key)
{
    key_part parts[MAX_KEY_PARTS];
    int n = split_key(key, parts);
    const json_t *node = item;
    for (int i = 0; i < n; i++) {
        if (!json_is_object(node)) return i > 0; /* a list or value of the group's replaces the key whole */
        if (!(node = json_object_get(node, parts[i].name))) return 0;
    }
    return n > 0;
}
