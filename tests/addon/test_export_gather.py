"""Gathering a Blender scene into the neutral description: compared against the scene itself."""
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import (add_camera, add_light, add_plane, material, missing_image, radians,  # noqa: E402
                           set_world, textured)
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.addon.render.gather import GatherError, gather_scene  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scene as S  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scratch  # noqa: E402


def gather(scene):
    return gather_scene(bpy.context.evaluated_depsgraph_get())


@pytest.fixture
def staged(empty_scene):
    add_camera(empty_scene)
    return empty_scene


# ---- camera and film -------------------------------------------------------------------------

@pytest.mark.parametrize("fit, size, lens", [("AUTO", (64, 40), 50), ("AUTO", (40, 64), 35),
                                             ("VERTICAL", (64, 40), 50), ("HORIZONTAL", (40, 64), 24)])
def test_field_of_view_matches_blenders_camera(staged, fit, size, lens):
    camera = staged.camera
    camera.data.sensor_fit, camera.data.lens = fit, lens
    staged.render.resolution_x, staged.render.resolution_y = size
    description = gather(staged)
    width, height = size
    # Blender's own angles: angle_x spans the sensor width, angle_y its height; the sensor spans the
    # fitted dimension (AUTO: the larger one, with the sensor width).
    horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and width >= height)
    fitted_angle = camera.data.angle_y if fit == "VERTICAL" else camera.data.angle_x
    tan_half = math.tan(fitted_angle / 2) * (1 if horizontal else width / height)
    expected = 2 * math.atan(tan_half)
    assert description.camera.fov_x_deg == pytest.approx(math.degrees(expected), rel=1e-6)


def test_resolution_percentage_and_border_give_film_and_crop(staged):
    render = staged.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = 200, 100, 50
    render.use_border = True
    render.border_min_x, render.border_max_x, render.border_min_y, render.border_max_y = 0.25, 0.77, 0.1, 0.5
    film = gather(staged).film
    assert (film.width, film.height) == (100, 50)
    # Blender truncates float32 products: 0.77f × 100 = 76.99999 → x 25..76; y 5..25 from the
    # bottom = rows 25..45 from the top.  (The engine tests check this against Blender's result size.)
    assert film.crop == (25, 25, 51, 20)


def test_camera_transform_is_the_objects_without_scale(staged):
    staged.camera.location = (1, 2, 3)
    staged.camera.rotation_euler = radians(30, 10, 45)
    staged.camera.scale = (2, 2, 2)
    bpy.context.view_layer.update()
    matrix = gather(staged).camera.to_world
    expected = np.array(staged.camera.matrix_world.normalized())
    assert np.allclose(matrix, expected, atol=1e-6)


def test_no_camera_is_a_clear_error(empty_scene):
    add_plane(empty_scene)
    with pytest.raises(GatherError, match="no active camera"):
        gather(empty_scene)


def test_panoramic_camera_is_refused_with_a_reason(staged):
    staged.camera.data.type = "PANO"
    with pytest.raises(GatherError, match="panoramic"):
        gather(staged)


# ---- geometry ----------------------------------------------------------------------------------

def test_meshes_keep_object_space_data_and_the_world_matrix(staged):
    obj = add_plane(staged, size=2.0, location=(1, 2, 3))
    obj.rotation_euler = radians(0, 0, 30)
    obj.scale = (1, 2, 1)
    bpy.context.view_layer.update()
    (shape,) = gather(staged).shapes
    assert np.allclose(shape.to_world, np.array(obj.matrix_world))
    assert shape.mesh.triangle_count == 2
    assert np.allclose(np.sort(shape.mesh.positions[:, 0]), [-1, -1, 1, 1])  # one vertex per face corner
    assert shape.mesh.uvs is not None and shape.mesh.uvs.min() == 0 and shape.mesh.uvs.max() == 1


def test_modifiers_are_applied_through_the_depsgraph(staged):
    obj = add_plane(staged)
    obj.modifiers.new("Subdivision", "SUBSURF").render_levels = 2
    obj.modifiers["Subdivision"].levels = 2
    (shape,) = gather(staged).shapes
    assert shape.mesh.triangle_count == 2 * 16


def test_smooth_shading_gives_vertex_normals_and_flat_shading_none(staged):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=8, ring_count=4)
    sphere = bpy.context.active_object
    assert gather(staged).shapes[0].mesh.normals is None  # flat by default
    bpy.ops.object.shade_smooth()
    normals = gather(staged).shapes[0].mesh.normals
    assert normals is not None and np.allclose(np.linalg.norm(normals, axis=1), 1, atol=1e-4)
    assert sphere.name in gather(staged).shapes[0].name


def test_material_slots_split_a_mesh_and_instances_share_data(staged):
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.active_object
    red, blue = material("Red", Color=(1, 0, 0, 1)), material("Blue", Color=(0, 0, 1, 1))
    cube.data.materials.append(red)
    cube.data.materials.append(blue)
    cube.data.polygons[0].material_index = 1
    twin = cube.copy()
    staged.collection.objects.link(twin)
    twin.location = (3, 0, 0)
    description = gather(staged)
    assert sorted(s.material for s in description.shapes) == ["material:Blue"] * 2 + ["material:Red"] * 2
    assert sum(s.mesh.triangle_count for s in description.shapes) == 24
    meshes = {id(s.mesh) for s in description.shapes}
    assert len(meshes) == 2  # the twin reuses the cube's two parts


def test_objects_hidden_from_render_are_left_out(staged):
    add_plane(staged, name="Shown")
    add_plane(staged, name="Hidden").hide_render = True
    assert [s.name for s in gather(staged).shapes] == ["Shown"]


def test_curves_and_text_are_rendered_as_meshes(staged):
    bpy.ops.object.text_add()
    assert gather(staged).shapes[0].mesh.triangle_count > 10


# ---- lights ----------------------------------------------------------------------------------

def test_light_power_follows_blenders_conventions(staged):
    add_light(staged, "POINT", energy=100, color=(1, 0.5, 0.25), shadow_soft_size=0)
    add_light(staged, "SPOT", energy=40, spot_size=math.radians(60), spot_blend=0.0)
    add_light(staged, "SUN", energy=3, rotation=radians(60, 0, 0))
    add_light(staged, "AREA", energy=50, shape="RECTANGLE", size=2, size_y=0.5)
    area2 = add_light(staged, "AREA", energy=50, shape="DISK", size=1, normalize=False)
    area2.scale = (2, 2, 2)
    add_light(staged, "POINT", energy=10, exposure=2.0, shadow_soft_size=0.1)
    bpy.context.view_layer.update()
    lights = gather(staged).lights
    point, spot, sun, rect, disk, exposed = lights
    assert np.allclose(point.intensity, np.array([1, 0.5, 0.25]) * 100 / (4 * math.pi))
    assert np.allclose(spot.intensity, 40 / (4 * math.pi)) and spot.cutoff_deg == pytest.approx(30)
    assert np.allclose(sun.irradiance, 3) and np.allclose(sun.direction, [0, math.sin(math.radians(60)),
                                                                          -math.cos(math.radians(60))])
    assert np.allclose(rect.radiance, 50 / (math.pi * 2 * 0.5)) and rect.shape == "rectangle"
    assert np.allclose(disk.radiance, 50 / math.pi) and disk.shape == "disk"  # not normalised: area ignored
    assert np.allclose(exposed.intensity, 40 / (4 * math.pi)) and exposed.radius == pytest.approx(0.1)


def test_spot_blend_places_mitsubas_ramp_on_blenders_half_point(staged):
    from scratch_iridescence.addon.render.gather.lights import spot_angles

    cutoff, beam = spot_angles(math.radians(60), 1.0)
    cos_half = math.cos(math.radians(30))
    half = math.degrees(math.acos(cos_half + 0.5 * (1 - cos_half)))  # smoothstep = 1/2 there
    assert cutoff == pytest.approx(30) and (beam + cutoff) / 2 == pytest.approx(half)
    assert spot_angles(math.radians(60), 0.0) == pytest.approx((30, 30))


# ---- world -----------------------------------------------------------------------------------

def test_world_colour_times_strength(staged):
    set_world(staged, (0.2, 0.4, 0.6), strength=2.0)
    world = gather(staged).world
    assert isinstance(world, S.ConstantWorld) and world.radiance == pytest.approx((0.4, 0.8, 1.2))


def test_black_or_missing_world_emits_nothing(staged):
    set_world(staged, (0, 0, 0))
    assert gather(staged).world is None
    staged.world = None
    assert gather(staged).world is None


def test_sky_texture_becomes_sunsky_with_blenders_sun_position(staged):
    world = set_world(staged)
    tree = world.node_tree
    sky = tree.nodes.new("ShaderNodeTexSky")
    sky.sky_type = "MULTIPLE_SCATTERING"
    sky.sun_elevation, sky.sun_rotation = math.radians(20), math.radians(90)
    tree.links.new(sky.outputs[0], tree.nodes["Background"].inputs["Color"])
    result = gather(staged).world
    assert isinstance(result, S.SkyWorld)
    assert np.allclose(result.sun_direction, [math.cos(math.radians(20)), 0, math.sin(math.radians(20))], atol=1e-6)
    sky.sun_disc = False
    assert gather(staged).world.sun_scale == 0


def test_environment_texture_with_mapping_rotation(staged, tmp_path):
    from scratch_iridescence.mitsuba_bridge.files.exr import write_exr

    write_exr(tmp_path / "sky.exr", np.ones((8, 16, 3), np.float32))
    world = set_world(staged, strength=1.5)
    tree = world.node_tree
    environment = tree.nodes.new("ShaderNodeTexEnvironment")
    environment.image = bpy.data.images.load(str(tmp_path / "sky.exr"))
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = radians(0, 0, 90)
    coordinates = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coordinates.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs[0], environment.inputs["Vector"])
    tree.links.new(environment.outputs[0], tree.nodes["Background"].inputs["Color"])
    result = gather(staged).world
    assert isinstance(result, S.EnvironmentWorld) and result.strength == 1.5
    assert result.texture.path.endswith("sky.exr")
    assert np.allclose(result.rotation @ [1, 0, 0], [0, 1, 0], atol=1e-6)


# ---- materials -------------------------------------------------------------------------------

def test_supported_shaders_map_to_their_counterparts(staged):
    shaders = {
        "P": material("P", "ShaderNodeBsdfPrincipled", **{"Base Color": (0.1, 0.2, 0.3, 1), "Metallic": 0.7,
                                                         "Roughness": 0.25, "IOR": 1.8}),
        "D": material("D", Color=(0.5, 0.4, 0.3, 1)),
        "G": material("G", "ShaderNodeBsdfAnisotropic", Color=(0.9, 0.8, 0.7, 1), Roughness=0.3),
        "E": material("E", "ShaderNodeEmission", Color=(1, 0.5, 0, 1), Strength=4.0),
    }
    for index, (name, mat) in enumerate(shaders.items()):
        add_plane(staged, location=(index * 3, 0, 0), mat=mat, name=name)
    materials = gather(staged).materials
    p, d, g, e = (materials[f"material:{name}"] for name in "PDGE")
    assert p == S.Principled(base_color=pytest.approx((0.1, 0.2, 0.3)), metallic=pytest.approx(0.7),
                             roughness=pytest.approx(0.25), ior=pytest.approx(1.8), coat_roughness=pytest.approx(0.03))
    assert d == S.Diffuse(pytest.approx((0.5, 0.4, 0.3)))
    assert g.alpha == pytest.approx(0.09) and g.color == pytest.approx((0.9, 0.8, 0.7))
    assert e.radiance == pytest.approx((4.0, 2.0, 0.0)) and e.bsdf is None


def test_unsupported_shader_falls_back_to_grey_with_one_warning_per_material(staged):
    toon = material("Toon", "ShaderNodeBsdfToon")
    for index in range(3):
        add_plane(staged, location=(index * 3, 0, 0), mat=toon, name=f"T{index}")
    description = gather(staged)
    warnings = [w for w in description.warnings if "Toon" in w]
    assert len(warnings) == 1 and "diffuse grey" in warnings[0]
    assert description.materials["material:Toon"] == S.Diffuse((0.5, 0.5, 0.5))


def test_unsupported_input_node_keeps_the_inputs_value_and_warns(staged):
    mat = material("Noisy", Color=(0.3, 0.3, 0.3, 1))
    noise = mat.node_tree.nodes.new("ShaderNodeTexNoise")
    mat.node_tree.links.new(noise.outputs["Color"], mat.node_tree.nodes["Diffuse BSDF"].inputs["Color"])
    add_plane(staged, mat=mat)
    description = gather(staged)
    assert description.materials["material:Noisy"] == S.Diffuse(pytest.approx((0.3, 0.3, 0.3)))
    assert any("Noise Texture" in w for w in description.warnings)


def test_image_textures_from_files_and_packed_pixels(staged, tmp_path):
    image = bpy.data.images.new("Painted", 4, 2)
    image.pixels.foreach_set(np.tile([1.0, 0.0, 0.0, 1.0], 8).astype(np.float32))
    mat, node = textured("Tex", image)
    node.interpolation = "Closest"
    add_plane(staged, mat=mat)
    texture = gather(staged).materials["material:Tex"].reflectance
    assert isinstance(texture, S.Texture) and texture.path is None
    assert texture.pixels.shape == (2, 4, 3) and np.allclose(texture.pixels, [1, 0, 0])
    assert texture.interpolation == "nearest"
    image.filepath_raw = str(tmp_path / "painted.png")
    image.file_format = "PNG"
    image.save()
    bpy.data.images.remove(image)
    node.image = bpy.data.images.load(str(tmp_path / "painted.png"))
    texture = gather(staged).materials["material:Tex"].reflectance
    assert texture.path == str(tmp_path / "painted.png") and texture.srgb


def test_missing_texture_renders_magenta_with_a_warning(staged, tmp_path):
    mat, _ = textured("Lost", missing_image(tmp_path / "gone.png"))
    add_plane(staged, mat=mat)
    description = gather(staged)
    texture = description.materials["material:Lost"].reflectance
    assert np.allclose(texture.pixels, [1, 0, 1])
    assert any("missing" in w and "gone" in w for w in description.warnings)


def test_textured_object_without_uvs_warns(staged):
    mat, _ = textured("Tex", bpy.data.images.new("img", 2, 2))
    plane = add_plane(staged, mat=mat)
    plane.data.uv_layers.remove(plane.data.uv_layers[0])
    description = gather(staged)
    assert description.shapes[0].mesh.uvs is None
    assert any("no UV map" in w for w in description.warnings)


def test_object_without_uvs_or_scratches_renders_silently(staged):
    plane = add_plane(staged, mat=material("Plain"))
    plane.data.uv_layers.remove(plane.data.uv_layers[0])
    add_light(staged, "SUN")
    assert gather(staged).warnings == ()


def test_a_nan_vertex_drops_its_triangles_with_a_warning(staged):
    plane = add_plane(staged, size=2.0)
    plane.data.calc_loop_triangles()
    corner = next(v for v in range(4) if sum(v in t.vertices for t in plane.data.loop_triangles) == 1)
    plane.data.vertices[corner].co = (math.nan, 0.0, 0.0)  # as a broken driver or script leaves it
    add_light(staged, "SUN")
    description = gather(staged)
    (shape,) = description.shapes
    assert shape.mesh.triangle_count == 1 and np.isfinite(shape.mesh.positions[shape.mesh.faces]).all()
    assert description.warnings == (f"mesh '{plane.name}': 1 of 2 triangles have NaN or infinite vertex "
                                    "positions or UVs and are not rendered",)


def test_empty_scene_warns_that_the_image_is_black(staged):
    assert any("no visible objects" in w for w in gather(staged).warnings)
    add_plane(staged)
    assert any("no lights" in w for w in gather(staged).warnings)


# ---- scratches ---------------------------------------------------------------------------------

def plate_scratches(count=50):
    return scratch.random_scratches(count, seed=3, width=scratch.Gaussian(4e-6, 1.3e-6),
                                    depth=scratch.Gaussian(250e-9, 80e-9), depth_variation=(1.1, 0.04))


def test_scratched_object_carries_its_scratches_and_settings(staged):
    staged.unit_settings.scale_length = 0.01  # one Blender unit is a centimetre
    plane = add_plane(staged, mat=material("Under"))
    storage.write_scratches(plane, plate_scratches())
    plane.scratch_iridescence.base_material = "Au"
    plane.scratch_iridescence.coherence_diameter_um = 40.0  # physical: the centimetre scene unit does not matter
    plane.scratch_iridescence.coherent = False
    plane.scratch_iridescence.diffuse_reflectance = (0.1, 0.0, 0.0)
    plane.scratch_iridescence.crossings = "height_field"
    plane.scratch_iridescence.depth_phase = "incidence"
    description = gather(staged)
    (shape,) = description.shapes
    metal = description.materials[shape.material]
    assert isinstance(metal, S.ScratchedMetal)
    assert metal.scratches == plate_scratches()
    assert metal.material == "Au" and metal.coherent is False and metal.metres_per_unit == pytest.approx(0.01)
    assert metal.coherence_diameter_m == pytest.approx(40e-6)
    assert metal.diffuse_reflectance == pytest.approx((0.1, 0.0, 0.0))
    assert (metal.crossings, metal.depth_phase) == ("height_field", "incidence")


def test_scratched_object_without_uvs_renders_unscratched_with_a_warning(staged):
    plane = add_plane(staged)
    storage.write_scratches(plane, plate_scratches())
    plane.data.uv_layers.remove(plane.data.uv_layers[0])
    description = gather(staged)
    assert description.materials[description.shapes[0].material].scratches.count == 0
    assert any("no UV map" in w and "scratches" in w for w in description.warnings)
