#!/usr/bin/env python3
"""Measures how a shape-flock cache looks as a flock (docs/shape-flock.md "The look in numbers"), from
the cache's positions alone, independently of the engine's own statistics.

    tools/flock-look.py OUT/frames.fmc [--json] [--check persistence=0.6,coherence=0.6,...]

At mid-flight (the first frame at which the agents' mean distance to their last-frame positions has
halved):
  persistence  of each agent's k = 6 nearest neighbours, the share still among its 6 nearest 1 s later
  coherence    the mean cosine between an agent's velocity fluctuation (its velocity minus the flock's
               mean) and its 6 nearest neighbours'
  smoothness   the per-agent acceleration autocorrelation at a lag of 4 frames over the 2 s around
               mid-flight: with b = a minus the agent's mean acceleration over that window,
               sum b_t . b_t+4 / sqrt(sum |b_t|^2 sum |b_t+4|^2), averaged over the agents
               (1 = smooth, 0 = noise)
Over the whole cache:
  dead_stop    the largest share, over the frames, of the moving agents that lose half their speed
               within 3 frames ("moving": faster than 10 % of the flock's median speed at mid-flight,
               so an agent creeping onto its destination is not counted), over the frames in which
               at least 5 % of the agents move (a handful of stragglers makes no share)
Velocities are central differences of positions, accelerations second differences (units per frame
scaled by the frame rate). Needs numpy (Debian's: run with /usr/bin/python3).

--check NAME=BOUND,... exits 1 naming every measure past its bound (dead_stop is an upper bound, the
others lower bounds); --compare OTHER.fmc adds the RMS position difference at this cache's mid-flight
frame and the median nearest-neighbour spacing there (the rules must move agents by more than it).
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
import flockmorph_cache  # noqa: E402

K = 6
LAG = 4
MOVING = 0.1
MIN_MOVING = 0.05


def knn(p, k=K, chunk=2048):
    """Indices of each point's k nearest others (brute force in chunks; exact)."""
    n = len(p)
    out = np.empty((n, k), dtype=np.int64)
    sq = (p * p).sum(1)
    for b in range(0, n, chunk):
        q = p[b:b + chunk]
        d2 = sq[b:b + chunk, None] + sq[None, :] - 2.0 * q @ p.T
        d2[np.arange(len(q)), np.arange(b, b + len(q))] = np.inf
        part = np.argpartition(d2, k, axis=1)[:, :k]
        out[b:b + chunk] = part
    return out


def nn_spacing(p, chunk=2048):
    sq = (p * p).sum(1)
    best = np.empty(len(p))
    for b in range(0, len(p), chunk):
        q = p[b:b + chunk]
        d2 = sq[b:b + chunk, None] + sq[None, :] - 2.0 * q @ p.T
        d2[np.arange(len(q)), np.arange(b, b + len(q))] = np.inf
        best[b:b + chunk] = np.sqrt(np.maximum(d2.min(1), 0))
    return float(np.median(best))


def positions(cache):
    return cache.read_range("position").astype(np.float64)  # (frames, agents, 3)


def mid_frame(p):
    d = np.linalg.norm(p - p[-1], axis=2).mean(1)
    half = np.nonzero(d <= 0.5 * d[0])[0]
    return int(half[0]) if len(half) else len(p) // 2


def velocities(p, fps):
    """Central differences of the positions (one-sided at the ends), units per second."""
    v = np.zeros_like(p)
    v[1:-1] = (p[2:] - p[:-2]) * (fps / 2)
    v[0], v[-1] = (p[1] - p[0]) * fps, (p[-1] - p[-2]) * fps
    return v


def accelerations(p, fps):
    a = np.zeros_like(p)
    a[1:-1] = (p[2:] - 2 * p[1:-1] + p[:-2]) * fps * fps
    return a


def persistence_at(p, fps, mid):
    """The share of each agent's K nearest at frame mid still among its K nearest 1 s later."""
    later = min(mid + int(round(fps)), len(p) - 1)
    nb_mid, nb_later = knn(p[mid]), knn(p[later])
    same = [len(set(nb_mid[i]) & set(nb_later[i])) for i in range(p.shape[1])]
    return float(np.mean(same)) / K


def coherence_at(p, v, mid):
    """The mean cosine between the velocity fluctuations of each agent and its K nearest at mid."""
    nb_mid = knn(p[mid])
    dv = v[mid] - v[mid].mean(0)
    unit = dv / np.maximum(np.linalg.norm(dv, axis=1, keepdims=True), 1e-12)
    return float((unit[:, None, :] * unit[nb_mid]).sum(2).mean())


def smoothness_at(a, fps, mid):
    """The per-agent acceleration autocorrelation at lag LAG over the 2 s around mid."""
    frames = len(a)
    lo, hi = max(1, mid - int(fps)), min(frames - 1 - LAG, mid + int(fps))
    mean = a[lo:hi + LAG].mean(0)  # each agent's own, so a steady turn is not counted as smooth
    a0, a1 = a[lo:hi] - mean, a[lo + LAG:hi + LAG] - mean
    num = (a0 * a1).sum((0, 2))
    den = np.sqrt((a0 * a0).sum((0, 2)) * (a1 * a1).sum((0, 2)))
    ok = den > 0
    return float((num[ok] / den[ok]).mean()) if ok.any() else 1.0


def measure(path):
    with flockmorph_cache.open(path) as cache:
        p = positions(cache)
        fps = cache.frame_rate
    frames, n, _ = p.shape
    mid = mid_frame(p)
    v = velocities(p, fps)
    persistence = persistence_at(p, fps, mid)
    coherence = coherence_at(p, v, mid)
    smoothness = smoothness_at(accelerations(p, fps), fps, mid)

    speed = np.linalg.norm(p[1:] - p[:-1], axis=2) * fps  # speed over frame f -> f+1
    threshold = MOVING * float(np.median(speed[min(mid, len(speed) - 1)]))
    worst, worst_frame = 0.0, 0
    for f in range(len(speed) - 3):
        moving = speed[f] > threshold
        count = int(moving.sum())
        if count < MIN_MOVING * n:  # a few stragglers make no share
            continue
        share = float((speed[f + 3][moving] < 0.5 * speed[f][moving]).sum()) / count
        if share > worst:
            worst, worst_frame = share, f
    return {
        "cache": path, "agents": n, "frames": frames, "mid_frame": mid,
        "persistence": persistence, "coherence": coherence, "smoothness": smoothness,
        "dead_stop": worst, "dead_stop_frame": worst_frame,
        "nn_spacing": nn_spacing(p[mid]), "_p": p,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cache")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--compare", metavar="OTHER.fmc")
    ap.add_argument("--check", metavar="NAME=BOUND,...")
    args = ap.parse_args()
    r = measure(args.cache)
    p = r.pop("_p")
    if args.compare:
        with flockmorph_cache.open(args.compare) as other:
            q = other.read(min(r["mid_frame"], len(other) - 1), "position").astype(np.float64)
        r["rms_difference"] = float(np.sqrt(((p[r["mid_frame"]] - q) ** 2).sum(1).mean()))
    if args.json:
        print(json.dumps(r, indent=1))
    else:
        for key, value in r.items():
            print(f"{key:16} {value:.4f}" if isinstance(value, float) else f"{key:16} {value}")
    failed = []
    for item in filter(None, (args.check or "").split(",")):
        name, bound = item.split("=")
        value = r["nn_spacing"] if name == "rms_difference_over_spacing" else r[name]
        if name == "rms_difference_over_spacing":
            value = r["rms_difference"] / r["nn_spacing"]
        bad = value > float(bound) if name == "dead_stop" else value < float(bound)
        if bad:
            failed.append(f"{name} {value:.4f} (bound {bound})")
    if failed:
        print(f"flock-look: {args.cache}: " + "; ".join(failed), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
