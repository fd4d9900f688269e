/* cache_dump CACHE OUT: writes every frame's attributes, as fm_cache_read_attr returns them,
 * one after another (frame by frame, attributes in the cache's order) to OUT. The Python
 * reader's test compares its arrays with these bytes. */
#include "flockmorph/flockmorph.h"

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv)
{
    if (argc != 3) return fprintf(stderr, "usage: cache_dump CACHE OUT\n"), FM_ERR_USAGE;
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(argv[1], &err);
    if (!r) return fprintf(stderr, "cache_dump: %s\n", err.message), (int)err.status;
    FILE *out = fopen(argv[2], "wb");
    fm_status st = out ? FM_OK : FM_ERR_IO;
    for (uint32_t k = 0; k < fm_cache_frames(r) && st == FM_OK; k++)
        for (int i = 0; i < fm_cache_attr_count(r) && st == FM_OK; i++) {
            const fm_cache_attr_info *a = fm_cache_attr_at(r, i);
            size_t bytes = a->bytes_per_agent * fm_cache_agents(r);
            void *buf = malloc(bytes + 1);
            st = buf ? fm_cache_read_attr(r, k, a->attr, buf, &err) : FM_ERR_MEMORY;
            if (st == FM_OK && fwrite(buf, 1, bytes, out) != bytes) st = FM_ERR_IO;
            free(buf);
        }
    if (out && fclose(out) != 0 && st == FM_OK) st = FM_ERR_IO;
    if (st != FM_OK) fprintf(stderr, "cache_dump: %s: %s\n", argv[1], err.message[0] ? err.message : "write failed");
    fm_cache_close(r);
    return (int)st;
}
