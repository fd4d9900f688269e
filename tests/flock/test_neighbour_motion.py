#!/usr/bin/env python3
"""tools/neighbour-motion.py's measure on positions whose answer is known: a rigid translation moves
no pair against another (0), two agents that fly apart at a known speed give exactly that relative
displacement over the radius, and pairs beyond the radius are not counted; a missing or foreign
file and a radius of 0 are a one-line error and exit status 1.

    test_neighbour_motion.py --source REPO
"""
import argparse
import importlib.util
import os
import subprocess
import sys
import unittest

import numpy as np

ARGS = None


def load_tool():
    path = os.path.join(ARGS.source, "tools", "neighbour-motion.py")
    spec = importlib.util.spec_from_file_location("neighbour_motion", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class NeighbourMotion(unittest.TestCase):
    def setUp(self):
        self.tool = load_tool()
        rng = np.random.default_rng(7)
        self.x0 = rng.uniform(0.0, 1.0, size=(4000, 3))

    def test_rigid_translation_moves_no_pair(self):
        _, rel = self.tool.relative_motion(self.x0, self.x0 + [0.3, -0.2, 0.1], 0.1)
        self.assertGreater(rel.size, 100)
        self.assertLess(rel.max(), 1e-12)

    def test_a_pair_flying_apart(self):
        x0 = np.array([[0.51, 0.52, 0.53], [0.54, 0.52, 0.53], [0.9, 0.9, 0.9]])
        x1 = x0 + [[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.0, 0.0, 0.0]]
        _, rel = self.tool.relative_motion(x0, x1, 0.1)
        self.assertEqual(rel.size, 1)  # the third agent is no one's neighbour
        self.assertAlmostEqual(rel[0], 0.2)

    def test_only_pairs_within_the_radius(self):
        radius = 0.05
        x1 = self.x0 + np.random.default_rng(8).normal(0, 0.01, size=self.x0.shape)
        _, rel = self.tool.relative_motion(self.x0, x1, radius)
        pairs = 0
        for i in range(len(self.x0)):  # brute force over the same cells
            key = np.floor(self.x0 / radius)
            same = np.all(key == key[i], axis=1) & (np.linalg.norm(self.x0 - self.x0[i], axis=1) < radius)
            pairs += int(same.sum()) - 1
        self.assertLessEqual(rel.size, pairs // 2)
        self.assertGreater(rel.size, 0.9 * pairs // 2)

    def test_a_bad_cache_is_a_clear_error(self):
        tool = os.path.join(ARGS.source, "tools", "neighbour-motion.py")
        for args, says in ((["/nonexistent/frames.fmc", "0.1"], "/nonexistent/frames.fmc"),
                           ([__file__, "0.1"], os.path.basename(__file__)),
                           ([__file__, "0"], "RADIUS must be > 0")):
            run = subprocess.run([sys.executable, tool] + args, capture_output=True, text=True)
            self.assertEqual(run.returncode, 1, run.stderr)
            self.assertIn(says, run.stderr)
            self.assertNotIn("Traceback", run.stderr)


def main():
    global ARGS
    ap = argparse.ArgumentParser()
    ap.add_argument("--source", required=True)
    ARGS, rest = ap.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest)


if __name__ == "__main__":
    main()
