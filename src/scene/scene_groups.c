/* A scene's `groups` list (docs/scene.md, "Groups"): several morphs in one shot. This file checks
 * the keys only a group has (name, start, after, avoid, source.group) and lays a group's item over
 * the scene's top level; scene.c then reads the merged document as it reads any scene. */
#include "scene_groups.h"
#include "fm_internal.h"
#include "json_locate.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* Keys the whole shot shares: one clock, one cache, one up axis. */
static const char *const SHARED_ONLY[] = {"mode", "time", "output", "up", "groups"};
/* Keys only a group item has; the merge leaves them out. */
static const char *const GROUP_ONLY[] = {"name", "start", "after", "avoid"};

typedef struct group_where {
    const char *file, *text;
    fm_error *err;
} group_where;

/* "FILE:LINE:COL: groups[i].KEY: what", the position that of groups[i].KEY (or of groups[i]). */
static fm_status fail_in_group(const group_where *w, int i, const char *key, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static fm_status fail_in_group(const group_where *w, int i, const char *key, const char *fmt, ...)
{
    char what[768], label[128];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    fm_json_step steps[3] = {{"groups", 0}, {NULL, i}, {key, 0}};
    int depth = i < 0 ? 1 : key ? 3 : 2, line = 0, col = 0;
    if (w->text && fm_json_locate(w->text, steps, depth, depth == 3, &line, &col) != 0 && depth == 3)
        fm_json_locate(w->text, steps, 2, 0, &line, &col);
    if (i < 0) snprintf(label, sizeof label, "groups");
    else snprintf(label, sizeof label, "groups[%d]%s%s", i, key ? "." : "", key ? key : "");
    if (line > 0) return fm_fail(w->err, FM_ERR_INPUT, "%s:%d:%d: %s: %s", w->file, line, col, label, what);
    return fm_fail(w->err, FM_ERR_INPUT, "%s: %s: %s", w->file, label, what);
}

static int listed(const char *key, const char *const *list, size_t count)
{
    for (size_t i = 0; i < count; i++)
        if (!strcmp(key, list[i])) return 1;
    return 0;
}

/* The index of the group called `name` among the first `before`, or -1. */
static int find_group(const fm_group_def *groups, int before, const char *name)
{
    for (int i = 0; i < before; i++)
        if (!strcmp(groups[i].name, name)) return i;
    return -1;
}

static int good_name(const char *s)
{
    size_t len = strlen(s);
    if (len == 0 || len >= sizeof ((fm_group_def *)0)->name) return 0;
    for (size_t i = 0; i < len; i++)
        if (!((s[i] >= 'a' && s[i] <= 'z') || (s[i] >= 'A' && s[i] <= 'Z') || (s[i] >= '0' && s[i] <= '9') ||
              s[i] == '_' || s[i] == '-'))
            return 0;
    return 1;
}

static fm_status read_name(const group_where *w, const json_t *item, int i, fm_group_def *groups)
{
    const json_t *v = json_object_get(item, "name");
    if (!v) return fail_in_group(w, i, NULL, "every group needs a \"name\"");
    if (!json_is_string(v) || !good_name(json_string_value(v)))
        return fail_in_group(w, i, "name", "must be a string of 1 to 63 letters, digits, '_' or '-'");
    if (find_group(groups, i, json_string_value(v)) >= 0)
        return fail_in_group(w, i, "name", "\"%s\" names an earlier group too", json_string_value(v));
    snprintf(groups[i].name, sizeof groups[i].name, "%s", json_string_value(v));
    return FM_OK;
}

/* A key holding the name of an earlier group: its index in *out. */
static fm_status read_earlier(const group_where *w, const json_t *v, int i, const char *key, fm_group_def *groups,
                              int32_t *out)
{
    if (!json_is_string(v)) return fail_in_group(w, i, key, "must be the name of an earlier group");
    int j = find_group(groups, i, json_string_value(v));
    if (j < 0)
        return fail_in_group(w, i, key, "\"%s\" is not the name of an earlier group (a group can only follow one "
                             "listed before it)", json_string_value(v));
    *out = j;
    return FM_OK;
}

/* "source": {"group": NAME} takes the whole source: the agents are that group's, where it formed. */
static fm_status read_source_group(const group_where *w, const json_t *item, int i, fm_group_def *groups)
{
    const json_t *source = json_object_get(item, "source"), *v = json_object_get(source, "group");
    if (!v) return FM_OK;
    if (json_object_size(source) != 1)
        return fail_in_group(w, i, "source", "a source that is a group's formed shape takes no other keys (mesh, "
                             "translate, scale, rotate_deg)");
    if (json_object_get(item, "n"))
        return fail_in_group(w, i, "n", "a group that starts from another's formed shape has that group's agents");
    return read_earlier(w, v, i, "source", groups, &groups[i].source_group);
}

static fm_status read_timing(const group_where *w, const json_t *item, int i, fm_group_def *groups)
{
    const json_t *start = json_object_get(item, "start"), *after = json_object_get(item, "after");
    if (start && (!json_is_number(start) || !(json_number_value(start) >= 0) || json_number_value(start) > 1e6))
        return fail_in_group(w, i, "start", "must be a number of seconds from 0 to 1e6");
    groups[i].start = start ? json_number_value(start) : 0.0;
    if (after) {
        fm_status st = read_earlier(w, after, i, "after", groups, &groups[i].after);
        if (st != FM_OK) return st;
    }
    const int32_t from = groups[i].source_group;
    if (from >= 0 && after && groups[i].after != from)
        return fail_in_group(w, i, "after", "this group starts from \"%s\"'s formed shape, so it starts after that "
                             "group: leave \"after\" out or name it", groups[from].name);
    if (from >= 0) groups[i].after = from;
    return FM_OK;
}

static fm_status read_avoid(const group_where *w, const json_t *item, int i, int count, const json_t *list,
                            fm_group_def *groups)
{
    const json_t *avoid = json_object_get(item, "avoid");
    if (!avoid) return FM_OK;
    if (!json_is_array(avoid)) return fail_in_group(w, i, "avoid", "must be a list of group names");
    for (size_t k = 0; k < json_array_size(avoid); k++) {
        const json_t *v = json_array_get(avoid, k);
        int j = -1;
        for (int g = 0; json_is_string(v) && g < count; g++)
            if (!strcmp(json_string_value(json_object_get(json_array_get(list, (size_t)g), "name")), json_string_value(v)))
                j = g;
        if (j < 0 || j == i)
            return fail_in_group(w, i, "avoid", "entry %zu must name another group of this scene", k);
        for (int a = 0; a < groups[i].avoid_count; a++)
            if (groups[i].avoid[a] == j) return fail_in_group(w, i, "avoid", "\"%s\" is listed twice", groups[j].name);
        groups[i].avoid[groups[i].avoid_count++] = j;
    }
    return FM_OK;
}

static fm_status check_item_keys(const group_where *w, const json_t *item, int i)
{
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)item, key, value) {
        if (listed(key, SHARED_ONLY, sizeof SHARED_ONLY / sizeof *SHARED_ONLY))
            return fail_in_group(w, i, key, "the whole shot shares it: set it at the scene's top level");
    }
    return FM_OK;
}

static fm_status read_group(const group_where *w, const json_t *list, int i, fm_group_def *groups)
{
    const json_t *item = json_array_get(list, (size_t)i);
    if (!json_is_object(item)) return fail_in_group(w, i, NULL, "a group must be a JSON object");
    groups[i] = (fm_group_def){.after = -1, .source_group = -1};
    fm_status st = read_name(w, item, i, groups);
    if (st == FM_OK) st = check_item_keys(w, item, i);
    if (st == FM_OK) st = read_source_group(w, item, i, groups);
    if (st == FM_OK) st = read_timing(w, item, i, groups);
    return st;
}

fm_status fm_groups_read(const json_t *root, const char *file, const char *text, fm_group_def *groups, int *count,
                         fm_error *err)
{
    const group_where w = {file, text, err};
    const json_t *list = json_object_get(root, "groups");
    *count = 0;
    if (!list) return FM_OK;
    if (!json_is_array(list) || json_array_size(list) < 1 || json_array_size(list) > FM_MAX_GROUPS)
        return fail_in_group(&w, -1, NULL, "must be a list of 1 to %d groups", FM_MAX_GROUPS);
    int n = (int)json_array_size(list);
    fm_status st = FM_OK;
    for (int i = 0; i < n && st == FM_OK; i++) st = read_group(&w, list, i, groups);
    for (int i = 0; i < n && st == FM_OK; i++) st = read_avoid(&w, json_array_get(list, (size_t)i), i, n, list, groups);
    if (st == FM_OK) *count = n;
    return st;
}

/* Lays `over` onto `base` (both objects): objects merge key by key, anything else replaces. */
static int merge_into(json_t *base, const json_t *over, int top)
{
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)over, key, value) {
        if (top && listed(key, GROUP_ONLY, sizeof GROUP_ONLY / sizeof *GROUP_ONLY)) continue;
        json_t *old = json_object_get(base, key);
        if (json_is_object(value) && json_is_object(old)) {
            if (!merge_into(old, value, 0)) return 0;
        } else if (json_object_set_new(base, key, json_deep_copy(value)) != 0) {
            return 0;
        }
    }
    return 1;
}

json_t *fm_groups_merge(const json_t *root, const fm_group_def *groups, int g)
{
    const json_t *item = json_array_get(json_object_get(root, "groups"), (size_t)g);
    json_t *doc = json_deep_copy(root);
    if (!doc || !item) return json_decref(doc), NULL;
    json_object_del(doc, "groups");
    if (!merge_into(doc, item, 1)) return json_decref(doc), NULL;
    if (groups[g].source_group < 0) return doc;
    /* the agents fly on from where the earlier group formed: its target is this group's source */
    json_t *earlier = fm_groups_merge(root, groups, groups[g].source_group);
    json_t *target = json_object_get(earlier, "target"), *n = json_object_get(earlier, "n");
    int ok = target && json_object_set(doc, "source", target) == 0;
    /* the same agents: the earlier group's n (the tetra morph takes the count from its tets) */
    ok = ok && (n ? json_object_set(doc, "n", n) == 0 : json_object_del(doc, "n") >= -1);
    json_decref(earlier);
    return ok ? doc : (json_decref(doc), NULL);
}
