"""Export folders: scene.xml + PLY + textures (+ scratch files), rendered without Blender."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_scenes import camera_at, quad, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge.folder import export
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr, write_exr
from scratch_iridescence.mitsuba_bridge.folder.ply import write_ply

ROOT = Path(__file__).resolve().parents[3]

#: The bridge's command line.
CLI = [sys.executable, "-m", "scratch_iridescence.mitsuba_bridge"]


def rich_scene(tmp_path):
    """Textures from a file and from pixels, an instanced mesh, every light and a sky."""
    image_file = tmp_path / "source" / "checker.exr"
    image_file.parent.mkdir()
    checker = np.kron(np.indices((4, 4)).sum(axis=0) % 2, np.ones((4, 4)))[..., None] * np.array([1.0, 0.5, 0.2])
    write_exr(image_file, checker.astype(np.float32))
    file_texture = S.Texture("checker.exr", path=str(image_file), srgb=False)
    pixel_texture = S.Texture("ramp", pixels=np.linspace(0, 1, 48, dtype=np.float32).reshape(4, 4, 3), srgb=True)
    mesh = quad(1.0, "tile")
    shapes = []
    for i, key in enumerate(("file", "pixels", "file")):
        matrix = np.eye(4)
        matrix[:3, 3] = (i - 1.0, 0, 0)
        shapes.append(S.Shape(f"tile{i}", mesh, matrix, key))
    spot = np.eye(4)
    spot[:3, 3] = (0, 0, 2)
    area = spot.copy()
    area[:3, 3] = (0.5, 0.5, 1.5)
    return simple_scene(
        film=S.Film(40, 30, crop=(5, 5, 30, 20)),
        camera=S.Camera(camera_at((0, 0, 3)), fov_x_deg=70, shift_x=0.05),
        shapes=shapes,
        materials={"file": S.Principled(base_color=file_texture, roughness=0.4),
                   "pixels": S.Diffuse(pixel_texture)},
        lights=[S.PointLight((1, 1, 1), (1, 1, 1)), S.SpotLight(spot, (2, 2, 2), 40, 30),
                S.SunLight((0.2, 0.1, -1), (0.5, 0.5, 0.5)), S.AreaLight(area, "disk", 0.3, 0.2, (3, 3, 3))],
        world=S.SkyWorld((0.3, 0.5, 0.8)))


def test01_folder_holds_scene_meshes_and_textures_with_relative_paths(variant, tmp_path):
    scene_file = export.export_folder(rich_scene(tmp_path), S.RenderSettings(spp=4), tmp_path / "out")
    files = sorted(str(p.relative_to(tmp_path / "out")) for p in (tmp_path / "out").rglob("*") if p.is_file())
    assert files == ["meshes/tile.ply", "scene.xml", "textures/checker.exr", "textures/ramp.exr"]
    text = scene_file.read_text()
    assert str(tmp_path) not in text  # relocatable
    assert text.count('<bsdf type="twosided" id=') == 2
    # The two "file" tiles share the mesh and material: one shapegroup, two instances; the third its own shape.
    assert text.count("meshes/tile.ply") == 2 and text.count('type="instance"') == 2


def test02_exported_folder_renders_like_the_in_memory_scene(variant, tmp_path):
    description = rich_scene(tmp_path)
    export.export_folder(description, S.RenderSettings(spp=4), tmp_path / "out")
    moved = tmp_path / "moved"
    (tmp_path / "out").rename(moved)  # a self-contained folder still renders after moving
    # The same schedule and seed: the same samples (a fixed schedule, whatever the timing).
    from scratch_iridescence.mitsuba_bridge.render import passes as render

    from_files = render.render_image(export.load_folder(moved), 16, seed=3)
    in_memory = render.render_image(builder.load_scene(description, S.RenderSettings()), 16, seed=3)
    assert from_files.shape == (20, 30, 4)
    assert np.allclose(from_files, in_memory, atol=1e-4)


def test03_ply_files_round_trip_through_mitsuba(variant, tmp_path):
    import mitsuba as mi

    rng = np.random.default_rng(0)
    positions = rng.random((50, 3)).astype(np.float32)
    normals = rng.random((50, 3)).astype(np.float32)
    uvs = rng.random((50, 2)).astype(np.float32)
    faces = rng.integers(0, 50, (30, 3)).astype(np.uint32)
    write_ply(tmp_path / "m.ply", positions, faces, normals, uvs)
    params = mi.traverse(mi.load_dict({"type": "ply", "filename": str(tmp_path / "m.ply")}))
    assert np.allclose(np.array(params["vertex_positions"]).reshape(-1, 3), positions)
    assert np.allclose(np.array(params["vertex_texcoords"]).reshape(-1, 2), uvs)
    assert np.array_equal(np.array(params["faces"]).reshape(-1, 3), faces)


def test04_command_line_renders_an_exported_folder_to_exr(variant, tmp_path):
    export.export_folder(rich_scene(tmp_path), S.RenderSettings(spp=4), tmp_path / "out")
    output = tmp_path / "image.exr"
    result = subprocess.run([*CLI, "render", str(tmp_path / "out"), "-o",
                             str(output), "--spp", "8"], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert "8/8 spp" in result.stdout and output.is_file()
    image = read_exr(output)
    assert image.shape == (20, 30, 4) and np.isfinite(image).all() and image[..., :3].mean() > 0.01


def test05_command_line_explains_a_missing_folder(tmp_path):
    result = subprocess.run([*CLI, "render", str(tmp_path / "nothing"), "-o",
                             str(tmp_path / "x.exr")], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 1 and "no such scene file" in result.stderr
    assert not (tmp_path / "x.exr").exists()


def test06_in_memory_objects_cannot_be_written_as_xml(variant):
    import mitsuba as mi
    from scratch_iridescence.mitsuba_bridge.folder.scenexml import dict_to_xml

    with pytest.raises(TypeError, match="cannot write"):
        dict_to_xml({"type": "scene", "a": {"type": "diffuse", "reflectance": mi.Bitmap(np.zeros((2, 2, 3)))}})


def test07_exr_round_trips_rgb_and_rgba(tmp_path):
    for channels in (3, 4):
        image = np.random.default_rng(channels).random((5, 7, channels)).astype(np.float32)
        write_exr(tmp_path / "a.exr", image)
        assert np.array_equal(read_exr(tmp_path / "a.exr"), image)


def scratched_scene(count, seed):
    from scratch_iridescence.mitsuba_bridge import scratch

    plate = S.ScratchedMetal(scratches=scratch.random_scratches(count, seed=seed), coherence_diameter_m=30e-6)
    return simple_scene(shapes=[S.Shape("plate", quad(1.0, "plate"), np.eye(4), "plate")],
                        materials={"plate": plate}, world=S.ConstantWorld((0.5, 0.5, 0.5)))


def folder_bytes(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test08_a_failed_re_export_leaves_the_previous_export_whole(variant, tmp_path, monkeypatch):
    export.export_folder(scratched_scene(20, seed=1), S.RenderSettings(), tmp_path / "out")
    (tmp_path / "out" / "notes.txt").write_text("mine")
    before = folder_bytes(tmp_path / "out")

    def full_disk(path, *args, **kwargs):
        assert (Path(path).parents[1] / "scratches" / "plate.npz").is_file()  # the new scratches are written
        raise OSError(28, "No space left on device")

    # Scratch files are written before meshes: the failure comes after the new scratch file exists.
    monkeypatch.setattr("scratch_iridescence.mitsuba_bridge.folder.resources.write_ply", full_disk)
    with pytest.raises(OSError, match="No space left"):
        export.export_folder(scratched_scene(30, seed=2), S.RenderSettings(), tmp_path / "out")
    assert folder_bytes(tmp_path / "out") == before  # old scene.xml with its own scratches, the user's file
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["meshes", "notes.txt", "scene.xml", "scratches"]


def test09_a_re_export_replaces_the_exported_files_and_keeps_others(variant, tmp_path):
    from scratch_iridescence.mitsuba_bridge import scratch

    export.export_folder(scratched_scene(20, seed=1), S.RenderSettings(), tmp_path / "out")
    (tmp_path / "out" / "render.exr").write_bytes(b"the user's render")
    export.export_folder(simple_scene(), S.RenderSettings(), tmp_path / "out")  # no scratches any more
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["meshes", "render.exr", "scene.xml"]
    assert (tmp_path / "out" / "render.exr").read_bytes() == b"the user's render"
    export.export_folder(scratched_scene(30, seed=2), S.RenderSettings(), tmp_path / "out")
    assert scratch.load(tmp_path / "out" / "scratches" / "plate.npz").count == 30


def test10_loading_a_folder_leaves_the_working_directory_alone(variant, tmp_path, monkeypatch):
    export.export_folder(scratched_scene(20, seed=1), S.RenderSettings(), tmp_path / "out")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # relative paths in scene.xml must resolve against the folder, not here
    scene = export.load_folder(tmp_path / "out")
    assert os.getcwd() == str(elsewhere)
    assert "scratches=20," in str(scene.shapes()[0].bsdf())


def test11_plugin_options_travel_through_the_exported_folder(variant, tmp_path):
    """``crossings`` and ``depth_phase`` reach scene.xml and the BSDF loaded from it (defaults stay unwritten)."""
    import dataclasses

    description = scratched_scene(20, seed=4)
    metal = dataclasses.replace(description.materials["plate"], crossings="height_field", depth_phase="incidence")
    export.export_folder(dataclasses.replace(description, materials={"plate": metal}), S.RenderSettings(spp=4),
                         tmp_path / "options")
    text = (tmp_path / "options" / "scene.xml").read_text()
    assert '<string name="crossings" value="height_field"/>' in text
    assert '<string name="depth_phase" value="incidence"/>' in text
    loaded = str(export.load_folder(tmp_path / "options").shapes()[0].bsdf())
    assert "crossings=height_field" in loaded and "depth_phase=incidence" in loaded
    export.export_folder(description, S.RenderSettings(spp=4), tmp_path / "defaults")
    assert "crossings" not in (tmp_path / "defaults" / "scene.xml").read_text()
