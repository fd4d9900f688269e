/* flockmorph info: a cache's agent and frame counts. */
#define _POSIX_C_SOURCE 200809L
#include "cli.h"

#include <stdio.h>

static const char *const USAGE_INFO = "usage: flockmorph info CACHE\n\nPrints the cache's agents, frames and frame rate.\n";


int cli_info(int argc, char **argv)
{
    if (cli_wants_help(argc, argv)) return printf("%s", USAGE_INFO), 0;
    cli_frame_options o;
    int rc = cli_parse_frame_options(argc, argv, USAGE_INFO, 1, &o);
    if (rc) return rc;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(o.cache, &err);
    if (!r) return cli_report(&err);
    if (fm_cache_warning(r)[0]) fprintf(stderr, "flockmorph: warning: %s\n", fm_cache_warning(r));
    printf("{\"agents\": %llu, \"frames\": %u, \"frame_rate\": %g, \"complete\": %s}\n",
           (unsigned long long)fm_cache_agents(r), fm_cache_frames(r), fm_cache_frame_rate(r),
           fm_cache_warning(r)[0] ? "false" : "true");
    fm_cache_close(r);
    return 0;
}

