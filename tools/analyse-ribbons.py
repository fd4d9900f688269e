#!/usr/bin/env python3
"""Measures whether a tetra morph's flock flies as one stream or as parallel ribbons (issue 14).

    tools/analyse-ribbons.py OUTDIR [--frames 60,80] [--json]

OUTDIR is a `flockmorph run` output (its stats.json and cache). The path is rebuilt as
src/morph/morph_path.c builds it (FM §5.1): C_S and C_T are the volume centroids of the tets of the
first and last frame, the curve runs through the scene's path.points (and any --set path.* of the
run's command line), and key points Q_0 .. Q_{m+1} are spaced evenly by arc length.

For each frame (default: those with at least half the peak number of flying agents), every flying
tet (phase 1) whose centroid lies in the middle 60 % of the path by arc length is projected onto
the plane normal to the path's local direction. The offset from the path is split into u (in the
path's best-fit plane) and w (along that plane's normal). Printed per frame:

- the largest gaps between the sorted offsets along the cross-section's widest axis (its first
  principal axis in (u, w)), as a fraction of its width;
- the clusters along that axis: runs separated by gaps wider than the agents' rest spacing
  cbrt(source volume / n), each holding at least 1 % of the agents (smaller runs are strays and
  join their neighbour);
- the same tets at rest: their rest centroids' offsets from C_S seen along f_0 (the first path
  direction), in the same (u, w) frame, on the same axis: the correlation of each tet's offset in
  flight with its offset at rest, and the clusters at rest. A correlation near 1 and the same
  clusters mean that the flight carries the source's silhouette unchanged (docs/scenarios.md).

Exit status 0; the numbers are for people and for tests/morph/test_path_ribbons.py (--json).
Needs numpy (Debian's python3-numpy: run it with /usr/bin/python3).
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
import flockmorph_cache  # noqa: E402

CURVE_SAMPLES_PER_SEGMENT = 64  # as morph_path.c
MIN_CLUSTER_SHARE = 0.01


def volume_centroid(tets):
    """The volume-weighted centroid of tets (n, 4, 3) and each tet's centroid."""
    c = tets.mean(1)
    e = tets[:, 1:] - tets[:, :1]
    vol = np.abs(np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2]))) / 6
    return (c * vol[:, None]).sum(0) / vol.sum(), c, vol.sum()


def path_settings(stats):
    """The scene's path block with the run's --set path.* overrides applied."""
    with open(stats["scene_absolute"]) as f:
        path = dict(json.load(f).get("path", {}))
    argv = stats.get("command_line", [])
    for i, arg in enumerate(argv[:-1]):
        if arg == "--set" and argv[i + 1].startswith("path."):
            key, value = argv[i + 1][5:].split("=", 1)
            try:
                path[key] = json.loads(value)
            except ValueError:
                path[key] = value
    return path


def catmull_rom(p0, p1, p2, p3, s):
    return 0.5 * (2 * p1 + (-p0 + p2) * s + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s * s
                  + (-p0 + 3 * p1 - 3 * p2 + p3) * s ** 3)


def dense_curve(ctrl, curve):
    if curve != "catmull_rom" or len(ctrl) < 3:
        return ctrl
    n, out = len(ctrl), []
    for i in range(n - 1):
        p0, p1, p2, p3 = ctrl[max(i - 1, 0)], ctrl[i], ctrl[i + 1], ctrl[min(i + 2, n - 1)]
        out += [catmull_rom(p0, p1, p2, p3, s / CURVE_SAMPLES_PER_SEGMENT) for s in range(CURVE_SAMPLES_PER_SEGMENT)]
    return np.array(out + [ctrl[-1]])


def key_points(dense, m):
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    s = arc[-1] * np.arange(m + 2) / (m + 1)
    return np.stack([np.interp(s, arc, dense[:, k]) for k in range(3)], axis=1)


def plane_normal(dense):
    """Normal of the path's best-fit plane; for a straight path any normal of it."""
    _, sv, vt = np.linalg.svd(dense - dense.mean(0))
    if len(sv) > 1 and sv[1] > 1e-9 * max(sv[0], 1e-300):
        return vt[2]
    t = vt[0]
    other = np.eye(3)[np.argmin(np.abs(t))]
    b = np.cross(t, other)
    return b / np.linalg.norm(b)


def lateral(points, dense, arc, b):
    """Arc length and (u, w) offsets of points from the polyline `dense`, in the frame (b x t, b)."""
    a, e = dense[:-1], np.diff(dense, axis=0)
    len2 = (e * e).sum(1)
    s = np.clip(np.einsum("pij,ij->pi", points[:, None, :] - a[None], e) / len2, 0, 1)
    foot = a[None] + s[..., None] * e[None]
    j = ((points[:, None, :] - foot) ** 2).sum(-1).argmin(1)
    t = e[j] / np.sqrt(len2[j])[:, None]
    off = points - foot[np.arange(len(points)), j]
    off -= (off * t).sum(1)[:, None] * t
    return arc[j] + s[np.arange(len(points)), j] * np.sqrt(len2[j]), (off * np.cross(b, t)).sum(1), off @ b


def clusters(x, min_gap, min_count):
    """Runs of sorted x split at gaps > min_gap; runs under min_count merge into a neighbour."""
    xs = np.sort(x)
    cuts = np.where(np.diff(xs) > min_gap)[0] + 1
    runs = [r for r in np.split(xs, cuts)]
    kept = []
    for r in runs:
        if kept and (len(r) < min_count or len(kept[-1]) < min_count):
            kept[-1] = np.concatenate([kept[-1], r])
        else:
            kept.append(r)
    out = []
    for i, r in enumerate(kept):
        gap = float(kept[i + 1][0] - r[-1]) if i + 1 < len(kept) else None
        out.append({"centre": float(r.mean()), "lo": float(r[0]), "hi": float(r[-1]), "count": int(len(r)),
                    "gap_after": gap})
    return out


def analyse_frame(cache, k, geo):
    tets = cache.read(k, "tet_vertices").astype(np.float64)
    flying = cache.read(k, "phase").ravel() == 1
    ids = cache.read(k, "id").ravel()[flying]
    c = tets.mean(1)[flying]
    s, u, w = lateral(c, geo["dense"], geo["arc"], geo["b"])
    mid = (s > 0.2 * geo["length"]) & (s < 0.8 * geo["length"])
    u, w, ids = u[mid], w[mid], ids[mid]
    if len(u) < 2:
        return {"frame": k, "flying": int(flying.sum()), "measured": int(len(u))}
    uw = np.stack([u, w], 1)
    _, _, axes = np.linalg.svd(uw - uw.mean(0), full_matrices=False)
    axis = axes[0] if axes[0][0] >= 0 else -axes[0]  # the cross-section's widest axis, toward +u
    x = uw @ axis
    xs = np.sort(x)
    width = float(xs[-1] - xs[0])
    gaps = np.sort(np.diff(xs))[::-1][:4]
    min_count = max(2, int(MIN_CLUSTER_SHARE * len(x)))
    found = clusters(x, geo["spacing"], min_count)
    rest = geo["rest"][ids] @ axis  # the same tets at rest, seen along f_0, on the same axis
    at_rest = clusters(rest, geo["spacing"], min_count)
    return {"frame": k, "time": cache.time(k), "flying": int(flying.sum()), "measured": int(len(x)),
            "u_range": [float(u.min()), float(u.max())], "w_range": [float(w.min()), float(w.max())],
            "width": width, "largest_gaps": [float(g) for g in gaps],
            "largest_gap_over_width": float(gaps[0] / width) if width > 0 else 0.0,
            "clusters": found, "cluster_count": len(found), "rest_cluster_count": len(at_rest),
            "rest_gaps": [c["gap_after"] for c in at_rest[:-1]],
            "rest_correlation": float(np.corrcoef(x, rest)[0, 1])}


def geometry(cache, stats):
    cs, c0, volume = volume_centroid(cache.read(0, "tet_vertices").astype(np.float64))
    ct, _, _ = volume_centroid(cache.read(len(cache) - 1, "tet_vertices").astype(np.float64))
    path = path_settings(stats)
    ctrl = np.array([cs] + [list(map(float, p)) for p in path.get("points", [])] + [ct])
    dense = dense_curve(ctrl, path.get("curve", "polyline"))
    q = key_points(dense, int(path.get("key_points", 32)))
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    b = plane_normal(dense)
    f0 = (q[1] - q[0]) / np.linalg.norm(q[1] - q[0])
    rest = np.zeros((cache.agents, 2))
    rest[cache.read(0, "id").ravel()] = np.stack([(c0 - cs) @ np.cross(b, f0), (c0 - cs) @ b], 1)
    return {"dense": dense, "arc": arc, "length": float(arc[-1]), "b": b, "rest": rest,
            "spacing": float(np.cbrt(volume / cache.agents)), "key_spacing": float(arc[-1] / (len(q) - 1)),
            "key_points": len(q) - 2}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("outdir")
    ap.add_argument("--frames", help="comma-separated frame numbers (default: mid-flight frames, every 10th)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    with open(os.path.join(args.outdir, "stats.json")) as f:
        stats = json.load(f)
    with flockmorph_cache.open(stats["cache"] if os.path.isabs(stats["cache"])
                               else os.path.join(args.outdir, os.path.basename(stats["cache"]))) as cache:
        geo = geometry(cache, stats)
        if args.frames:
            frames = [int(k) for k in args.frames.split(",")]
        else:
            counts = np.array([(cache.read(k, "phase") == 1).sum() for k in range(len(cache))])
            frames = [k for k in range(0, len(cache), 10) if counts[k] >= 0.5 * counts.max()]
        result = {"path_length": geo["length"], "key_points": geo["key_points"], "key_spacing": geo["key_spacing"],
                  "agent_spacing": geo["spacing"], "frames": [analyse_frame(cache, k, geo) for k in frames]}
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(f"path length {result['path_length']:.3f}, m = {result['key_points']} key points "
          f"{result['key_spacing']:.3f} apart, agent spacing {result['agent_spacing']:.4f} (the cluster gap)")
    for fr in result["frames"]:
        if "clusters" not in fr:
            print(f"frame {fr['frame']}: {fr['measured']} flying tets mid-path, nothing to measure")
            continue
        print(f"frame {fr['frame']} (t = {fr['time']:.2f} s): {fr['measured']} of {fr['flying']} flying tets "
              f"mid-path, width {fr['width']:.2f}, u {fr['u_range'][0]:.2f}..{fr['u_range'][1]:.2f}, "
              f"w {fr['w_range'][0]:.2f}..{fr['w_range'][1]:.2f}, largest gap / width "
              f"{fr['largest_gap_over_width']:.3f}, corr(rest) {fr['rest_correlation']:.4f}, "
              f"at rest {fr['rest_cluster_count']} clusters (gaps "
              f"{', '.join(f'{g:.3f}' for g in fr['rest_gaps']) or 'none'})")
        for c in fr["clusters"]:
            gap = f", then a gap of {c['gap_after']:.3f}" if c["gap_after"] is not None else ""
            print(f"    cluster at {c['centre']:+.2f} ({c['lo']:+.2f}..{c['hi']:+.2f}), {c['count']} tets{gap}")
    measured = [fr for fr in result["frames"] if "clusters" in fr]
    if measured:
        print("clusters per frame:", " ".join(str(fr["cluster_count"]) for fr in measured),
              "| at rest:", " ".join(str(fr["rest_cluster_count"]) for fr in measured),
              f"| largest gap / width: max {max(fr['largest_gap_over_width'] for fr in measured):.3f}"
              f" | corr(rest): min {min(fr['rest_correlation'] for fr in measured):.4f}")


if __name__ == "__main__":
    main()
