#!/usr/bin/env python3
"""Avoidance that cannot deadlock (issue 38), measured from the caches.

Three scenes whose straight path runs into an obstacle:
  rook:  examples/castling/rook.json with path.points=[] (the rook flies straight at the king);
  wall:  tests/morph/detour/wall.json, a moon to a star with a wall square to the flight spanning it;
  cup:   tests/morph/detour/cup.json, suzanne to a torus with a cup (five slabs) open toward the flock
         on the straight path: a scene the detour was not tuned on.
Each as it is (the path routed round the obstacle, obstacles.route), and the rook and the wall also
with the path left straight through it (obstacles.route false), where only the detours of stalled
tets (obstacles.detour_time) get them past. For each: every tet has arrived (phase 3) in the cache's last frame, before time.frame_limit, and no tet
vertex is inside an obstacle in any frame. The inside test shares nothing with the engine: the scene's
obstacle meshes read and placed here, ray parity along the three axes (a majority of two), on the
triangles binned by their shadow on the plane across the ray; a vertex counts when it is deeper than
DEPTH_TOL (a tet in contact has a vertex on the surface, where float rounding decides the side). The
wall also runs with 1 and 2 threads: the two caches are byte for byte the same.

    test_detour.py --cli build/flockmorph --tmp DIR --source REPO
"""
import hashlib
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import morph_test_args  # noqa: E402

ARGS = None
DEPTH_TOL = 1e-5
BINS = 48
BATCH = 32  # frames tested together


def run(name, scene, threads=2, *sets):
    out = os.path.join(ARGS.tmp, f"detour_{name}_{threads}")
    cmd = [ARGS.cli, "run", scene, "-o", out, "--quiet", "--threads", str(threads)]
    for s in sets:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(out, "stats.json")) as f:
        stats = json.load(f)
    return os.path.join(out, "frames.fmc"), stats


def load_obj(path):
    import numpy as np
    v, t = [], []
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                v.append([float(x) for x in w[1:4]])
            elif w[0] == "f":
                idx = [int(x.split("/")[0]) for x in w[1:]]
                idx = [i - 1 if i > 0 else len(v) + i for i in idx]
                t += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
    return np.array(v, float), np.array(t, int)


def obstacles_of(scene):
    """The scene's obstacle meshes, placed: scale, then translate (no scene here rotates one)."""
    import numpy as np
    with open(scene) as f:
        d = json.load(f)
    meshes = []
    for o in d["obstacles"]["meshes"]:
        if any(o.get("rotate_deg", [0, 0, 0])):
            raise SystemExit("test_detour: rotated obstacles are not placed here")
        v, t = load_obj(os.path.join(os.path.dirname(scene), o["mesh"]))
        v = v * o.get("scale", 1.0) + np.array(o.get("translate", [0, 0, 0]), float)
        meshes.append((v, t))
    return d, meshes


class Inside:
    """Ray parity for one closed triangle mesh."""

    def __init__(self, v, t):
        import numpy as np
        self.v, self.t = v, t
        self.a, self.b, self.c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        self.lo, self.hi = v.min(0), v.max(0)
        self.bins = []
        for axis in range(3):
            u, w = [k for k in range(3) if k != axis]
            tri_lo = np.minimum(np.minimum(self.a, self.b), self.c)[:, [u, w]]
            tri_hi = np.maximum(np.maximum(self.a, self.b), self.c)[:, [u, w]]
            lo, hi = self.lo[[u, w]], self.hi[[u, w]]
            size = (hi - lo) / BINS
            c0 = np.clip(((tri_lo - lo) / size).astype(int), 0, BINS - 1)
            c1 = np.clip(((tri_hi - lo) / size).astype(int), 0, BINS - 1)
            cells = [[] for _ in range(BINS * BINS)]
            for i in range(len(t)):
                for x in range(c0[i, 0], c1[i, 0] + 1):
                    for y in range(c0[i, 1], c1[i, 1] + 1):
                        cells[x * BINS + y].append(i)
            self.bins.append((u, w, lo, size, [np.array(c, int) for c in cells]))

    def crossings(self, p, axis):
        """Odd where the ray from p along +axis crosses the mesh an odd number of times."""
        import numpy as np
        u, w, lo, size, cells = self.bins[axis]
        cu = np.clip(((p[:, u] - lo[0]) / size[0]).astype(int), 0, BINS - 1)
        cw = np.clip(((p[:, w] - lo[1]) / size[1]).astype(int), 0, BINS - 1)
        cell = cu * BINS + cw
        odd = np.zeros(len(p), bool)
        order = np.argsort(cell, kind="stable")
        bounds = np.searchsorted(cell[order], np.arange(BINS * BINS + 1))
        for k in np.nonzero(np.diff(bounds))[0]:  # the cells that hold points
            tris = cells[k]
            if len(tris) == 0:
                continue
            at_cell = order[bounds[k]:bounds[k + 1]]
            q = p[at_cell]
            a, b, c = self.a[tris], self.b[tris], self.c[tris]
            pu, pw = q[:, u][:, None], q[:, w][:, None]

            def edge(x, y):  # which side of edge x->y the point lies, in the (u, w) plane
                return (y[:, u] - x[:, u]) * (pw - x[:, w]) - (y[:, w] - x[:, w]) * (pu - x[:, u])
            e0, e1, e2 = edge(a, b), edge(b, c), edge(c, a)
            hit = ((e0 > 0) & (e1 > 0) & (e2 > 0)) | ((e0 < 0) & (e1 < 0) & (e2 < 0))
            n = np.cross(b - a, c - a)  # where along the ray: the triangle's plane at (pu, pw)
            with np.errstate(divide="ignore", invalid="ignore"):
                at = a[:, axis] - (n[:, u] * (pu - a[:, u]) + n[:, w] * (pw - a[:, w])) / n[:, axis]
            hit &= at > q[:, axis][:, None]
            odd[at_cell] = (hit.sum(1) & 1).astype(bool)
        return odd

    def inside(self, p):
        import numpy as np
        out = np.zeros(len(p), bool)
        near = np.all((p >= self.lo) & (p <= self.hi), axis=1)
        if near.any():
            q = p[near]
            votes = sum(self.crossings(q, axis).astype(int) for axis in range(3))
            out[np.nonzero(near)[0]] = votes >= 2
        return out

    def depth(self, p):
        """Distance from each p to the mesh's surface (exact, point to triangle)."""
        import numpy as np
        best = np.full(len(p), np.inf)
        for i in range(len(p)):
            best[i] = np.sqrt(point_triangle_d2(p[i], self.a, self.b, self.c).min())
        return best


def point_triangle_d2(p, a, b, c):
    """Squared distance from the point p to each triangle (a, b, c): to the plane where p projects
    inside, else to the nearest of the three edges."""
    import numpy as np
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    s = np.einsum("ij,ij->i", p - a, n) / nn
    q = p - s[:, None] * n
    inside = ((np.einsum("ij,ij->i", np.cross(b - a, q - a), n) >= 0) & (np.einsum("ij,ij->i", np.cross(c - b, q - b), n) >= 0)
              & (np.einsum("ij,ij->i", np.cross(a - c, q - c), n) >= 0))
    plane = s * s * nn

    def seg(x, y):
        e = y - x
        t = np.clip(np.einsum("ij,ij->i", p - x, e) / np.einsum("ij,ij->i", e, e), 0, 1)
        d = p - (x + t[:, None] * e)
        return np.einsum("ij,ij->i", d, d)
    return np.where(inside, plane, np.minimum(np.minimum(seg(a, b), seg(b, c)), seg(c, a)))


def check_inside_test():
    """The inside test itself, on a unit cube of 12 triangles: right near every face, or the scenes'
    zero proves nothing."""
    import numpy as np
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    t = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                  [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    rng = np.random.default_rng(7)
    p = rng.uniform(-0.2, 1.2, (20000, 3))
    truth = np.all((p > 0) & (p < 1), axis=1)
    got = Inside(v, t).inside(p)
    depth = Inside(v, t).depth(p[truth][:50])
    want = np.minimum(p[truth][:50], 1 - p[truth][:50]).min(1)
    return int((got != truth).sum()) + int((np.abs(depth - want) > 1e-12).sum())


def check_cache(name, cache, frame_limit, meshes, attr="tet_vertices", agents="tets", points="vertex"):
    """Every agent arrived (phase 3: a tet arrived, a shape-flock agent bound) in the last frame, before
    frame_limit, and no point of `attr` inside a mesh in any frame: the failures, as lines."""
    import numpy as np
    sys.path.insert(0, os.path.join(ARGS.source, "python"))
    import flockmorph_cache
    tests = [Inside(v, t) for v, t in meshes]
    bad_frames, bad_vertices, deepest = [], 0, 0.0
    with flockmorph_cache.Cache(cache) as c:
        frames = len(c)
        for first in range(0, frames, BATCH):  # frames in batches: one pass of the cells for each
            last = min(first + BATCH, frames)
            p = np.asarray(c.read_range(attr, first, last), float)
            per_frame = p[0].size // 3
            p = p.reshape(-1, 3)
            for m in tests:
                inside = np.nonzero(m.inside(p))[0]
                if len(inside) == 0:
                    continue
                d = m.depth(p[inside])
                deep = inside[d > DEPTH_TOL]
                if len(deep):
                    bad_frames.append(first + int(deep[0]) // per_frame)
                    bad_vertices += len(deep)
                    deepest = max(deepest, float(d.max()))
        phase = np.asarray(c.read(frames - 1, "phase")).ravel()
    left = int((phase != 3).sum())
    print(f"{name}: {frames} frames (limit {frame_limit}), {left} of {phase.size} {agents} not arrived, "
          f"{bad_vertices} {points}-frames inside an obstacle (deepest {deepest:.3g})")
    fails = []
    if left or frames >= frame_limit:
        fails.append(f"{name}: {left} {agents} not arrived after {frames} frames (limit {frame_limit})")
    if bad_vertices:
        fails.append(f"{name}: {bad_vertices} {points}-frames inside an obstacle, from frame {bad_frames[0]}, up to {deepest:.3g} deep")
    return fails


def main():
    global ARGS
    ARGS = morph_test_args.parse_args()
    failures = []
    wrong = check_inside_test()
    if wrong:
        failures.append(f"the inside test is wrong on {wrong} points of a cube")
    rook = os.path.join(ARGS.source, "examples", "castling", "rook.json")
    wall = os.path.join(ARGS.source, "tests", "morph", "detour", "wall.json")
    scenes = [("rook", rook, ("path.points=[]",)),
              ("wall", wall, ()),
              ("cup", os.path.join(ARGS.source, "tests", "morph", "detour", "cup.json"), ()),
              # the detours alone, on the straight path through the obstacle
              ("rook_unrouted", rook, ("path.points=[]", "obstacles.route=false")),
              ("wall_unrouted", wall, ("obstacles.route=false",))]
    for name, scene, sets in scenes:
        d, meshes = obstacles_of(scene)
        cache, stats = run(name, scene, 2, *sets)
        print(f"{name}: path_routed {stats.get('path_routed')}, detour_agent_steps {stats.get('detour_agent_steps')}")
        failures += check_cache(name, cache, d["time"]["frame_limit"], meshes)
        if name == "wall":
            one, _ = run(name, scene, 1, *sets)
            digest = [hashlib.sha256(open(x, "rb").read()).hexdigest() for x in (cache, one)]
            if digest[0] != digest[1]:
                failures.append("wall: the caches of 1 and 2 threads differ")
    return morph_test_args.finish(failures)


if __name__ == "__main__":
    sys.exit(main())
