/* flockmorph — turn one 3D shape into another as a flock.
 *
 * The public C API: this umbrella header includes every part of it; everything under src/ and
 * kernels/ is internal.
 *
 *   flockmorph/core.h    version, status codes and errors, progress, agent phases
 *   flockmorph/scene.h   fm_scene_def: every parameter of a run, from a scene file or code
 *   flockmorph/cache.h   the native frame cache: writer and reader
 *   flockmorph/run.h     one run control for both modes: progress, checkpoints, stop, resume
 *   flockmorph/morph.h   the tetra flock morph: fm_morph_model, fm_morph_state, fm_morph_run
 *   flockmorph/flock.h   the shape-constrained flock: fm_flock_model, fm_flock_state, fm_flock_run
 *   flockmorph/export.h  one frame to PLY, OBJ, VTK or OpenVDB
 *   flockmorph/render.h  the ray-cast preview, PNG and video
 *
 * Every fallible call takes an fm_error* and returns an fm_status (or NULL for constructors);
 * on failure err->message says what went wrong and names the file, line, key or element.
 */
#ifndef FLOCKMORPH_H
#define FLOCKMORPH_H

#include "flockmorph/core.h"
#include "flockmorph/scene.h"
#include "flockmorph/cache.h"
#include "flockmorph/run.h"
#include "flockmorph/morph.h"
#include "flockmorph/flock.h"
#include "flockmorph/export.h"
#include "flockmorph/render.h"

#endif /* FLOCKMORPH_H */
