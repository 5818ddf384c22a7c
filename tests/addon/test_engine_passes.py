"""Blender's data passes through the engine: Depth, Denoising Albedo and Denoising Normal exist when the view
layer asks for them, hold what Cycles writes (a diffuse plane's base colour, its normal in Cycles' camera
space, the distance along the camera's axis; the same scene rendered by Cycles), and feed the
compositor's Denoise node headless."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import add_camera, add_plane, material, set_world, setup_render  # noqa: E402
from test_ui import Layout  # noqa: E402
from scratch_iridescence.addon.render import panels  # noqa: E402
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr  # noqa: E402

WIDTH, HEIGHT = 32, 24
BASE = (0.8, 0.3, 0.1)
TILT = math.radians(30)  # the camera looks 30° away from straight down
CAMERA = (0.0, -1.0, 2.0)


def staged_plane(scene, engine="MITSUBA_SCRATCH", samples=16, *, passes=True):
    setup_render(scene, WIDTH, HEIGHT, samples=samples, engine=engine)
    if engine == "CYCLES":
        scene.cycles.samples, scene.cycles.device, scene.cycles.use_denoising = samples, "CPU", False
        scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
        scene.view_layers[0].cycles.denoising_store_passes = passes
    else:
        scene.scratch_iridescence.denoising_data = passes
    scene.view_layers[0].use_pass_z = passes
    add_plane(scene, size=6.0, mat=material("Base", Color=(*BASE, 1)))
    add_camera(scene, location=CAMERA, rotation=(TILT, 0, 0))
    set_world(scene, (0.05, 0.05, 0.05))
    return scene


def compositor(scene):
    """The scene's compositor: a Render Layers node and the Group Output (what ``write_still`` saves)."""
    tree = bpy.data.node_groups.new("Passes", "CompositorNodeTree")
    scene.compositing_node_group = tree
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    return tree, tree.nodes.new("CompositorNodeRLayers"), tree.nodes.new("NodeGroupOutput")


def render_pass(scene, name, path):
    """The render pass ``name`` (H, W, 3), row 0 at the top, read back from the EXR the compositor writes."""
    tree, layers, output = compositor(scene)
    tree.links.new(layers.outputs[name], output.inputs[0])
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    bpy.data.node_groups.remove(tree)
    return read_exr(path)[..., :3]


def camera_space_normal():
    """The plane's normal (world +Z) in Cycles' camera space: Blender's camera x, y and −z."""
    return np.array([0.0, math.sin(TILT), -math.cos(TILT)])


def expected_depth():
    """Distance along the camera's axis to the plane at each pixel centre (row 0 at the top)."""
    focal = 50.0 / 36.0  # Blender's default lens over the sensor width (fit Auto, landscape)
    xs = ((np.arange(WIDTH) + 0.5) / WIDTH - 0.5)
    ys = (0.5 - (np.arange(HEIGHT) + 0.5) / HEIGHT) * HEIGHT / WIDTH
    x, y = np.meshgrid(xs, ys)
    # camera frame in the world: right (1, 0, 0), up (0, cos, sin), forward (0, sin, −cos)
    up, forward = np.array([0, math.cos(TILT), math.sin(TILT)]), np.array([0, math.sin(TILT), -math.cos(TILT)])
    directions = x[..., None] * np.array([1, 0, 0]) + y[..., None] * up + focal * forward
    t = -CAMERA[2] / directions[..., 2]  # where each ray meets z = 0
    points = np.array(CAMERA) + t[..., None] * directions
    return (points - np.array(CAMERA)) @ forward


def test_passes_are_registered_only_when_the_view_layer_asks(empty_scene):
    scene = staged_plane(empty_scene, passes=False)
    _, layers, _ = compositor(scene)
    assert [o.name for o in layers.outputs if o.enabled] == ["Image", "Alpha"]
    scene.view_layers[0].use_pass_z = True
    scene.scratch_iridescence.denoising_data = True
    assert {o.name for o in layers.outputs if o.enabled} == {"Image", "Alpha", "Depth", "Denoising Normal",
                                                             "Denoising Albedo"}
    # View Layer Properties › Passes shows both switches for this engine
    layout = Layout()
    panels.SCRATCH_PT_view_layer_passes.draw(SimpleNamespace(layout=layout), bpy.context)
    assert {"use_pass_combined", "use_pass_z", "denoising_data"} <= set(layout.shown)


def test_passes_hold_base_colour_camera_space_normal_and_axis_depth(empty_scene, tmp_path):
    scene = staged_plane(empty_scene)
    albedo = render_pass(scene, "Denoising Albedo", tmp_path / "albedo.exr")
    np.testing.assert_allclose(albedo.reshape(-1, 3), np.broadcast_to(BASE, (WIDTH * HEIGHT, 3)), atol=0.005)
    normal = render_pass(scene, "Denoising Normal", tmp_path / "normal.exr")
    np.testing.assert_allclose(normal.reshape(-1, 3), np.broadcast_to(camera_space_normal(), (WIDTH * HEIGHT, 3)),
                               atol=1e-4)
    depth = render_pass(scene, "Depth", tmp_path / "depth.exr")[..., 0]
    # a pixel's 16 samples spread over it: their mean depth scatters around the centre's by 0.07 % (one σ)
    np.testing.assert_allclose(depth, expected_depth(), rtol=0.005)
    assert np.mean(depth / expected_depth() - 1) == pytest.approx(0.0, abs=2e-4)
    combined = render_pass(scene, "Image", tmp_path / "combined.exr")
    assert combined.mean() == pytest.approx(np.mean(BASE) * 0.05, rel=0.1)  # the plane lit by the dim world


def test_background_has_cycles_depth_and_no_normal(empty_scene, tmp_path):
    scene = staged_plane(empty_scene)
    scene.camera.rotation_euler = (math.radians(100), 0, 0)  # above the horizon: only the world is seen
    depth = render_pass(scene, "Depth", tmp_path / "depth.exr")
    normal = render_pass(scene, "Denoising Normal", tmp_path / "normal.exr")
    albedo = render_pass(scene, "Denoising Albedo", tmp_path / "albedo.exr")
    assert (depth == 1e10).all() and (normal == 0).all()
    # the world's colour, as Cycles' background albedo (here the image's there: its spectral noise included)
    assert albedo.mean(axis=(0, 1)) == pytest.approx([0.05] * 3, rel=0.03)


def test_passes_agree_with_cycles(cycles, tmp_path):
    ours, theirs = {}, {}
    for engine, store in (("MITSUBA_SCRATCH", ours), ("CYCLES", theirs)):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = staged_plane(bpy.context.scene, engine=engine)
        for name in ("Denoising Albedo", "Denoising Normal", "Depth"):
            store[name] = render_pass(scene, name, tmp_path / f"{engine}-{name}.exr")
    # Cycles adds its Principled specular's share to the albedo (≈ 1 %) and writes one sample's depth per pixel
    np.testing.assert_allclose(ours["Denoising Albedo"], theirs["Denoising Albedo"], atol=0.03)
    np.testing.assert_allclose(ours["Denoising Normal"], theirs["Denoising Normal"], atol=1e-3)
    np.testing.assert_allclose(ours["Depth"], theirs["Depth"], rtol=0.01)


def test_denoise_node_runs_headless_and_brings_the_image_closer_to_the_converged_one(empty_scene, tmp_path):
    scene = staged_plane(empty_scene, samples=512)
    reference = render_pass(scene, "Image", tmp_path / "reference.exr")
    scene.scratch_iridescence.samples = 2
    noisy = render_pass(scene, "Image", tmp_path / "noisy.exr")
    tree, layers, output = compositor(scene)
    denoise = tree.nodes.new("CompositorNodeDenoise")
    for name in ("Image", "Albedo", "Normal"):
        source = {"Image": "Image", "Albedo": "Denoising Albedo", "Normal": "Denoising Normal"}[name]
        tree.links.new(layers.outputs[source], denoise.inputs[name])
    tree.links.new(denoise.outputs["Image"], output.inputs[0])
    scene.render.filepath = str(tmp_path / "denoised.exr")
    bpy.ops.render.render(write_still=True)
    denoised = read_exr(tmp_path / "denoised.exr")[..., :3]
    error = lambda image: np.abs(image - reference).mean() / reference.mean()  # noqa: E731
    assert np.isfinite(denoised).all()
    assert error(denoised) < 0.5 * error(noisy)
