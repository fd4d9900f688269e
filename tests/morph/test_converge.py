#!/usr/bin/env python3
"""Convergence at strong style fields (issue 38), measured from the cache.

examples/creatures at FM Table I's curl-noise gain (30 in our units; the example ships 12) with the
fade at its defaults (style.fade_distance, style.fade_time): the cache's last frame has every tet
arrived (phase 3), before time.frame_limit (3000). With both fades off (-1, FM eq 6 as written) the
same run leaves tets circling in an eddy at the frame limit, and the run names them: the warning on
stderr and stats.json's "stragglers" give their count and the first ids, which are the smallest ids
the cache's last frame has not arrived, with their distance outside the switch sphere.

    test_converge.py --cli build/flockmorph --tmp DIR --source REPO
"""
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import morph_test_args  # noqa: E402

ARGS = None
LIMIT = 3000


def run(name, *sets):
    out = os.path.join(ARGS.tmp, f"converge_{name}")
    cmd = [ARGS.cli, "run", os.path.join(ARGS.source, "examples", "creatures", "scene.json"), "-o", out, "--quiet",
           "--threads", "2", "--set", "style.fields.0.gain=30", "--set", f"time.frame_limit={LIMIT}"]
    for s in sets:
        cmd += ["--set", s]
    r = subprocess.run(cmd, check=True, text=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    with open(os.path.join(out, "stats.json")) as f:
        stats = json.load(f)
    return os.path.join(out, "frames.fmc"), stats, r.stderr


def last_frame(path):
    sys.path.insert(0, os.path.join(ARGS.source, "python"))
    import numpy as np
    import flockmorph_cache
    with flockmorph_cache.Cache(path) as c:
        f = c[len(c) - 1]
        phase = np.asarray(f["phase"]).ravel()
        ids = np.asarray(f["id"]).ravel() if "id" in f else np.arange(phase.size)
        return len(c), phase, ids


def main():
    global ARGS
    ARGS = morph_test_args.parse_args()
    failures = []

    cache, stats, _ = run("faded")
    frames, phase, _ = last_frame(cache)
    left = int((phase != 3).sum())
    print(f"gain 30, fade at its defaults: {frames} frames, {left} of {phase.size} tets not arrived")
    if left or frames >= LIMIT:
        failures.append(f"gain 30: {left} tets not arrived after {frames} frames (limit {LIMIT})")
    if not stats["all_arrived"] or stats.get("stragglers") is not None:
        failures.append("gain 30: stats.json does not say all arrived")

    cache, stats, err = run("unfaded", "style.fade_distance=-1", "style.fade_time=-1")
    frames, phase, ids = last_frame(cache)
    left = sorted(int(i) for i in ids[phase != 3])
    print(f"gain 30, no fade: {frames} frames, {len(left)} tets not arrived")
    st = stats.get("stragglers") or {}
    if not left or frames != LIMIT:
        failures.append("gain 30 without the fade arrives: this test no longer sees the eddies")
    elif st.get("count") != len(left) or [e["id"] for e in st.get("first", [])] != left[:8]:
        failures.append(f"stats.json stragglers {st} are not the cache's {len(left)} ({left[:8]} ...)")
    msg = f"warning: stopped at the frame limit ({LIMIT} frames) with {len(left)} agents not yet arrived ("
    if msg not in err or "first by id: %d flying " % (left[0] if left else -1) not in err:
        failures.append(f"the warning does not name the stragglers: {err.strip()}")
    return morph_test_args.finish(failures)


if __name__ == "__main__":
    sys.exit(main())
