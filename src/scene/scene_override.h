/* Overrides (`--set KEY=VALUE`, wedges) applied to a scene's JSON before scene.c reads it, and
 * the override an error is about. */
#ifndef FM_SCENE_OVERRIDE_H
#define FM_SCENE_OVERRIDE_H

#include "fm_internal.h"

#include <jansson.h>

/* "an object", "a number", ... for messages. */
const char *fm_json_type_name(const json_t *v);

/* An override's VALUE: the JSON it is, or the text as a string if it is not JSON (NULL if it is
 * not UTF-8). A new reference. */
json_t *fm_override_value(const char *text);

/* Applies the overrides to the document in order and records each in def->overrides (its path
 * as messages write keys, and its label); an override that cannot be applied (a list index past
 * the end, a key through a number) fails with FM_ERR_INPUT naming it. */
fm_status fm_overrides_apply(json_t *root, const fm_scene_override *set, int count, fm_scene_def *def,
                             fm_error *err);

/* The last of def's overrides whose path is `path`, a group holding it or a key inside it
 * ("source" and "source.mesh" both blame --set source.mesh=...), or NULL. */
const fm_scene_override_note *fm_override_blame(const fm_scene_def *def, const char *path);

/* Whether a shot's group item sets `key` itself (or a list or value above it), so that the group
 * never sees the scene's top-level value of it. */
int fm_override_shadowed(const json_t *item, const char *key);

#endif
