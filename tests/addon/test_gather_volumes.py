"""Volume shaders gathered into homogeneous volumes: Cycles' coefficients per node, sums and mixes,
the world's volume, inputs that vary in space rendered at their mean, and the messages."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import add_camera, add_plane  # noqa: E402
from scratch_iridescence.addon.render.gather import gather_scene  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scene as S  # noqa: E402


@pytest.fixture
def staged(empty_scene):
    add_camera(empty_scene)
    return empty_scene


def volume_material(name, kind=None, surface=None, **inputs):
    """A material with ``kind`` (a volume shader node) on its Volume output and ``surface`` (a node kind) or
    nothing on its Surface; returns (material, volume node)."""
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    volume = None
    if kind is not None:
        volume = tree.nodes.new(kind)
        for key, value in inputs.items():
            volume.inputs[key].default_value = value
        tree.links.new(volume.outputs[0], output.inputs["Volume"])
    if surface is not None:
        tree.links.new(tree.nodes.new(surface).outputs[0], output.inputs["Surface"])
    return mat, volume


def gathered(scene, mat):
    add_plane(scene, mat=mat)
    description = gather_scene(bpy.context.evaluated_depsgraph_get())
    return description.materials[f"material:{mat.name}"], list(description.warnings)


def approx(values):
    return pytest.approx(tuple(values), abs=1e-6)


def same_volume(volume, scattering=(0, 0, 0), absorption=(0, 0, 0), anisotropy=0.0) -> bool:
    return (volume.scattering == approx(scattering) and volume.absorption == approx(absorption)
            and volume.anisotropy == pytest.approx(anisotropy))


def test_principled_volume_has_cycles_coefficients_and_no_surface_is_an_interface(staged):
    mat, _ = volume_material("Smoke", "ShaderNodeVolumePrincipled", Color=(0.8, 0.5, 0.2, 1), Density=2.0,
                             Anisotropy=0.3, **{"Absorption Color": (0.25, 0.0, 1.0, 1)})
    result, warnings = gathered(staged, mat)
    assert isinstance(result, S.Volumetric) and result.surface == S.Interface()
    colour = np.array([0.8, 0.5, 0.2])
    absorption = np.maximum(1 - colour, 0) * np.maximum(1 - np.sqrt([0.25, 0.0, 1.0]), 0)
    assert result.volume.scattering == approx(2.0 * colour)
    assert result.volume.absorption == approx(2.0 * absorption)
    assert result.volume.anisotropy == pytest.approx(0.3)
    assert not any("rendered black" in w or "nothing is connected" in w for w in warnings)


def test_scatter_absorption_and_coefficients_nodes(staged):
    scatter, _ = gathered(staged, volume_material("S", "ShaderNodeVolumeScatter", Color=(0.5, 1.0, 0.25, 1),
                                                  Density=4.0, Anisotropy=-0.2)[0])
    assert same_volume(scatter.volume, scattering=(2.0, 4.0, 1.0), anisotropy=-0.2)
    absorb, _ = gathered(staged, volume_material("A", "ShaderNodeVolumeAbsorption", Color=(0.5, 1.0, 0.25, 1),
                                                 Density=4.0)[0])
    assert absorb.volume.absorption == approx((2.0, 0.0, 3.0)) and absorb.volume.scattering == approx((0, 0, 0))
    mat, node = volume_material("C", "ShaderNodeVolumeCoefficients", Anisotropy=0.5)
    node.inputs["Absorption Coefficients"].default_value = (0.1, 0.2, 0.3)
    node.inputs["Scatter Coefficients"].default_value = (1.0, 2.0, 3.0)
    coefficients, _ = gathered(staged, mat)
    assert same_volume(coefficients.volume, (1, 2, 3), (0.1, 0.2, 0.3), 0.5)


def test_add_and_mix_shaders_sum_and_weigh_coefficients(staged):
    mat, _ = volume_material("Sum")
    tree = mat.node_tree
    add = tree.nodes.new("ShaderNodeAddShader")
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.25
    absorb = tree.nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value, absorb.inputs["Density"].default_value = (0, 0, 0, 1), 1.0
    scatter = tree.nodes.new("ShaderNodeVolumeScatter")
    scatter.inputs["Color"].default_value, scatter.inputs["Density"].default_value = (1, 1, 1, 1), 2.0
    tree.links.new(absorb.outputs[0], add.inputs[0])
    tree.links.new(scatter.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], mix.inputs[2])  # mixed with nothing at factor 0.25
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Volume"])
    result, _ = gathered(staged, mat)
    assert result.volume.absorption == approx((0.25,) * 3) and result.volume.scattering == approx((0.5,) * 3)


def test_surface_and_volume_together_keep_both(staged):
    mat, _ = volume_material("Tinted glass", "ShaderNodeVolumeAbsorption", surface="ShaderNodeBsdfGlass",
                             Color=(0.2, 0.6, 1.0, 1), Density=1.0)
    result, _ = gathered(staged, mat)
    assert isinstance(result.surface, S.Dielectric) and result.volume.absorption == approx((0.8, 0.4, 0.0))


def test_an_image_on_the_density_is_rendered_at_its_mean_with_a_warning_naming_it(staged):
    mat, node = volume_material("Clouds", "ShaderNodeVolumePrincipled", Color=(1, 1, 1, 1))
    pixels = np.zeros((2, 4, 4), np.float32)
    pixels[..., 3] = 1
    pixels[:, :1, :3] = 1.0  # a quarter of the pixels white, the rest black: mean 0.25
    image = bpy.data.images.new("mask", 4, 2, alpha=True, float_buffer=True)
    image.pixels.foreach_set(pixels.ravel())
    texture = mat.node_tree.nodes.new("ShaderNodeTexImage")
    texture.image, texture.name = image, "Density Mask"
    mat.node_tree.links.new(texture.outputs["Color"], node.inputs["Density"])
    noise = mat.node_tree.nodes.new("ShaderNodeTexNoise")
    mat.node_tree.links.new(noise.outputs["Fac"], node.inputs["Anisotropy"])
    result, warnings = gathered(staged, mat)
    assert result.volume.scattering == approx((0.25,) * 3)
    assert result.volume.anisotropy == pytest.approx(0.5)
    assert any("'Density Mask'" in w and "mean 0.25" in w for w in warnings)
    assert any("'Noise Texture'" in w and "mean 0.5" in w for w in warnings)


def test_volume_emission_and_unsupported_nodes_are_named(staged):
    mat, _ = volume_material("Fire", "ShaderNodeVolumePrincipled", **{"Emission Strength": 3.0})
    _, warnings = gathered(staged, mat)
    assert any("volume emission" in w and "Principled Volume" in w for w in warnings)
    glow, _ = volume_material("Glow", "ShaderNodeEmission")
    result, warnings = gathered(staged, glow)
    assert result == S.Interface()  # the surface lets light through, as Cycles' does
    assert any("'Emission'" in w and "Volume output is not supported" in w for w in warnings)


def test_nothing_on_surface_or_volume_still_renders_black_with_the_message(staged):
    mat, _ = volume_material("Empty")
    result, warnings = gathered(staged, mat)
    assert result == S.Diffuse((0.0, 0.0, 0.0))
    assert any("nothing is connected to the output's Surface or Volume" in w for w in warnings)


def test_world_volume_is_gathered_beside_the_world_colour(staged):
    world = bpy.data.worlds.new("Fog")
    staged.world = world
    tree = world.node_tree
    fog = tree.nodes.new("ShaderNodeVolumeScatter")
    fog.inputs["Density"].default_value = 0.05
    fog.inputs["Color"].default_value = (1, 1, 1, 1)
    tree.links.new(fog.outputs[0], tree.nodes["World Output"].inputs["Volume"])
    description = gather_scene(bpy.context.evaluated_depsgraph_get())
    assert same_volume(description.world_volume, scattering=(0.05,) * 3)
    assert isinstance(description.world, S.ConstantWorld)


def test_a_geometry_attribute_inside_a_mesh_volume_is_zero_as_in_cycles(staged):
    """Cycles reads a mesh's geometry attributes as 0 inside its volume (a cube whose points carry d = 3
    and an absorption of density d renders clear there): the same here, with a warning naming the node."""
    mat, node = volume_material("Attr", "ShaderNodeVolumeAbsorption", Color=(0, 0, 0, 1))
    attribute = mat.node_tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "d"
    mat.node_tree.links.new(attribute.outputs["Fac"], node.inputs["Density"])
    result, warnings = gathered(staged, mat)
    assert result.volume.empty
    assert any("geometry attribute 'd'" in w and "'Attribute'" in w for w in warnings)
