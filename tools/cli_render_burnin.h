/* `flockmorph render --burn-in` (cli_render_burnin.c, docs/render.md "Burn-in"). */
#ifndef FM_CLI_RENDER_BURNIN_H
#define FM_CLI_RENDER_BURNIN_H

#include <stddef.h>

/* Draws text (one line, cut at the image's edge) into the bottom-left corner of a width x height
 * RGB image: white 5 x 7 dot letters, a dot height / 270 pixels wide (at least 1), on a box that
 * keeps a third of the picture's light. */
void cli_burn_in(unsigned char *rgb, int width, int height, const char *text);
/* The scene's name for the burn-in: from the `scene` of stats.json beside the cache (the file's
 * name without .json, or its folder's for a scene.json), else the cache's folder's name, or its
 * own without the extension. */
void cli_burn_in_scene(const char *cache, char *out, size_t size);

#endif
