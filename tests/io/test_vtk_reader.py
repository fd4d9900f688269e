#!/usr/bin/env python3
"""Reads `flockmorph export --format vtk` back with VTK itself (Debian's python3-vtk9, the
vtkXMLUnstructuredGridReader ParaView opens .vtu files with) and compares every value with the
cache as python/flockmorph_cache.py reads it, so neither our writer nor our checker
(tests/check_vtk.py) is the judge of the compressed layout.

Two caches: a tet cache from `flockmorph run` on examples/words cut short (13,818 tets, several
compressed blocks an array), and a point-flock cache from tests/cache_points (position, velocity,
orientation, id, phase). Per frame: the points and cells, agent_id / id, phase, the tets'
velocity (the central difference of the float centroids, one-sided at the first and last
frames, computed here with numpy) and the flock's velocity and orient (x, y, z, w) bit for bit.
A copy with one wrong block size must make VTK's reader report an error. Without VTK's Python
modules it prints SKIPPED and exits 77 (FM_WITH_VTK=1 tools/setup.sh installs them).

    test_vtk_reader.py --cli build/flockmorph --points build/tests/cache_points --tmp DIR --source REPO
"""
import argparse
import os
import shutil
import struct
import subprocess
import sys
import unittest

import numpy as np

try:
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkCommand, vtkOutputWindow, vtkStringOutputWindow
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
except ImportError:
    vtkXMLUnstructuredGridReader = None

SKIP = 77  # SKIP_RETURN_CODE in tests/CMakeLists.txt
POINT_AGENTS, POINT_FRAMES = 500, 12
VTK_VERTEX, VTK_TETRA = 1, 10
ARGS = None
fmc = None  # python/flockmorph_cache.py, imported from --source


def read_vtu(path):
    """The grid VTK reads from path, and the errors its reader reported."""
    errors = []
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.AddObserver(vtkCommand.ErrorEvent, lambda obj, event: errors.append(event))
    reader.Update()
    return reader.GetOutput(), errors


def array(data, name):
    a = data.GetArray(name)
    if a is None:
        raise AssertionError(f"no array {name}")
    return vtk_to_numpy(a)


def centroid_velocity(cache, k):
    """The exporter's documented tet velocity at frame k: the float centroids (the vertices summed
    in double, in order) differenced between k - 1 and k + 1, one-sided at the ends."""
    before, after = max(k - 1, 0), min(k + 1, cache.frames - 1)

    def centroids(f):
        v = cache.read(f, "tet_vertices").astype(np.float64)
        return (0.25 * (v[:, 0] + v[:, 1] + v[:, 2] + v[:, 3])).astype(np.float32)

    dt = (after - before) / cache.frame_rate
    return ((centroids(after).astype(np.float64) - centroids(before)) / dt).astype(np.float32)


class VtkReadsExports(unittest.TestCase):
    def assertBits(self, got, want, what):
        """float32 arrays equal bit for bit."""
        got, want = np.ascontiguousarray(got), np.ascontiguousarray(want)
        self.assertEqual((got.shape, got.dtype), (want.shape, want.dtype), what)
        self.assertTrue(np.array_equal(got.view(np.uint32), want.view(np.uint32)),
                        f"{what}: max difference {np.max(np.abs(got.astype(float) - want))}")

    def check_cells(self, grid, n, per_cell, cell_type):
        self.assertEqual(grid.GetNumberOfCells(), n)
        self.assertEqual(grid.GetNumberOfPoints(), per_cell * n)
        types = vtk_to_numpy(grid.GetCellTypesArray())
        self.assertTrue((types == cell_type).all())
        cells = grid.GetCells()
        self.assertTrue(np.array_equal(vtk_to_numpy(cells.GetConnectivityArray()), np.arange(per_cell * n)))
        self.assertTrue(np.array_equal(vtk_to_numpy(cells.GetOffsetsArray()), np.arange(0, per_cell * n + 1, per_cell)))

    def test_tets(self):
        with fmc.open(ARGS.tets) as cache:
            self.assertGreater(cache.agents * 48, 3 * 32768, "Points should span several blocks")
            for k in range(cache.frames):
                path = os.path.join(ARGS.tets_dir, f"frames_{k:05d}.vtu")
                grid, errors = read_vtu(path)
                self.assertEqual(errors, [], path)
                self.check_cells(grid, cache.agents, 4, VTK_TETRA)
                points = vtk_to_numpy(grid.GetPoints().GetData())
                self.assertBits(points, cache.read(k, "tet_vertices").reshape(-1, 3), f"{path}: points")
                cells = grid.GetCellData()
                self.assertEqual(sorted(cells.GetArrayName(i) for i in range(cells.GetNumberOfArrays())),
                                 sorted(["agent_id", "velocity"] + (["phase"] if "phase" in cache.attributes else [])))
                self.assertTrue(np.array_equal(array(cells, "agent_id"), np.arange(cache.agents)))
                # every point its own id, 4 x its tet's agent_id + the vertex
                data = grid.GetPointData()
                self.assertEqual([data.GetArrayName(i) for i in range(data.GetNumberOfArrays())], ["id"])
                self.assertTrue(np.array_equal(array(data, "id"), np.arange(4 * cache.agents)))
                self.assertBits(array(cells, "velocity"), centroid_velocity(cache, k), f"{path}: velocity")
                if "phase" in cache.attributes:
                    self.assertTrue(np.array_equal(array(cells, "phase"), cache.read(k, "phase")[:, 0]))

    def test_points(self):
        with fmc.open(ARGS.points_cache) as cache:
            for k in range(cache.frames):
                path = os.path.join(ARGS.points_dir, f"points_{k:05d}.vtu")
                grid, errors = read_vtu(path)
                self.assertEqual(errors, [], path)
                self.check_cells(grid, cache.agents, 1, VTK_VERTEX)
                self.assertBits(vtk_to_numpy(grid.GetPoints().GetData()), cache.read(k, "position"), f"{path}: points")
                data = grid.GetPointData()
                self.assertEqual(sorted(data.GetArrayName(i) for i in range(data.GetNumberOfArrays())),
                                 ["id", "orient", "phase", "velocity"])
                self.assertTrue(np.array_equal(array(data, "id"), cache.read(k, "id")[:, 0]))
                self.assertTrue(np.array_equal(array(data, "phase"), cache.read(k, "phase")[:, 0]))
                self.assertBits(array(data, "velocity"), cache.read(k, "velocity"), f"{path}: velocity")
                # Houdini's order x, y, z, w; the cache stores w, x, y, z
                self.assertBits(array(data, "orient"), cache.read(k, "orientation")[:, [1, 2, 3, 0]], f"{path}: orient")

    def test_wrong_block_size_is_refused(self):
        """The reader checks what we write: Points' header [blocks, 32768, last, sizes...] with a
        block size of 32767 makes it fail, so a wrong layout cannot pass the tests above."""
        good = os.path.join(ARGS.tets_dir, "frames_00000.vtu")
        bad = os.path.join(ARGS.tmp, "vtk_reader", "bad_block.vtu")
        with open(good, "rb") as f:
            raw = bytearray(f.read())
        at = raw.index(b'<AppendedData encoding="raw">')
        at = raw.index(b"_", at) + 1 + 8  # Points is the first array; its block size field
        self.assertEqual(struct.unpack_from("<Q", raw, at)[0], 32768)
        struct.pack_into("<Q", raw, at, 32767)
        with open(bad, "wb") as f:
            f.write(raw)
        log = vtkStringOutputWindow()  # the error is expected: VTK's messages go here, not to the log
        usual = vtkOutputWindow.GetInstance()
        vtkOutputWindow.SetInstance(log)
        try:
            _, errors = read_vtu(bad)
        finally:
            vtkOutputWindow.SetInstance(usual)
        self.assertTrue(errors, "VTK read a file with a wrong block size without an error")
        self.assertIn("Zlib error", log.GetOutput())


def run(*cmd):
    done = subprocess.run([str(c) for c in cmd], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))}: exit {done.returncode}\n{done.stdout}")


def main(argv):
    global ARGS, fmc
    p = argparse.ArgumentParser()
    for name in ("--cli", "--points", "--tmp", "--source"):
        p.add_argument(name, required=True)
    ARGS = p.parse_args(argv)
    if vtkXMLUnstructuredGridReader is None:
        print("SKIPPED: VTK's Python modules are not installed (FM_WITH_VTK=1 tools/setup.sh, or "
              "apt-get install python3-vtk9)")
        return SKIP
    sys.path.insert(0, os.path.join(ARGS.source, "python"))
    sys.path.insert(0, os.path.join(ARGS.source, "tests", "blender"))
    import flockmorph_cache as fmc
    from test_blender_import import tet_cache  # examples/words cut short, as the add-on's test
    work = os.path.join(ARGS.tmp, "vtk_reader")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    ARGS.tets = tet_cache(ARGS.cli, ARGS.source, work)
    ARGS.tets_dir = os.path.join(work, "tets_vtk")
    run(ARGS.cli, "export", ARGS.tets, "--format", "vtk", "-o", ARGS.tets_dir, "--quiet")
    ARGS.points_cache = os.path.join(work, "points.fmc")
    run(ARGS.points, ARGS.points_cache, POINT_AGENTS, POINT_FRAMES)
    ARGS.points_dir = os.path.join(work, "points_vtk")
    run(ARGS.cli, "export", ARGS.points_cache, "--format", "vtk", "-o", ARGS.points_dir, "--quiet")
    result = unittest.TextTestRunner(stream=sys.stdout, verbosity=2).run(
        unittest.defaultTestLoader.loadTestsFromTestCase(VtkReadsExports))
    return 0 if result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
