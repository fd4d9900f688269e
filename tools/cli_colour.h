/* `flockmorph render --color MODE [--color-range LO:HI]`: what each agent's colour means
 * (tools/cli_render_colour.c; docs/render.md, "Colour"). */
#ifndef FM_CLI_COLOUR_H
#define FM_CLI_COLOUR_H

#include "flockmorph/flockmorph.h"

#include <stdint.h>

typedef enum cli_colour_mode { CLI_COLOUR_SPEED, CLI_COLOUR_PHASE, CLI_COLOUR_ID } cli_colour_mode;

/* The options as given. */
typedef struct cli_colour_options {
    cli_colour_mode mode;
    int fixed_range; /* --color-range LO:HI was given */
    double lo, hi;
} cli_colour_options;

/* --color (NULL: speed) and --color-range (NULL: none); 0 or FM_ERR_USAGE with a message that
 * names the option. */
int cli_colour_parse(const char *mode, const char *range, const char *usage, cli_colour_options *o);

/* The colouring of one render call: the options, the cache it reads, the scale fixed for all the
 * frames of the call, and per-frame buffers. */
typedef struct cli_colouring {
    cli_colour_options o;
    fm_cache_reader *r; /* not owned */
    const char *path;
    int points;         /* 1: a point cache (position), 0: tets */
    int velocity;       /* 1: the cache has a velocity attribute (speed = |velocity|) */
    size_t n;
    float *value;       /* speed: n values; phase: n x 3 sRGB */
    float *scratch;     /* one frame of positions, tet vertices or velocities */
    double *here, *there; /* n x 3 agent centres of this frame and of its neighbour */
    uint8_t *phase;
} cli_colouring;

/* Checks the cache against the mode (phase needs a phase attribute) and allocates; 0 or an exit
 * status (after printing the error). */
int cli_colour_open(cli_colouring *c, const cli_colour_options *o, fm_cache_reader *r, const char *path,
                    int points);
/* Fixes the speed scale for the frames first, first + step, ... last (unless --color-range gave it)
 * and prints the line that says what the colours mean on stderr; 0 or an exit status. */
int cli_colour_fix_scale(cli_colouring *c, uint32_t first, uint32_t last, uint32_t step);
/* The colours of one frame (pointing into c until the next call); 0 or an exit status. */
int cli_colour_frame(cli_colouring *c, uint32_t frame, fm_render_colours *out);
void cli_colour_free(cli_colouring *c);

#endif
