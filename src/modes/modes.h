/* The one place that chooses by the scene's mode (modes.c): what the engine's mode-free calls
 * (fm_checkpoint_check, the memory estimate of a scene) need from the mode a scene names. Above
 * both modes; nothing below includes it. */
#ifndef FM_MODES_H
#define FM_MODES_H

#include "memory.h"

/* The memory estimate of the scene's mode for n agents (docs/limits.md). */
fm_memory_estimate fm_memory_estimate_for(const fm_scene_def *def, int64_t n);

#endif
