"""File > Export > Mitsuba Scene: a self-contained folder that renders without Blender."""
from __future__ import annotations

import bpy
from bpy.props import StringProperty

from . import backend
from .gather import GatherError, gather_scene, gather_settings

__all__ = ["SCRATCH_OT_export_mitsuba"]


class SCRATCH_OT_export_mitsuba(bpy.types.Operator):
    """Export the scene as a Mitsuba 3 folder (scene.xml, PLY meshes, textures, scratch files) that
    'python -m scratch_iridescence.mitsuba_bridge render FOLDER -o out.exr' renders without Blender"""

    bl_idname = "scratch.export_mitsuba"
    bl_label = "Export Mitsuba Scene"
    bl_options = {"REGISTER"}

    directory: StringProperty(name="Folder", description="Folder to write the scene into (created if needed)",
                              subtype="DIR_PATH")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        if (problem := backend.problem()) is not None:
            self.report({"ERROR"}, f"Export Mitsuba Scene: {problem}")
            return {"CANCELLED"}
        from ...mitsuba_bridge.device import variants
        from ...mitsuba_bridge.render.activation import activate
        from ...mitsuba_bridge.folder import export as bridge_export

        if not self.directory:
            self.report({"ERROR"}, "choose a folder to export into")
            return {"CANCELLED"}
        folder = bpy.path.abspath(self.directory)
        try:
            depsgraph = context.evaluated_depsgraph_get()
            description = gather_scene(depsgraph)
            settings = gather_settings(context.scene)
            activate(settings.variant)
            scene_file = bridge_export.export_folder(description, settings, folder)
        except (GatherError, variants.VariantError, ImportError, OSError) as error:
            self.report({"ERROR"}, f"Export Mitsuba Scene: {error}")
            return {"CANCELLED"}
        for warning in description.warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, f"Exported {len(description.shapes)} shapes to {scene_file}")
        return {"FINISHED"}


def _menu(self, context):
    self.layout.operator(SCRATCH_OT_export_mitsuba.bl_idname, text="Mitsuba Scene (Scratch Iridescence)")


def register():
    bpy.utils.register_class(SCRATCH_OT_export_mitsuba)
    bpy.types.TOPBAR_MT_file_export.append(_menu)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(_menu)
    bpy.utils.unregister_class(SCRATCH_OT_export_mitsuba)
