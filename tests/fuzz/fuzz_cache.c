/* libFuzzer target: the cache reader. The input is the cache file (in a memfd, so nothing touches
 * the disk); every frame it lists is read. */
#define _GNU_SOURCE
#include "fuzz_check.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Frames larger than this are not read (the caller must hold agents × bytes per agent). */
enum { MAX_FRAME_BYTES = 16 << 20 };

static int write_all(int fd, const uint8_t *data, size_t size)
{
    while (size > 0) {
        ssize_t n = write(fd, data, size);
        if (n <= 0) return -1;
        data += n, size -= (size_t)n;
    }
    return 0;
}

/* Every attribute of every frame the cache lists (formats 2 to 4 have several; format 4 in pieces). */
static void read_every_frame(fm_cache_reader *r)
{
    uint64_t agents = fm_cache_agents(r);
    if (agents > MAX_FRAME_BYTES / 48) return;
    void *frame = malloc(agents ? agents * 48 : 1); /* 48 bytes per agent: the largest attribute */
    FUZZ_ASSERT(frame != NULL);
    for (uint32_t f = 0; f < fm_cache_frames(r); f++)
        for (int i = 0; i < fm_cache_attr_count(r); i++) {
            fm_error err = {0};
            fuzz_expect_clean(fm_cache_read_attr(r, f, fm_cache_attr_at(r, i)->attr, frame, &err), &err);
        }
    free(frame);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    int fd = memfd_create("fuzz_cache", 0);
    FUZZ_ASSERT(fd >= 0 && write_all(fd, data, size) == 0);
    char path[64];
    snprintf(path, sizeof path, "/proc/self/fd/%d", fd);
    fm_error err = {0};
    fm_cache_reader *r = fm_cache_open(path, &err);
    if (!r) {
        FUZZ_ASSERT(err.status != FM_OK);
        fuzz_expect_clean(err.status, &err);
    } else {
        /* what open promises: a usable frame rate, an index no larger than the file */
        FUZZ_ASSERT(isfinite(fm_cache_frame_rate(r)) && fm_cache_frame_rate(r) > 0);
        FUZZ_ASSERT((uint64_t)fm_cache_frames(r) * 8 <= size && fm_cache_warning(r) != NULL);
        /* formats 3 and 4: a complete cache's header states its frame count (0 only if it is empty) */
        FUZZ_ASSERT(fm_cache_version(r) < 3 || fm_cache_warning(r)[0] || fm_cache_header_frames(r) == fm_cache_frames(r));
        read_every_frame(r);
        fm_cache_close(r);
    }
    close(fd);
    return 0;
}
