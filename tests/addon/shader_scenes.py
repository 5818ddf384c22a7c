"""One small scene per shader, rendered by this engine and by Cycles (the per-shader agreement tests).

A smooth UV sphere (radius 0.5 m, Blender's own UV map) wearing the shader
stands on a grey diffuse floor under a uniform white world; a 64 × 64 camera
looks at it from 30° above. Both engines render it with fixed seeds; the
figures compared are the mean luminance of the sphere's disc and of the whole
image. Building a material is one function per shader in :data:`SHADERS`.
"""
import math

import bpy
import numpy as np

from render_scenes import add_plane, look_at_rotation, material, render_to, setup_render

RESOLUTION = 64
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def _link(mat, output, node_input):
    mat.node_tree.links.new(output, node_input)


def _node(mat, kind, **inputs):
    node = mat.node_tree.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return node


def _shader(mat):
    return mat.node_tree.nodes["Material Output"].inputs["Surface"].links[0].from_node


def _image(name, pixels):
    """A float (linear) image of ``pixels`` (H, W, 4), row 0 at the top."""
    height, width = pixels.shape[:2]
    image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    image.pixels.foreach_set(np.ascontiguousarray(pixels[::-1], dtype=np.float32).ravel())
    image.pack()
    return image


def _image_node(mat, image, *, non_colour=False):
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    if non_colour:
        image.colorspace_settings.name = "Non-Color"
    return node


def _stripes(width=64, height=32, count=8):
    """Values 0 and 1 in ``count`` vertical stripes (a mask along u)."""
    u = (np.arange(width) + 0.5) / width
    level = (np.floor(u * count) % 2).astype(np.float32)
    return np.broadcast_to(level, (height, width))


def _waves(width=128, height=64, count=12):
    """A smooth height field along u: 0.5 + 0.5 sin."""
    u = (np.arange(width) + 0.5) / width
    level = (0.5 + 0.5 * np.sin(2 * math.pi * count * u)).astype(np.float32)
    return np.broadcast_to(level, (height, width))


def _rgba(level):
    return np.dstack([level, level, level, np.ones_like(level)])


# ---- one material per shader --------------------------------------------------------------------------

def diffuse():
    return material("Diffuse", Color=(0.6, 0.4, 0.2, 1))


def glossy():
    return material("Glossy", "ShaderNodeBsdfAnisotropic", Color=(0.9, 0.7, 0.5, 1), Roughness=0.3)


def glass():
    return material("Glass", "ShaderNodeBsdfGlass", Color=(1, 1, 1, 1), Roughness=0.0, IOR=1.45)


def rough_glass():
    mat = material("RoughGlass", "ShaderNodeBsdfGlass", Color=(0.8, 0.9, 1, 1), Roughness=0.3, IOR=1.5)
    _shader(mat).distribution = "GGX"  # Cycles' default Multiscatter GGX adds energy Mitsuba's GGX lacks
    return mat


def refraction():
    return material("Refraction", "ShaderNodeBsdfRefraction", Color=(0.9, 0.9, 0.9, 1), Roughness=0.0, IOR=1.45)


def translucent():
    return material("Translucent", "ShaderNodeBsdfTranslucent", Color=(0.7, 0.7, 0.7, 1))


def transparent():
    return material("Transparent", "ShaderNodeBsdfTransparent", Color=(0.5, 0.5, 0.5, 1))


def principled():
    return material("Principled", "ShaderNodeBsdfPrincipled",
                    **{"Base Color": (0.8, 0.2, 0.2, 1), "Roughness": 0.4, "Metallic": 0.0})


def principled_sheen():
    """Sheen on a dark base: Cycles' microfiber sheen (Principled v2) against Mitsuba's Disney sheen."""
    return material("Sheen", "ShaderNodeBsdfPrincipled",
                    **{"Base Color": (0.05, 0.05, 0.3, 1), "Roughness": 0.6, "Sheen Weight": 1.0,
                       "Sheen Roughness": 0.5})


def principled_transmission():
    return material("Transmission", "ShaderNodeBsdfPrincipled",
                    **{"Base Color": (1, 1, 1, 1), "Transmission Weight": 1.0, "Roughness": 0.0, "IOR": 1.45})


def principled_alpha():
    return material("Alpha", "ShaderNodeBsdfPrincipled", **{"Base Color": (0.8, 0.2, 0.2, 1), "Alpha": 0.4})


def mix_shader():
    mat = material("Mix", "ShaderNodeMixShader", Fac=0.3)
    _link(mat, _node(mat, "ShaderNodeBsdfDiffuse", Color=(0.2, 0.5, 0.8, 1)).outputs[0], _shader(mat).inputs[1])
    _link(mat, _node(mat, "ShaderNodeBsdfAnisotropic", Roughness=0.2).outputs[0], _shader(mat).inputs[2])
    return mat


def mix_textured():
    mat = material("MixTextured", "ShaderNodeMixShader")
    mask = _image_node(mat, _image("stripes", _rgba(_stripes())), non_colour=True)
    _link(mat, mask.outputs["Color"], _shader(mat).inputs["Fac"])
    _link(mat, _node(mat, "ShaderNodeBsdfDiffuse", Color=(0.8, 0.8, 0.8, 1)).outputs[0], _shader(mat).inputs[1])
    _link(mat, _node(mat, "ShaderNodeBsdfDiffuse", Color=(0.1, 0.1, 0.1, 1)).outputs[0], _shader(mat).inputs[2])
    return mat


def _added(name, diffuse_colour, glossy_colour, roughness):
    mat = material(name, "ShaderNodeAddShader")
    _link(mat, _node(mat, "ShaderNodeBsdfDiffuse", Color=diffuse_colour).outputs[0], _shader(mat).inputs[0])
    _link(mat, _node(mat, "ShaderNodeBsdfAnisotropic", Color=glossy_colour, Roughness=roughness).outputs[0],
          _shader(mat).inputs[1])
    return mat


def add_shader():
    return _added("Add", (0.4, 0.3, 0.2, 1), (0.3, 0.3, 0.3, 1), 0.25)


def add_capped():
    """White diffuse + white glossy: Cycles' sum reflects up to twice the light; here both halves are halved."""
    return _added("AddCapped", (1, 1, 1, 1), (1, 1, 1, 1), 0.3)


def emission_mix():
    mat = material("Glow", "ShaderNodeMixShader", Fac=0.5)
    _link(mat, _node(mat, "ShaderNodeEmission", Color=(1, 0.6, 0.3, 1), Strength=2.0).outputs[0],
          _shader(mat).inputs[1])
    _link(mat, _node(mat, "ShaderNodeBsdfDiffuse", Color=(0.5, 0.5, 0.5, 1)).outputs[0], _shader(mat).inputs[2])
    return mat


def normal_map():
    mat = material("NormalMap", Color=(0.7, 0.7, 0.7, 1))
    u_slope = 0.6 * np.sin(2 * math.pi * 12 * (np.arange(128) + 0.5) / 128)  # tangent-space x tilt
    normal = np.stack([u_slope, np.zeros_like(u_slope), np.sqrt(1 - u_slope ** 2)], axis=-1)
    pixels = np.broadcast_to(np.append(0.5 + 0.5 * normal, np.ones((128, 1)), axis=1), (64, 128, 4))
    node = _node(mat, "ShaderNodeNormalMap")
    _link(mat, _image_node(mat, _image("normals", pixels), non_colour=True).outputs["Color"], node.inputs["Color"])
    _link(mat, node.outputs[0], _shader(mat).inputs["Normal"])
    return mat


def bump():
    mat = material("Bump", Color=(0.7, 0.7, 0.7, 1))
    node = _node(mat, "ShaderNodeBump", Strength=1.0, Distance=0.02)
    _link(mat, _image_node(mat, _image("waves", _rgba(_waves())), non_colour=True).outputs["Color"],
          node.inputs["Height"])
    _link(mat, node.outputs[0], _shader(mat).inputs["Normal"])
    return mat


def checker():
    mat = material("Checker")
    node = _node(mat, "ShaderNodeTexChecker", Color1=(0.9, 0.9, 0.9, 1), Color2=(0.1, 0.1, 0.1, 1), Scale=6.0)
    _link(mat, _node(mat, "ShaderNodeTexCoord").outputs["UV"], node.inputs["Vector"])
    _link(mat, node.outputs["Color"], _shader(mat).inputs["Color"])
    return mat


def checker_generated():
    """A checker with nothing on its Vector: Cycles' default Generated coordinates, a 3D checker."""
    mat = material("CheckerGenerated")
    node = _node(mat, "ShaderNodeTexChecker", Color1=(0.9, 0.9, 0.9, 1), Color2=(0.1, 0.1, 0.1, 1), Scale=4.0)
    _link(mat, node.outputs["Color"], _shader(mat).inputs["Color"])
    return mat


def image_generated():
    """Stripes along the Generated x (Flat projection), i.e. across the sphere's bounding box, not its UVs."""
    mat = material("ImageGenerated")
    node = _image_node(mat, _image("stripes", _rgba(0.1 + 0.8 * _stripes(count=6))))
    _link(mat, _node(mat, "ShaderNodeTexCoord").outputs["Generated"], node.inputs["Vector"])
    _link(mat, node.outputs["Color"], _shader(mat).inputs["Color"])
    return mat


def ramp_on_image():
    mat = material("Ramp")
    ramp = _node(mat, "ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.8, 0.2, 0.1, 1)
    ramp.color_ramp.elements[1].color = (0.1, 0.3, 0.8, 1)
    _link(mat, _image_node(mat, _image("waves", _rgba(_waves())), non_colour=True).outputs["Color"], ramp.inputs["Fac"])
    _link(mat, ramp.outputs["Color"], _shader(mat).inputs["Color"])
    return mat


def math_and_mix_rgb():
    mat = material("Maths", "ShaderNodeBsdfPrincipled")
    maths = _node(mat, "ShaderNodeMath")
    maths.operation, maths.inputs[0].default_value, maths.inputs[1].default_value = "MULTIPLY", 0.5, 0.6
    _link(mat, maths.outputs[0], _shader(mat).inputs["Roughness"])
    mix = mat.node_tree.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    sockets = {socket.identifier: socket for socket in mix.inputs}
    sockets["A_Color"].default_value, sockets["B_Color"].default_value = (0.9, 0.8, 0.7, 1), (0.5, 0.5, 0.5, 1)
    invert = _node(mat, "ShaderNodeInvert", Fac=0.5)
    _link(mat, mix.outputs[2], invert.inputs["Color"])
    _link(mat, invert.outputs[0], _shader(mat).inputs["Base Color"])
    return mat


def _volume_only(name, kind, **inputs):
    """A material with ``kind`` on its Volume output and nothing on its Surface (smoke in a closed mesh)."""
    return material(name, kind, output_socket="Volume", **inputs)


def volume_principled():
    return _volume_only("Smoke", "ShaderNodeVolumePrincipled", Color=(0.8, 0.8, 0.8, 1), Density=3.0,
                        Anisotropy=0.3, **{"Absorption Color": (0.4, 0.4, 0.4, 1)})


def volume_scatter():
    return _volume_only("Mist", "ShaderNodeVolumeScatter", Color=(0.9, 0.6, 0.3, 1), Density=4.0, Anisotropy=-0.3)


def volume_absorption():
    return _volume_only("Ink", "ShaderNodeVolumeAbsorption", Color=(0.3, 0.6, 0.9, 1), Density=2.0)


def volume_in_glass():
    mat = material("Tinted", "ShaderNodeBsdfGlass", Color=(1, 1, 1, 1), Roughness=0.0, IOR=1.45)
    absorb = _node(mat, "ShaderNodeVolumeAbsorption", Color=(0.4, 0.7, 0.9, 1), Density=1.5)
    _link(mat, absorb.outputs[0], mat.node_tree.nodes["Material Output"].inputs["Volume"])
    return mat


def world_fog():
    """A grey sphere in a scattering world volume, lit by an area light above (a uniform world at infinity
    is lost in the fog, in both engines)."""
    return material("FogSphere", Color=(0.6, 0.6, 0.6, 1))


def _fog_staging(scene):
    world = scene.world
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    fog = world.node_tree.nodes.new("ShaderNodeVolumeScatter")
    fog.inputs["Color"].default_value, fog.inputs["Density"].default_value = (1, 1, 1, 1), 0.08
    world.node_tree.links.new(fog.outputs[0], world.node_tree.nodes["World Output"].inputs["Volume"])
    light = bpy.data.lights.new("Panel", "AREA")
    light.energy, light.size = 400.0, 1.5
    obj = bpy.data.objects.new("Panel", light)
    scene.collection.objects.link(obj)
    obj.location = (0.0, 0.5, 3.0)


SHADERS = {function.__name__: function for function in (
    diffuse, glossy, glass, rough_glass, refraction, translucent, transparent, principled, principled_transmission,
    principled_alpha, principled_sheen, mix_shader, mix_textured, add_shader, add_capped, emission_mix, normal_map,
    bump, checker, checker_generated, image_generated, ramp_on_image, math_and_mix_rgb, volume_principled,
    volume_scatter, volume_absorption, volume_in_glass, world_fog)}
#: Scenes that change the staging besides the sphere's material.
STAGING = {"world_fog": _fog_staging}


def build(scene, shader: str) -> None:
    """The sphere wearing ``SHADERS[shader]`` on a grey floor under a white world, and the camera."""
    from scratch_iridescence.scenes import staging

    staging.constant_world(scene, (1.0, 1.0, 1.0))
    add_plane(scene, size=20, mat=material("Floor", Color=(0.5, 0.5, 0.5, 1)), name="Floor")
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.5, location=(0, 0, 0.5))
    sphere = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    sphere.data.materials.append(SHADERS[shader]())
    if shader in STAGING:
        STAGING[shader](scene)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    camera.data.lens = 50
    camera.location = (0, -3.2 * math.cos(math.radians(30)), 0.5 + 3.2 * math.sin(math.radians(30)))
    camera.rotation_euler = look_at_rotation(camera.location, (0, 0, 0.5))
    scene.camera = camera


def sphere_mask():
    """Pixels well inside the sphere's disc (row 0 at the top), from Blender's own camera projection."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    scene = bpy.context.scene
    centre = world_to_camera_view(scene, scene.camera, Vector((0, 0, 0.5)))
    edge = world_to_camera_view(scene, scene.camera, Vector((0.5, 0, 0.5)))
    radius = (edge.x - centre.x) * RESOLUTION
    ys, xs = np.mgrid[0:RESOLUTION, 0:RESOLUTION] + 0.5
    cx, cy = centre.x * RESOLUTION, (1 - centre.y) * RESOLUTION
    return (xs - cx) ** 2 + (ys - cy) ** 2 < (0.85 * radius) ** 2


def render(engine: str, shader: str, path, *, samples: int, seed: int = 0):
    """(sphere mean luminance, image mean luminance, image) of ``shader``'s scene rendered by ``engine``."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    setup_render(scene, RESOLUTION, RESOLUTION, samples=samples, engine=engine)
    if engine == "CYCLES":
        cycles = scene.cycles
        cycles.samples, cycles.use_denoising, cycles.seed = samples, False, seed
        cycles.use_adaptive_sampling = False
        cycles.max_bounces = cycles.diffuse_bounces = cycles.glossy_bounces = 12
        cycles.transmission_bounces = cycles.transparent_max_bounces = 12
        cycles.volume_bounces = 12  # Cycles' default is 0 (single scattering); Mitsuba's volpath has no such limit
        cycles.blur_glossy = 0.0  # no glossy filter: Mitsuba has none
        cycles.pixel_filter_type, cycles.filter_width = "BOX", 1.0  # this engine's default pixel filter
        cycles.sample_clamp_direct = cycles.sample_clamp_indirect = 0.0
        scene.cycles.device = "CPU"
    else:
        scene.scratch_iridescence.seed, scene.scratch_iridescence.max_depth = seed, 13
    build(scene, shader)
    image = render_to(scene, path)[..., :3] @ LUMINANCE
    return float(image[sphere_mask()].mean()), float(image.mean()), image
