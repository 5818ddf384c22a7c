"""The demo (``make demo``) at a tiny resolution: scene saved, rendered through the engine, EXR and PNG written."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def run_demo(output, *extra):
    result = subprocess.run([sys.executable, "-m", "scratch_iridescence.scenes.demo", "--output", str(output),
                             "--resolution", "120", "75", "--samples", "16", *extra],
                            capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    return output, result.stdout


@pytest.fixture(scope="module")
def tiny_demo(tmp_path_factory):
    return run_demo(tmp_path_factory.mktemp("demo"))


def glint_statistics(output):
    """(p99 / median luminance, share of strongly coloured pixels among the brightest tenth) on the plate."""
    plate = read_exr(output / "demo.exr")[25:70, 25:95, :3]  # inside the plate in this camera's frame
    luminance = plate.mean(axis=-1)
    bright = plate[luminance > np.percentile(luminance, 90)]
    chroma = (bright.max(axis=-1) - bright.min(axis=-1)) / bright.mean(axis=-1)
    return np.percentile(luminance, 99) / np.median(luminance), np.mean(chroma > 0.5)


def test_demo_writes_blend_exr_and_png_and_prints_progress(tiny_demo):
    output, log = tiny_demo
    assert (output / "demo.blend").is_file() and (output / "demo.png").is_file()
    assert read_exr(output / "demo.exr").shape == (75, 120, 4)
    assert "Sample 16/16" in log and "demo: wrote" in log


def test_demo_blend_holds_the_scratched_plate_under_a_sky(tiny_demo, addon):
    from scratch_iridescence.addon import storage

    output, _ = tiny_demo
    bpy.ops.wm.open_mainfile(filepath=str(output / "demo.blend"))
    scene = bpy.context.scene
    plate = bpy.data.objects["Scratched plate"]
    scratches = storage.read_scratches(plate)
    assert scratches.count == 3000
    assert 3.5e-6 < scratches.width.mean() < 4.5e-6 and 220e-9 < scratches.depth.mean() < 280e-9
    assert np.allclose(scratches.depth_variation, (1.1, 0.04))
    assert scene.render.engine == "MITSUBA_SCRATCH" and scene.camera is not None
    sky = [node for node in scene.world.node_tree.nodes if node.bl_idname == "ShaderNodeTexSky"]
    assert len(sky) == 1 and sky[0].sun_disc


def test_demo_plate_shows_coloured_glints_that_a_plain_plate_lacks(tiny_demo, tmp_path):
    contrast, coloured = glint_statistics(tiny_demo[0])
    plain_contrast, plain_coloured = glint_statistics(run_demo(tmp_path, "--scratches", "0")[0])
    # Scratched: sparse glints far brighter than the sky in the mirror, most of the brightest coloured.
    assert contrast > 5 and coloured > 0.3
    # The same plate without scratches is a mirror of the sky: smooth and nearly grey.
    assert plain_contrast < 4 and plain_coloured < 0.1
