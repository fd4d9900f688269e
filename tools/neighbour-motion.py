#!/usr/bin/env python3
"""How far a shape flock's neighbours move against each other from frame to frame (issue 40): the
figure that decides whether a Verlet neighbour list, built with a skin and reused for several
steps as LAMMPS and GROMACS reuse theirs, can pay.

    tools/neighbour-motion.py CACHE.fmc RADIUS [--json]

For each pair of consecutive frames, the pairs of agents closer than RADIUS at the first frame
(found within cells of edge RADIUS: pairs across a cell face are left out, which changes no
percentile much) and the length of the difference of their displacements, |dx_i - dx_j|, over
RADIUS. A list built with skin s stays exact while every pair's relative displacement since the
build is below s; so a median of 0.4 says half the pairs use up a skin of 0.4 RADIUS in one
frame. Printed per frame: the mean displacement, the pairs, and the relative displacement's
median, p90, p99 and max in units of RADIUS (with --json one object per line).

RADIUS: the flock's largest perception radius, stats.json's "max_perception_radius".
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


def relative_motion(x0, x1, radius, offsets=5):
    """|dx_i - dx_j| / radius over pairs within radius that share a cell (up to `offsets` apart
    in the cell-sorted order)."""
    dx = x1 - x0
    key = np.floor(x0 / radius).astype(np.int64)
    cell = (key[:, 0] * 73856093) ^ (key[:, 1] * 19349663) ^ (key[:, 2] * 83492791)
    order = np.argsort(cell, kind="stable")
    cell, xs, ds = cell[order], x0[order], dx[order]
    out = []
    for s in range(1, offsets + 1):
        near = (cell[s:] == cell[:-s]) & (np.linalg.norm(xs[s:] - xs[:-s], axis=1) < radius)
        out.append(np.linalg.norm(ds[s:][near] - ds[:-s][near], axis=1) / radius)
    return np.linalg.norm(dx, axis=1).mean(), np.concatenate(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cache")
    ap.add_argument("radius", type=float)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if not args.radius > 0:
        sys.exit("neighbour-motion: RADIUS must be > 0")
    try:
        report(args)
    except BrokenPipeError:  # the reader stopped early (| head)
        sys.stderr.close()
    except (OSError, ValueError, KeyError) as e:  # the reader's messages name the file
        sys.exit(f"neighbour-motion: {e}")


def report(args):
    with flockmorph_cache.open(args.cache) as cache:
        previous = None
        for index in range(len(cache)):
            x = cache.read(index, "position").astype(np.float64)
            if previous is not None:
                mean, rel = relative_motion(previous, x, args.radius)
                q = np.percentile(rel, [50, 90, 99, 100]) if rel.size else [float("nan")] * 4
                row = {"frame": index, "mean_displacement": mean, "pairs": int(rel.size),
                       "median": q[0], "p90": q[1], "p99": q[2], "max": q[3]}
                if args.json:
                    print(json.dumps(row))
                else:
                    print("frame %3d: displacement %.4f, %8d pairs, relative/radius median %.3f p90 %.3f p99 %.3f max %.3f"
                          % (index, mean, rel.size, q[0], q[1], q[2], q[3]))
            previous = x


if __name__ == "__main__":
    main()
