/* The shape flock's agents' frames from their velocities. */
#ifndef FM_KERNEL_ORIENT_H
#define FM_KERNEL_ORIENT_H

void fm_flock_update_orientation(float *q, const float v[3]);

#endif
