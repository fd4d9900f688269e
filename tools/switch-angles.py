#!/usr/bin/env python3
"""Measures the kink at the phase switch of a tetra morph (issue 38) from its frame cache alone.

    tools/switch-angles.py CACHE.fmc [--json] [--check] [--max-angle 30] [--max-ratio 1.25]
                           [--share 0.95]

For every tet, the switch is the first frame f whose phase is phase 2 (homing) or later while
frame f - 1's is phase 1 (flying); the phase values are fm_phase's (include/flockmorph/core.h).
Its centroid velocity just before the switch is the centroid difference over frames f - 2 -> f - 1
(both in phase 1), just after it over frames f -> f + 1 (phase 2, or arrived at f + 1). The frame
interval f - 1 -> f that holds the switch step itself is left out, so each velocity belongs to
one phase. Tets that were not yet flying at f - 2 (launched into or near the target sphere), whose
switch is too close to either end of the cache, or which do not move on one side are skipped and
counted.

Printed (and with --json as one object): the heading change between the two velocities (degrees)
and their speed ratio (larger / smaller): median, p95 and max, and the shares of tets within
--max-angle degrees and within a ratio of --max-ratio. With --check the exit status is 1 unless
both shares are at least --share (issue 38: 30 degrees and x1.25 for 95 % of the tets).

Also printed, for people: the worst frame-to-frame heading change over the first half second of
phase 2 (the turn a blend spreads out), median and p95 over tets.

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

PHASE_FLYING, PHASE_HOMING = 1, 2  # fm_phase (include/flockmorph/core.h)
AFTER_WINDOW_S = 0.5  # how far into phase 2 the worst frame-to-frame turn is looked for


def centroids_and_phases(path):
    """Every frame's tet centroids (frames, agents, 3) in float64 and phases (frames, agents)."""
    with flockmorph_cache.open(path) as cache:
        frames, agents = len(cache), cache.agents
        c = np.empty((frames, agents, 3))
        ph = np.empty((frames, agents), dtype=np.uint8)
        for k in range(frames):
            c[k] = cache.read(k, "tet_vertices").astype(np.float64).mean(axis=1)
            ph[k] = cache.read(k, "phase").reshape(agents)
        return c, ph, cache.frame_rate


def angle_deg(a, b):
    """The angle between the rows of a and b, degrees (rows of zero length give nan)."""
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("...i,...i->...", a, b) / (na * nb)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def measure(path, max_angle, max_ratio):
    c, ph, frame_rate = centroids_and_phases(path)
    frames, agents = ph.shape
    flying = ph == PHASE_FLYING
    switched = (ph[1:] >= PHASE_HOMING) & flying[:-1]  # switched[f - 1]: the switch lies in f - 1 -> f
    has = switched.any(axis=0)
    f = switched.argmax(axis=0) + 1  # the first phase-2 frame
    idx = np.arange(agents)
    ok = has & (f >= 2) & (f + 1 < frames)
    fs = np.where(ok, f, 2)
    ok &= flying[fs - 2, idx]
    before = c[fs - 1, idx] - c[fs - 2, idx]
    after = c[np.minimum(fs + 1, frames - 1), idx] - c[fs, idx]
    sb, sa = np.linalg.norm(before, axis=1), np.linalg.norm(after, axis=1)
    ok &= (sb > 0) & (sa > 0)
    angle = angle_deg(before, after)[ok]
    ratio = (np.maximum(sb, sa)[ok] / np.minimum(sb, sa)[ok])

    # The worst turn between consecutive frame intervals over the first AFTER_WINDOW_S of phase 2.
    window = max(1, int(round(AFTER_WINDOW_S * frame_rate)))
    worst = np.zeros(agents)
    for j in range(window):
        k = fs + j
        valid = ok & (k + 2 < frames)
        kk = np.minimum(k, frames - 3)
        d0 = c[kk + 1, idx] - c[kk, idx]
        d1 = c[kk + 2, idx] - c[kk + 1, idx]
        moving = (np.linalg.norm(d0, axis=1) > 0) & (np.linalg.norm(d1, axis=1) > 0)
        a = np.where(valid & moving, angle_deg(d0, d1), 0.0)
        worst = np.maximum(worst, np.nan_to_num(a))
    worst = worst[ok]

    def pct(x, q):
        return float(np.percentile(x, q)) if x.size else float("nan")

    return {
        "cache": path, "agents": int(agents), "measured": int(ok.sum()),
        "skipped": int(agents - ok.sum()), "never_switched": int((~has).sum()),
        "heading_deg": {"median": pct(angle, 50), "p95": pct(angle, 95),
                        "max": float(angle.max()) if angle.size else float("nan")},
        "speed_ratio": {"median": pct(ratio, 50), "p95": pct(ratio, 95),
                        "max": float(ratio.max()) if ratio.size else float("nan")},
        "share_within_angle": float((angle <= max_angle).mean()) if angle.size else 0.0,
        "share_within_ratio": float((ratio <= max_ratio).mean()) if ratio.size else 0.0,
        "max_angle": max_angle, "max_ratio": max_ratio,
        "worst_turn_first_0.5s_deg": {"median": pct(worst, 50), "p95": pct(worst, 95)},
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cache")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--check", action="store_true", help="exit 1 unless both shares reach --share")
    ap.add_argument("--max-angle", type=float, default=30.0)
    ap.add_argument("--max-ratio", type=float, default=1.25)
    ap.add_argument("--share", type=float, default=0.95)
    args = ap.parse_args()
    r = measure(args.cache, args.max_angle, args.max_ratio)
    if args.json:
        print(json.dumps(r, indent=1))
    else:
        h, s, w = r["heading_deg"], r["speed_ratio"], r["worst_turn_first_0.5s_deg"]
        print(f"{r['cache']}: {r['measured']} of {r['agents']} tets measured ({r['skipped']} skipped, "
              f"{r['never_switched']} never switched)")
        print(f"  heading change: median {h['median']:.1f} deg, p95 {h['p95']:.1f}, max {h['max']:.1f}; "
              f"within {args.max_angle:g} deg: {100 * r['share_within_angle']:.1f} %")
        print(f"  speed ratio:    median {s['median']:.3f}, p95 {s['p95']:.3f}, max {s['max']:.2f}; "
              f"within x{args.max_ratio:g}: {100 * r['share_within_ratio']:.1f} %")
        print(f"  worst frame-to-frame turn in the first {AFTER_WINDOW_S:g} s of phase 2: "
              f"median {w['median']:.1f} deg, p95 {w['p95']:.1f}")
    if args.check:
        bad = [what for what, share in (("heading", r["share_within_angle"]), ("speed", r["share_within_ratio"]))
               if share < args.share]
        if bad or r["measured"] == 0:
            print(f"FAIL: {', '.join(bad) or 'no tet measured'} below {100 * args.share:g} %", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
