#!/usr/bin/env python3
"""The radius-edge distribution of a tetra morph's tets in one frame of its cache (issue 38).

    tools/tet-quality.py CACHE.fmc [--frame K] [--json] [--check] [--max-share 0.05]
                         [--bound 2.0] [--hard 4.0]

The radius-edge ratio of a tet is its circumradius over its shortest edge (what TetGen's -q
bounds; a regular tet has 0.612). It is computed here from the cache's float vertices alone, in
float64, by a formula the engine does not use: 24 V R = sqrt((x+y+z)(x+y-z)(x-y+z)(-x+y+z)) with
x, y, z the products of the three pairs of opposite edge lengths and V from the triple product.

--frame K picks the frame (default -1, the last: the formed target when every tet arrived; 0 is
the source tets). Printed (and with --json as one object): the tet count, the shares of tets above
--bound and above --hard, the median, the 95th percentile and the max. With --check the exit
status is 1 unless at most --max-share of the tets exceed --bound and none exceeds --hard
(issue 38's target: 5 % above 2.0 and none above 4.0).

Reads the cache with python/flockmorph_cache.py, not the engine's statistics. Needs numpy
(Debian's python3-numpy: run it with /usr/bin/python3).
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
import flockmorph_cache  # noqa: E402


def radius_edge(tets):
    """Radius-edge ratios of tets (agents, 4, 3); a flat tet gives inf."""
    p = tets.astype(np.float64)

    def length(a, b):
        return np.linalg.norm(p[:, a] - p[:, b], axis=1)

    e = {(a, b): length(a, b) for a in range(4) for b in range(a + 1, 4)}
    x, y, z = e[0, 1] * e[2, 3], e[0, 2] * e[1, 3], e[0, 3] * e[1, 2]
    u, v, w = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    volume = np.abs(np.einsum("ij,ij->i", u, np.cross(v, w))) / 6.0
    heron = np.clip((x + y + z) * (x + y - z) * (x - y + z) * (-x + y + z), 0.0, None)
    shortest = np.min(np.stack(list(e.values())), axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sqrt(heron) / (24.0 * volume)
        ratio = r / shortest
    return np.where(np.isfinite(ratio), ratio, np.inf)


def measure(path, frame, bound, hard):
    with flockmorph_cache.open(path) as cache:
        frames = len(cache)
        k = frame if frame >= 0 else frames + frame
        if not 0 <= k < frames:
            raise SystemExit(f"tet-quality: {path} has {frames} frames, no frame {frame}")
        ratio = radius_edge(cache.read(k, "tet_vertices").reshape(-1, 4, 3))
    n = len(ratio)
    return {
        "cache": path, "frame": k, "frames": frames, "tets": n,
        "bound": bound, "hard": hard,
        "share_above_bound": float(np.count_nonzero(ratio > bound) / n) if n else 0.0,
        "share_above_hard": float(np.count_nonzero(ratio > hard) / n) if n else 0.0,
        "above_hard": int(np.count_nonzero(ratio > hard)),
        "median": float(np.median(ratio)) if n else float("nan"),
        "p95": float(np.percentile(ratio, 95)) if n else float("nan"),
        "max": float(ratio.max()) if n else float("nan"),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cache")
    ap.add_argument("--frame", type=int, default=-1, help="frame index; negative counts from the end (default -1)")
    ap.add_argument("--bound", type=float, default=2.0, help="the radius-edge bound (default 2.0)")
    ap.add_argument("--hard", type=float, default=4.0, help="no tet above this with --check (default 4.0)")
    ap.add_argument("--max-share", type=float, default=0.05,
                    help="with --check, the largest share of tets above --bound (default 0.05)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args()
    m = measure(args.cache, args.frame, args.bound, args.hard)
    if args.json:
        print(json.dumps(m, indent=2))
    else:
        print(f"{m['cache']} frame {m['frame']} of {m['frames']}: {m['tets']} tets")
        print(f"  radius-edge above {m['bound']:g}: {100 * m['share_above_bound']:.2f} %")
        print(f"  radius-edge above {m['hard']:g}: {100 * m['share_above_hard']:.3f} % ({m['above_hard']} tets)")
        print(f"  median {m['median']:.3f}, p95 {m['p95']:.3f}, max {m['max']:.3f}")
    if args.check:
        ok = m["share_above_bound"] <= args.max_share and m["above_hard"] == 0
        if not ok:
            print(f"tet-quality: FAIL: {100 * m['share_above_bound']:.2f} % above {m['bound']:g} (at most "
                  f"{100 * args.max_share:g} % allowed), {m['above_hard']} above {m['hard']:g} (none allowed)",
                  file=sys.stderr)
        return 0 if ok else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
