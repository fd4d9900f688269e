/* What every fuzz target asserts about the engine's answer to an input: it is accepted, or it is
 * rejected with a status the input explains (input, I/O or memory) and a message. Anything else
 * aborts, which libFuzzer reports as a crash and the ctest replay (replay_main.c) as a failure. */
#ifndef FM_FUZZ_CHECK_H
#define FM_FUZZ_CHECK_H

#include "flockmorph/flockmorph.h"

#include <stdio.h>
#include <stdlib.h>

#define FUZZ_ASSERT(cond)                                                                  \
    do {                                                                                   \
        if (!(cond)) {                                                                     \
            fprintf(stderr, "%s:%d: FUZZ_ASSERT(%s) failed\n", __FILE__, __LINE__, #cond); \
            abort();                                                                       \
        }                                                                                  \
    } while (0)

/* A clean outcome: FM_OK, or an input, I/O or memory error with a non-empty message. */
static inline void fuzz_expect_clean(fm_status st, const fm_error *err)
{
    if (st == FM_OK) return;
    if ((st == FM_ERR_INPUT || st == FM_ERR_IO || st == FM_ERR_MEMORY) && err->message[0]) return;
    fprintf(stderr, "fuzz: unclean rejection: status %d, message \"%s\"\n", (int)st, err->message);
    abort();
}

#endif
