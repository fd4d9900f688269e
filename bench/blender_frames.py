"""Times the Blender add-on on one cache: the import, a frame change in order and at random, and the
add-on's handler alone (reading the cache and writing the mesh, without Blender's evaluation).

    blender -b --factory-startup --python bench/blender_frames.py -- CACHE [AUTO|MESH|POINTS] [ADDON_ZIP]

ADDON_ZIP (default build/flockmorph_import.zip) is installed into BLENDER_USER_SCRIPTS if set,
else into Blender's user scripts folder. Prints one JSON line; docs/blender.md keeps the figures.
"""
import json
import random
import resource
import sys
import time

import addon_utils
import bpy


def per_frame_ms(frames, action):
    t0 = time.perf_counter()
    for f in frames:
        action(f)
    return round((time.perf_counter() - t0) / len(frames) * 1000, 1)


def main(argv):
    cache = argv[0]
    mode = argv[1] if len(argv) > 1 else "AUTO"
    bpy.ops.preferences.addon_install(filepath=argv[2] if len(argv) > 2 else "build/flockmorph_import.zip",
                                      overwrite=True)
    addon_utils.enable("flockmorph_import", default_set=True)
    from flockmorph_import import importer

    t0 = time.perf_counter()
    bpy.ops.import_scene.flockmorph(filepath=cache, mode=mode)
    import_ms = round((time.perf_counter() - t0) * 1000)
    scene, mesh = bpy.context.scene, bpy.context.active_object.data
    frames = list(range(scene.frame_start, scene.frame_end + 1))
    shuffled = random.Random(1).sample(frames, len(frames))
    print(json.dumps({
        "cache": cache, "mode": mesh[importer.SETTINGS]["mode"], "vertices": len(mesh.vertices),
        "frames": len(frames), "import_ms": import_ms,
        "frame_change_in_order_ms": per_frame_ms(frames, scene.frame_set),
        "frame_change_random_ms": per_frame_ms(shuffled, scene.frame_set),
        "handler_in_order_ms": per_frame_ms(frames, lambda f: importer.load_frame(mesh, f)),
        "max_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
    }))


main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
