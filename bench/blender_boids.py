"""Times Blender's own boids, the peer of the shape flock (docs/performance.md, tools/bench-peers.sh).

    blender -b --factory-startup --python bench/blender_boids.py -- [AGENTS [FRAMES [THREADS]]]

Builds a particle system with boids physics on a cube (AGENTS particles, default 100000, all born on
the first frame, living past the last; the default boid rules: separate, flock, goal, avoid
collision), then steps it frame by frame in order (one physics step a frame: the settings' default
subframes and timestep) and times FRAMES frames after the first (default 5). THREADS (default 0:
Blender's choice) fixes the scene's thread count. Prints one JSON line with agent-steps per second.
"""
import json
import sys
import time

import bpy


def flock(agents):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cube_add(size=10)
    emitter = bpy.context.active_object
    emitter.modifiers.new("boids", type='PARTICLE_SYSTEM')
    settings = emitter.particle_systems[0].settings
    settings.count = agents
    settings.frame_start = settings.frame_end = 1
    settings.lifetime = 100000
    settings.emit_from = 'VOLUME'
    settings.physics_type = 'BOIDS'
    return emitter


def locations(emitter):
    particles = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get()).particle_systems[0].particles
    out = [0.0] * (3 * len(particles))
    particles.foreach_get("location", out)
    return out


def main(argv):
    agents = int(argv[0]) if len(argv) > 0 else 100000
    frames = int(argv[1]) if len(argv) > 1 else 5
    threads = int(argv[2]) if len(argv) > 2 else 0
    scene = bpy.context.scene
    emitter = flock(agents)
    scene = bpy.context.scene
    if threads > 0:
        scene.render.threads_mode = 'FIXED'
        scene.render.threads = threads
    scene.frame_start, scene.frame_end = 1, frames + 2
    scene.frame_set(1)  # births every particle
    scene.frame_set(2)  # the first step: caches warmed, as bench_suite's warm-up step
    before = locations(emitter)
    t0 = time.perf_counter()
    for f in range(3, frames + 3):
        scene.frame_set(f)
    seconds = time.perf_counter() - t0
    after = locations(emitter)
    particles = emitter.evaluated_get(bpy.context.evaluated_depsgraph_get()).particle_systems[0].particles
    alive = sum(1 for p in particles if p.alive_state == 'ALIVE')
    # the boids did fly: the mean distance each particle moved over the timed frames
    moved = sum(((after[3 * i] - before[3 * i]) ** 2 + (after[3 * i + 1] - before[3 * i + 1]) ** 2 +
                 (after[3 * i + 2] - before[3 * i + 2]) ** 2) ** 0.5 for i in range(agents)) / agents
    print(json.dumps({"peer": "blender_boids", "blender": bpy.app.version_string, "agents": agents, "alive": alive,
                      "frames": frames, "threads": threads or "auto", "seconds": round(seconds, 3),
                      "mean_distance_moved": round(moved, 4),
                      "agent_steps_per_second": agents * frames / seconds}))


main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
