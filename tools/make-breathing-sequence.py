#!/usr/bin/env python3
"""Writes a breathing, nodding creature as an OBJ mesh sequence: a moving target for the tetra
morph (target_motion.sequence, docs/morph.md#a-target-that-moves) made from any closed OBJ mesh.

    tools/make-breathing-sequence.py IN.obj OUT_DIR/breath_%03d.obj [--frames 24] [--breath 0.08]
                                     [--nod 8] [--up z]

One breath in FRAMES meshes, looping (mesh FRAMES would be mesh 0 again; mesh 0 is IN.obj's shape).
In mesh k, with phase p = 2 pi k / FRAMES and h the vertex's height in [0, 1] (bottom to top along
--up, over the mesh's bounding box):

- breath: about the box centre c, x <- c + (x - c)(1 + BREATH sin(p) (0.4 + 0.6 h)): the top swells
  more than the bottom, so the shape changes, not only its size;
- nod: a rotation about the horizontal axis through c (the first axis after --up) by
  NOD sin(p) h degrees: the top bends forward and back, the bottom stays.

Only the `v` lines change; every other line (faces, groups, normals, texture coordinates) is copied
as it is, so each mesh lists the same vertices in the same order with the same triangles, which is
what flockmorph matches a sequence by. Deterministic, standard library only, 6 decimals.
"""
import argparse
import math
import os
import sys

AXES = {"x": 0, "y": 1, "z": 2}


def read_vertices(lines):
    """The positions of the `v` lines, in order."""
    return [[float(t) for t in line.split()[1:4]] for line in lines if line.startswith("v ")]


def deform(v, k, frames, breath, nod_deg, up, lo, hi):
    """Vertex v of mesh k (see the module's docstring)."""
    c = [(lo[i] + hi[i]) / 2 for i in range(3)]
    h = (v[up] - lo[up]) / (hi[up] - lo[up]) if hi[up] > lo[up] else 0.0
    p = 2 * math.pi * k / frames
    s = 1 + breath * math.sin(p) * (0.4 + 0.6 * h)
    d = [(v[i] - c[i]) * s for i in range(3)]
    axis = (up + 1) % 3  # rotate in the plane of up and the remaining axis
    other = 3 - up - axis
    a = math.radians(nod_deg * math.sin(p) * h)
    u, w = d[up], d[other]
    d[up], d[other] = u * math.cos(a) - w * math.sin(a), u * math.sin(a) + w * math.cos(a)
    return [c[i] + d[i] for i in range(3)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mesh")
    ap.add_argument("pattern", help="output file name pattern with one integer, e.g. out/breath_%%03d.obj")
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--breath", type=float, default=0.08, help="relative swell at the top (default 0.08)")
    ap.add_argument("--nod", type=float, default=8.0, help="degrees the top bends (default 8)")
    ap.add_argument("--up", choices=sorted(AXES), default="z")
    a = ap.parse_args()
    if a.frames < 1:
        sys.exit("make-breathing-sequence: --frames must be >= 1")
    with open(a.mesh) as f:
        lines = f.read().splitlines()
    verts = read_vertices(lines)
    if not verts:
        sys.exit(f"make-breathing-sequence: {a.mesh} has no vertices")
    lo = [min(v[i] for v in verts) for i in range(3)]
    hi = [max(v[i] for v in verts) for i in range(3)]
    up = AXES[a.up]
    os.makedirs(os.path.dirname(a.pattern % 0) or ".", exist_ok=True)
    for k in range(a.frames):
        out, i = [f"# flockmorph breathing sequence, mesh {k} of {a.frames}: tools/make-breathing-sequence.py "
                  f"{os.path.basename(a.mesh)} --breath {a.breath} --nod {a.nod} --up {a.up}"], 0
        for line in lines:
            if line.startswith("v "):
                x = deform(verts[i], k, a.frames, a.breath, a.nod, up, lo, hi) if k else verts[i]
                out.append("v %.6f %.6f %.6f" % tuple(x))
                i += 1
            else:
                out.append(line)
        with open(a.pattern % k, "w") as f:
            f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
