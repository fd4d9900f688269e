/* The dispatch by scene mode (modes.h): each mode's member table and memory estimate. */
#include "flock.h"
#include "modes.h"
#include "morph.h"

fm_memory_estimate fm_memory_estimate_for(const fm_scene_def *def, int64_t n)
{
    return def->mode == FM_MODE_SHAPE_FLOCK ? fm_flock_memory_estimate(def, n) : fm_morph_memory_estimate(def, n);
}

fm_status fm_checkpoint_check(const char *path, const fm_scene_def *def, fm_error *err)
{
    if (def->mode == FM_MODE_SHAPE_FLOCK)
        return fm_ckpt_check(path, def, fm_flock_state_members, fm_flock_state_member_count, err);
    return fm_ckpt_check(path, def, fm_morph_state_members, fm_morph_state_member_count, err);
}
