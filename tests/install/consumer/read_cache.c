/* A program outside flockmorph that reads a cache through the installed package: opens CACHE,
 * checks its agent count against AGENTS, reads its last frame and checks that every value is
 * finite, and that the headers' version is the one the package was found with (EXPECTED_VERSION,
 * from find_package or pkg-config --modversion). Exit 0 only if all of that holds.
 *   read_cache CACHE AGENTS */
#include <flockmorph/cache.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv)
{
    if (argc != 3) return fprintf(stderr, "usage: read_cache CACHE AGENTS\n"), 2;
    if (strcmp(FM_VERSION_STRING, EXPECTED_VERSION) != 0)
        return fprintf(stderr, "read_cache: headers say %s, the package %s\n", FM_VERSION_STRING, EXPECTED_VERSION), 1;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(argv[1], &err);
    if (!r) return fprintf(stderr, "read_cache: %s\n", err.message), 1;
    uint64_t agents = fm_cache_agents(r), expected = strtoull(argv[2], NULL, 10);
    uint32_t frames = fm_cache_frames(r);
    if (agents != expected || frames == 0)
        return fprintf(stderr, "read_cache: %llu agents (expected %llu), %u frames\n", (unsigned long long)agents,
                       (unsigned long long)expected, frames), fm_cache_close(r), 1;
    /* a tet cache through fm_cache_read_frame, a point cache through fm_cache_read_attr */
    int tets = fm_cache_has_attr(r, FM_ATTR_TET_VERTICES);
    size_t count = (size_t)agents * (tets ? 12 : 3);
    float *v = malloc(count * sizeof *v);
    fm_status st = !v ? FM_ERR_MEMORY
                 : tets ? fm_cache_read_frame(r, frames - 1, v, &err)
                        : fm_cache_read_attr(r, frames - 1, FM_ATTR_POSITION, v, &err);
    int bad = 0;
    for (size_t i = 0; st == FM_OK && i < count; i++) bad += !isfinite(v[i]);
    if (st != FM_OK) fprintf(stderr, "read_cache: frame %u: %s\n", frames - 1, err.message);
    else if (bad) fprintf(stderr, "read_cache: %d values of frame %u are not finite\n", bad, frames - 1);
    else printf("read_cache: %s: %llu agents, %u frames, frame %u finite (flockmorph %s)\n", argv[1],
                (unsigned long long)agents, frames, frames - 1, FM_VERSION_STRING);
    free(v);
    fm_cache_close(r);
    return st == FM_OK && !bad ? 0 : 1;
}
