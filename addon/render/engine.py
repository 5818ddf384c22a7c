"""The render engine: a thin class that dispatches to :func:`frame.render_frame`."""
from __future__ import annotations

import bpy

from .frame import render_frame

__all__ = ["MitsubaScratchEngine", "ENGINE_ID"]

ENGINE_ID = "MITSUBA_SCRATCH"


class MitsubaScratchEngine(bpy.types.RenderEngine):
    """Renders with Mitsuba 3 (spectral), scratched objects with the scratch_diffraction BSDF."""

    bl_idname = ENGINE_ID
    bl_label = "Mitsuba Scratch"
    # Material and world preview thumbnails would start the spectral path tracer
    # (and compile its kernels) for every swatch: let Blender's EEVEE draw them.
    bl_use_preview = False
    # No interactive viewport render of our own: Material Preview and Rendered
    # shading in the viewport use EEVEE, so materials still look right there.
    bl_use_eevee_viewport = True
    # Materials are Blender's standard shader nodes (Principled, Diffuse...),
    # which the exporter translates; no custom node system.
    bl_use_shading_nodes_custom = False
    # Frames go through Blender's compositor and sequencer like any engine's.
    bl_use_postprocess = True
    # Mitsuba renders on the CPU (LLVM) or through CUDA, never with OpenGL.
    bl_use_gpu_context = False

    def render(self, depsgraph):
        render_frame(self, depsgraph)


def register():
    bpy.utils.register_class(MitsubaScratchEngine)


def unregister():
    bpy.utils.unregister_class(MitsubaScratchEngine)
