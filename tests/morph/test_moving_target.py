#!/usr/bin/env python3
"""A target that moves (issue 38), measured from the cache with numpy, never from the engine's stats.

The test makes its own mesh sequence: examples/moon's star, twisted about its axis and stretched by
an amount that grows with the height (not a similarity, so no triangle keeps its shape), MESHES
meshes looping at RATE meshes a second, and a target_motion.path the target walks along from START.
A sphere's tets morph into it with motion starting while about half of them are still homing, so
some arrive before the target moves and the rest chase it.

The sequence's surface at each checked frame's time t is rebuilt here, independently of the engine:
the OBJ files parsed as they are listed, placed (scale, translate), interpolated linearly between
meshes i0 = floor(f) mod MESHES and i0 + 1 at f = (t - START) RATE (mesh 0 before START), and
translated by the path's offset, speed (t - START) along [0, 0, 0] then the points. Then:

- every vertex of every arrived tet (phase 3) is inside or on the deformed surface: its distance
  outside (winding number < 1/2) is at most TOL;
- the vertices on the surface stay on it: each (row, vertex) whose distance to the surface at its
  first arrived frame is below TOL has, at every later checked frame, a distance at most TOL
  (max and p99 printed);
- the motion is real: those vertices move by more than 1000 TOL on average between the start and
  the end, and over a third of all vertices are on the surface;
- the run writes the same bytes with 1 and 2 threads (a moving target is a pure function of time).

TOL = 1e-5 units. The cache holds float32: at the scene's coordinates (|x| < 16) their spacing is
2^-19 = 1.9e-6, and a surface vertex carries three roundings of at most half a spacing in each
coordinate (its rest position in float, which its binding starts from, and the frame's output),
which is at most 3 * 0.95e-6 * sqrt(3) = 4.9e-6 from the surface; the sequence is interpolated in
double on both sides. TOL is twice that, and 1e-6 of the scene's extent.

    test_moving_target.py --cli build/flockmorph --tmp DIR --source REPO
"""
import json
import math
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import morph_test_args  # noqa: E402

MESHES, RATE, START = 8, 4.0, 2.6
PATH, SPEED = [[3.0, 0.0, 0.0], [3.0, 2.0, 1.0]], 2.0
SCALE, TRANSLATE = 0.6, [6.0, 0.0, 0.0]
TOL = 1e-5
FRAME_LIMIT = 150
ARGS = None


def deform(v, k, lo, hi):
    """Mesh k of the sequence: twist about z and stretch along x, both growing with the height."""
    p = 2 * math.pi * k / MESHES
    h = (v[2] - lo) / (hi - lo)
    a = 0.5 * math.sin(p) * h
    x, y = v[0] * (1 + 0.2 * math.sin(p) * h), v[1]
    return [x * math.cos(a) - y * math.sin(a), x * math.sin(a) + y * math.cos(a), v[2] + 0.3 * math.sin(p) * h * h]


def write_sequence(src):
    with open(src) as f:
        lines = f.read().splitlines()
    verts = [[float(t) for t in line.split()[1:4]] for line in lines if line.startswith("v ")]
    lo, hi = min(v[2] for v in verts), max(v[2] for v in verts)
    for k in range(MESHES):
        out, i = [], 0
        for line in lines:
            if line.startswith("v "):
                out.append("v %.6f %.6f %.6f" % tuple(deform(verts[i], k, lo, hi) if k else verts[i]))
                i += 1
            else:
                out.append(line)
        with open(os.path.join(ARGS.tmp, "twist_%02d.obj" % k), "w") as f:
            f.write("\n".join(out) + "\n")


def read_obj(path, np):
    """Vertices as listed and triangles over them (OBJ faces fanned, 1-based, v/vt/vn allowed)."""
    v, tri = [], []
    with open(path) as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] == "v":
                v.append([float(x) for x in t[1:4]])
            elif t[0] == "f":
                idx = [int(x.split("/")[0]) - 1 for x in t[1:]]
                tri += [[idx[0], idx[j], idx[j + 1]] for j in range(1, len(idx) - 1)]
    return np.array(v) * SCALE + np.array(TRANSLATE), np.array(tri)


def path_offset(along, np):
    start = np.zeros(3)
    for p in PATH:
        p = np.array(p)
        seg = np.linalg.norm(p - start)
        if along < seg:
            return start + (p - start) * (along / seg)
        along -= seg
        start = p
    return start


def surface_at(t, meshes, np):
    tau = max(0.0, t - START)
    f = tau * RATE
    i0 = int(math.fmod(math.floor(f), MESHES))
    w = f - math.floor(f)
    a, b = meshes[i0], meshes[(i0 + 1) % MESHES]
    return a + w * (b - a) + path_offset(SPEED * tau, np)


def point_triangle_distance(p, a, b, c, np):
    """Distances from points p (P, 3) to triangles (T, 3) each: (P, T), Ericson's regions, vectorised."""
    ab, ac = b - a, c - a
    ap = p[:, None, :] - a[None]
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p[:, None, :] - b[None]
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p[:, None, :] - c[None]
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = vb / denom
        w = vc / denom
        q = a[None] + v[..., None] * ab[None] + w[..., None] * ac[None]  # inside the face
        # edges
        t_ab = np.clip(d1 / (d1 - d3), 0, 1)
        t_ac = np.clip(d2 / (d2 - d6), 0, 1)
        t_bc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
    q_ab = a[None] + np.nan_to_num(t_ab)[..., None] * ab[None]
    q_ac = a[None] + np.nan_to_num(t_ac)[..., None] * ac[None]
    q_bc = b[None] + np.nan_to_num(t_bc)[..., None] * (c - b)[None]
    cand = [q, q_ab, q_ac, q_bc]
    inside = (va >= 0) & (vb >= 0) & (vc >= 0) & (denom > 0)
    dist = [np.linalg.norm(p[:, None, :] - x, axis=-1) for x in cand]
    dist[0] = np.where(inside, dist[0], np.inf)
    return np.minimum.reduce(dist)


def distances(points, verts, tri, np):
    """Unsigned distance of each point to the surface, and whether it is inside (winding number)."""
    a, b, c = verts[tri[:, 0]], verts[tri[:, 1]], verts[tri[:, 2]]
    out, inside = np.empty(len(points)), np.empty(len(points), bool)
    for s in range(0, len(points), 512):
        p = points[s:s + 512].astype(np.float64)
        out[s:s + 512] = point_triangle_distance(p, a, b, c, np).min(axis=1)
        ra, rb, rc = a[None] - p[:, None], b[None] - p[:, None], c[None] - p[:, None]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (ra, rb, rc))
        num = (ra * np.cross(rb, rc)).sum(-1)
        den = la * lb * lc + (ra * rb).sum(-1) * lc + (ra * rc).sum(-1) * lb + (rb * rc).sum(-1) * la
        wind = (2 * np.arctan2(num, den)).sum(axis=1) / (4 * math.pi)
        inside[s:s + 512] = wind > 0.5
    return out, inside


def run(threads):
    out = os.path.join(ARGS.tmp, f"moving_target_{threads}")
    scene = {
        "source": {"mesh": os.path.join(ARGS.source, "examples", "flock_cylinder_sphere", "sphere.obj"),
                   "translate": [-8.0, 0.0, 1.0], "scale": 0.5},
        "target": {"mesh": os.path.join(ARGS.tmp, "twist_00.obj"), "translate": TRANSLATE, "scale": SCALE},
        "speed0": 8.0,
        "time": {"frame_rate": 24, "time_step": 1 / 48, "frame_limit": FRAME_LIMIT},
        "path": {"points": [[-1.0, -3.0, 3.0]]},
        "launch_rate": 3000,
        "target_motion": {"sequence": os.path.join(ARGS.tmp, "twist_%02d.obj"), "frames": MESHES,
                          "frame_rate": RATE, "start": START, "path": PATH, "speed": SPEED},
    }
    path = os.path.join(ARGS.tmp, "moving_target.json")
    with open(path, "w") as f:
        json.dump(scene, f)
    subprocess.run([ARGS.cli, "run", path, "-o", out, "--quiet", "--threads", str(threads)], check=True)
    return os.path.join(out, "frames.fmc")


def main():
    global ARGS
    ARGS = morph_test_args.parse_args()
    sys.path.insert(0, os.path.join(ARGS.source, "python"))
    import numpy as np
    import flockmorph_cache
    write_sequence(os.path.join(ARGS.source, "examples", "moon", "star.obj"))
    failures = []
    caches = [run(1), run(2)]
    with open(caches[0], "rb") as a, open(caches[1], "rb") as b:
        if a.read() != b.read():
            failures.append("the caches of 1 and 2 threads differ")
    meshes, tri = [], None
    for k in range(MESHES):
        v, tri = read_obj(os.path.join(ARGS.tmp, "twist_%02d.obj" % k), np)
        meshes.append(v)
    with flockmorph_cache.Cache(caches[0]) as c:
        count = len(c)
        checked = sorted(set(range(0, count, 12)) | {count - 1})  # every 0.5 s
        first_d = None  # each (row, vertex)'s distance at its first arrived frame, nan before
        worst_out, stay, moved_from, moved = 0.0, [], None, 0.0
        arrived_at_start = 0
        for k in checked:
            t = k / c.frame_rate
            tets = np.asarray(c.read(k, "tet_vertices"), dtype=np.float64).reshape(-1, 4, 3)
            phase = np.asarray(c.read(k, "phase")).ravel()
            if first_d is None:
                first_d = np.full((len(phase), 4), np.nan)
            rows = np.nonzero(phase == 3)[0]
            if t <= START:
                arrived_at_start = len(rows)
            if len(rows) == 0:
                continue
            # tets share vertices (the same bits: one binding): each position measured once
            pts, back = np.unique(tets[rows].reshape(-1, 3), axis=0, return_inverse=True)
            d, inside = distances(pts, surface_at(t, meshes, np), tri, np)
            d, inside = d[back.ravel()].reshape(-1, 4), inside[back.ravel()].reshape(-1, 4)
            worst_out = max(worst_out, float(np.where(inside, 0.0, d).max()))
            known = ~np.isnan(first_d[rows])
            surf = known & (first_d[rows] < TOL)
            stay += list(d[surf])
            sub = first_d[rows]
            sub[~known] = d[~known]
            first_d[rows] = sub
            if t > START and moved_from is None:
                moved_from = (k, tets.copy(), first_d < TOL)
        last = tets
    on_surface = first_d < TOL
    share = float(on_surface.sum()) / on_surface.size
    stay = np.array(stay)
    if moved_from is not None:
        k0, t0, surf0 = moved_from
        moved = float(np.linalg.norm(last[surf0[:, :, None].repeat(3, 2)].reshape(-1, 3)
                                     - t0[surf0[:, :, None].repeat(3, 2)].reshape(-1, 3), axis=1).mean())
    print(f"{count} frames, {len(checked)} checked; {arrived_at_start} of {len(first_d)} tets arrived before the "
          f"motion starts; {share:.1%} of the vertices on the surface")
    if len(stay):
        print(f"on-surface vertices in later frames: {len(stay)} measures, distance to the deformed surface max "
              f"{stay.max():.3g}, p99 {np.percentile(stay, 99):.3g} (tolerance {TOL:g})")
    print(f"largest distance outside the deformed target: {worst_out:.3g}; surface vertices moved {moved:.3g} "
          f"on average after the motion started")
    if not len(stay) or stay.max() > TOL:
        failures.append(f"on-surface vertices leave the deformed surface: max {stay.max() if len(stay) else None}")
    if worst_out > TOL:
        failures.append(f"a vertex lies {worst_out:.3g} outside the deformed target")
    if share < 1 / 3:
        failures.append(f"only {share:.1%} of the vertices on the surface: the test sees too few")
    if moved < 1000 * TOL:
        failures.append(f"the surface vertices moved {moved:.3g} on average: the target does not move")
    if not 0 < arrived_at_start < len(first_d):
        failures.append(f"{arrived_at_start} tets arrived before the motion: none would chase it, or all")
    if int((phase != 3).sum()):
        failures.append(f"{int((phase != 3).sum())} tets have not arrived at the frame limit")
    return morph_test_args.finish(failures)


if __name__ == "__main__":
    sys.exit(main())
