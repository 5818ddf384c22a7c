"""The render engine: a thin class that dispatches to :func:`frame.render_frame` (F12) and
:class:`viewport.ViewportRender` (Rendered viewport shading)."""
from __future__ import annotations

import bpy

from . import backend
from .frame import data_passes, render_frame

__all__ = ["MitsubaScratchEngine", "ENGINE_ID"]

ENGINE_ID = "MITSUBA_SCRATCH"


class MitsubaScratchEngine(bpy.types.RenderEngine):
    """Renders with Mitsuba 3 (spectral), scratched objects with the scratch_diffraction BSDF."""

    bl_idname = ENGINE_ID
    bl_label = "Mitsuba Scratch"
    # Material and world preview thumbnails would start the spectral path tracer
    # (and compile its kernels) for every swatch: let Blender's EEVEE draw them.
    bl_use_preview = False
    # As in Cycles: Material Preview shading uses EEVEE; Rendered shading calls
    # view_update/view_draw below (Blender uses them whenever the engine has them).
    bl_use_eevee_viewport = True
    # Materials are Blender's standard shader nodes (Principled, Diffuse...),
    # which the exporter translates; no custom node system.
    bl_use_shading_nodes_custom = False
    # Frames go through Blender's compositor and sequencer like any engine's.
    bl_use_postprocess = True
    # Mitsuba renders on the CPU (LLVM) or through CUDA or Metal, never with OpenGL; the
    # viewport image is drawn in view_draw, where Blender provides the context.
    bl_use_gpu_context = False

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.viewport = None

    def __del__(self):
        # Blender frees the engine when the viewport leaves Rendered shading or closes:
        # the worker stops after its current pass (nothing waits for it here).
        try:
            viewport = getattr(self, "viewport", None)
        except ReferenceError:  # Blender quitting freed the engine's data first: viewport.py's exit handler stops it
            return
        if viewport is not None:
            viewport.stop()

    def render(self, depsgraph):
        render_frame(self, depsgraph)

    def update_render_passes(self, scene=None, renderlayer=None):
        # The passes the view layer asks for (Z, Denoising Data), as Cycles registers them: Blender allocates
        # them in the render result and the compositor's Render Layers node shows them.
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        for name, (channels, chan_id, kind) in data_passes(scene, renderlayer).items():
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)

    def view_update(self, context, depsgraph):
        if self.viewport is None:
            if (problem := backend.problem()) is not None:  # Mitsuba unusable here: say so in the viewport
                self.update_stats("", problem)
                return
            from .viewport import ViewportRender

            self.viewport = ViewportRender()
        self.viewport.view_update(context, depsgraph)

    def view_draw(self, context, depsgraph):
        if self.viewport is not None:
            self.viewport.view_draw(self, context, depsgraph)


def register():
    bpy.utils.register_class(MitsubaScratchEngine)


def unregister():
    bpy.utils.unregister_class(MitsubaScratchEngine)
    # Persistent Data's scratch tables (maybe hundreds of MB) go with the add-on, not with Blender
    from ...mitsuba_bridge.bsdf import persistent

    persistent.forget()
