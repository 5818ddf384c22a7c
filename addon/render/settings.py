"""Render settings of a scene: ``scene.scratch_iridescence`` (one PointerProperty on Scene)."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty

from ...mitsuba_bridge.scene import FILTERS

__all__ = ["SCRATCH_PG_render"]


def _tag_scene(settings, context):
    # Properties defined in Python tag no depsgraph update: tag the scene so that the Rendered
    # viewport (view_update) restarts with the new settings.
    settings.id_data.update_tag()


def _tag_view_layers(settings, context):
    # A pass switched on or off changes the passes Blender allocates and the compositor's sockets.
    for view_layer in settings.id_data.view_layers:
        view_layer.update_render_passes()


_FILTER_LABELS = {
    "box": ("Box", "One pixel wide box: every glint lands in exactly one pixel (best for scratches)"),
    "tent": ("Tent", "Triangle filter, two pixels wide: slightly softer"),
    "gaussian": ("Gaussian", "Gaussian filter: smooth, but smears glints over neighbouring pixels"),
}
_FILTER_ITEMS = [(key, *_FILTER_LABELS[key]) for key in FILTERS]


class SCRATCH_PG_render(bpy.types.PropertyGroup):
    """How the Mitsuba Scratch engine renders this scene."""

    samples: IntProperty(
        name="Samples", description="Samples per pixel; glints and diffraction colours need many",
        default=64, min=1, soft_max=4096, update=_tag_scene)
    viewport_samples: IntProperty(
        name="Viewport Samples", description="Samples per pixel after which the Rendered viewport stops "
                                             "refining (and stops using the CPU or GPU)",
        default=1024, min=1, soft_max=16384, update=_tag_scene)
    viewport_start_divisor: EnumProperty(
        name="Start Pixel Size",
        description="After each change the viewport first renders one sample with pixels this many times "
                    "larger (fast), then refines at full resolution",
        items=[("1", "1x", "No reduced first pass"), ("2", "2x", "Half resolution first"),
               ("4", "4x", "Quarter resolution first"), ("8", "8x", "One eighth resolution first")],
        default="4", update=_tag_scene)
    viewport_freeze: BoolProperty(
        name="Replay Passes",
        description="Record the viewport's render pass once and replay it after camera moves instead of "
                    "tracing it again (Dr.Jit's freeze: much faster passes); turn off if the viewport "
                    "misbehaves",
        default=True, update=_tag_scene)
    max_depth: IntProperty(
        name="Max Depth", description="Longest light path in segments: 1 shows only light sources, 2 adds "
                                      "direct lighting, each more adds one bounce",
        default=8, min=1, soft_max=64, update=_tag_scene)
    seed: IntProperty(name="Seed", description="Seed of the random samples (change for another noise pattern)",
                      default=0, min=0, update=_tag_scene)
    variant: EnumProperty(
        name="Device",
        description="Mitsuba variant; all are spectral, which diffraction colours need",
        # Explicit numbers: files store the number, so a new item takes a new one whatever its place
        items=[("auto", "Automatic", "The GPU (CUDA on NVIDIA, Metal on Apple silicon) when available, "
                                     "else the CPU", 0),
               ("cuda_ad_spectral", "GPU (CUDA)", "Mitsuba's cuda_ad_spectral variant (NVIDIA GPUs)", 1),
               ("metal_ad_spectral", "GPU (Metal)", "Mitsuba's metal_ad_spectral variant (Apple GPUs, macOS on "
                                                    "Apple silicon)", 3),
               ("llvm_ad_spectral", "CPU (LLVM)", "Mitsuba's llvm_ad_spectral variant (vectorised CPU)", 2)],
        default="auto", update=_tag_scene)
    footprint_filter: BoolProperty(
        name="Footprint Filter",
        description="Average each scratched surface over the patch a sample stands for (its share of the "
                    "pixel), so that glints settle in a few samples; the image converges to the same one. "
                    "Off: every sample sees one point, as the paper renders. Off by default for now: far views "
                    "(many scratches per pixel) cost much more per sample with it",
        default=False, update=_tag_scene)
    sampler: EnumProperty(
        name="Sampler",
        description="How each pixel's samples are spread",
        # Explicit numbers: files store the number, so a new item takes a new one whatever its place
        items=[("multijitter", "Multi-Jittered", "Correlated multi-jittered samples (Mitsuba's multijitter): "
                                                 "stratified within each chunk of samples, less noise at equal "
                                                 "samples on surfaces. Experimental: some volumes render a few "
                                                 "percent too bright with it", 0),
               ("independent", "Independent", "Independent uniform random samples (Mitsuba's independent)", 1)],
        default="independent", update=_tag_scene)
    film_filter: EnumProperty(
        name="Pixel Filter", description="Reconstruction filter of the film",
        items=_FILTER_ITEMS, default="box", update=_tag_scene)
    denoising_data: BoolProperty(
        name="Denoising Data",
        description="Also render the Denoising Albedo and Denoising Normal passes (as Cycles' Denoising Data) "
                    "for the compositor's Denoise node",
        default=False, update=_tag_view_layers)


def register():
    bpy.utils.register_class(SCRATCH_PG_render)
    bpy.types.Scene.scratch_iridescence = bpy.props.PointerProperty(type=SCRATCH_PG_render)


def unregister():
    del bpy.types.Scene.scratch_iridescence
    bpy.utils.unregister_class(SCRATCH_PG_render)
