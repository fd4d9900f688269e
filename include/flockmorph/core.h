/* flockmorph: what every part of the API shares: the version, status codes and errors, the
 * preprocessing progress callback and the agents' phases. */
#ifndef FLOCKMORPH_CORE_H
#define FLOCKMORPH_CORE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FM_VERSION_STRING "0.1.0"

/* Status codes double as the CLI's exit codes. */
typedef enum fm_status {
    FM_OK = 0,
    FM_ERR_USAGE = 1,    /* bad command line */
    FM_ERR_INPUT = 2,    /* bad scene file, mesh or parameter */
    FM_ERR_IO = 3,       /* cannot read or write a file */
    FM_ERR_MEMORY = 4,   /* allocation failed */
    FM_ERR_INTERNAL = 5, /* a library failed in a way the input does not explain */
    FM_STOPPED = 6       /* not an error: fm_morph_run_controlled stopped on request after its checkpoint,
                            or fm_flock_run_controlled at a frame boundary (the CLI then exits 128
                            + the signal's number) */
} fm_status;

typedef struct fm_error {
    fm_status status;
    char message[2048];
} fm_error;

/* Progress of long preprocessing stages (either mode's model build); may be NULL. fraction is in
 * [0, 1]. */
typedef void (*fm_progress_fn)(const char *stage, double fraction, void *user);

/* An agent's phase, in both modes. The tetra morph: waiting in the source, flying the path, homing
 * to its target tet, arrived. The shape flock: FLYING under forces, HOMING in the stepped approach,
 * ARRIVED bound or floating. */
typedef enum fm_phase {
    FM_PHASE_WAITING = 0,  /* tetra morph: not launched yet, at rest in the source */
    FM_PHASE_FLYING = 1,   /* tetra morph phase 1: following the path (FM eq 8) */
    FM_PHASE_HOMING = 2,   /* tetra morph phase 2: flying straight to its target tet (FM eq 9) */
    FM_PHASE_ARRIVED = 3
} fm_phase;

#ifdef __cplusplus
}
#endif

#endif /* FLOCKMORPH_CORE_H */
