#!/usr/bin/env python3
"""FM eq 3 carries the source's silhouette along the path: the ribbons of issue 14.

V_g = speed0 * f_i (eq 3) is one vector for every agent nearest key point Q_i, so with no style
field, path width or MDE the flock translates along the path and keeps each tet's offset from it:
the cross-section in flight is the source seen along the path's first direction f_0. A source whose
silhouette has a gap (two boxes side by side, the letters of examples/words) flies as parallel
ribbons with that gap; a solid one flies as one stream. The key points' spacing does not make the
ribbons: the count and the gap are the same for m = 4, 32 and 256. examples/words flies as the
letters of "casa" seen along f_0 (docs/scenarios.md, "Ribbons in flight").

Measured by tools/analyse-ribbons.py on mid-flight frames (phase 1, middle 60 % of the path):

    test_path_ribbons.py --cli build/flockmorph --tmp DIR --source REPO
"""
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import morph_test_args  # noqa: E402

ARGS = None
HALF = 0.5  # the boxes' half size
GAP = 1.5  # between the two source boxes, along y: normal to the path's plane (xz)


def box(cx, cy, cz, hx, hy, hz, base):
    """An outward-wound box as OBJ lines, its vertices numbered from base + 1."""
    v = [f"v {cx + sx * hx} {cy + sy * hy} {cz + sz * hz}" for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = [f"f {base + a + 1} {base + b + 1} {base + c + 1}\nf {base + a + 1} {base + c + 1} {base + d + 1}"
         for a, b, c, d in quads]
    return v + f


def write_mesh(name, boxes):
    lines = []
    for i, b in enumerate(boxes):
        lines += box(*b, base=8 * i)
    with open(os.path.join(ARGS.tmp, name), "w") as f:
        f.write("\n".join(lines) + "\n")


def run(name, source, key_points):
    """Runs source -> one box along a curved path; the analysis of its mid-flight frames."""
    off = HALF + GAP / 2
    write_mesh("ribbons_two.obj", [(0, -off, 0, HALF, HALF, HALF), (0, off, 0, HALF, HALF, HALF)])
    write_mesh("ribbons_solid.obj", [(0, 0, 0, HALF, off + HALF, HALF)])
    write_mesh("ribbons_target.obj", [(0, 0, 0, HALF, HALF, 2 * HALF)])
    scene = {"source": {"mesh": source, "translate": [-10, 0, 0]},
             "target": {"mesh": "ribbons_target.obj", "translate": [10, 0, 0]},
             "n": 3000, "speed0": 10, "launch_rate": 3000,
             "path": {"points": [[0, 0, 6]], "key_points": key_points, "curve": "catmull_rom"}}
    path = os.path.join(ARGS.tmp, f"ribbons_{name}.json")
    with open(path, "w") as f:
        json.dump(scene, f)
    out = os.path.join(ARGS.tmp, f"ribbons_{name}")
    subprocess.run([ARGS.cli, "run", path, "-o", out, "--quiet", "--threads", "2"], check=True,
                   stdout=subprocess.DEVNULL)
    return analyse(name, out)


def analyse(name, out):
    done = subprocess.run([sys.executable, os.path.join(ARGS.source, "tools", "analyse-ribbons.py"), out, "--json"],
                          check=True, stdout=subprocess.PIPE, text=True)
    frames = [fr for fr in json.loads(done.stdout)["frames"] if "clusters" in fr]
    if len(frames) < 3:
        raise AssertionError(f"{name}: only {len(frames)} mid-flight frames to measure")
    return frames


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    return cond


def main():
    global ARGS
    ARGS = morph_test_args.parse_args()
    ok = True
    for m in (4, 32, 256):
        frames = run(f"two_m{m}", "ribbons_two.obj", m)
        counts = [fr["cluster_count"] for fr in frames]
        gaps = [fr["clusters"][0]["gap_after"] for fr in frames if fr["cluster_count"] == 2]
        corr = min(fr["rest_correlation"] for fr in frames)
        ok &= check(counts == [2] * len(counts), f"two boxes, m = {m}: two ribbons in every mid-flight frame {counts}")
        ok &= check(all(abs(g - GAP) < 0.1 * GAP for g in gaps),
                    f"two boxes, m = {m}: the gap in flight is the rest gap {GAP} within 10 % "
                    f"({min(gaps, default=0):.3f} .. {max(gaps, default=0):.3f})")
        ok &= check(corr > 0.99, f"two boxes, m = {m}: offsets in flight track those at rest (correlation {corr:.4f})")
    frames = run("solid", "ribbons_solid.obj", 32)
    counts = [fr["cluster_count"] for fr in frames]
    worst = max(fr["largest_gap_over_width"] for fr in frames)
    ok &= check(counts == [1] * len(counts) and worst < 0.05,
                f"one solid box of the same extent: one stream {counts}, largest gap / width {worst:.3f}")
    out = os.path.join(ARGS.tmp, "ribbons_words")
    subprocess.run([ARGS.cli, "run", os.path.join(ARGS.source, "examples", "words", "scene.json"), "-o", out,
                    "--quiet", "--threads", "2"], check=True, stdout=subprocess.DEVNULL)
    frames = analyse("words", out)
    counts = [fr["cluster_count"] for fr in frames]
    rest = [fr["rest_cluster_count"] for fr in frames]
    corr = min(fr["rest_correlation"] for fr in frames)
    ok &= check(max(counts) >= 2 and all(abs(a - b) <= 1 for a, b in zip(counts, rest)) and corr > 0.99,
                f"examples/words: the ribbons {counts} are the letters' silhouette at rest {rest} "
                f"(correlation {corr:.4f})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
