"""The pictures docs/editor.md and docs/rendering.md show, rendered through the engine.

* ``first-render.png``: Blender's startup file (cube, point light, camera) with the cube scratched by
  Generate's defaults, rendered before and after *Add Glint Lighting* (Object › Scratches), with the
  startup file's own colour management (AgX);
* ``denoise.png``: a sphere on a floor under an area light at 8 spp, as rendered and through the
  compositor's Denoise node fed with the engine's Denoising Albedo and Denoising Normal passes.

    .venv/bin/python -m scratch_iridescence.scenes.docs_pictures --output docs
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np


def _render_png(scene, path: Path) -> np.ndarray:
    """Render ``scene`` through its colour management; returns the 8-bit pixels (H, W, C) (``path``: where the PNG
    lies meanwhile)."""
    import bpy
    import mitsuba as mi

    settings = scene.render.image_settings
    settings.media_type, settings.file_format, settings.color_depth = "IMAGE", "PNG", "8"
    settings.color_mode = "RGB"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    pixels = np.array(mi.Bitmap(str(path)))
    path.unlink()
    return pixels


def _engine(scene, resolution, samples: int) -> None:
    scene.render.engine = "MITSUBA_SCRATCH"
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.scratch_iridescence.samples = samples


def _side_by_side(path: Path, left: np.ndarray, right: np.ndarray, gap: int = 4) -> Path:
    import mitsuba as mi

    spacer = np.full((left.shape[0], gap, left.shape[2]), 255, dtype=left.dtype)
    mi.Bitmap(np.ascontiguousarray(np.concatenate([left, spacer, right], axis=1))).write(str(path))
    return path


def first_render(output: Path, resolution=(320, 180), samples: int = 64) -> Path:
    """The startup cube, scratched, before and after Add Glint Lighting."""
    import bpy

    bpy.ops.wm.read_homefile(use_factory_startup=True)
    scene = bpy.context.scene
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    bpy.ops.scratch.generate()
    _engine(scene, resolution, samples)
    before = _render_png(scene, output / "first-render-before.png")
    bpy.ops.scratch.add_glint_lighting()
    return _side_by_side(output / "first-render.png", before, _render_png(scene, output / "first-render-after.png"))


def denoise(output: Path, resolution=(320, 200), samples: int = 8) -> Path:
    """A noisy render beside the compositor's Denoise node fed with the engine's denoising passes."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    _engine(scene, resolution, samples)
    scene.scratch_iridescence.denoising_data = True

    floor_material = bpy.data.materials.new("Floor")
    floor_material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.5, 0.5, 1)
    bpy.ops.mesh.primitive_plane_add(size=20)
    bpy.context.active_object.data.materials.append(floor_material)
    ball = bpy.data.materials.new("Ball")
    principled = ball.node_tree.nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (0.8, 0.15, 0.1, 1)
    principled.inputs["Roughness"].default_value = 0.35
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=(0, 0, 0.6))
    bpy.ops.object.shade_smooth()
    bpy.context.active_object.data.materials.append(ball)
    light = bpy.data.lights.new("Panel", "AREA")
    light.energy, light.size = 300.0, 1.0
    lamp = bpy.data.objects.new("Panel", light)
    scene.collection.objects.link(lamp)
    lamp.location, lamp.rotation_euler = (1.5, -1.0, 3.0), (math.radians(25), math.radians(20), 0)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    camera.location, camera.rotation_euler = (0, -4.5, 2.0), (math.radians(70), 0, 0)
    scene.camera = camera
    world = bpy.data.worlds.new("Dim")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.02, 0.02, 0.025, 1)
    scene.world = world

    raw = _render_png(scene, output / "denoise-raw.png")
    tree = bpy.data.node_groups.new("Denoise", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    layers, node, result = (tree.nodes.new(kind) for kind in
                            ("CompositorNodeRLayers", "CompositorNodeDenoise", "NodeGroupOutput"))
    tree.links.new(layers.outputs["Image"], node.inputs["Image"])
    tree.links.new(layers.outputs["Denoising Albedo"], node.inputs["Albedo"])
    tree.links.new(layers.outputs["Denoising Normal"], node.inputs["Normal"])
    tree.links.new(node.outputs["Image"], result.inputs[0])
    scene.compositing_node_group = tree
    return _side_by_side(output / "denoise.png", raw, _render_png(scene, output / "denoise-clean.png"))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="docs", help="folder for first-render.png and denoise.png")
    args = parser.parse_args(argv)
    from .. import register, unregister  # the extension package

    output = Path(args.output).resolve()
    output.mkdir(parents=True, exist_ok=True)
    register()
    try:
        for picture in (first_render(output), denoise(output)):
            print(f"docs_pictures: wrote {picture}", flush=True)
    finally:
        unregister()
    return 0


if __name__ == "__main__":
    sys.exit(main())
