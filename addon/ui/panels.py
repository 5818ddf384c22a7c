"""Object properties panel "Scratches" (count, summary, file buttons, render and overlay settings) and menus."""
from __future__ import annotations

import math

import bpy

from .. import storage
from ..operators.files import SCRATCH_OT_clear, SCRATCH_OT_export_file, SCRATCH_OT_import_file
from ..operators.generate import SCRATCH_OT_generate
from ..mesh import peek, scratch_uv_layer
from ..render.glints import SCRATCH_OT_add_glint_lighting, glint_check
from ..geometry.units import format_length
from .overlay import overlay_error

__all__ = ["SCRATCH_PT_scratches", "SCRATCH_PT_scratch_render", "SCRATCH_PT_scratch_overlay",
           "SCRATCH_MT_object"]


def summary_lines(obj) -> list[str]:
    """The panel's summary of ``obj``'s scratches, as text lines."""
    summary = storage.scratch_summary(obj)
    count = summary["count"]
    if count == 0:
        return ["No scratches"]
    return [f"{count:,} scratch" + ("" if count == 1 else "es"),
            f"Mean depth {format_length(summary['mean_depth'])}, "
            f"mean width {format_length(summary['mean_width'])}"]


class _ObjectPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and obj.type == "MESH"


class SCRATCH_PT_scratches(_ObjectPanel, bpy.types.Panel):
    bl_label = "Scratches"

    def draw(self, context):
        obj = context.object
        layout = self.layout
        column = layout.column(align=True)
        for i, line in enumerate(summary_lines(obj)):
            column.label(text=line, icon="STROKE" if i == 0 else "BLANK1")
        damaged = overlay_error(obj)
        if damaged:
            layout.label(text=damaged, icon="ERROR")
        layer = scratch_uv_layer(obj.data)
        if layer is None:
            layout.label(text="No UV map: unwrap the mesh to add scratches", icon="ERROR")
        else:
            layout.label(text=f"UV map: {layer.name}", icon="GROUP_UVS")
        draw_glint_check(layout, context, obj)
        row = layout.row(align=True)
        row.operator(SCRATCH_OT_generate.bl_idname, text="Generate...", icon="ADD")
        row.operator(SCRATCH_OT_clear.bl_idname, text="Clear", icon="TRASH")
        row = layout.row(align=True)
        row.operator(SCRATCH_OT_import_file.bl_idname, text="Import...", icon="IMPORT")
        row.operator(SCRATCH_OT_export_file.bl_idname, text="Export...", icon="EXPORT")


def draw_glint_check(layout, context, obj) -> None:
    """When no light of the scene can show ``obj``'s glints: say so, and offer the light that does."""
    check = glint_check(context, obj)
    if check is None or check.shows:
        return
    box = layout.box()
    column = box.column(align=True)
    column.label(text="No light can show these glints", icon="ERROR")
    if check.tilt is None:
        column.label(text="A uniform world shows none", icon="BLANK1")
    else:
        column.label(text=f"Best light {math.degrees(check.tilt):.0f}° off the mirror direction", icon="BLANK1")
        column.label(text=f"(the scratches reach {math.degrees(check.reach):.0f}°)", icon="BLANK1")
    box.operator(SCRATCH_OT_add_glint_lighting.bl_idname, icon="LIGHT_SUN")


class SCRATCH_PT_scratch_render(_ObjectPanel, bpy.types.Panel):
    bl_label = "Rendering"
    bl_parent_id = "SCRATCH_PT_scratches"

    def draw(self, context):
        settings = context.object.scratch_iridescence
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(settings, "base_material")
        layout.prop(settings, "coherence_diameter_um")
        layout.prop(settings, "coherent")
        layout.prop(settings, "diffuse_reflectance")
        layout.prop(settings, "crossings")
        layout.prop(settings, "depth_phase")


class SCRATCH_PT_scratch_overlay(_ObjectPanel, bpy.types.Panel):
    bl_label = "Viewport Overlay"
    bl_parent_id = "SCRATCH_PT_scratches"

    def draw_header(self, context):
        self.layout.prop(context.object.scratch_iridescence, "show_overlay", text="")

    def draw(self, context):
        obj = context.object
        settings = obj.scratch_iridescence
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.active = settings.show_overlay
        layout.prop(settings, "overlay_color_by")
        low, high = colour_range(obj)
        if high > 0:
            layout.label(text=f"Blue {format_length(low)} to yellow {format_length(high)}", icon="COLOR")


def colour_range(obj) -> tuple[float, float]:
    """The value range the overlay's colour ramp spans for ``obj`` (0, 0 until first drawn)."""
    data = peek("overlay", obj)
    if data is None or data.key[:2] != (storage.scratch_token(obj), obj.scratch_iridescence.overlay_color_by):
        return 0.0, 0.0
    return data.value_range


class SCRATCH_MT_object(bpy.types.Menu):
    bl_label = "Scratches"
    bl_idname = "SCRATCH_MT_object"

    def draw(self, context):
        layout = self.layout
        layout.operator(SCRATCH_OT_generate.bl_idname, text="Generate...")
        layout.operator(SCRATCH_OT_clear.bl_idname)
        layout.separator()
        layout.operator(SCRATCH_OT_import_file.bl_idname, text="Import...")
        layout.operator(SCRATCH_OT_export_file.bl_idname, text="Export...")


def _object_menu(self, context):
    self.layout.separator()
    self.layout.menu(SCRATCH_MT_object.bl_idname)


_CLASSES = (SCRATCH_PT_scratches, SCRATCH_PT_scratch_render, SCRATCH_PT_scratch_overlay, SCRATCH_MT_object)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.VIEW3D_MT_object.append(_object_menu)


def unregister():
    bpy.types.VIEW3D_MT_object.remove(_object_menu)
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
