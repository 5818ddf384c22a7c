"""The first render shows glints: Blender's startup cube, scratched with Generate, is a dark mirror under its
point light; the panel's check and the render report say so, and Add Glint Lighting (one click) adds the
sun that makes the render's brightest pixels diffraction-coloured."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import render_to  # noqa: E402
from test_ui import Layout  # noqa: E402
from scratch_iridescence.addon.ui import panels  # noqa: E402
from scratch_iridescence.addon.render.gather import gather_scene  # noqa: E402
from scratch_iridescence.addon.render.glints import GLINT_SUN_NAME, glint_check  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scene as S  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scratch  # noqa: E402
from scratch_iridescence.mitsuba_bridge.scene.glints import (check_glints, glint_reach,  # noqa: E402
                                                             mirror_light_direction)

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@pytest.fixture
def startup_cube(addon):
    """Blender's startup file (cube, point light, camera) with the cube scratched by Generate's defaults."""
    bpy.ops.wm.read_homefile(use_factory_startup=True)
    cube = bpy.data.objects["Cube"]
    bpy.context.view_layer.objects.active = cube
    cube.select_set(True)
    assert bpy.ops.scratch.generate() == {"FINISHED"}
    return cube


def glint_warnings():
    return [w for w in gather_scene(bpy.context.evaluated_depsgraph_get()).warnings if "glints" in w]


def panel_shows():
    """What the object's Scratches panel draws for the active object (a recording stand-in for the layout)."""
    layout = Layout()
    panels.SCRATCH_PT_scratches.draw(SimpleNamespace(layout=layout), bpy.context)
    return layout.shown


def chroma(rgb):
    """(max − min) / max per pixel: 0 for grey, 1 for a pure primary or secondary colour."""
    return (rgb.max(axis=-1) - rgb.min(axis=-1)) / np.maximum(rgb.max(axis=-1), 1e-12)


def test_startup_cube_is_found_unlit_and_one_click_lights_its_glints(startup_cube, tmp_path):
    check = glint_check(bpy.context, startup_cube)
    assert check is not None and not check.shows
    assert math.degrees(check.tilt) > math.degrees(check.reach)  # the point light is far off every mirror direction
    (warning,) = glint_warnings()
    assert "'Cube'" in warning and "Add Glint Lighting" in warning
    shown = panel_shows()
    assert "scratch.add_glint_lighting" in shown and "label:No light can show these glints" in shown

    assert bpy.ops.scratch.add_glint_lighting() == {"FINISHED"}
    sun = bpy.data.objects[GLINT_SUN_NAME]
    assert sun.type == "LIGHT" and sun.data.type == "SUN"
    assert sun.matrix_world.to_3x3().col[2].z > 0  # it shines from above the horizon
    check = glint_check(bpy.context, startup_cube)
    assert check.shows and check.tilt < math.radians(0.5)
    assert not glint_warnings() and "scratch.add_glint_lighting" not in panel_shows()

    scene = bpy.context.scene
    scene.render.engine = "MITSUBA_SCRATCH"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 96, 54, 100
    scene.scratch_iridescence.samples = 16
    scene.render.image_settings.file_format, scene.render.image_settings.color_depth = "OPEN_EXR", "32"
    image = render_to(scene, tmp_path / "first.exr")[..., :3]
    luminance = image @ LUMINANCE
    brightest = image[luminance >= np.quantile(luminance, 0.98)]
    # diffraction colours: the brightest 2 % are strongly coloured (measured 0.49; grey and white are 0)
    assert chroma(brightest).mean() > 0.25
    # they stand out of the dark mirror, which reflects the grey world (measured 8.7×)
    assert np.quantile(luminance, 0.98) > 5 * np.quantile(luminance, 0.5)
    # and are not clipped: through the file's own view transform (AgX), as the artist sees them, few pixels reach
    # white in any channel (measured 0.31 %; with a 0.1 W/m² sun 0.77 %, Blender's default 1 W/m² 2.1 %)
    bpy.data.images["Render Result"].save_render(str(tmp_path / "first.png"), scene=_png(scene))
    scene.render.image_settings.file_format, scene.render.image_settings.color_depth = "OPEN_EXR", "32"
    shown = np.asarray(bpy.data.images.load(str(tmp_path / "first.png")).pixels[:]).reshape(54, 96, 4)[..., :3]
    assert (shown.max(axis=-1) >= 254 / 255).mean() < 0.006
    # the control: the same cube and lights without scratches render its grey material; only the spectral
    # noise of 16 samples colours its brightest pixels (measured 0.15): the threshold lies between
    assert bpy.ops.scratch.clear() == {"FINISHED"}
    plain = render_to(scene, tmp_path / "plain.exr")[..., :3]
    luminance = plain @ LUMINANCE
    assert chroma(plain[luminance >= np.quantile(luminance, 0.98)]).mean() < 0.25


def _png(scene):
    """``scene`` with 8-bit PNG output settings (the view transform applies to such saves)."""
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = "PNG", "8", "RGB"
    return scene


def test_check_geometry_against_closed_forms():
    """A flat plate facing up seen from 45°: a sun in its mirror direction shows glints, one 60° away does
    not, a uniform world never does, an environment map always may."""
    plate = (np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
    scratches = scratch.random_scratches(50, seed=1, width=scratch.Constant(4e-6), length=(0.1, 0.2))
    eye = np.array([0.0, -1.0, 1.0]) / math.sqrt(2)
    camera = S.Camera(np.array([[1, 0, 0, 0], [0, math.cos(math.pi / 4), -math.sin(math.pi / 4), -3],
                                [0, math.sin(math.pi / 4), math.cos(math.pi / 4), 3], [0, 0, 0, 1.0]]))
    mirror = np.array([0.0, 1.0, 1.0]) / math.sqrt(2)  # where the plate mirrors the camera
    assert np.allclose(camera.to_world[:3, 3] / np.linalg.norm(camera.to_world[:3, 3]), eye)
    direction, point = mirror_light_direction(plate, camera)
    assert np.allclose(direction, mirror) and np.allclose(point, 0.0)
    sun = lambda towards: S.SunLight(tuple(-np.asarray(towards)), (1.0, 1.0, 1.0))  # noqa: E731
    assert check_glints(plate, scratches, camera, [sun(mirror)], None).shows
    tilted = np.array([0.0, math.cos(math.radians(105)), math.sin(math.radians(105))])  # 60° from the mirror
    away = check_glints(plate, scratches, camera, [sun(tilted)], None)
    assert not away.shows and math.degrees(away.tilt) == pytest.approx(30.0, abs=0.01)  # the half vector: half
    assert not check_glints(plate, scratches, camera, [], S.ConstantWorld((1.0, 1.0, 1.0))).shows
    environment = S.EnvironmentWorld(S.Texture("sky", pixels=np.ones((2, 4, 3), np.float32)))
    assert check_glints(plate, scratches, camera, [], environment).shows
    # the reach: a triangular groove's slope plus two diffraction orders of the longest visible wavelength
    for profile in scratch.Profile:
        single = scratch.random_scratches(1, seed=2, width=scratch.Constant(4e-6), profile=profile)
        slope = math.atan(2 * 250e-9 / 4e-6) if profile == scratch.Profile.TRIANGULAR else 0.0
        assert glint_reach(single) == pytest.approx(slope + 0.5 * math.asin(2 * 700e-9 / 4e-6))


def test_an_environment_map_or_an_emissive_object_counts_as_able(startup_cube):
    """The panel's check does not read images: an environment map is assumed to hold bright spots that glint,
    and an emissive object is an extended light; either silences the warning."""
    world = bpy.context.scene.world
    tree = world.node_tree
    environment = tree.nodes.new("ShaderNodeTexEnvironment")
    environment.image = bpy.data.images.new("sky", 8, 4, float_buffer=True)
    tree.links.new(environment.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    assert glint_check(bpy.context, startup_cube).shows
    tree.nodes.remove(environment)
    assert not glint_check(bpy.context, startup_cube).shows
    bpy.ops.mesh.primitive_plane_add(location=(0, 0, 5))
    glow = bpy.data.materials.new("Glow")
    glow.node_tree.nodes["Principled BSDF"].inputs["Emission Strength"].default_value = 2.0
    bpy.context.active_object.data.materials.append(glow)
    assert glint_check(bpy.context, startup_cube).shows
