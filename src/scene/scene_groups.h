/* A scene's `groups` list (scene_groups.c; docs/scene.md, "Groups"). */
#ifndef FM_SCENE_GROUPS_H
#define FM_SCENE_GROUPS_H

#include "flockmorph/scene.h"

#include <jansson.h>

/* Checks root's `groups` and fills groups[0 .. *count): names, start, after, source.group and
 * avoid. *count is 0 for a scene without groups. Errors name the file, line and key. */
fm_status fm_groups_read(const json_t *root, const char *file, const char *text, fm_group_def *groups, int *count,
                         fm_error *err);

/* A new document: root without `groups`, group g's item laid over it (objects merged key by key,
 * other values replaced; name, start, after and avoid left out); a source that names a group is
 * that group's merged target. NULL when out of memory. */
json_t *fm_groups_merge(const json_t *root, const fm_group_def *groups, int g);

#endif
