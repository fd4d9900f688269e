"""Turns a flockmorph cache (.fmc, docs/cache-format.md) into a Blender object and animates it.

How the animation works, and why: the object's mesh keeps its topology, and a frame-change
handler (`on_frame_change`, registered by the add-on) writes the positions of the scene's frame
into it, read from the cache on demand. The cache has an index and per-frame chunks, so any frame
is a random access that decodes one chunk (at most `key_interval` with delta encoding), and
reading frames in order decodes one chunk each. Memory stays at one frame whatever the cache's
length, and the file on disk stays the only copy of the animation. Shape keys baked per frame
were the alternative: they need no add-on at render time, but they hold every frame in the .blend
(48 bytes per tet and frame: 200 MB for 13,818 tets over 300 frames), and they cannot animate the
velocity and orientation attributes that point flocks carry.

The settings an object was imported with live on its mesh as the custom property "flockmorph",
so a saved .blend animates again when it is opened with the add-on enabled. The cache's path does
not: it lives in a CacheFile datablock (the mesh's ID property "flockmorph_cache" points at it).
Blender's path walker (bpath) visits every CacheFile's `filepath`, so Blender's own tools see and
fix it: saving a .blend for the first time makes it relative (`//`), File > External Data's Make
Paths Relative/Absolute, Report Missing Files and Find Missing Files act on it, and a .blend moved
with its cache finds it. A CacheFile opens a file only when its name ends in .abc or .usd*, so an
.fmc in one costs nothing. (An Image or Text datablock would be visited too, but Blender would try
to load the .fmc as an image or as text; a Mesh Cache modifier only reads MDD and PC2.)
"""
import importlib.util
import os
from pathlib import Path

import bpy
import numpy as np


def _load_reader():
    """flockmorph_cache: the copy packaged next to this file (build/flockmorph_import.zip), or in
    a source checkout the one source of truth, python/flockmorph_cache.py."""
    try:
        from . import flockmorph_cache
        return flockmorph_cache
    except ImportError:
        pass
    source = Path(__file__).resolve().parents[2] / "python" / "flockmorph_cache.py"
    if not source.is_file():
        raise ImportError("flockmorph_cache.py is missing: install the add-on from build/flockmorph_import.zip "
                          "(docs/blender.md)")
    spec = importlib.util.spec_from_file_location("flockmorph_cache", source)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


fmc = _load_reader()

SETTINGS = "flockmorph"  # the mesh's custom property
CACHE_LINK = "flockmorph_cache"  # the mesh's ID property: the CacheFile datablock holding the cache's path
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)  # outward, docs/cache-format.md
MODES = ("AUTO", "MESH", "POINTS")


class ImportFailed(ValueError):
    """A cache that cannot be imported with the options given; the message says why."""


# ---------------------------------------------------------------- open caches

_open_caches = {}  # absolute path -> ((mtime_ns, size), flockmorph_cache.Cache)


def open_cache(path):
    """The open cache at `path`, reopened when the file changed on disk (a new run)."""
    try:
        st = os.stat(path)
    except OSError as e:
        raise ImportFailed(f"{path}: cannot open: {e.strerror}") from None
    stamp = (st.st_mtime_ns, st.st_size)
    held = _open_caches.get(path)
    if held and held[0] == stamp:
        return held[1]
    if held:
        held[1].close()
        del _open_caches[path]
    cache = fmc.open(path)
    _open_caches[path] = (stamp, cache)
    return cache


def close_caches():
    for _, cache in _open_caches.values():
        cache.close()
    _open_caches.clear()


# ---------------------------------------------------------------- the cache's path, in a CacheFile

def cache_file_of(mesh):
    """The CacheFile datablock naming the mesh's cache, or None (a .blend from before the
    CacheFile, whose settings hold the absolute path as "cache")."""
    linked = mesh.get(CACHE_LINK)
    return linked if isinstance(linked, bpy.types.CacheFile) else None


def cache_path(mesh):
    """The absolute path of the mesh's cache: its CacheFile's path resolved against the .blend
    (or the library the CacheFile comes from), or the path a pre-CacheFile import stored."""
    linked = cache_file_of(mesh)
    if linked is None:
        return mesh[SETTINGS]["cache"]
    return os.path.normpath(bpy.path.abspath(linked.filepath, library=linked.library))


def stored_path(path):
    """`path` as the CacheFile keeps it: relative (`//`) to a saved .blend when the preference
    File Paths > Default > Relative Paths is on (Blender's default), else absolute. An unsaved
    .blend keeps it absolute until its first save, which makes every path relative."""
    if bpy.data.filepath and bpy.context.preferences.filepaths.use_relative_paths:
        try:
            return bpy.path.relpath(path)
        except ValueError:  # another drive (Windows): no relative path exists
            pass
    return path


def link_cache_file(mesh, path, name):
    """Points the mesh at a CacheFile for the cache at absolute `path`: an existing one naming the
    same file, or a new one named `name`."""
    for linked in bpy.data.cache_files:
        if linked.library is None and os.path.normpath(bpy.path.abspath(linked.filepath)) == path:
            break
    else:
        before = set(bpy.data.cache_files)
        bpy.ops.cachefile.open(filepath=stored_path(path))  # bpy.data.cache_files has no new()
        (linked,) = set(bpy.data.cache_files) - before
        linked.name = name
        linked.user_clear()  # the operator counted a user for a UI slot it had not; the mesh is the user
    mesh[CACHE_LINK] = linked


# mesh name -> (path, file stamp, message): the last error the frame handler met for the mesh,
# which holds while the mesh names the same file, unchanged (a good frame clears it)
_errors = {}


def file_stamp(path):
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_mtime_ns, st.st_size


def note_error(mesh, message):
    path = cache_path(mesh)
    _errors[mesh.name_full] = (path, file_stamp(path), message)


def cache_status(mesh):
    """None when the mesh's cache can be read, else what is wrong, for the panel and the console."""
    path = cache_path(mesh)
    stamp = file_stamp(path)
    if stamp is None:
        return f"cache missing: {path} (File > External Data > Find Missing Files, or set the path here)"
    error = _errors.get(mesh.name_full)
    return error[2] if error and error[:2] == (path, stamp) else None


# ---------------------------------------------------------------- frames and geometry

def cache_frame(settings, scene_frame):
    """The cache frame shown at `scene_frame`: `first` at scene frame `start`, then one cache
    frame every `step`, held at the ends of the range."""
    k = settings["first"] + (scene_frame - settings["start"]) * settings["step"]
    return min(max(k, settings["first"]), settings["last"])


def agent_points(cache, k):
    """One point per agent at frame k: the `position` attribute, or the tet's centroid."""
    if "position" in cache.attributes:
        return cache.read(k, "position")
    v = cache.read(k, "tet_vertices")
    return (v[:, 0].astype(np.float64) + v[:, 1] + v[:, 2] + v[:, 3]) * 0.25  # 6x faster than mean(axis=1)


def vertex_positions(cache, k, mode):
    if mode == "MESH":
        return cache.read(k, "tet_vertices").reshape(-1, 3)
    return agent_points(cache, k)


def euler_xyz(quaternions):
    """Blender's XYZ Euler angles (R = Rz·Ry·Rx) of quaternions (w, x, y, z), shape (n, 3): the
    Rotation input of Geometry Nodes' Instance on Points in Blender 3.4, which has no quaternion
    type. A zero quaternion gives no rotation."""
    q = np.asarray(quaternions, dtype=np.float64)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norm > 0, q / np.where(norm > 0, norm, 1), [1.0, 0.0, 0.0, 0.0])
    w, x, y, z = q.T
    r00, r01 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z)
    r10, r11 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z)
    r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    cos_y = np.hypot(r00, r10)
    locked = cos_y < 1e-6  # Y = ±90°: only X − Z (or X + Z) is defined; take Z = 0
    ex = np.where(locked, np.arctan2(-r20 * r01, r11), np.arctan2(r21, r22))
    ey = np.arctan2(-r20, cos_y)
    ez = np.where(locked, 0.0, np.arctan2(r10, r00))
    return np.stack([ex, ey, ez], axis=1)


def agent_attributes(cache, k, scale):
    """The mesh attributes of frame k, one row per agent: {name: (type, foreach key, values)}."""
    out = {}
    names = cache.attributes
    if "velocity" in names:
        out["velocity"] = ("FLOAT_VECTOR", "vector", cache.read(k, "velocity") * scale)
    if "orientation" in names:
        q = cache.read(k, "orientation")
        out["orientation"] = ("FLOAT_COLOR", "color", q)  # w, x, y, z in the colour's r, g, b, a
        out["rotation"] = ("FLOAT_VECTOR", "vector", euler_xyz(q))
    for name in ("id", "phase", "group"):
        if name in names:
            out[name] = ("INT", "value", cache.read(k, name).astype(np.int32))
    return out


def build_topology(mesh, agents, mode):
    """Four vertices and four outward triangles per agent (MESH), or one vertex (POINTS)."""
    if mode == "POINTS":
        mesh.vertices.add(agents)
        return
    corners = (TET_FACES[None, :, :] + 4 * np.arange(agents, dtype=np.int32)[:, None, None]).reshape(-1)
    faces = 4 * agents
    mesh.vertices.add(4 * agents)
    mesh.loops.add(corners.size)
    mesh.polygons.add(faces)
    mesh.loops.foreach_set("vertex_index", corners)
    mesh.polygons.foreach_set("loop_start", np.arange(0, corners.size, 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(faces, 3, dtype=np.int32))
    mesh.update(calc_edges=True)


def load_frame(mesh, scene_frame):
    """Writes the cache frame shown at `scene_frame` into the mesh: positions and attributes."""
    settings = mesh[SETTINGS]
    cache = open_cache(cache_path(mesh))
    mode, scale = settings["mode"], settings["scale"]
    per_agent = 4 if mode == "MESH" else 1
    if cache.agents * per_agent != len(mesh.vertices):
        raise ImportFailed(f"{cache.path}: the cache now has {cache.agents} agents, the object was imported "
                           f"with {len(mesh.vertices) // per_agent}; import it again")
    k = cache_frame(settings, scene_frame)
    xyz = vertex_positions(cache, k, mode) * scale
    mesh.vertices.foreach_set("co", np.ascontiguousarray(xyz, dtype=np.float32).reshape(-1))
    for name, (kind, key, values) in agent_attributes(cache, k, scale).items():
        attr = mesh.attributes.get(name)
        if attr is None:
            attr = mesh.attributes.new(name, kind, "POINT")
        values = np.repeat(values, per_agent, axis=0)
        dtype = np.int32 if kind == "INT" else np.float32
        attr.data.foreach_set(key, np.ascontiguousarray(values, dtype=dtype).reshape(-1))
    mesh.update()


# ---------------------------------------------------------------- import

def choose_mode(cache, mode):
    if mode not in MODES:
        raise ImportFailed(f"mode must be one of {', '.join(MODES)}, not {mode!r}")
    has_tets = "tet_vertices" in cache.attributes
    if mode == "AUTO":
        return "MESH" if has_tets else "POINTS"
    if mode == "MESH" and not has_tets:
        raise ImportFailed(f"{cache.path}: a point-flock cache has no tet_vertices to build a mesh from; "
                           "import it as a point cloud")
    if mode == "POINTS" and not has_tets and "position" not in cache.attributes:
        raise ImportFailed(f"{cache.path}: the cache has neither tet_vertices nor position")
    return mode


def frame_range(cache, first, last, step):
    """(first, last) cache frames, last = −1 meaning the cache's last frame and moved down onto
    the step grid, so the animation ends on a frame it shows."""
    if cache.frames == 0:
        raise ImportFailed(f"{cache.path}: the cache has no frames")
    if step < 1:
        raise ImportFailed(f"frame step must be at least 1, not {step}")
    if last < 0:
        last = cache.frames - 1
    if not 0 <= first <= last < cache.frames:
        raise ImportFailed(f"{cache.path}: frame range {first} … {last} is not within the cache's "
                           f"{cache.frames} frames (0 … {cache.frames - 1})")
    return first, first + (last - first) // step * step


def set_scene_timing(scene, cache, settings):
    """Scene frames start … end show the imported frames at the cache's own speed."""
    scene.frame_start = settings["start"]
    scene.frame_end = settings["start"] + (settings["last"] - settings["first"]) // settings["step"]
    rate = cache.frame_rate / settings["step"]
    if rate > 0 and np.isfinite(rate):
        scene.render.fps = max(1, round(rate))
        scene.render.fps_base = scene.render.fps / rate  # Blender's frame rate is fps / fps_base


ANIMATE = ("ADDON", "PC2")  # by this add-on's frame handler; by a Mesh Cache modifier reading a PC2 bake


def import_cache(context, path, mode="AUTO", first=0, last=-1, step=1, start=1, scale=1.0, set_scene=False,
                 animate="ADDON"):
    """Creates the animated object of the cache at `path` in the active collection and returns
    (object, warning or None). Raises ImportFailed (a ValueError) with a message for the user.
    `set_scene` sets the scene's frame range and rate to the frames shown; `animate` "PC2" also
    bakes the positions to //<object>.pc2 beside the saved .blend, read by a Mesh Cache modifier,
    so the .blend animates without the add-on."""
    path = os.path.abspath(bpy.path.abspath(path))
    cache = open_cache(path)
    if cache.agents == 0:
        raise ImportFailed(f"{path}: the cache has no agents")
    if not scale > 0:
        raise ImportFailed(f"scale must be positive, not {scale}")
    if animate not in ANIMATE:
        raise ImportFailed(f"animate must be one of {', '.join(ANIMATE)}, not {animate!r}")
    if animate == "PC2":
        require_saved_blend()
    mode = choose_mode(cache, mode)
    first, last = frame_range(cache, first, last, step)
    settings = {"mode": mode, "first": first, "last": last, "step": step, "start": start, "scale": float(scale)}
    name = f"{Path(path).parent.name}_{Path(path).stem}"
    mesh = bpy.data.meshes.new(name)
    build_topology(mesh, cache.agents, mode)
    mesh[SETTINGS] = settings
    link_cache_file(mesh, path, name)
    obj = bpy.data.objects.new(name, mesh)
    context.collection.objects.link(obj)
    for other in context.view_layer.objects:
        other.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    scene = context.scene
    if set_scene:
        set_scene_timing(scene, cache, settings)
    # The handler changes mesh data while frames render: Blender needs the interface locked then.
    scene.render.use_lock_interface = True
    load_frame(mesh, scene.frame_current)
    if animate == "PC2":
        bake_pc2(obj, f"//{bpy.path.clean_name(obj.name)}.pc2")
    return obj, cache.warning


# ---------------------------------------------------------------- baking to a point cache

PC2_MODIFIER = "flockmorph PC2"  # the Mesh Cache modifier bake_pc2 adds


def write_pc2(path, frames, start, points):
    """A PC2 file (Blender's Mesh Cache modifier, docs/export.md): "POINTCACHE2\\0", version 1, the
    point count, the start frame, the sample rate (1: one sample a scene frame) and the sample
    count, then float32 x, y, z little-endian; `frames` yields one (points, 3) array per sample."""
    import struct
    with open(path + ".partial", "wb") as f:
        f.write(struct.pack("<12siiffi", b"POINTCACHE2\0", 1, points, float(start), 1.0, len(frames)))
        for xyz in frames:
            f.write(np.ascontiguousarray(xyz, dtype="<f4").tobytes())
    os.replace(path + ".partial", path)


def require_saved_blend():
    if not bpy.data.filepath:
        raise ImportFailed("save the .blend first: the modifier finds the point cache by a path relative to it")


def bake_pc2(obj, filepath):
    """Writes the vertex positions of every scene frame the import shows, start ... end, into the
    PC2 file `filepath` (a Blender path: `//` is the .blend's folder) and adds a Mesh Cache
    modifier that reads it by a `//`-relative path, so the saved .blend animates without the
    add-on. Returns the file's absolute path. The attributes (velocity, orientation, phase) stay
    those of the frame last shown: the modifier moves vertices only."""
    mesh = obj.data
    if obj.type != "MESH" or SETTINGS not in mesh:
        raise ImportFailed(f"{obj.name} was not imported from a flockmorph cache")
    require_saved_blend()
    settings = mesh[SETTINGS]
    cache = open_cache(cache_path(mesh))
    samples = range(settings["first"], settings["last"] + 1, settings["step"])
    per_agent = 4 if settings["mode"] == "MESH" else 1
    target = os.path.abspath(bpy.path.abspath(filepath))
    os.makedirs(os.path.dirname(target), exist_ok=True)
    write_pc2(target, [vertex_positions(cache, k, settings["mode"]) * settings["scale"] for k in samples],
              settings["start"], cache.agents * per_agent)
    mod = obj.modifiers.get(PC2_MODIFIER) or obj.modifiers.new(PC2_MODIFIER, "MESH_CACHE")
    mod.cache_format = "PC2"
    mod.filepath = bpy.path.relpath(target)
    mod.time_mode, mod.play_mode = "FRAME", "SCENE"
    mod.frame_start, mod.frame_scale = float(settings["start"]), 1.0
    mod.forward_axis, mod.up_axis = "POS_Y", "POS_Z"  # flockmorph's axes are Blender's
    return target


# ---------------------------------------------------------------- the handler

_reported = set()  # (mesh, message) pairs already printed, so a missing file is reported once


def animated_meshes(scene):
    meshes = {}
    for obj in scene.objects:
        if obj.type == "MESH" and SETTINGS in obj.data:
            meshes[obj.data.name_full] = obj.data
    return meshes.values()


def report_once(mesh, message):
    if (mesh.name_full, message) not in _reported:
        _reported.add((mesh.name_full, message))
        print(f"flockmorph: {mesh.name_full}: {message}")


@bpy.app.handlers.persistent
def on_frame_change(scene, *_):
    for mesh in animated_meshes(scene):
        try:
            load_frame(mesh, scene.frame_current)
            _errors.pop(mesh.name_full, None)
        except (ValueError, OSError, KeyError, IndexError) as e:
            note_error(mesh, str(e))
            report_once(mesh, cache_status(mesh) or str(e))


def missing_caches():
    """(mesh, message) for every flockmorph mesh of the file whose cache cannot be read."""
    found = []
    for mesh in bpy.data.meshes:
        if SETTINGS in mesh:
            status = cache_status(mesh)
            if status:
                found.append((mesh, status))
    return found


@bpy.app.handlers.persistent
def on_load(*_):
    """A .blend opened with a cache out of reach says so at once, on the console and, with a
    window, in a pop-up, rather than leaving the object frozen at its saved frame."""
    _errors.clear()
    missing = missing_caches()
    for mesh, message in missing:
        report_once(mesh, message)
    window_manager = bpy.context.window_manager
    if missing and not bpy.app.background and window_manager is not None and window_manager.windows:
        def draw(menu, _context):
            for mesh, message in missing:
                menu.layout.label(text=f"{mesh.name_full}: {message}", icon="ERROR")
        window_manager.popup_menu(draw, title="flockmorph: caches not found", icon="ERROR")
