"""Small Blender scenes built in code for the render, export and engine tests."""
import math

import bpy
import numpy as np

ENGINE = "MITSUBA_SCRATCH"


def setup_render(scene, width=32, height=24, samples=4, engine=ENGINE):
    scene.render.engine = engine
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.scratch_iridescence.samples = samples
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    return scene


def add_camera(scene, location=(0, 0, 5), rotation=(0, 0, 0), **data):
    camera = bpy.data.cameras.new("Camera")
    for key, value in data.items():
        setattr(camera, key, value)
    obj = bpy.data.objects.new("Camera", camera)
    scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler = location, rotation
    scene.camera = obj
    return obj


def material(name, shader="ShaderNodeBsdfDiffuse", *, output_socket="Surface", **inputs):
    """A material whose Surface (or ``output_socket``: "Volume") is one ``shader`` node with ``inputs`` set."""
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    node = tree.nodes.new(shader)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], output.inputs[output_socket])
    return mat


def textured(name, image):
    """A Diffuse material whose colour comes from an Image Texture node showing ``image``; returns (material, node)."""
    mat = material(name)
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    mat.node_tree.links.new(node.outputs["Color"], mat.node_tree.nodes["Diffuse BSDF"].inputs["Color"])
    return mat, node


def missing_image(path, name="gone"):
    """An image datablock pointing at a file that does not exist."""
    image = bpy.data.images.new(name, 2, 2)
    image.source = "FILE"
    image.filepath = str(path)
    return image


def emission(name="Glow", colour=(1, 1, 1, 1), strength=1.0):
    return material(name, "ShaderNodeEmission", Color=colour, Strength=strength)


def add_plane(scene, size=2.0, location=(0, 0, 0), mat=None, name="Plane"):
    mesh = bpy.data.meshes.new(name)
    h = size / 2
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UVMap")
    mesh.uv_layers["UVMap"].uv.foreach_set("vector", [0, 0, 1, 0, 1, 1, 0, 1])
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    obj.location = location
    if mat is not None:
        mesh.materials.append(mat)
    return obj


def add_light(scene, kind, location=(0, 0, 2), rotation=(0, 0, 0), **data):
    light = bpy.data.lights.new(kind.title(), kind)
    for key, value in data.items():
        setattr(light, key, value)
    obj = bpy.data.objects.new(kind.title(), light)
    scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler = location, rotation
    return obj


def set_world(scene, colour=(0, 0, 0), strength=1.0):
    """A uniform world (the paper scenes' staging helper)."""
    from scratch_iridescence.scenes import staging

    return staging.constant_world(scene, colour, strength=strength)


def render_to(scene, path):
    """``bpy.ops.render.render(write_still=True)`` into ``path``; returns the image (H, W, 4), row 0 at the top."""
    from scratch_iridescence.mitsuba_bridge.files.exr import read_exr

    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_exr(path)


def bright_centroid(image, threshold=0.2):
    ys, xs = np.nonzero(image[..., :3].mean(axis=-1) > threshold)
    assert len(xs), "nothing bright in the image"
    return xs.mean() + 0.5, ys.mean() + 0.5


def blender_pixel(scene, camera, point):
    """Where Blender's own camera model puts ``point``: pixels from the top-left corner."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    bpy.context.view_layer.update()
    ndc = world_to_camera_view(scene, camera, Vector(point))
    width = scene.render.resolution_x * scene.render.resolution_percentage / 100
    height = scene.render.resolution_y * scene.render.resolution_percentage / 100
    return ndc.x * width, (1 - ndc.y) * height


def look_at_rotation(location, target):
    from mathutils import Vector

    direction = Vector(target) - Vector(location)
    return direction.to_track_quat("-Z", "Y").to_euler()


def radians(*degrees):
    return tuple(math.radians(d) for d in degrees)


def store_unfittable_scratches(obj) -> None:
    """Store on ``obj`` a thousand scratches 2·10⁴ UV units long: within the scratch format's bounds, but their
    tables would need about 298 GiB (tests/bridge/bsdf/tables/test_extreme_sets.py)."""
    from scratch_iridescence.addon import storage
    from scratch_iridescence.mitsuba_bridge import scratch

    lines = [np.array([[-1e4, -9e3 + k], [1e4, 9e3 - k]]) for k in range(1000)]
    storage.write_scratches(obj, scratch.ScratchSet.from_polylines(lines, width=1e-6, depth=1e-7))
