"""Render properties panels of the engine, and Blender's own panels made available to it.

Blender shows a built-in panel only for the engines in its ``COMPAT_ENGINES``;
a new engine would otherwise lose the output, camera, light, material and
world panels.  Every engine-neutral panel that EEVEE shows is opened to this
engine too (EEVEE's own sampling, ray tracing, light probe... panels are not).
"""
from __future__ import annotations

import importlib.metadata
import importlib.util

import bpy

from .engine import ENGINE_ID

__all__ = ["SCRATCH_PT_render_sampling", "SCRATCH_PT_render_film", "SCRATCH_PT_render_device",
           "SCRATCH_PT_render_performance", "SCRATCH_PT_view_layer_passes", "compatible_panels"]

# Panels EEVEE shows whose settings mean nothing to this engine.
_SKIP_WORDS = ("eevee", "lightprobe", "freestyle", "gpencil", "grease_pencil", "shadow_terminator", "passes",
               "light_distance", "light_influence", "light_shadow")
# EEVEE-named panels that are in fact the generic material, world and light editors.
_KEEP = {"EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface", "EEVEE_WORLD_PT_surface",
         "DATA_PT_EEVEE_light"}


def compatible_panels():
    """Blender's panels that should also appear for this engine."""
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if not engines or "BLENDER_EEVEE" not in engines:
            continue
        name = panel.__name__
        if name in _KEEP or not any(word in name.lower() for word in _SKIP_WORDS):
            yield panel


class _RenderPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE_ID}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class SCRATCH_PT_render_sampling(_RenderPanel, bpy.types.Panel):
    bl_label = "Sampling"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.scratch_iridescence
        column = layout.column(align=True)
        column.prop(settings, "viewport_samples", text="Viewport")
        column.prop(settings, "samples", text="Render")
        layout.prop(settings, "viewport_start_divisor")
        layout.prop(settings, "viewport_freeze")
        layout.prop(settings, "seed")
        layout.prop(settings, "max_depth")
        layout.prop(settings, "sampler")
        layout.prop(settings, "footprint_filter")


class SCRATCH_PT_render_film(_RenderPanel, bpy.types.Panel):
    bl_label = "Film"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(context.scene.scratch_iridescence, "film_filter")
        layout.prop(context.scene.render, "film_transparent", text="Transparent")


class SCRATCH_PT_render_device(_RenderPanel, bpy.types.Panel):
    bl_label = "Device"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(context.scene.scratch_iridescence, "variant")
        version = mitsuba_version()
        if version is None:
            layout.label(text="Mitsuba is not installed: reinstall the extension for your platform", icon="ERROR")
        else:
            layout.label(text=f"Mitsuba {version}", icon="INFO")


def mitsuba_version():
    """The installed Mitsuba's version, found without importing it (a first import takes a moment)."""
    if importlib.util.find_spec("mitsuba") is None:
        return None
    try:
        return importlib.metadata.version("mitsuba")
    except importlib.metadata.PackageNotFoundError:
        return "(version unknown)"


class SCRATCH_PT_render_performance(_RenderPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        column = layout.column(heading="Final Render")
        # Blender's own setting, as Cycles shows it: here it keeps the scratch tables between F12 renders
        column.prop(context.scene.render, "use_persistent_data", text="Persistent Data")


class SCRATCH_PT_view_layer_passes(_RenderPanel, bpy.types.Panel):
    """View Layer Properties › Passes: the data passes this engine writes (as Cycles' Data panel)."""

    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        column = layout.column(heading="Data", align=True)
        column.prop(context.view_layer, "use_pass_combined")
        column.prop(context.view_layer, "use_pass_z")
        column.prop(context.scene.scratch_iridescence, "denoising_data")


_CLASSES = (SCRATCH_PT_render_sampling, SCRATCH_PT_render_film, SCRATCH_PT_render_device,
            SCRATCH_PT_render_performance, SCRATCH_PT_view_layer_passes)
_opened: list = []


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    for panel in compatible_panels():
        panel.COMPAT_ENGINES.add(ENGINE_ID)
        _opened.append(panel)


def unregister():
    for panel in _opened:
        panel.COMPAT_ENGINES.discard(ENGINE_ID)
    _opened.clear()
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
