#!/usr/bin/env python3
"""Out of memory is exit 4 (issue 42; docs/errors.md, "Out of memory").

The CLI runs under several address-space limits (bash -c 'ulimit -v N; ...'): a tiny run, then a
render of its cache (Embree's device) and an inspect. At every level each command must exit 0 or 4,
and an exit 4 must say what it could not have; never a signal, nor 1 (libgomp's "Thread creation
failed"), 2 (assimp's "cannot read the mesh (std::bad_alloc)"), 5 (the writer thread, zstd, Embree)
or 127. Below some level the program cannot even be loaded (the dynamic loader's exit 127, or
log4cplus, which OpenVDB links, aborting in its initializer before main): that floor is found first
(the lowest limit at which `flockmorph --version` runs our code) and the levels start there, so
that the test does not depend on the libraries' sizes.

    test_memory_limits.py --cli build/flockmorph --tmp DIR
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "helpers"))
from octahedron import octahedron_obj  # noqa: E402

MB = 1024  # ulimit -v counts KiB


def limited(cli, kib, args, timeout=60):
    """`cli args` under ulimit -v kib: (exit status, stderr); a signal gives 128 + its number, as a shell."""
    command = "ulimit -v %d; exec \"$0\" \"$@\"" % kib
    done = subprocess.run(["bash", "-c", command, cli, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True, timeout=timeout)
    return (128 - done.returncode if done.returncode < 0 else done.returncode), done.stderr


def load_floor(cli):
    """The lowest limit (to 4 MiB) at which the program runs its own code: --version exits 0, or 4
    when its threads do not fit."""
    lo, hi = 16 * MB, 2048 * MB
    if limited(cli, hi, ["--version"])[0] not in (0, 4):
        sys.exit("flockmorph --version fails under 2 GiB")
    while hi - lo > 4 * MB:
        mid = (lo + hi) // 2
        if limited(cli, mid, ["--version"])[0] in (0, 4):
            hi = mid
        else:
            lo = mid
    return hi


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--cli", required=True)
    p.add_argument("--tmp", required=True)
    a = p.parse_args()
    folder = os.path.join(a.tmp, "memory_limits")
    shutil.rmtree(folder, ignore_errors=True)
    os.makedirs(folder)
    with open(os.path.join(folder, "octahedron.obj"), "w") as f:
        f.write(octahedron_obj())
    scene = os.path.join(folder, "scene.json")
    with open(scene, "w") as f:
        json.dump({"source": {"mesh": "octahedron.obj", "translate": [-10, 0, 0]},
                   "target": {"mesh": "octahedron.obj", "translate": [10, 0, 0]}, "time": {"frame_limit": 20}}, f)
    floor = load_floor(a.cli)
    print(f"the program loads from ulimit -v {floor // MB} MiB")
    failures, outcomes = [], {0: 0, 4: 0}
    for extra in (0, 8, 16, 32, 48, 96):
        kib = floor + extra * MB
        out = os.path.join(folder, f"out_{extra}")
        cache = os.path.join(out, "frames.fmc")
        commands = [["run", scene, "-o", out, "--quiet"],
                    ["render", cache, "-o", os.path.join(folder, f"f{extra}.png"), "--size", "32x32"], ["inspect", cache]]
        for args in commands:
            if args[0] != "run" and not os.path.exists(args[1]):
                continue  # the run was out of memory: nothing to read
            rc, err = limited(a.cli, kib, args)
            line = f"ulimit -v {kib // MB} MiB: {args[0]}: exit {rc}"
            print(line + (": " + (err.strip().splitlines() or ["(no message)"])[-1] if rc else ""))
            if rc not in (0, 4):
                failures.append(f"{line}, expected 0 or 4:\n{err}")
            elif rc == 4 and not ("flockmorph: error:" in err and ("memory" in err or "cannot start" in err)):
                failures.append(f"{line} without a message saying what could not be had:\n{err}")
            else:
                outcomes[rc] += 1
    if outcomes[0] == 0 or outcomes[4] == 0:
        failures.append(f"the levels did not span both outcomes ({outcomes}): the test shows nothing")
    for f in failures:
        print("FAIL:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
