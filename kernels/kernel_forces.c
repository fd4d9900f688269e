/* The forces' SIMD variants, picked at run time (kernel_forces.h). */
#include "kernel_forces.h"

int64_t fm_kernel_other_forces(const fm_forces_view *w, const fm_forces_arrays *x, int64_t begin, int64_t end)
{
    fm_other_forces_fn *variant = FM_SIMD_PICK(fm_kernel_other_forces);
    return variant ? variant(w, x, begin, end) : begin;
}

int64_t fm_kernel_combine_forces(const fm_forces_arrays *x, int64_t begin, int64_t end)
{
    fm_combine_forces_fn *variant = FM_SIMD_PICK(fm_kernel_combine_forces);
    return variant ? variant(x, begin, end) : begin;
}

int64_t fm_kernel_move_flying(const fm_forces_arrays *x, float *const p[3], float *const v[3], uint8_t *phase,
                              const float *max_speed, float dt, float arrival_radius, uint8_t homing, int64_t begin,
                              int64_t end)
{
    fm_move_flying_fn *variant = FM_SIMD_PICK(fm_kernel_move_flying);
    return variant ? variant(x, p, v, phase, max_speed, dt, arrival_radius, homing, begin, end) : begin;
}
