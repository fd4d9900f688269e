#!/usr/bin/env python3
"""The shape flock's path routed round the obstacles (issue 38, obstacles.route), measured from the cache.

Two scenes of tests/flock/route: examples/flock_cylinder_sphere's cylinder to sphere with no path
points, so R is the straight line O1 -> O2, and half way on it
  wall.json: a wall (tests/morph/detour/slab_x.obj, doubled: 0.8 x 12.8 x 12.8) square to R, wider
             than the flock: its push alone leaves agents pressed against it for good;
  ball.json: a ball of radius 4 (the target's sphere, scaled 0.8), which the push alone lets agents into.
Each runs with obstacles.route false (printed, not required) and as it is, routed, where:
- every agent is bound (phase 3, "arrived" in test_detour's words) in the cache's last frame, before time.frame_limit;
- no agent position is inside the wall in any frame, by tests/morph/test_detour.py's inside test
  (ray parity along the three axes, its own numpy, sharing nothing with the engine; a position counts
  when deeper than its DEPTH_TOL);
- 1 and 2 threads write the same bytes (the wall).

    test_flock_route.py --cli FLOCKMORPH --tmp DIR --source REPO
"""
import hashlib
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "morph"))
import morph_test_args  # noqa: E402  (--cli, --tmp made, --source)
import test_detour  # noqa: E402  (obstacles_of, check_cache: its inside test)


def run(args, scene, name, threads, *sets):
    out = os.path.join(args.tmp, f"flock_route_{name}_{threads}")
    cmd = [args.cli, "run", scene, "-o", out, "--quiet", "--threads", str(threads)]
    for s in sets:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return os.path.join(out, "frames.fmc")


def main():
    args = morph_test_args.parse_args()
    test_detour.ARGS = args
    failures = []
    if test_detour.check_inside_test():
        failures.append("the inside test is wrong on a cube")
    for scene_name in ("wall", "ball"):
        scene = os.path.join(args.source, "tests", "flock", "route", scene_name + ".json")
        d, meshes = test_detour.obstacles_of(scene)
        limit = d["time"]["frame_limit"]
        for routed, sets in ((False, ("obstacles.route=false",)), (True, ())):
            name = f"{scene_name}_{'routed' if routed else 'unrouted'}"
            cache = run(args, scene, name, 2, *sets)
            fails = test_detour.check_cache(name, cache, limit, meshes, "position", "agents", "position")
            if not routed:
                continue
            failures += fails
            if scene_name == "wall":
                one = run(args, scene, name, 1, *sets)
                digest = [hashlib.sha256(open(x, "rb").read()).hexdigest() for x in (cache, one)]
                if digest[0] != digest[1]:
                    failures.append(f"{name}: the caches of 1 and 2 threads differ")
    return morph_test_args.finish(failures)


if __name__ == "__main__":
    sys.exit(main())
