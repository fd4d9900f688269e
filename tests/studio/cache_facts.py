"""What the studio's browser test checks against the Python reader (python/flockmorph_cache.py):

    cache_facts.py CACHE [--frame K] [--near X,Y,Z]

prints JSON: the frame count, each frame's SHA-256 of its tet_vertices (or position) bytes as the
reader decodes them, frame K's values, and the smallest distance from any agent's centroid in any
frame to the point (the route passes the moved control point)."""
import argparse
import hashlib
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
import flockmorph_cache  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("cache")
    ap.add_argument("--frame", type=int)
    ap.add_argument("--near")
    a = ap.parse_args()
    with flockmorph_cache.open(a.cache) as c:
        name = "tet_vertices" if "tet_vertices" in c.attributes else "position"
        out = {"frames": len(c), "agents": c.agents, "attribute": name, "sha256": []}
        near = np.array([float(v) for v in a.near.split(",")]) if a.near else None
        nearest = float("inf")
        for k in range(len(c)):
            values = c.read(k, name)
            out["sha256"].append(hashlib.sha256(np.ascontiguousarray(values).tobytes()).hexdigest())
            if near is not None:
                centroids = values.mean(axis=1) if values.ndim == 3 else values
                nearest = min(nearest, float(np.linalg.norm(centroids - near, axis=1).min()))
        if a.frame is not None:
            out["frame"] = c.read(a.frame, name).reshape(-1).tolist()
        if near is not None:
            out["nearest"] = nearest
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
