"""The demo: a scratched aluminium plate under sun and sky (the paper's Fig. 7(b)), rendered through the engine.

Builds the scene in code with bpy: a 10 cm plate carrying 3 000 random scratches
(depth G_D[250, 80] nm, width G_W[4, 1.3] µm, depth variation D[1.1, 0.04]) on a
dark table, Blender's sky with its sun, and a camera looking at the plate close to
the sun's mirror direction, where the scratches light up in diffraction colours.
Saves ``demo.blend``, renders it with MITSUBA_SCRATCH (``bpy.ops.render.render``)
and writes ``demo.exr`` (linear) and ``demo.png`` (display-referred: Standard view, exposure −6.5).

    .venv/bin/python -m scratch_iridescence.scenes.demo --output out     # what `make demo` runs
    .venv/bin/python -m scratch_iridescence.scenes.demo --output /tmp/d --resolution 64 40 --samples 4
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

PLATE_SIZE_M = 0.10
SUN_ELEVATION_DEG = 35.0
SUN_ROTATION_DEG = 0.0  # the sun stands towards +Y


def build_scene(scene, *, scratch_count: int = 3000, seed: int = 7, resolution=(720, 450), samples: int = 128):
    """Fill ``scene`` (expected empty) with the demo plate, table, sky and camera."""
    import bpy
    from mathutils import Vector

    from ..mitsuba_bridge import scratch
    from ..addon import storage

    # ---- the plate: a 10 cm square with UVs over [0, 1]², scratched ----
    bpy.ops.mesh.primitive_plane_add(size=PLATE_SIZE_M, location=(0, 0, 0.002))
    plate = bpy.context.active_object
    plate.name = "Scratched plate"
    metal = bpy.data.materials.new("Brushed aluminium")  # what EEVEE's viewport shows; the render uses scratches
    principled = metal.node_tree.nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (0.91, 0.92, 0.92, 1.0)
    principled.inputs["Metallic"].default_value = 1.0
    principled.inputs["Roughness"].default_value = 0.05
    plate.data.materials.append(metal)
    if scratch_count:
        scratches = scratch.random_scratches(
            scratch_count, seed=seed, width=scratch.Gaussian(4e-6, 1.3e-6), depth=scratch.Gaussian(250e-9, 80e-9),
            depth_variation=(1.1, 0.04), length=(0.2, 0.6), region=((0.02, 0.02), (0.98, 0.98)))
        storage.write_scratches(plate, scratches)
        plate.scratch_iridescence.base_material = "Al"

    # ---- a dark table so the plate stands out ----
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0, 0, 0))
    table = bpy.context.active_object
    table.name = "Table"
    slate = bpy.data.materials.new("Slate")
    diffuse = slate.node_tree.nodes["Principled BSDF"]
    diffuse.inputs["Base Color"].default_value = (0.03, 0.03, 0.035, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.9
    table.data.materials.append(slate)

    # ---- sun and sky ----
    world = bpy.data.worlds.new("Sun and sky")
    scene.world = world
    sky = world.node_tree.nodes.new("ShaderNodeTexSky")
    sky.sky_type = "MULTIPLE_SCATTERING"
    sky.sun_elevation, sky.sun_rotation = math.radians(SUN_ELEVATION_DEG), math.radians(SUN_ROTATION_DEG)
    world.node_tree.links.new(sky.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])

    # ---- camera: 12° above the sun's mirror direction ----
    # Scratches perpendicular to the half vector light up: around the sun's highlight (here just
    # beyond the plate's far edge) they form arcs, split into colours by diffraction a few degrees
    # away from it.
    camera_data = bpy.data.cameras.new("Camera")
    camera_data.lens = 50
    camera = bpy.data.objects.new("Camera", camera_data)
    scene.collection.objects.link(camera)
    elevation = math.radians(SUN_ELEVATION_DEG + 12.0)
    distance = 0.24
    camera.location = Vector((0.0, -math.cos(elevation) * distance, math.sin(elevation) * distance))
    target = Vector((0.0, 0.012, 0.0))
    camera.rotation_euler = (target - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera

    # ---- render settings ----
    render = scene.render
    render.engine = "MITSUBA_SCRATCH"
    render.resolution_x, render.resolution_y = resolution
    render.resolution_percentage = 100
    scene.scratch_iridescence.samples = samples
    scene.scratch_iridescence.film_filter = "box"
    # Sun glints are ~1000 times brighter than the sky in the mirror: expose for the glints, and
    # keep their colours (AgX would desaturate them towards white).
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.exposure = -6.5
    return plate


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="out", help="folder for demo.blend, demo.exr and demo.png")
    parser.add_argument("--resolution", type=int, nargs=2, default=(720, 450), metavar=("W", "H"))
    parser.add_argument("--samples", type=int, default=128)
    parser.add_argument("--scratches", type=int, default=3000)
    args = parser.parse_args(argv)

    started = time.perf_counter()
    import bpy

    from .. import register, unregister  # the extension package

    output = Path(args.output).resolve()
    output.mkdir(parents=True, exist_ok=True)
    register()
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        build_scene(scene, scratch_count=args.scratches, resolution=tuple(args.resolution), samples=args.samples)
        bpy.ops.wm.save_as_mainfile(filepath=str(output / "demo.blend"))
        print(f"demo: scene built and saved to {output / 'demo.blend'} ({time.perf_counter() - started:.1f} s); "
              f"rendering {args.resolution[0]} x {args.resolution[1]} at {args.samples} spp", flush=True)

        settings = scene.render.image_settings
        settings.file_format, settings.color_depth, settings.exr_codec = "OPEN_EXR", "32", "ZIP"
        scene.render.filepath = str(output / "demo.exr")
        bpy.ops.render.render(write_still=True)
        settings.file_format, settings.color_depth = "PNG", "8"
        bpy.data.images["Render Result"].save_render(filepath=str(output / "demo.png"), scene=scene)
    finally:
        unregister()
    print(f"demo: wrote {output / 'demo.exr'} and {output / 'demo.png'} in {time.perf_counter() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
