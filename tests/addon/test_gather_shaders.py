"""Shader node trees gathered into the neutral description: each node's settings, folding and baking."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import add_camera, add_plane, material  # noqa: E402
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.addon.render.gather import gather_scene  # noqa: E402
from scratch_iridescence.addon.render.gather.scratch_group import add_scratch_node  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scene as S  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scratch  # noqa: E402


@pytest.fixture
def staged(empty_scene):
    add_camera(empty_scene)
    return empty_scene


def gathered(scene, mat):
    """The neutral material of a plane wearing ``mat``, and the warnings about materials."""
    add_plane(scene, mat=mat)
    description = gather_scene(bpy.context.evaluated_depsgraph_get())
    return description.materials[f"material:{mat.name}"], [w for w in description.warnings if w.startswith("material")]


def node(mat, kind, **inputs):
    result = mat.node_tree.nodes.new(kind)
    for key, value in inputs.items():
        result.inputs[key].default_value = value
    return result


def link(mat, output, node_input):
    mat.node_tree.links.new(output, node_input)


def shader_of(mat):
    return mat.node_tree.nodes["Material Output"].inputs["Surface"].links[0].from_node


def image(name, pixels):
    """A float image of ``pixels`` (H, W, 4), row 0 at the top."""
    height, width = pixels.shape[:2]
    result = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    result.pixels.foreach_set(np.ascontiguousarray(pixels[::-1], dtype=np.float32).ravel())
    return result


def image_node(mat, img):
    result = mat.node_tree.nodes.new("ShaderNodeTexImage")
    result.image = img
    return result


# ---- shaders -------------------------------------------------------------------------------------------

def test_glass_refraction_translucent_and_transparent_keep_their_settings(staged):
    glass, _ = gathered(staged, material("G", "ShaderNodeBsdfGlass", Color=(0.9, 1, 1, 1), Roughness=0.2, IOR=1.33))
    assert glass == S.Dielectric(pytest.approx((0.9, 1, 1)), ior=pytest.approx(1.33), alpha=pytest.approx(0.04))
    refraction, _ = gathered(staged, material("R", "ShaderNodeBsdfRefraction", IOR=1.6, Roughness=0.0))
    assert refraction.reflect is False and refraction.ior == pytest.approx(1.6) and refraction.alpha == 0
    translucent, _ = gathered(staged, material("T", "ShaderNodeBsdfTranslucent", Color=(0.2, 0.4, 0.6, 1)))
    assert translucent == S.Translucent(pytest.approx((0.2, 0.4, 0.6)))
    transparent, warnings = gathered(staged, material("C", "ShaderNodeBsdfTransparent", Color=(1, 0.5, 0.5, 1)))
    assert transparent == S.Transparent(pytest.approx((1, 0.5, 0.5)))
    assert any("tinted Transparent" in w for w in warnings)


def test_mix_shader_with_a_constant_or_an_image_factor(staged):
    mat = material("M", "ShaderNodeMixShader", Fac=0.3)
    mix = shader_of(mat)
    link(mat, node(mat, "ShaderNodeBsdfDiffuse").outputs[0], mix.inputs[1])
    link(mat, node(mat, "ShaderNodeBsdfAnisotropic").outputs[0], mix.inputs[2])
    result, _ = gathered(staged, mat)
    assert isinstance(result, S.Mix) and result.factor == pytest.approx(0.3)
    assert isinstance(result.first, S.Diffuse) and isinstance(result.second, S.Glossy)
    mask = image_node(mat, image("mask", np.zeros((2, 2, 4))))
    link(mat, mask.outputs["Color"], mix.inputs["Fac"])
    result = gather_scene(bpy.context.evaluated_depsgraph_get()).materials["material:M"]
    assert isinstance(result.factor, S.Texture) and result.factor.name == "mask"
    mix.inputs["Fac"].links[0].is_muted = True
    mix.inputs["Fac"].default_value = 1.0  # a constant 0 or 1 keeps only one branch
    assert isinstance(gather_scene(bpy.context.evaluated_depsgraph_get()).materials["material:M"], S.Glossy)


def test_unconnected_shader_socket_is_black_as_in_cycles(staged):
    mat = material("Half", "ShaderNodeMixShader", Fac=0.5)
    link(mat, node(mat, "ShaderNodeBsdfDiffuse").outputs[0], shader_of(mat).inputs[1])
    result, _ = gathered(staged, mat)
    assert result.second == S.Diffuse((0.0, 0.0, 0.0))


def test_emission_in_a_mix_or_add_becomes_the_surfaces_emitter(staged):
    mat = material("Glow", "ShaderNodeAddShader")
    add = shader_of(mat)
    link(mat, node(mat, "ShaderNodeEmission", Color=(1, 0.5, 0, 1), Strength=2.0).outputs[0], add.inputs[0])
    link(mat, node(mat, "ShaderNodeBsdfDiffuse", Color=(0.3, 0.3, 0.3, 1)).outputs[0], add.inputs[1])
    result, _ = gathered(staged, mat)
    assert result.radiance == pytest.approx((2.0, 1.0, 0.0)) and isinstance(result.bsdf, S.Diffuse)
    mixed = material("Dim", "ShaderNodeMixShader", Fac=0.25)
    link(mixed, node(mixed, "ShaderNodeEmission", Strength=4.0).outputs[0], shader_of(mixed).inputs[1])
    link(mixed, node(mixed, "ShaderNodeBsdfDiffuse").outputs[0], shader_of(mixed).inputs[2])
    result, _ = gathered(staged, mixed)
    assert result.radiance == pytest.approx((3.0, 3.0, 3.0))
    assert result.bsdf.factor == pytest.approx(0.25) and result.bsdf.first == S.Diffuse((0.0, 0.0, 0.0))


def test_alpha_constant_or_from_an_images_alpha_becomes_a_mask(staged):
    mat = material("A", "ShaderNodeBsdfPrincipled", Alpha=0.4)
    result, _ = gathered(staged, mat)
    assert isinstance(result, S.Mask) and result.opacity == pytest.approx(0.4)
    pixels = np.ones((2, 2, 4))
    pixels[:, 0, 3] = 0.0  # left column transparent
    texture = image_node(mat, image("cutout", pixels))
    link(mat, texture.outputs["Alpha"], shader_of(mat).inputs["Alpha"])
    opacity = gather_scene(bpy.context.evaluated_depsgraph_get()).materials["material:A"].opacity
    assert isinstance(opacity, S.Texture) and np.allclose(opacity.pixels[..., 0], [[0, 1], [0, 1]])


def test_normal_map_and_bump_wrap_the_bsdf(staged):
    mat = material("N", Color=(0.5, 0.5, 0.5, 1))
    normal_map = node(mat, "ShaderNodeNormalMap")
    link(mat, image_node(mat, image("normals", np.full((2, 2, 4), 0.5))).outputs["Color"], normal_map.inputs["Color"])
    bump = node(mat, "ShaderNodeBump", Strength=0.5, Distance=0.2)
    link(mat, image_node(mat, image("heights", np.zeros((2, 2, 4)))).outputs["Color"], bump.inputs["Height"])
    link(mat, normal_map.outputs[0], bump.inputs["Normal"])
    link(mat, bump.outputs[0], shader_of(mat).inputs["Normal"])
    result, _ = gathered(staged, mat)
    assert isinstance(result, S.NormalMap) and result.texture.name == "normals"
    assert isinstance(result.bsdf, S.Bump) and result.bsdf.scale == pytest.approx(0.1)
    assert result.bsdf.height.name == "heights" and isinstance(result.bsdf.bsdf, S.Diffuse)


# ---- values: folding and baking ----------------------------------------------------------------------------

def test_math_mix_invert_and_ramp_on_constants_fold_to_numbers(staged):
    mat = material("F", "ShaderNodeBsdfPrincipled")
    principled = shader_of(mat)
    math = node(mat, "ShaderNodeMath")
    math.operation, math.inputs[0].default_value, math.inputs[1].default_value = "MULTIPLY", 0.5, 0.8
    link(mat, math.outputs[0], principled.inputs["Roughness"])
    mix = mat.node_tree.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    mix.inputs[6].default_value, mix.inputs[7].default_value = (0.5, 1, 1, 1), (0.5, 0.5, 0.2, 1)
    invert = node(mat, "ShaderNodeInvert", Fac=1.0)
    link(mat, mix.outputs[2], invert.inputs["Color"])  # Result_Color
    link(mat, invert.outputs[0], principled.inputs["Base Color"])
    ramp = node(mat, "ShaderNodeValToRGB", Fac=0.25)
    link(mat, ramp.outputs["Color"], principled.inputs["Metallic"])  # black → white ramp: 0.25
    result, warnings = gathered(staged, mat)
    assert result.roughness == pytest.approx(0.4)
    assert result.base_color == pytest.approx((1 - 0.25, 1 - 0.5, 1 - 0.2))
    assert result.metallic == pytest.approx(0.25, abs=1e-3)
    assert not warnings


def test_ramp_and_invert_on_an_image_are_baked_per_pixel(staged):
    mat = material("B")
    levels = np.array([[0.0, 0.25], [0.5, 1.0]])
    img = image("levels", np.dstack([levels] * 3 + [np.ones((2, 2))]))
    ramp = node(mat, "ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (1, 0, 0, 1)
    ramp.color_ramp.elements[1].color = (0, 0, 1, 1)
    link(mat, image_node(mat, img).outputs["Color"], ramp.inputs["Fac"])
    invert = node(mat, "ShaderNodeInvert", Fac=1.0)
    link(mat, ramp.outputs["Color"], invert.inputs["Color"])
    link(mat, invert.outputs[0], shader_of(mat).inputs["Color"])
    result, _ = gathered(staged, mat)
    texture = result.reflectance
    assert isinstance(texture, S.Texture) and texture.pixels.shape == (2, 2, 3) and not texture.srgb
    expected = np.array([[list(ramp.color_ramp.evaluate(float(v)))[:3] for v in row] for row in levels])
    np.testing.assert_allclose(texture.pixels, 1 - expected, atol=2e-3)


def test_checker_texture_becomes_a_uv_checker(staged):
    mat = material("K")
    checker = node(mat, "ShaderNodeTexChecker", Color1=(1, 0, 0, 1), Color2=(0, 0, 1, 1), Scale=8.0)
    coordinates = node(mat, "ShaderNodeTexCoord")
    link(mat, coordinates.outputs["UV"], checker.inputs["Vector"])
    link(mat, checker.outputs["Color"], shader_of(mat).inputs["Color"])
    result, warnings = gathered(staged, mat)
    assert result.reflectance == S.Checker((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), 8.0, "uv")
    assert not warnings


def test_unsupported_node_deep_in_a_chain_is_named_once(staged):
    mat = material("W")
    invert = node(mat, "ShaderNodeInvert")
    link(mat, node(mat, "ShaderNodeTexVoronoi").outputs["Color"], invert.inputs["Color"])
    link(mat, invert.outputs[0], shader_of(mat).inputs["Color"])
    _, warnings = gathered(staged, mat)
    assert sum("Voronoi Texture" in w for w in warnings) == 1


# ---- scratches in a material ---------------------------------------------------------------------------------

def test_scratch_group_places_the_scratch_bsdf_inside_a_mix(staged):
    mat = material("Scratchy", "ShaderNodeMixShader")
    mix = shader_of(mat)
    link(mat, image_node(mat, image("where", np.ones((2, 2, 4)))).outputs["Color"], mix.inputs["Fac"])
    link(mat, node(mat, "ShaderNodeBsdfPrincipled").outputs[0], mix.inputs[1])
    link(mat, add_scratch_node(mat).outputs[0], mix.inputs[2])
    plane = add_plane(staged, mat=mat)
    storage.write_scratches(plane, scratch.random_scratches(20, seed=1))
    description = gather_scene(bpy.context.evaluated_depsgraph_get())
    result = description.materials["scratches:Plane"]
    assert isinstance(result, S.Mix) and isinstance(result.factor, S.Texture)
    assert isinstance(result.first, S.Principled) and isinstance(result.second, S.ScratchedMetal)
    assert result.second.scratches.count == 20


def test_scratch_group_without_scratches_renders_its_stand_in_with_a_warning(staged):
    mat = material("Lone", "ShaderNodeMixShader", Fac=1.0)
    link(mat, add_scratch_node(mat).outputs[0], shader_of(mat).inputs[2])
    result, warnings = gathered(staged, mat)
    assert isinstance(result, S.Glossy) and any("carries no scratches" in w for w in warnings)


def test_add_scratch_bsdf_operator_mixes_it_in_and_a_mask_limits_the_scratches(staged):
    mat = material("Painted", "ShaderNodeBsdfPrincipled")
    plane = add_plane(staged, mat=mat)
    storage.write_scratches(plane, scratch.random_scratches(10, seed=2))
    bpy.context.view_layer.objects.active = plane
    assert bpy.ops.scratch.add_scratch_bsdf() == {"FINISHED"}
    mix = shader_of(mat)
    assert mix.bl_idname == "ShaderNodeMixShader" and mix.inputs["Fac"].default_value == 1.0
    assert mix.inputs[1].links[0].from_node.bl_idname == "ShaderNodeBsdfPrincipled"
    assert mix.inputs[2].links[0].from_node.node_tree.name.startswith("Scratch BSDF")
    # Factor 1: the scratch BSDF everywhere, exactly as an object without the group.
    assert isinstance(gather_scene(bpy.context.evaluated_depsgraph_get()).materials["scratches:Plane"],
                      S.ScratchedMetal)
    link(mat, image_node(mat, image("mask", np.ones((2, 2, 4)))).outputs["Color"], mix.inputs["Fac"])
    result = gather_scene(bpy.context.evaluated_depsgraph_get()).materials["scratches:Plane"]
    assert isinstance(result, S.Mix) and isinstance(result.second, S.ScratchedMetal)


def test_emission_under_a_textured_mix_factor_is_halved_with_a_warning(staged):
    mat = material("Patchy", "ShaderNodeMixShader")
    link(mat, image_node(mat, image("patches", np.ones((2, 2, 4)))).outputs["Color"], shader_of(mat).inputs["Fac"])
    link(mat, node(mat, "ShaderNodeEmission", Strength=2.0).outputs[0], shader_of(mat).inputs[1])
    link(mat, node(mat, "ShaderNodeBsdfDiffuse").outputs[0], shader_of(mat).inputs[2])
    result, warnings = gathered(staged, mat)
    assert result.radiance == pytest.approx((1.0, 1.0, 1.0)) and isinstance(result.bsdf.factor, S.Texture)
    assert any("textured factor" in w for w in warnings)


# ---- texture coordinates -------------------------------------------------------------------------------

def test_checker_without_a_vector_uses_generated_coordinates_of_the_mesh(staged):
    """Cycles' default for procedural textures: the object's texture space, (co − location) / (2 size) + 0.5
    (the default cube: (co + 1) / 2), given per corner vertex to the meshes of that material."""
    mat = material("K3")
    checker = node(mat, "ShaderNodeTexChecker", Scale=3.0)
    link(mat, checker.outputs["Color"], shader_of(mat).inputs["Color"])
    bpy.ops.mesh.primitive_cube_add(size=2.0)
    cube = bpy.context.active_object
    cube.data.materials.append(mat)
    description = gather_scene(bpy.context.evaluated_depsgraph_get())
    assert description.materials["material:K3"].reflectance.coordinates == "generated"
    (shape,) = description.shapes
    np.testing.assert_allclose(shape.mesh.generated, (shape.mesh.positions + 1) / 2, atol=1e-6)
    assert not [w for w in description.warnings if "K3" in w]
    # a texture space of its own (Auto Texture Space off) moves and scales the coordinates
    cube.data.use_auto_texspace = False
    cube.data.texspace_location, cube.data.texspace_size = (0.5, 0, 0), (2, 1, 0.5)
    (shape,) = gather_scene(bpy.context.evaluated_depsgraph_get()).shapes
    expected = (shape.mesh.positions - np.array([0.5, 0, 0])) / (2 * np.array([2, 1, 0.5])) + 0.5
    np.testing.assert_allclose(shape.mesh.generated, expected, atol=1e-6)


def test_texture_coordinate_outputs_choose_uv_or_generated(staged):
    mat = material("Coords")
    coordinates = node(mat, "ShaderNodeTexCoord")
    texture = image_node(mat, image("flat", np.ones((2, 2, 4), np.float32)))
    link(mat, coordinates.outputs["Generated"], texture.inputs["Vector"])
    link(mat, texture.outputs["Color"], shader_of(mat).inputs["Color"])
    result, warnings = gathered(staged, mat)
    assert result.reflectance.coordinates == "generated" and not warnings
    description = gather_scene(bpy.context.evaluated_depsgraph_get())
    assert all(shape.mesh.generated is not None for shape in description.shapes)
    link(mat, coordinates.outputs["Object"], texture.inputs["Vector"])
    result, warnings = gathered(staged, mat)
    assert result.reflectance.coordinates == "uv"
    assert any("'Object' of 'Texture Coordinate'" in w and "UV map is used" in w for w in warnings)
    # meshes of materials without Generated textures carry no such coordinates
    plain, _ = gathered(staged, material("Plain"))
    assert all(shape.mesh.generated is None for shape in gather_scene(bpy.context.evaluated_depsgraph_get()).shapes
               if shape.material == "material:Plain")


def test_add_shader_that_creates_energy_is_named_in_a_warning(staged):
    mat = material("Sum", "ShaderNodeAddShader")
    link(mat, node(mat, "ShaderNodeBsdfDiffuse", Color=(1, 1, 1, 1)).outputs[0], shader_of(mat).inputs[0])
    link(mat, node(mat, "ShaderNodeBsdfAnisotropic", Color=(1, 1, 1, 1)).outputs[0], shader_of(mat).inputs[1])
    _, warnings = gathered(staged, mat)
    assert any("Add Shader 'Add Shader'" in w and "2.00×" in w and "0.50×" in w for w in warnings)
    dim = material("Dim", "ShaderNodeAddShader")
    link(dim, node(dim, "ShaderNodeBsdfDiffuse", Color=(0.4, 0.3, 0.2, 1)).outputs[0], shader_of(dim).inputs[0])
    link(dim, node(dim, "ShaderNodeBsdfAnisotropic", Color=(0.3, 0.3, 0.3, 1)).outputs[0], shader_of(dim).inputs[1])
    _, warnings = gathered(staged, dim)
    assert not any("'Dim'" in w for w in warnings)  # 0.4 + 0.3 ≤ 1: rendered as Cycles' sum
