#!/usr/bin/env python3
"""A target that travels (issue 37, SCF Figure 1), measured from the cache of examples/flock_travel alone:
the flock forms a bird, which then glides along its route (target.path.*) with every agent bound on it.

- At the last frame before the route's start every agent is bound (phase 3); those positions are the
  bird's surface at rest.
- At every later frame each agent is within TOLERANCE of that surface carried along the route, which
  this test evaluates on its own from the scene file (numpy): the interpolating cubic B-spline with
  natural ends through target.path.points, by arc length (dense Gauss-Legendre sums, inverted by
  interpolation), the raised-cosine ease of target.path.ease, and the turn with the route's tangent,
  which on a level route is a turn about the vertical by the angle from the first tangent to the
  current one: p(t) = B(u) + R_z(angle) (p_rest - B(0)).
- The bound agents never move faster than MaxSpeed's top (shape_flock.max_speed, default [12, 18]),
  and the ride asks less than its bottom, so no agent trails.
- 1 and 2 threads write the same bytes.

    test_flock_travel.py --cli FLOCKMORPH --tmp DIR --source REPO
"""
import json
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "morph"))
import morph_test_args  # noqa: E402  (--cli, --tmp made, --source)

TOLERANCE = 1e-4  # units: 30 times the 3.4e-6 measured, which is the float32 cache's resolution at |x| < 40
ARRIVED = 3


class Route:
    """The interpolating uniform cubic B-spline through q with natural ends, by arc length."""

    def __init__(self, q):
        q = np.asarray(q, dtype=np.float64)
        n = len(q) - 1
        # control points P_-1 .. P_n+1: P_0 = Q_0, P_n = Q_n, P_i-1 + 4 P_i + P_i+1 = 6 Q_i inside
        a = np.zeros((n + 1, n + 1))
        rhs = np.zeros((n + 1, 3))
        a[0, 0] = a[n, n] = 1
        rhs[0], rhs[n] = q[0], q[n]
        for i in range(1, n):
            a[i, i - 1:i + 2] = 1, 4, 1
            rhs[i] = 6 * q[i]
        p = np.linalg.solve(a, rhs)
        self.ctrl = np.vstack([2 * p[0] - p[1], p, 2 * p[n] - p[n - 1]])
        self.segments = n
        # arc length: 5-point Gauss-Legendre on 2000 intervals a segment
        x, w = np.polynomial.legendre.leggauss(5)
        self.u = np.linspace(0, n, 2000 * n + 1)
        mid, half = 0.5 * (self.u[1:] + self.u[:-1]), 0.5 * (self.u[1:] - self.u[:-1])
        nodes = mid[:, None] + half[:, None] * x[None, :]
        speed = np.linalg.norm(self.eval(nodes.ravel())[1], axis=1).reshape(nodes.shape)
        self.s = np.concatenate([[0], np.cumsum((speed * w).sum(1) * half)])
        self.length = self.s[-1]

    def eval(self, u):
        u = np.clip(np.atleast_1d(u), 0, self.segments)
        i = np.minimum(u.astype(int), self.segments - 1)
        t = (u - i)[:, None]
        s = 1 - t
        w = [s ** 3 / 6, (3 * t ** 3 - 6 * t ** 2 + 4) / 6, (-3 * t ** 3 + 3 * t ** 2 + 3 * t + 1) / 6, t ** 3 / 6]
        dw = [-s * s / 2, (3 * t * t - 4 * t) / 2, (-3 * t * t + 2 * t + 1) / 2, t * t / 2]
        c = self.ctrl
        p = sum(w[j] * c[i + j] for j in range(4))
        d = sum(dw[j] * c[i + j] for j in range(4))
        return p, d

    def at_fraction(self, f):
        """B and its unit tangent at arc-length fraction f (Newton from the table's interpolation)."""
        target = np.clip(f, 0, 1) * self.length
        u = np.interp(target, self.s, self.u)
        for _ in range(3):
            k = np.clip(np.searchsorted(self.u, u) - 1, 0, len(self.u) - 2)
            p, d = self.eval(u)
            sp = np.linalg.norm(d, axis=1)
            # length from u[k] to u by Simpson (fine: the interval is 1/2000 of a segment)
            m = 0.5 * (self.u[k] + u)
            s_mid = np.linalg.norm(self.eval(m)[1], axis=1)
            s_lo = np.linalg.norm(self.eval(self.u[k])[1], axis=1)
            length = self.s[k] + (u - self.u[k]) / 6 * (s_lo + 4 * s_mid + sp)
            u = u - (length - target) / sp
        p, d = self.eval(u)
        return p, d / np.linalg.norm(d, axis=1, keepdims=True)


def eased(x, e_in, e_out):
    """The fraction of the way at normalised time x: raised-cosine speed ramps, a cruise between."""
    top = 1.0 / (1.0 - 0.5 * (e_in + e_out))
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    if x < e_in:
        return top * (0.5 * x - e_in / (2 * np.pi) * np.sin(np.pi * x / e_in))
    y = 1 - x
    if y < e_out:
        return 1 - top * (0.5 * y - e_out / (2 * np.pi) * np.sin(np.pi * y / e_out))
    return top * (0.5 * e_in + x - e_in)


def run(args, threads):
    out = os.path.join(args.tmp, f"flock_travel_{threads}")
    scene = os.path.join(args.source, "examples", "flock_travel", "scene.json")
    subprocess.run([args.cli, "run", scene, "-o", out, "--threads", str(threads), "--quiet"], check=True,
                   stdout=subprocess.DEVNULL)
    return out


def main():
    args = morph_test_args.parse_args(__doc__.split("\n")[0])
    sys.path.insert(0, os.path.join(args.source, "python"))
    import flockmorph_cache

    out1, out2 = run(args, 1), run(args, 2)
    with open(os.path.join(out1, "frames.fmc"), "rb") as a, open(os.path.join(out2, "frames.fmc"), "rb") as b:
        assert a.read() == b.read(), "1 and 2 threads wrote different caches"
    with open(os.path.join(args.source, "examples", "flock_travel", "scene.json")) as f:
        scene = json.load(f)
    with open(os.path.join(out1, "stats.json")) as f:
        stats = json.load(f)
    travel = scene["target"]["path"]
    points = np.array(travel["points"], dtype=np.float64)
    assert np.all(points[:, 2] == points[0, 2]), "the test's closed-form turn needs a level route"
    speed = travel.get("speed", 0) or scene.get("speed0", 10.0)
    ease = travel.get("ease", 1.0)
    route = Route(points)
    duration = max(route.length / speed + ease, 2 * ease)
    start = travel["start"]
    flock = stats["shape_flock"]
    assert abs(flock["target_path_start"] - start) < 1e-12, flock["target_path_start"]
    assert abs(flock["target_path_end"] - (start + duration)) < 1e-6, (flock["target_path_end"], start + duration)
    assert abs(flock["target_path_length"] - route.length) < 1e-6 * route.length, (flock["target_path_length"], route.length)

    with flockmorph_cache.open(os.path.join(out1, "frames.fmc")) as cache:
        p = cache.read_range("position").astype(np.float64)
        phase = cache.read_range("phase")
        fps = cache.frame_rate
    frames = len(p)
    times = np.arange(frames) / fps
    rest_frame = int(np.nonzero(times < start)[0][-1])
    assert np.all(phase[rest_frame] == ARRIVED), f"{int((phase[rest_frame] != ARRIVED).sum())} agents not bound at frame {rest_frame}"
    assert times[-1] >= start + duration - 1e-9, "the run ended before the target stopped"
    rest = p[rest_frame]
    b0, t0 = route.at_fraction(0.0)
    worst, worst_frame, moved = 0.0, -1, 0.0
    for f in range(rest_frame + 1, frames):
        u = eased((times[f] - start) / duration, ease / duration, ease / duration)
        b, t = route.at_fraction(u)
        angle = np.arctan2(t0[0, 0] * t[0, 1] - t0[0, 1] * t[0, 0], t0[0, 0] * t[0, 0] + t0[0, 1] * t[0, 1])
        c, s = np.cos(angle), np.sin(angle)
        rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        want = b + (rest - b0) @ rot.T
        err = float(np.abs(p[f] - want).max())
        moved = max(moved, float(np.abs(want - rest).max()))
        if err > worst:
            worst, worst_frame = err, f
    ride = np.linalg.norm(p[rest_frame + 1:] - p[rest_frame:-1], axis=2) * fps
    print(f"test_flock_travel: route {route.length:.3f} units, {start:.3f} s to {start + duration:.3f} s; "
          f"frames {rest_frame + 1}..{frames - 1}: largest distance from the carried surface {worst:.3g} units "
          f"(frame {worst_frame}), the shape moved up to {moved:.2f} units; fastest bound agent {ride.max():.2f} units/s")
    assert moved > 10, "the target did not travel"
    assert worst <= TOLERANCE, f"an agent is {worst:.3g} units off the carried surface at frame {worst_frame}"
    assert np.all(phase[rest_frame:] == ARRIVED)
    assert ride.max() < 12.0, "the ride asks more than the lowest MaxSpeed: agents would trail"
    print("test_flock_travel: passed")


if __name__ == "__main__":
    main()
