/* cache_points OUT AGENTS FRAMES: writes a point-flock cache (position, velocity, orientation, id,
 * phase) of agents on helices, as the shape-constrained flock will, for the Blender add-on's test
 * (tests/blender/test_blender_import.py). Frame rate 25, the default cache options.
 *
 * Agent a circles the z axis at radius 2 + a/4, climbing; its orientation turns x along the
 * velocity (yaw, then pitch) and banks it by a roll that grows with a (0.3 + 0.4·a radians), so the rotations cover every
 * axis. Agent 0 climbs straight up instead, the gimbal-lock case of an XYZ Euler conversion. */
#include "flockmorph/flockmorph.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define RATE 25.0

typedef struct flock_frame {
    float *position, *velocity, *orientation;
    uint32_t *id;
    uint8_t *phase;
} flock_frame;

/* q = q1 ⊗ q2, quaternions (w, x, y, z). */
static void quat_mul(const double q1[4], const double q2[4], double out[4])
{
    out[0] = q1[0] * q2[0] - q1[1] * q2[1] - q1[2] * q2[2] - q1[3] * q2[3];
    out[1] = q1[0] * q2[1] + q1[1] * q2[0] + q1[2] * q2[3] - q1[3] * q2[2];
    out[2] = q1[0] * q2[2] - q1[1] * q2[3] + q1[2] * q2[0] + q1[3] * q2[1];
    out[3] = q1[0] * q2[3] + q1[1] * q2[2] - q1[2] * q2[1] + q1[3] * q2[0];
}

/* The frame with x along v (yaw about z, then pitch up), banked by `roll` about x. */
static void orientation_along(const double v[3], double roll, double q[4])
{
    double yaw = atan2(v[1], v[0]), pitch = atan2(v[2], hypot(v[0], v[1]));
    const double qz[4] = {cos(yaw / 2), 0, 0, sin(yaw / 2)};
    const double qy[4] = {cos(-pitch / 2), 0, sin(-pitch / 2), 0}; /* about y, +angle tips x down */
    const double qx[4] = {cos(roll / 2), sin(roll / 2), 0, 0};
    double zy[4];
    quat_mul(qz, qy, zy);
    quat_mul(zy, qx, q);
}

static void agent_state(uint64_t a, double t, double p[3], double v[3])
{
    if (a == 0) { /* straight up */
        p[0] = p[1] = 0, p[2] = t;
        v[0] = v[1] = 0, v[2] = 1;
        return;
    }
    double r = 2 + 0.25 * (double)a, w = 1.0 + 0.05 * (double)a, phi = 0.7 * (double)a, climb = 0.3;
    p[0] = r * cos(w * t + phi), p[1] = r * sin(w * t + phi), p[2] = climb * t;
    v[0] = -r * w * sin(w * t + phi), v[1] = r * w * cos(w * t + phi), v[2] = climb;
}

static void fill_frame(const flock_frame *f, uint64_t agents, uint32_t k)
{
    double t = k / RATE;
    for (uint64_t a = 0; a < agents; a++) {
        double p[3], v[3], q[4];
        agent_state(a, t, p, v);
        orientation_along(v, 0.3 + 0.4 * (double)a, q);
        for (int c = 0; c < 3; c++) f->position[3 * a + c] = (float)p[c], f->velocity[3 * a + c] = (float)v[c];
        for (int c = 0; c < 4; c++) f->orientation[4 * a + c] = (float)q[c];
        f->id[a] = (uint32_t)(1000 + 3 * a);
        f->phase[a] = (uint8_t)((a + k / 8) % 4);
    }
}

int main(int argc, char **argv)
{
    if (argc != 4) return fprintf(stderr, "usage: cache_points OUT AGENTS FRAMES\n"), FM_ERR_USAGE;
    uint64_t agents = strtoull(argv[2], NULL, 10);
    uint32_t frames = (uint32_t)strtoul(argv[3], NULL, 10);
    const fm_cache_attr attrs[] = {FM_ATTR_POSITION, FM_ATTR_VELOCITY, FM_ATTR_ORIENTATION, FM_ATTR_ID, FM_ATTR_PHASE};
    flock_frame f = {malloc(agents * 12 + 1), malloc(agents * 12 + 1), malloc(agents * 16 + 1),
                     malloc(agents * 4 + 1), malloc(agents + 1)};
    fm_error err = {0};
    fm_cache_options opts = fm_default_cache_options();
    fm_cache_writer *w = fm_cache_writer_create_attrs(argv[1], agents, RATE, attrs, 5, &opts, &err);
    fm_status st = w && f.position && f.velocity && f.orientation && f.id && f.phase ? FM_OK : FM_ERR_MEMORY;
    for (uint32_t k = 0; k < frames && st == FM_OK; k++) {
        fill_frame(&f, agents, k);
        const void *data[] = {f.position, f.velocity, f.orientation, f.id, f.phase};
        st = fm_cache_writer_add_frame_attrs(w, data, &err);
    }
    if (w) st = st == FM_OK ? fm_cache_writer_finish(w, &err) : (fm_cache_writer_abort(w), st);
    if (st != FM_OK || !w) fprintf(stderr, "cache_points: %s\n", err.message[0] ? err.message : "out of memory");
    free(f.position), free(f.velocity), free(f.orientation), free(f.id), free(f.phase);
    return w ? (int)st : (int)err.status;
}
