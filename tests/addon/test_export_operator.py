"""File > Export > Mitsuba Scene: a folder the command line renders like the engine does."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import add_camera, add_light, add_plane, emission, render_to, setup_render, textured  # noqa: E402
from scratch_iridescence.mitsuba_bridge.exr import read_exr, write_exr  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def striped_scene(empty_scene, tmp_path):
    setup_render(empty_scene, 40, 30, samples=16)
    add_camera(empty_scene, location=(0.2, -0.1, 5), lens=40)
    write_exr(tmp_path / "stripes.exr", np.kron(np.arange(4) % 2, np.ones(4))[None, :, None].repeat(8, 0)
              * np.ones(3, np.float32))
    add_plane(empty_scene, size=3, mat=textured("Striped", bpy.data.images.load(str(tmp_path / "stripes.exr")))[0])
    add_plane(empty_scene, size=0.4, location=(1, 1, 0.5), mat=emission(strength=4), name="Lamp")
    add_light(empty_scene, "SUN", energy=2)
    return empty_scene


def test_export_writes_a_self_contained_folder(striped_scene, tmp_path):
    assert bpy.ops.scratch.export_mitsuba(directory=str(tmp_path / "scene")) == {"FINISHED"}
    files = sorted(str(p.relative_to(tmp_path / "scene")) for p in (tmp_path / "scene").rglob("*") if p.is_file())
    assert files == ["meshes/Lamp.ply", "meshes/Plane.ply", "scene.xml", "textures/stripes.exr"]


def test_command_line_render_of_the_export_matches_the_engine(striped_scene, tmp_path):
    # 1024 samples (the export carries them to the command line): the ratio of the two means spreads by
    # 0.65 % over seeds at 128, 2.7 sigma inside the 2 % tolerance; about 0.23 % here.
    striped_scene.scratch_iridescence.samples = 1024
    engine_image = render_to(striped_scene, tmp_path / "engine.exr")
    bpy.ops.scratch.export_mitsuba(directory=str(tmp_path / "scene"))
    cli = [sys.executable, "-m", "scratch_iridescence.mitsuba_bridge"]
    result = subprocess.run([*cli, "render", str(tmp_path / "scene"),
                             "-o", str(tmp_path / "cli.exr")], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    cli_image = read_exr(tmp_path / "cli.exr")
    assert cli_image.shape == engine_image.shape == (30, 40, 4)
    # Same picture up to Monte Carlo noise (the two scenes list their emitters in another order, so
    # even equal seeds draw different samples); alpha is Mitsuba's coverage in the command line's EXR.
    cli, engine = cli_image[..., :3], engine_image[..., :3]
    assert engine.mean() > 0.1 and cli.mean() == pytest.approx(engine.mean(), rel=0.02)
    assert np.corrcoef(cli[..., 1].ravel(), engine[..., 1].ravel())[0, 1] > 0.98


def test_export_without_a_camera_reports_an_error(empty_scene, tmp_path):
    add_plane(empty_scene)
    with pytest.raises(RuntimeError, match="no active camera"):
        bpy.ops.scratch.export_mitsuba(directory=str(tmp_path / "scene"))
    assert not (tmp_path / "scene" / "scene.xml").exists()
