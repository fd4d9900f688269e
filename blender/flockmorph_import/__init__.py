"""flockmorph cache importer for Blender 3.4: File > Import > flockmorph cache (.fmc).

Imports a cache written by `flockmorph run` as an animated mesh (four vertices and four triangles
per tet) or as a point cloud (one vertex per agent, with velocity, orientation and rotation
attributes for point flocks). docs/blender.md describes installation, the options, how the
animation works (importer.py) and Geometry Nodes instancing.
"""

bl_info = {
    "name": "flockmorph cache (.fmc)",
    "author": "flockmorph",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > flockmorph cache (.fmc)",
    "description": "Import a flockmorph frame cache as an animated mesh or point cloud",
    "category": "Import-Export",
}

if "importer" in locals():  # Blender's "Reload Scripts"
    import importlib
    importlib.reload(importer)  # noqa: F821 - bound by the import below on the first load

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import importer


class IMPORT_SCENE_OT_flockmorph(bpy.types.Operator, ImportHelper):
    """Import a flockmorph frame cache as an animated mesh or point cloud"""
    bl_idname = "import_scene.flockmorph"
    bl_label = "Import flockmorph cache"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".fmc"
    filter_glob: StringProperty(default="*.fmc", options={"HIDDEN"})

    mode: EnumProperty(
        name="As",
        items=[
            ("AUTO", "Automatic", "A mesh for a tet cache, a point cloud for a point flock"),
            ("MESH", "Mesh", "Four vertices and four triangles per tet"),
            ("POINTS", "Point Cloud", "One vertex per agent: the tet's centroid, or the position of a point flock"),
        ],
        default="AUTO",
    )
    frame_first: IntProperty(name="First Frame", description="First cache frame to show", default=0, min=0)
    frame_last: IntProperty(name="Last Frame", description="Last cache frame to show (-1: the cache's last)",
                            default=-1, min=-1)
    frame_step: IntProperty(name="Frame Step", description="Show every n-th cache frame", default=1, min=1)
    start_frame: IntProperty(name="Start at Scene Frame", description="Scene frame that shows the first cache frame",
                             default=1)
    scale: FloatProperty(name="Scale", description="Multiplies positions and velocities", default=1.0,
                         min=1e-6, soft_max=100.0)
    set_scene: BoolProperty(name="Set Scene Frames and FPS",
                            description="Set the scene's frame range and frame rate to play the cache at its own "
                                        "speed (off: the scene's range and rate stay as they are)",
                            default=False)
    animate: EnumProperty(
        name="Animate With",
        items=[
            ("ADDON", "This Add-on", "A frame handler reads each frame from the cache: positions and attributes"),
            ("PC2", "Mesh Cache Modifier (PC2)", "Also bake the positions to //<object>.pc2 beside the saved "
                                                 ".blend, read by a Mesh Cache modifier: the .blend animates "
                                                 "without this add-on"),
        ],
        default="ADDON",
    )

    def execute(self, context):
        try:
            _, warning = importer.import_cache(
                context, self.filepath, mode=self.mode, first=self.frame_first, last=self.frame_last,
                step=self.frame_step, start=self.start_frame, scale=self.scale, set_scene=self.set_scene,
                animate=self.animate)
        except ValueError as e:  # ImportFailed, and the reader's errors for files that are not caches
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        if warning:
            self.report({"WARNING"}, warning)
        return {"FINISHED"}


class OBJECT_OT_flockmorph_bake_pc2(bpy.types.Operator):
    """Bake the active flockmorph object to a PC2 point cache read by a Mesh Cache modifier, so the
    saved .blend animates without this add-on (a render farm node)"""
    bl_idname = "object.flockmorph_bake_pc2"
    bl_label = "Bake flockmorph to PC2"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="File", subtype="FILE_PATH",
                             description="The PC2 file; // is the .blend's folder (default: //<object>.pc2)",
                             default="")

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "MESH" and importer.SETTINGS in obj.data

    def execute(self, context):
        obj = context.active_object
        try:
            path = importer.bake_pc2(obj, self.filepath or f"//{bpy.path.clean_name(obj.name)}.pc2")
        except (ValueError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"baked {obj.name} to {path}")
        return {"FINISHED"}


class DATA_PT_flockmorph(bpy.types.Panel):
    """Properties > Object Data > flockmorph: the cache's path (a CacheFile, so File > External
    Data's tools fix it too), and what is wrong when the cache cannot be read."""
    bl_label = "flockmorph"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and obj.type == "MESH" and importer.SETTINGS in obj.data

    def draw(self, context):
        mesh = context.object.data
        layout = self.layout
        linked = importer.cache_file_of(mesh)
        if linked is not None:
            layout.prop(linked, "filepath", text="Cache")
        else:
            layout.label(text=f"Cache: {importer.cache_path(mesh)}")
        status = importer.cache_status(mesh)
        if status:
            column = layout.column()
            column.alert = True
            column.label(text=status, icon="ERROR")
        s = mesh[importer.SETTINGS]
        layout.label(text=f"{s['mode'].lower()}: cache frames {s['first']} … {s['last']} step {s['step']}, "
                          f"from scene frame {s['start']}, scale {s['scale']:g}")
        if context.object.modifiers.get(importer.PC2_MODIFIER):
            layout.label(text="Positions also from the Mesh Cache modifier (PC2)", icon="MODIFIER")


def menu_func_bake(self, context):
    self.layout.operator(OBJECT_OT_flockmorph_bake_pc2.bl_idname)


def menu_func_import(self, context):
    self.layout.operator(IMPORT_SCENE_OT_flockmorph.bl_idname, text="flockmorph cache (.fmc)")


def register():
    bpy.utils.register_class(IMPORT_SCENE_OT_flockmorph)
    bpy.utils.register_class(OBJECT_OT_flockmorph_bake_pc2)
    bpy.utils.register_class(DATA_PT_flockmorph)
    bpy.types.TOPBAR_MT_file_import.append(menu_func_import)
    bpy.types.VIEW3D_MT_object_animation.append(menu_func_bake)
    bpy.app.handlers.frame_change_pre.append(importer.on_frame_change)
    bpy.app.handlers.load_post.append(importer.on_load)


def unregister():
    bpy.app.handlers.load_post.remove(importer.on_load)
    bpy.app.handlers.frame_change_pre.remove(importer.on_frame_change)
    bpy.utils.unregister_class(DATA_PT_flockmorph)
    bpy.types.VIEW3D_MT_object_animation.remove(menu_func_bake)
    bpy.types.TOPBAR_MT_file_import.remove(menu_func_import)
    bpy.utils.unregister_class(OBJECT_OT_flockmorph_bake_pc2)
    bpy.utils.unregister_class(IMPORT_SCENE_OT_flockmorph)
    importer.close_caches()
