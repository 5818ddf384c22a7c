"""Props, lights, cameras and render settings shared by the paper's scenes (bpy).

Everything here is what an artist would click together: mesh primitives with
their own UV maps, materials from Principled BSDF nodes, Blender lights and
worlds, a camera aimed at a point, and the Mitsuba Scratch engine's settings.
Scratches are never written here: the figure modules put them on with the
add-on's operators (:func:`stroke` builds the replayed strokes).
"""
from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np

__all__ = ["active", "operator", "stroke", "material", "plane", "disc", "metal_plate", "table", "towards", "camera",
           "area_light", "point_light", "lamp_studio", "studio_plate", "sky_world", "constant_world",
           "environment_world", "render_settings", "look_at_rotation", "import_scratches", "cd_surroundings"]


@contextmanager
def active(obj):
    """Make ``obj`` the only selected and the active object while the block runs (operators act on it)."""
    import bpy

    layer = bpy.context.view_layer
    previous = layer.objects.active
    for other in layer.objects:
        other.select_set(False)
    obj.select_set(True)
    layer.objects.active = obj
    try:
        yield obj
    finally:
        obj.select_set(False)
        layer.objects.active = previous


def operator(call, obj, **properties):
    """Run an add-on operator (e.g. ``bpy.ops.scratch.generate``) on ``obj``; raise if it did not finish."""
    with active(obj):
        result = call(**properties)
    if "FINISHED" not in result:
        raise RuntimeError(f"{call.idname_py()} on {obj.name} did not finish: {result}")
    return result


def import_scratches(obj, scratches, filename: str, workdir=None):
    """Put a scratch set made in code on ``obj`` as a user would: saved as a scratch file, then the Import
    operator (replacing what ``obj`` carried). ``workdir`` keeps the file (a temporary folder by default)."""
    import tempfile
    from pathlib import Path

    import bpy

    from ..mitsuba_bridge import scratch

    with tempfile.TemporaryDirectory() as temporary:
        path = Path(workdir or temporary) / filename
        path.parent.mkdir(parents=True, exist_ok=True)
        scratch.save(scratches, path)
        operator(bpy.ops.scratch.import_file, obj, filepath=str(path), mode="REPLACE")


def cd_surroundings(inner_m: float, hole_m: float, height_m: float):
    """A CD's clear polycarbonate hub (from its hole to where the metal starts) and the dark cloth under it."""
    hub = material("Polycarbonate hub", (0.6, 0.62, 0.65), roughness=0.25)
    disc("CD hub", inner_m, (0.0, 0.0, height_m), hub, vertices=128, hole=hole_m)
    cloth = material("Dark cloth", (0.02, 0.02, 0.025), roughness=1.0)
    plane("Cloth", 1.0, (0.0, 0.0, 0.0), cloth)


def stroke(points, starts=None) -> list[dict]:
    """Replayable ``stroke`` items (OperatorStrokeElement) of world-space ``points``.

    ``starts`` marks the points that begin a new scratch (``is_start``); by
    default only the first one does.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if starts is None:
        starts = np.zeros(len(points), dtype=bool)
        starts[:1] = True
    return [{"name": "", "location": tuple(map(float, p)), "mouse": (0.0, 0.0), "mouse_event": (0.0, 0.0),
             "pressure": 1.0, "size": 0.0, "x_tilt": 0.0, "y_tilt": 0.0, "time": 0.0, "is_start": bool(s)}
            for p, s in zip(points, starts)]


# ------------------------------------------------------------------- objects
def material(name: str, colour, *, roughness: float = 0.5, metallic: float = 0.0):
    """A Principled BSDF material (what both EEVEE and the Mitsuba engine read)."""
    import bpy

    mat = bpy.data.materials.new(name)
    node = mat.node_tree.nodes["Principled BSDF"]
    node.inputs["Base Color"].default_value = (*colour, 1.0)
    node.inputs["Roughness"].default_value = roughness
    node.inputs["Metallic"].default_value = metallic
    return mat


def _finish(obj, name: str, mat):
    obj.name = name
    if mat is not None:
        obj.data.materials.append(mat)
    return obj


def plane(name: str, size, location=(0.0, 0.0, 0.0), mat=None, rotation=(0.0, 0.0, 0.0)):
    """A rectangle (``size`` = x or (x, y) in metres) with the primitive's UV map over [0, 1]²."""
    import bpy

    sx, sy = (size, size) if np.isscalar(size) else size
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=location, rotation=rotation)
    obj = bpy.context.active_object
    obj.scale = (sx, sy, 1.0)
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    return _finish(obj, name, mat)


def disc(name: str, radius: float, location=(0.0, 0.0, 0.0), mat=None, vertices: int = 256,
         hole: float = 0.0):
    """A flat disc (an annulus when ``hole`` > 0) with a planar UV map: the disc's box is [0, 1]².

    One UV unit is ``2 * radius`` metres in both directions, so scratches given
    in UV around (0.5, 0.5) keep their shape.
    """
    import bmesh
    import bpy

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    angles = np.linspace(0.0, 2.0 * np.pi, vertices, endpoint=False)
    ring = lambda r: [bm.verts.new((r * math.cos(a), r * math.sin(a), 0.0)) for a in angles]  # noqa: E731
    outer = ring(radius)
    if hole > 0:
        inner = ring(hole)
        for i in range(vertices):
            j = (i + 1) % vertices
            bm.faces.new((inner[i], outer[i], outer[j], inner[j]))  # counter-clockwise seen from +Z
    else:
        bm.faces.new(outer)
    uv_layer = bm.loops.layers.uv.new("UVMap")
    for face in bm.faces:
        for loop in face.loops:
            x, y, _ = loop.vert.co
            loop[uv_layer].uv = (0.5 + x / (2 * radius), 0.5 + y / (2 * radius))
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    return _finish(obj, name, mat)


def metal_plate(name: str, size_m, *, metal: str = "Al", height_m: float = 0.002):
    """A metal plate (UVs over [0, 1]²) lying on the table; the scratch BSDF's base ``metal``, no scratches yet."""
    look = material(f"{name} metal", (0.91, 0.92, 0.92), roughness=0.05, metallic=1.0)  # the viewport's look
    obj = plane(name, size_m, (0.0, 0.0, height_m), look)
    obj.scratch_iridescence.base_material = metal
    return obj


def table(name: str = "Table", size_m=2.0, colour=(0.025, 0.025, 0.028)):
    """A dark diffuse table top at z = 0, so that scratched metal stands out against it."""
    return plane(name, size_m, (0.0, 0.0, 0.0), material(f"{name} top", colour, roughness=0.9))


def towards(elevation_deg: float, azimuth_deg: float, distance: float, target=(0.0, 0.0, 0.0)):
    """The point ``distance`` from ``target`` at ``elevation_deg`` above the table, towards ``azimuth_deg``
    (0: +Y, 90: +X)."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return (target[0] + distance * math.cos(e) * math.sin(a), target[1] + distance * math.cos(e) * math.cos(a),
            target[2] + distance * math.sin(e))


# ------------------------------------------------------------ camera, lights
def look_at_rotation(location, target):
    """Euler rotation that points an object's -Z axis from ``location`` at ``target`` (Y up)."""
    from mathutils import Vector

    return (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()


def camera(scene, location, target, *, lens_mm: float = 50.0):
    """A perspective camera at ``location`` looking at ``target``; becomes the scene camera."""
    import bpy

    data = bpy.data.cameras.new("Camera")
    data.lens = lens_mm
    data.clip_start = 0.005
    obj = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = look_at_rotation(location, target)
    scene.camera = obj
    return obj


def area_light(scene, name: str, location, target, *, power_w: float, size, shape: str = "RECTANGLE",
               colour=(1.0, 1.0, 1.0)):
    """An area light facing ``target`` (``size`` = (x, y) in metres; RECTANGLE, DISK...)."""
    import bpy

    data = bpy.data.lights.new(name, "AREA")
    data.shape = shape
    sx, sy = (size, size) if np.isscalar(size) else size
    data.size, data.size_y = sx, sy
    data.energy = power_w
    data.color = colour
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = look_at_rotation(location, target)
    return obj


def point_light(scene, name: str, location, *, power_w: float, radius: float = 0.0, colour=(1.0, 1.0, 1.0)):
    """A point light (``radius`` > 0: a small emitting sphere)."""
    import bpy

    data = bpy.data.lights.new(name, "POINT")
    data.energy = power_w
    data.shadow_soft_size = radius
    data.color = colour
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    obj.location = location
    return obj


def sky_world(scene, *, sun_elevation_deg: float, sun_rotation_deg: float, strength: float = 1.0,
              sun_intensity: float = 1.0):
    """Blender's Multiple Scattering sky with its sun (Mitsuba's ``sunsky`` in the render)."""
    import bpy

    world = bpy.data.worlds.new("Sun and sky")
    scene.world = world
    tree = world.node_tree
    sky = tree.nodes.new("ShaderNodeTexSky")
    sky.sky_type = "MULTIPLE_SCATTERING"
    sky.sun_elevation = math.radians(sun_elevation_deg)
    sky.sun_rotation = math.radians(sun_rotation_deg)
    sky.sun_intensity = sun_intensity
    background = tree.nodes["Background"]
    background.inputs["Strength"].default_value = strength
    tree.links.new(sky.outputs["Color"], background.inputs["Color"])
    return world


def constant_world(scene, colour, *, strength: float = 1.0):
    """A uniform world (a dim room) of linear RGB ``colour``."""
    import bpy

    world = bpy.data.worlds.new("Room")
    scene.world = world
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*colour, 1.0)
    background.inputs["Strength"].default_value = strength
    return world


def environment_world(scene, name: str, pixels: np.ndarray, *, strength: float = 1.0):
    """An environment (HDRI) made in code: ``pixels`` (H, W, 3) linear RGB, equirectangular, row 0 at the top.

    The image is a generated float image held in the .blend (packed), so the
    scene file is self-contained.
    """
    import bpy

    height, width, _ = pixels.shape
    image = bpy.data.images.new(name, width=width, height=height, alpha=False, float_buffer=True)
    rgba = np.ones((height, width, 4), dtype=np.float32)
    rgba[..., :3] = pixels[::-1]  # Blender stores rows bottom-up
    image.pixels.foreach_set(rgba.ravel())
    image.pack()
    world = bpy.data.worlds.new(name)
    scene.world = world
    tree = world.node_tree
    node = tree.nodes.new("ShaderNodeTexEnvironment")
    node.image = image
    background = tree.nodes["Background"]
    background.inputs["Strength"].default_value = strength
    tree.links.new(node.outputs["Color"], background.inputs["Color"])
    return world


def lamp_studio(scene, *, lamp_elevation_deg: float = 40.0, camera_above_mirror_deg: float = 15.0,
                camera_distance_m: float = 0.24, lens_mm: float = 50.0, target=(0.0, 0.004, 0.0)):
    """A dark studio around a plate at the origin: one small lamp and a camera on the other side.

    The lamp (a 3 mm sphere of 20 W, 35 cm away) stands ``lamp_elevation_deg``
    above the table towards +Y; the camera looks from the opposite side,
    ``camera_above_mirror_deg`` above the lamp's mirror direction, so the
    lamp's reflection lies near the plate's far edge and the scratch glints
    around it cross the plate.  Returns the camera.
    """
    point_light(scene, "Lamp", towards(lamp_elevation_deg, 0.0, 0.35), power_w=20.0, radius=0.0015)
    constant_world(scene, (0.01, 0.01, 0.012))
    return camera(scene, towards(lamp_elevation_deg + camera_above_mirror_deg, 180.0, camera_distance_m), target,
                  lens_mm=lens_mm)


def studio_plate(scene, generate: dict, *, resolution, samples: int, exposure: float, size_m: float = 0.10,
                 diffuse_reflectance=None):
    """A metal plate scratched by the Generate operator (``generate``: its settings) in the lamp studio."""
    import bpy

    plate = metal_plate("Scratched plate", size_m, metal="Al")
    if diffuse_reflectance is not None:
        plate.scratch_iridescence.diffuse_reflectance = diffuse_reflectance
    operator(bpy.ops.scratch.generate, plate, **generate)
    table()
    lamp_studio(scene)
    render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=exposure)
    return plate


def render_settings(scene, *, resolution, samples: int, max_depth: int = 4, exposure: float = 0.0, seed: int = 0):
    """The Mitsuba Scratch engine, a box pixel filter and the Standard view (colours kept, not desaturated)."""
    render = scene.render
    render.engine = "MITSUBA_SCRATCH"
    render.resolution_x, render.resolution_y = (int(v) for v in resolution)
    render.resolution_percentage = 100
    settings = scene.scratch_iridescence
    settings.samples = int(samples)
    settings.max_depth = int(max_depth)
    settings.seed = int(seed)
    settings.film_filter = "box"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.exposure = exposure
