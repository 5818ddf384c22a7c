"""``render-frames`` and ``export-frames``: an animation exported with pip's bpy (no Blender binary) and
rendered frame by frame, here or on a ``LocalCluster``; each frame is its exported folder's one-machine render."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from scratch_iridescence.mitsuba_bridge.cli.main import main  # noqa: E402
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr  # noqa: E402

VARIANT = ["--variant", "llvm_ad_spectral"]


@pytest.fixture(scope="module")
def blend(tmp_path_factory):
    """The moving square of the farm tests (tests/farm/moving_square.py), saved by a separate bpy process."""
    path = tmp_path_factory.mktemp("shot") / "shot.blend"
    subprocess.run([sys.executable, str(Path(__file__).parents[1] / "farm" / "moving_square.py"), str(path)],
                   check=True, capture_output=True)
    return path


def bright_x(image):
    columns = np.nonzero(image[..., :3].mean(axis=(0, 2)) > 0.5)[0]
    return columns.mean()


@pytest.fixture(scope="module")
def rendered(blend, tmp_path_factory):
    out = tmp_path_factory.mktemp("frames")
    assert main(["render-frames", str(blend), "--frames", "1-3", "-o", str(out / "frame_####.exr"), "-q",
                 *VARIANT]) == 0
    return out


def test01_render_frames_writes_each_frame_showing_its_own_time(rendered):
    assert sorted(p.name for p in rendered.iterdir()) == ["frame_0001.exr", "frame_0002.exr", "frame_0003.exr"]
    xs = [bright_x(read_exr(rendered / f"frame_000{n}.exr")) for n in (1, 2, 3)]
    assert xs[0] < xs[1] < xs[2], xs  # the square moves left to right


def test02_a_frame_is_its_exported_folders_render_bit_for_bit(blend, rendered, tmp_path):
    assert main(["export-frames", str(blend), "--frames", "2", "-o", str(tmp_path / "scene_####")]) == 0
    assert (tmp_path / "scene_0002" / "scene.xml").is_file()
    assert main(["render", str(tmp_path / "scene_0002"), "-o", str(tmp_path / "two.exr"), "-q", *VARIANT]) == 0
    assert read_exr(tmp_path / "two.exr").tobytes() == read_exr(rendered / "frame_0002.exr").tobytes()


def test03_bad_frames_and_files_are_one_line_errors(blend, tmp_path):
    def refused(*argv):
        result = subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", *map(str, argv)],
                                capture_output=True, text=True)
        error = result.stderr.strip()
        assert result.returncode in (1, 2) and "\n" not in error and error.startswith("error: "), error
        return error

    assert "expected numbers and ranges" in refused("render-frames", blend, "--frames", "1-x", "-o",
                                                    tmp_path / "f_#.exr")
    assert "need a # in the name" in refused("render-frames", blend, "--frames", "1-2", "-o", tmp_path / "f.exr")
    assert "no such .blend file" in refused("render-frames", tmp_path / "none.blend", "--frames", "1", "-o",
                                            tmp_path / "f_#.exr")


@pytest.mark.slow
def test04_frames_on_a_local_cluster_equal_the_frames_rendered_here(blend, rendered, tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR", str(tmp_path / "cache"))
    result = subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render-frames", str(blend),
                             "--frames", "1-3", "-o", str(tmp_path / "frame_####.exr"), "--cluster", "local:2",
                             *VARIANT], capture_output=True, text=True, timeout=900, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "shot.blend" in result.stdout and "sent to 2 of 2 workers" in result.stdout
    for n in (1, 2, 3):
        assert read_exr(tmp_path / f"frame_000{n}.exr").tobytes() == read_exr(rendered / f"frame_000{n}.exr").tobytes()
