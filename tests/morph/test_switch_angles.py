#!/usr/bin/env python3
"""The phase switch without a kink (issue 38), measured from the cache by tools/switch-angles.py.

examples/words with the default phase2.blend_time: for 95 % of the tets the heading changes by at
most 30 degrees and the speed by at most x1.25 across the switch to phase 2 (centroid velocities
one frame before and one frame after it), and the last frame is still the target's
tetrahedralization (stats.json final_max_vertex_error), with no inverted tet, at the same frame
count as the paper's hard switch. With phase2.blend_time 0 (the hard switch) the same check fails:
the kink is there and the measure sees it.

    test_switch_angles.py --cli build/flockmorph --tmp DIR --source REPO
"""
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import morph_test_args  # noqa: E402

ARGS = None


def run(name, *sets):
    out = os.path.join(ARGS.tmp, f"switch_{name}")
    cmd = [ARGS.cli, "run", os.path.join(ARGS.source, "examples", "words", "scene.json"), "-o", out, "--quiet",
           "--threads", "2"]
    for s in sets:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(out, "stats.json")) as f:
        stats = json.load(f)
    script = os.path.join(ARGS.source, "tools", "switch-angles.py")
    r = subprocess.run([sys.executable, script, os.path.join(out, "frames.fmc"), "--check"], text=True,
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    print(f"{name}:\n{r.stdout}", end="")
    return r.returncode, stats


def main():
    global ARGS
    ARGS = morph_test_args.parse_args()
    failures = []
    rc, blended = run("blend")
    if rc != 0:
        failures.append("with the default blend, the switch is not within 30 deg and x1.25 for 95 % of the tets")
    if blended["final_max_vertex_error"] > 2e-6:
        failures.append(f"the last frame is {blended['final_max_vertex_error']} from the target")
    if blended["inverted_tet_frames"] != 0 or not blended["target_tets_filled_once"]:
        failures.append("a tet inverted, or a target tet was not filled once")
    rc_hard, hard = run("hard", "phase2.blend_time=0")
    if rc_hard == 0:
        failures.append("the hard switch (blend_time 0) passes the check: the measure does not see the kink")
    if blended["frames"] != hard["frames"]:
        failures.append(f"the blend changed when the flock arrives: {blended['frames']} frames, "
                        f"hard switch {hard['frames']}")
    return morph_test_args.finish(failures)


if __name__ == "__main__":
    sys.exit(main())
