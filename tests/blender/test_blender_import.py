#!/usr/bin/env python3
"""Tests the Blender add-on (blender/flockmorph_import) in Debian's Blender 3.4, headless.

Run by ctest with the system python3, this script writes two caches: a tet cache from
`flockmorph run` on examples/words cut to 30 frames, and a point-flock cache from
tests/cache_points. It then starts

    blender -b --factory-startup --python-exit-code 1 --python THIS -- ARGS

in which the script installs the add-on from the packaged zip into a scratch user-scripts folder,
imports the caches with several options, sets scene frames, and compares the objects' evaluated
vertex positions and attributes with the frames python/flockmorph_cache.py reads (max abs
difference <= 1e-6 x the scene's size). It also checks the scene's frame range and frame rate,
Geometry Nodes instancing on the point flock's rotation attribute, a .blend saved and opened
again, a cache cut short, and the errors. It bakes an import to PC2 (the Mesh Cache modifier),
checks the samples against `flockmorph export -o FILE.pc2` byte for byte, moves the saved .blend
and its point cache to another folder, and evaluates two frames of it in a second Blender without
the add-on. It saves a .blend, moves it with its cache to another folder and reopens it: the
cache's path is a CacheFile's, relative (//), the positions are the reader's bit for bit, and
Blender's make_paths_absolute/relative and find_missing_files handle the path; a missing cache is
printed when the .blend opens and shown in the add-on's panel. Without blender on PATH it prints SKIPPED and exits 77.

    test_blender_import.py --cli build/flockmorph --points build/tests/cache_points \\
        --addon-zip build/flockmorph_import.zip --tmp DIR --source REPO
"""
import argparse
import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import time
import types
import unittest
import warnings
import zipfile

import numpy as np

try:
    import bpy
except ImportError:  # the outer run, in the system python3
    bpy = None

SKIP = 77  # SKIP_RETURN_CODE in tests/CMakeLists.txt
WORDS_FRAMES = 30
POINT_AGENTS, POINT_FRAMES = 40, 60
ADDON = "flockmorph_import"


def parse(argv):
    p = argparse.ArgumentParser()
    p.add_argument("--source", required=True)
    p.add_argument("--tmp", required=True)
    p.add_argument("--addon-zip", required=True)
    p.add_argument("--cli")
    p.add_argument("--points")
    p.add_argument("--tets-cache")
    p.add_argument("--points-cache")
    return p.parse_args(argv)


# ---------------------------------------------------------------- outer: caches, then Blender

def run(*cmd, **kw):
    done = subprocess.run([str(c) for c in cmd], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))}: exit {done.returncode}\n{done.stdout}")
    return done.stdout


def tet_cache(cli, source, work):
    """examples/words (13,818 tets) cut to its first 30 frames, while the letters take off."""
    words = os.path.join(source, "examples", "words")
    with open(os.path.join(words, "scene.json")) as f:
        scene = json.load(f)
    for shape in ("source", "target"):
        scene[shape]["mesh"] = os.path.join(words, scene[shape]["mesh"])
    scene["time"]["frame_limit"] = WORDS_FRAMES
    with open(os.path.join(work, "scene.json"), "w") as f:
        json.dump(scene, f)
    # The frame limit stops the run before the letters arrive, which the CLI reports as a warning.
    run(cli, "run", os.path.join(work, "scene.json"), "-o", os.path.join(work, "run"), "--quiet", "--threads", "1")
    return os.path.join(work, "run", "frames.fmc")


def check_zip(args):
    """The zip must hold the add-on's files and the reader exactly as they are in the source tree."""
    sources = {f"{ADDON}/flockmorph_cache.py": os.path.join(args.source, "python", "flockmorph_cache.py")}
    folder = os.path.join(args.source, "blender", ADDON)
    sources.update({f"{ADDON}/{n}": os.path.join(folder, n) for n in os.listdir(folder) if n.endswith(".py")})
    with zipfile.ZipFile(args.addon_zip) as z:
        packed = {n for n in z.namelist() if not n.endswith("/")}
        if packed != set(sources):
            raise SystemExit(f"{args.addon_zip} holds {sorted(packed)}, expected {sorted(sources)}")
        for name, path in sources.items():
            with open(path, "rb") as f:
                if z.read(name) != f.read():
                    raise SystemExit(f"{args.addon_zip}: {name} differs from {path}; rebuild it "
                                     "(cmake --build build --target blender_addon)")


def outer(args):
    blender = shutil.which("blender")
    if blender is None:
        print("SKIPPED: blender not installed (apt-get install blender)")
        return SKIP
    check_zip(args)
    work = os.path.join(args.tmp, "blender")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    tets = tet_cache(args.cli, args.source, work)
    points = os.path.join(work, "points.fmc")
    run(args.points, points, POINT_AGENTS, POINT_FRAMES)
    # A scratch user-scripts folder, so installing the add-on leaves ~/.config alone.
    env = dict(os.environ, BLENDER_USER_SCRIPTS=os.path.join(work, "scripts"))
    cmd = [blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python", os.path.abspath(__file__),
           "--", "--source", args.source, "--tmp", work, "--addon-zip", args.addon_zip,
           "--tets-cache", tets, "--points-cache", points, "--cli", args.cli]
    t0 = time.monotonic()
    done = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    print(done.stdout)
    print(f"blender: exit {done.returncode} after {time.monotonic() - t0:.1f} s")
    return 0 if done.returncode == 0 else 1


# ---------------------------------------------------------------- inner: in Blender

ARGS = None
fmc = None  # the reference reader, python/flockmorph_cache.py


def reset_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for mesh in list(bpy.data.meshes):
        bpy.data.meshes.remove(mesh)
    bpy.data.batch_remove(list(bpy.data.cache_files))
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end, scene.frame_current = 1, 250, 1
    scene.render.fps, scene.render.fps_base = 24, 1.0


def import_cache(path, **options):
    before = set(bpy.data.objects)
    bpy.ops.import_scene.flockmorph(filepath=path, **options)
    added = set(bpy.data.objects) - before
    assert len(added) == 1, f"the import added {len(added)} objects"
    return added.pop()


def evaluated(obj):
    """The evaluated mesh of obj (after modifiers); callers must not keep it past the next frame."""
    return obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data


def positions(mesh):
    co = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def attribute(mesh, name, key, width, dtype=np.float32):
    values = np.empty(len(mesh.vertices) * width, dtype=dtype)
    mesh.attributes[name].data.foreach_get(key, values)
    return values.reshape(len(mesh.vertices), width)


def scene_size(cache):
    lo, hi = cache.bounds()
    return float(np.max(hi - lo))


class BlenderBase(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        with fmc.open(ARGS.tets_cache) as tets:
            cls.tol = 1e-6 * scene_size(tets)

    def setUp(self):
        reset_scene()
        self.tets = fmc.open(ARGS.tets_cache)
        self.points = fmc.open(ARGS.points_cache)
        self.addCleanup(self.tets.close)
        self.addCleanup(self.points.close)

    def moving_frame(self):
        """A cache frame whose neighbours differ from it by far more than the tolerance, so a
        frame-mapping error cannot pass."""
        k = self.tets.frames // 3
        for j in (k - 1, k + 1):
            self.assertGreater(np.abs(self.tets.read(j, "tet_vertices") - self.tets.read(k, "tet_vertices")).max(),
                               1000 * self.tol)
        return k

    def assert_positions(self, obj, scene_frame, want, scale=1.0):
        bpy.context.scene.frame_set(scene_frame)
        got = positions(evaluated(obj))
        self.assertEqual(got.shape, want.shape)
        np.testing.assert_allclose(got, want * scale, rtol=0, atol=self.tol * max(scale, 1.0),
                                   err_msg=f"scene frame {scene_frame}")

    def assert_fps(self, rate):
        r = bpy.context.scene.render
        self.assertAlmostEqual(r.fps / r.fps_base, rate, places=5)



class BlenderCase(BlenderBase):
    def test_addon_installed_from_the_zip(self):
        import flockmorph_import
        installed = os.path.join(os.environ["BLENDER_USER_SCRIPTS"], "addons", ADDON)
        self.assertEqual(os.path.dirname(flockmorph_import.__file__), installed)
        self.assertEqual(os.path.dirname(flockmorph_import.importer.fmc.__file__), installed)
        self.assertIn("flockmorph", dir(bpy.ops.import_scene))
        drawn = getattr(bpy.types.TOPBAR_MT_file_import.draw, "_draw_funcs", [])
        self.assertIn(flockmorph_import.menu_func_import, drawn)

    def test_tet_mesh_follows_the_cache(self):
        c = self.tets
        obj = import_cache(ARGS.tets_cache, set_scene=True)
        scene = bpy.context.scene
        self.assertEqual((scene.frame_start, scene.frame_end), (1, c.frames))
        self.assert_fps(c.frame_rate)
        mesh = obj.data
        self.assertEqual((len(mesh.vertices), len(mesh.polygons)), (4 * c.agents, 4 * c.agents))
        corners = np.empty(12 * c.agents, dtype=np.int32)
        mesh.polygons.foreach_get("vertices", corners)
        tet = np.array([0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3])
        np.testing.assert_array_equal(corners.reshape(c.agents, 12), tet + 4 * np.arange(c.agents)[:, None])
        k = self.moving_frame()
        for scene_frame, frame in ((1 + k, k), (c.frames, c.frames - 1), (1, 0), (c.frames + 5, c.frames - 1),
                                   (-3, 0), (k, k - 1)):
            self.assert_positions(obj, scene_frame, c.read(frame, "tet_vertices").reshape(-1, 3))
        scene.frame_set(1 + k)
        phase = attribute(evaluated(obj), "phase", "value", 1, np.int32)
        np.testing.assert_array_equal(phase[:, 0], np.repeat(c.read(k, "phase")[:, 0], 4))
        ids = attribute(evaluated(obj), "id", "value", 1, np.int32)  # a tet's id on its four vertices
        np.testing.assert_array_equal(ids[:, 0], np.repeat(c.read(k, "id")[:, 0], 4))
        self.assertEqual(ids[-1, 0], c.agents - 1)

    def test_frame_range_step_start_and_scale(self):
        c = self.tets
        first, last, step, start, scale = 3, c.frames - 2, 5, 10, 0.3
        obj = import_cache(ARGS.tets_cache, frame_first=first, frame_last=last, frame_step=step,
                           start_frame=start, scale=scale, set_scene=True)
        shown = (last - first) // step  # scene frames after the start
        scene = bpy.context.scene
        self.assertEqual((scene.frame_start, scene.frame_end), (start, start + shown))
        self.assert_fps(c.frame_rate / step)
        for scene_frame, frame in ((start, first), (start + 2, first + 2 * step), (start - 4, first),
                                   (start + shown, first + shown * step), (start + shown + 3, first + shown * step)):
            self.assert_positions(obj, scene_frame, c.read(frame, "tet_vertices").reshape(-1, 3), scale)

    def test_tets_as_a_point_cloud_of_centroids(self):
        c = self.tets
        obj = import_cache(ARGS.tets_cache, mode="POINTS")
        self.assertEqual((len(obj.data.vertices), len(obj.data.polygons)), (c.agents, 0))
        k = self.moving_frame()
        self.assert_positions(obj, 1 + k, c.read(k, "tet_vertices").astype(np.float64).sum(axis=1) / 4)

    def test_point_flock_with_attributes(self):
        c = self.points
        scale = 2.0
        obj = import_cache(ARGS.points_cache, scale=scale, set_scene=True)
        self.assertEqual((len(obj.data.vertices), len(obj.data.polygons)), (c.agents, 0))
        self.assertEqual((bpy.context.scene.frame_start, bpy.context.scene.frame_end), (1, c.frames))
        self.assert_fps(c.frame_rate)
        from mathutils import Euler, Quaternion
        for k in (0, 17, c.frames - 1):
            self.assert_positions(obj, 1 + k, c.read(k, "position"), scale)
            mesh = evaluated(obj)
            np.testing.assert_allclose(attribute(mesh, "velocity", "vector", 3), c.read(k, "velocity") * scale,
                                       rtol=1e-6, atol=0)
            q = c.read(k, "orientation")
            np.testing.assert_array_equal(attribute(mesh, "orientation", "color", 4), q)
            np.testing.assert_array_equal(attribute(mesh, "id", "value", 1, np.int32), c.read(k, "id"))
            np.testing.assert_array_equal(attribute(mesh, "phase", "value", 1, np.int32), c.read(k, "phase"))
            rotation = attribute(mesh, "rotation", "vector", 3)
            for a in range(c.agents):  # the Euler angles make the quaternion's rotation
                got, want = Euler(rotation[a], "XYZ").to_matrix(), Quaternion(q[a]).to_matrix()
                self.assertLess(max(abs(got[i][j] - want[i][j]) for i in range(3) for j in range(3)), 1e-5,
                                f"frame {k} agent {a}")

    def test_geometry_nodes_instances_along_the_velocity(self):
        """docs/blender.md's recipe: Instance on Points with Rotation from the rotation attribute.
        The instance is a two-vertex line along +x, which the orientation turns along the
        velocity."""
        c = self.points
        obj = import_cache(ARGS.points_cache)
        tree = bpy.data.node_groups.new("flock birds", "GeometryNodeTree")
        tree.inputs.new("NodeSocketGeometry", "Geometry")
        tree.outputs.new("NodeSocketGeometry", "Geometry")
        group_in, group_out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
        line = tree.nodes.new("GeometryNodeMeshLine")
        line.inputs["Count"].default_value = 2
        line.inputs["Offset"].default_value = (1.0, 0.0, 0.0)
        rotation = tree.nodes.new("GeometryNodeInputNamedAttribute")
        rotation.data_type = "FLOAT_VECTOR"
        rotation.inputs["Name"].default_value = "rotation"
        instance, realize = tree.nodes.new("GeometryNodeInstanceOnPoints"), tree.nodes.new("GeometryNodeRealizeInstances")
        tree.links.new(group_in.outputs["Geometry"], instance.inputs["Points"])
        tree.links.new(line.outputs["Mesh"], instance.inputs["Instance"])
        tree.links.new(rotation.outputs["Attribute"], instance.inputs["Rotation"])
        tree.links.new(instance.outputs["Instances"], realize.inputs["Geometry"])
        tree.links.new(realize.outputs["Geometry"], group_out.inputs["Geometry"])
        obj.modifiers.new("birds", "NODES").node_group = tree
        k = 23
        bpy.context.scene.frame_set(1 + k)
        got = positions(evaluated(obj)).reshape(c.agents, 2, 3)
        velocity = c.read(k, "velocity")
        np.testing.assert_allclose(got[:, 0], c.read(k, "position"), atol=self.tol, rtol=0)
        np.testing.assert_allclose(got[:, 1] - got[:, 0], velocity / np.linalg.norm(velocity, axis=1, keepdims=True),
                                   atol=1e-5, rtol=0)

    def test_saved_blend_animates_after_opening(self):
        c = self.tets
        import_cache(ARGS.tets_cache)
        k = self.moving_frame()
        path = os.path.join(ARGS.tmp, "saved.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path)
        bpy.ops.wm.open_mainfile(filepath=path)
        (obj,) = [o for o in bpy.data.objects if "flockmorph" in o.data]
        self.assert_positions(obj, 1 + k, c.read(k, "tet_vertices").reshape(-1, 3))

    def test_import_leaves_the_scene_range_unless_asked(self):
        """A second import (here any import with the defaults) keeps the scene's range and rate;
        Set Scene Frames and FPS sets them."""
        scene = bpy.context.scene
        scene.frame_start, scene.frame_end, scene.render.fps = 7, 99, 25
        import_cache(ARGS.tets_cache, frame_step=2)
        import_cache(ARGS.points_cache)
        self.assertEqual((scene.frame_start, scene.frame_end, scene.render.fps, scene.render.fps_base), (7, 99, 25, 1.0))
        import_cache(ARGS.points_cache, start_frame=3, set_scene=True)
        self.assertEqual((scene.frame_start, scene.frame_end), (3, 3 + self.points.frames - 1))
        self.assert_fps(self.points.frame_rate)

    def test_cache_cut_short_imports_its_complete_frames(self):
        cut = os.path.join(ARGS.tmp, "cut.fmc")
        with open(ARGS.tets_cache, "rb") as f:
            data = f.read()
        with open(cut, "wb") as f:
            f.write(data[:len(data) * 2 // 3])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            c = fmc.open(cut)
            self.addCleanup(c.close)
            obj = import_cache(cut, set_scene=True)
        self.assertFalse(c.complete)
        self.assertGreater(c.frames, 1)
        self.assertEqual(bpy.context.scene.frame_end, c.frames)
        self.assert_positions(obj, c.frames + 10, c.read(-1, "tet_vertices").reshape(-1, 3))

    def test_a_cache_replaced_on_disk_is_reopened(self):
        """The handler notices the new file and, as its agent count no longer matches, leaves the
        mesh as it was (a message, not an exception)."""
        copy = os.path.join(ARGS.tmp, "replaced.fmc")
        shutil.copyfile(ARGS.tets_cache, copy)
        obj = import_cache(copy)
        k = self.moving_frame()
        self.assert_positions(obj, 1 + k, self.tets.read(k, "tet_vertices").reshape(-1, 3))
        shutil.copyfile(ARGS.points_cache, copy)
        self.assert_positions(obj, 2 + k, self.tets.read(k, "tet_vertices").reshape(-1, 3))

    def test_errors_name_the_problem_and_add_nothing(self):
        not_a_cache = os.path.join(ARGS.tmp, "scene.json")
        cases = [
            (ARGS.points_cache, {"mode": "MESH"}, "no tet_vertices"),
            (not_a_cache, {}, "not a flockmorph cache"),
            (os.path.join(ARGS.tmp, "missing.fmc"), {}, "cannot open"),
            (ARGS.tets_cache, {"frame_first": self.tets.frames}, "is not within the cache's"),
            (ARGS.tets_cache, {"frame_first": 5, "frame_last": 4}, "is not within the cache's"),
        ]
        for path, options, message in cases:
            with self.assertRaises(RuntimeError, msg=f"{path} {options}") as caught:
                bpy.ops.import_scene.flockmorph(filepath=path, **options)
            self.assertIn(message, str(caught.exception))
            self.assertEqual(len(bpy.data.objects), 0)


# Run by a second Blender on the moved .blend, without the add-on: the evaluated vertex positions
# of the scene frames given, saved as .npy, and what add-ons and frame handlers that Blender has.
NO_ADDON_SCRIPT = """
import json, sys
import bpy, numpy as np
out, name, frames = sys.argv[-3], sys.argv[-2], [int(f) for f in sys.argv[-1].split(",")]
obj = bpy.data.objects[name]
for f in frames:
    bpy.context.scene.frame_set(f)
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    co = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    np.save(f"{out}/frame_{f}.npy", co.reshape(-1, 3))
with open(f"{out}/blender.json", "w") as fp:
    json.dump({"addons": list(bpy.context.preferences.addons.keys()),
               "handlers": [h.__name__ for h in bpy.app.handlers.frame_change_pre],
               "modifiers": [(m.type, m.filepath) for m in obj.modifiers]}, fp)
"""


class BakeCase(BlenderBase):
    def test_bake_matches_the_cli_pc2(self):
        """A default import baked by the add-on holds the bytes `flockmorph export -o FILE.pc2`
        writes; only the start frame differs (scene frame 1 against cache frame 0)."""
        obj = import_cache(ARGS.tets_cache)
        blend = os.path.join(ARGS.tmp, "bake_cli", "scene.blend")
        os.makedirs(os.path.dirname(blend), exist_ok=True)
        bpy.ops.wm.save_as_mainfile(filepath=blend)
        baked = importer().bake_pc2(obj, "//baked.pc2")
        cli_pc2 = os.path.join(ARGS.tmp, "bake_cli", "cli.pc2")
        subprocess.run([ARGS.cli, "export", ARGS.tets_cache, "-o", cli_pc2, "--quiet"], check=True,
                       stdout=subprocess.DEVNULL)
        with open(baked, "rb") as f:
            ours = f.read()
        with open(cli_pc2, "rb") as f:
            theirs = f.read()
        self.assertEqual(ours[:20], theirs[:20])  # signature, version, points
        self.assertEqual(np.frombuffer(ours[20:24], "<f4")[0], 1.0)
        self.assertEqual(np.frombuffer(theirs[20:24], "<f4")[0], 0.0)
        self.assertEqual(ours[24:], theirs[24:])

    def test_pc2_import_animates_without_the_addon(self):
        """The import mode Animate With: Mesh Cache Modifier writes //<object>.pc2 beside the saved
        .blend; moved with it, the .blend animates in a Blender without the add-on."""
        c = self.tets
        first, step, start = 2, 3, 5
        last = first + (c.frames - 1 - first) // step * step
        work, moved = os.path.join(ARGS.tmp, "bake"), os.path.join(ARGS.tmp, "bake_moved")
        for d in (work, moved):
            shutil.rmtree(d, ignore_errors=True)
        os.makedirs(work)
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(work, "scene.blend"))
        obj = import_cache(ARGS.tets_cache, frame_first=first, frame_step=step, start_frame=start, animate="PC2")
        self.assertTrue(os.path.isfile(os.path.join(work, f"{obj.name}.pc2")))
        mod = obj.modifiers["flockmorph PC2"]
        self.assertEqual((mod.type, mod.cache_format), ("MESH_CACHE", "PC2"))
        self.assertTrue(mod.filepath.startswith("//"), mod.filepath)
        bpy.ops.wm.save_mainfile()
        shutil.copytree(work, moved)
        shutil.rmtree(work)  # only the // path can find the copy
        frames = {start: first, start + 1: first + step, start + 4: first + 4 * step,
                  start + (last - first) // step + 3: last}
        scripts = os.path.join(ARGS.tmp, "no_addon_scripts")
        os.makedirs(scripts, exist_ok=True)
        env = dict(os.environ, BLENDER_USER_SCRIPTS=scripts)
        done = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", os.path.join(moved, "scene.blend"),
                               "--python-exit-code", "1", "--python-expr", NO_ADDON_SCRIPT, "--", moved, obj.name,
                               ",".join(map(str, frames))], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
        self.assertEqual(done.returncode, 0, done.stdout)
        with open(os.path.join(moved, "blender.json")) as f:
            seen = json.load(f)
        self.assertNotIn(ADDON, seen["addons"])
        self.assertNotIn("on_frame_change", seen["handlers"])
        self.assertEqual(seen["modifiers"], [["MESH_CACHE", mod.filepath]])
        got = {f: np.load(os.path.join(moved, f"frame_{f}.npy")) for f in frames}
        a, b = got[start], got[start + 1]
        self.assertGreater(np.abs(a - b).max(), 1000 * self.tol, "two frames of the saved file do not differ")
        for f, k in frames.items():
            np.testing.assert_allclose(got[f], c.read(k, "tet_vertices").reshape(-1, 3), rtol=0, atol=self.tol,
                                       err_msg=f"scene frame {f} (cache frame {k}) without the add-on")

    def test_bake_needs_a_saved_blend(self):
        bpy.ops.wm.read_homefile(use_empty=True)
        self.assertEqual(bpy.data.filepath, "")
        with self.assertRaises(RuntimeError) as caught:
            bpy.ops.import_scene.flockmorph(filepath=ARGS.points_cache, animate="PC2")
        self.assertIn("save the .blend first", str(caught.exception))
        self.assertEqual(len(bpy.data.objects), 0)
        obj = import_cache(ARGS.points_cache)
        with self.assertRaises(RuntimeError) as caught:
            bpy.ops.object.flockmorph_bake_pc2()
        self.assertIn("save the .blend first", str(caught.exception))
        self.assertEqual(len(obj.modifiers), 0)


class Recorder:
    """Stands in for a panel's UILayout: keeps the labels drawn and whether they were drawn alert."""
    def __init__(self, labels=None):
        self.labels = [] if labels is None else labels
        self.alert = False

    def label(self, text="", icon="NONE"):
        self.labels.append((text, icon, self.alert))

    def prop(self, *_args, **_kw):
        pass

    def column(self, **_kw):
        return Recorder(self.labels)


class RelocateCase(BlenderBase):
    """The cache's path is a CacheFile's: relative to the saved .blend, and Blender's own path
    tools (File > External Data) see it, make it absolute or relative, report and find it."""

    def setUp(self):
        super().setUp()
        bpy.ops.wm.read_homefile(use_empty=True)
        self.root = os.path.join(ARGS.tmp, "relocate")
        shutil.rmtree(self.root, ignore_errors=True)
        self.project = os.path.join(self.root, "shot")
        os.makedirs(os.path.join(self.project, "caches"))
        self.cache = os.path.join(self.project, "caches", "frames.fmc")
        shutil.copyfile(ARGS.tets_cache, self.cache)

    def flock_object(self):
        (obj,) = [o for o in bpy.data.objects if "flockmorph" in o.data]
        return obj

    def assert_bit_identical(self, obj, scene_frame, k):
        bpy.context.scene.frame_set(scene_frame)
        np.testing.assert_array_equal(positions(evaluated(obj)), self.tets.read(k, "tet_vertices").reshape(-1, 3),
                                      err_msg=f"scene frame {scene_frame}")

    def panel_labels(self, obj):
        import flockmorph_import
        recorder = Recorder()
        flockmorph_import.DATA_PT_flockmorph.draw(types.SimpleNamespace(layout=recorder),
                                                  types.SimpleNamespace(object=obj))
        return recorder.labels

    def test_moved_with_its_cache_and_fixed_by_blenders_path_tools(self):
        obj = import_cache(self.cache)
        linked = obj.data["flockmorph_cache"]
        self.assertIsInstance(linked, bpy.types.CacheFile)
        self.assertEqual(linked.filepath, self.cache)  # absolute until the .blend is saved
        self.assertNotIn("cache", obj.data["flockmorph"].keys())
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(self.project, "shot.blend"))
        self.assertEqual(linked.filepath, "//caches/frames.fmc")
        moved = os.path.join(self.root, "moved")
        os.rename(self.project, moved)  # the .blend and its cache together; the old folder is gone
        bpy.ops.wm.open_mainfile(filepath=os.path.join(moved, "shot.blend"))
        obj, k = self.flock_object(), self.moving_frame()
        linked = obj.data["flockmorph_cache"]
        self.assertEqual(linked.filepath, "//caches/frames.fmc")
        self.assert_bit_identical(obj, 1 + k, k)
        self.assertEqual([t for t, icon, alert in self.panel_labels(obj) if alert], [])

        bpy.ops.file.make_paths_absolute()
        self.assertEqual(linked.filepath, os.path.join(moved, "caches", "frames.fmc"))
        self.assert_bit_identical(obj, 3 + k, 2 + k)
        bpy.ops.file.make_paths_relative()
        self.assertEqual(linked.filepath, "//caches/frames.fmc")

        # The cache moves on its own: the panel says so, then Find Missing Files finds it.
        elsewhere = os.path.join(moved, "elsewhere", "deep")
        os.makedirs(elsewhere)
        os.rename(os.path.join(moved, "caches", "frames.fmc"), os.path.join(elsewhere, "frames.fmc"))
        bpy.context.scene.frame_set(5)
        alerts = [(t, icon) for t, icon, alert in self.panel_labels(obj) if alert]
        self.assertEqual(len(alerts), 1, alerts)
        self.assertIn(f"cache missing: {os.path.join(moved, 'caches', 'frames.fmc')}", alerts[0][0])
        self.assertEqual(alerts[0][1], "ERROR")
        bpy.ops.file.find_missing_files(directory=moved)
        self.assertEqual(linked.filepath, "//elsewhere/deep/frames.fmc")
        self.assertEqual([t for t, icon, alert in self.panel_labels(obj) if alert], [])
        self.assert_bit_identical(obj, 2 + k, 1 + k)

    def test_a_saved_blend_stores_the_path_relative_at_import(self):
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(self.project, "shot.blend"))
        a, b = import_cache(self.cache), import_cache(self.cache, mode="POINTS")
        self.assertEqual(a.data["flockmorph_cache"].filepath, "//caches/frames.fmc")
        self.assertEqual(a.data["flockmorph_cache"], b.data["flockmorph_cache"])  # one CacheFile a cache
        self.assertEqual(len(bpy.data.cache_files), 1)

    def test_a_missing_cache_is_reported_when_the_blend_opens(self):
        """Opening a .blend whose cache is gone prints the path at once (the add-on's load
        handler), and the panel says so before any frame changes."""
        import_cache(self.cache)
        blend = os.path.join(self.project, "shot.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend)
        os.remove(self.cache)
        importer()._reported.clear()
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            bpy.ops.wm.open_mainfile(filepath=blend)
        self.assertIn(f"caches_frames: cache missing: {self.cache}", printed.getvalue())
        alerts = [t for t, icon, alert in self.panel_labels(self.flock_object()) if alert]
        self.assertEqual(len(alerts), 1, alerts)
        self.assertIn(f"cache missing: {self.cache}", alerts[0])

    def test_a_blend_from_before_the_cache_file_still_animates(self):
        """An import of an older add-on kept the absolute path in the settings."""
        obj = import_cache(self.cache)
        del obj.data["flockmorph_cache"]
        obj.data["flockmorph"]["cache"] = self.cache
        k = self.moving_frame()
        self.assert_bit_identical(obj, 1 + k, k)


def importer():
    import flockmorph_import.importer
    return flockmorph_import.importer


def inner(args):
    global ARGS, fmc
    ARGS = args
    sys.path.insert(0, os.path.join(args.source, "python"))
    import flockmorph_cache
    fmc = flockmorph_cache
    import addon_utils
    bpy.ops.preferences.addon_install(filepath=args.addon_zip, overwrite=True)
    if addon_utils.enable(ADDON, default_set=True) is None:
        print(f"cannot enable the add-on {ADDON} installed from {args.addon_zip}")
        return 1
    result = unittest.TextTestRunner(stream=sys.stdout, verbosity=2).run(
        unittest.TestSuite([unittest.defaultTestLoader.loadTestsFromTestCase(BlenderCase),
                            unittest.defaultTestLoader.loadTestsFromTestCase(BakeCase),
                            unittest.defaultTestLoader.loadTestsFromTestCase(RelocateCase)]))
    return 0 if result.wasSuccessful() else 1


if __name__ == "__main__":
    if bpy is None:
        sys.exit(outer(parse(sys.argv[1:])))
    sys.exit(inner(parse(sys.argv[sys.argv.index("--") + 1:])))
