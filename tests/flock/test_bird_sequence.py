#!/usr/bin/env python3
"""tools/make-bird-sequence.py against the meshes committed in examples/flock_bird: run into a fresh
directory, it writes the same file names with the same bytes. The committed meshes are also checked
as the example needs them: one vertex count and one triangle list in all of them, every edge shared
by exactly two triangles in opposite directions (closed and oriented), the wing tips travelling
at least 3 units over the wingbeat (so the tracking shows), and under 1 MB in all.

    test_bird_sequence.py --source REPO --tmp DIR
"""
import argparse
import filecmp
import glob
import os
import shutil
import subprocess
import sys
import unittest

ARGS = None
MIN_TIP_TRAVEL = 3.0
MAX_BYTES = 1 << 20


def committed():
    return sorted(glob.glob(os.path.join(ARGS.source, "examples", "flock_bird", "bird_*.obj")))


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            words = line.split()
            if words and words[0] == "v":
                verts.append(tuple(float(w) for w in words[1:4]))
            elif words and words[0] == "f":
                faces.append(tuple(int(w) - 1 for w in words[1:4]))
    return verts, faces


class BirdSequence(unittest.TestCase):
    def test_the_script_writes_the_committed_bytes(self):
        out = os.path.join(ARGS.tmp, "bird_sequence")
        shutil.rmtree(out, ignore_errors=True)
        script = os.path.join(ARGS.source, "tools", "make-bird-sequence.py")
        subprocess.run([sys.executable, script, out], check=True, stdout=subprocess.DEVNULL)
        names = [os.path.basename(p) for p in committed()]
        self.assertGreater(len(names), 1)
        self.assertEqual(sorted(os.listdir(out)), names)
        match, mismatch, errors = filecmp.cmpfiles(os.path.join(ARGS.source, "examples", "flock_bird"), out, names,
                                                   shallow=False)
        self.assertEqual((mismatch, errors), ([], []))

    def test_help(self):
        script = os.path.join(ARGS.source, "tools", "make-bird-sequence.py")
        done = subprocess.run([sys.executable, script, "--help"], capture_output=True, text=True)
        self.assertEqual(done.returncode, 0)
        self.assertIn("OUT_DIR", done.stdout)

    def test_the_meshes_share_a_closed_connectivity(self):
        meshes = [read_obj(p) for p in committed()]
        verts0, faces0 = meshes[0]
        for verts, faces in meshes[1:]:
            self.assertEqual(len(verts), len(verts0))
            self.assertEqual(faces, faces0)
        edges = {}
        for f in faces0:
            for k in range(3):
                edges[f[k], f[(k + 1) % 3]] = edges.get((f[k], f[(k + 1) % 3]), 0) + 1
        self.assertTrue(all(n == 1 and edges.get((b, a)) == 1 for (a, b), n in edges.items()))

    def test_the_wing_tips_travel(self):
        meshes = [read_obj(p)[0] for p in committed()]
        travel = max(max(m[i][2] for m in meshes) - min(m[i][2] for m in meshes) for i in range(len(meshes[0])))
        print(f"  wing tip travel {travel:.3f} units (in the mesh's own units)")
        self.assertGreaterEqual(travel, MIN_TIP_TRAVEL)

    def test_the_meshes_are_small(self):
        total = sum(os.path.getsize(p) for p in committed())
        print(f"  {len(committed())} meshes, {total} bytes")
        self.assertLess(total, MAX_BYTES)


def main():
    global ARGS
    parser = argparse.ArgumentParser()
    parser.add_argument("--source", required=True)
    parser.add_argument("--tmp", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == "__main__":
    main()
