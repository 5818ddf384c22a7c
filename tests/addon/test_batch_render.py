"""Batch rendering as ``blender -b file.blend -E MITSUBA_SCRATCH -o //frames/shot_#### -F OPEN_EXR -a`` does it.

No Blender executable here: a fresh interpreter with the bpy module does, step by
step, what Blender's command line does with those arguments (docs/rendering.md,
"Batch rendering from the command line"): start with the extension enabled, open
the saved .blend, set the engine, the output path and format, then render the
animation (``-a``) or one frame (``-f N``, which Blender runs as a one-frame
animation).  The files must appear with Blender's own frame naming.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import add_camera, add_light, add_plane, bright_centroid, emission, material  # noqa: E402
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]

#: ``blender -b <blend> -E MITSUBA_SCRATCH -o <output> -F OPEN_EXR [-s S -e E] (-a | -f N)``, argument by argument.
COMMAND_LINE = r"""
import sys
import bpy, scratch_iridescence
blend, output, frames = sys.argv[1], sys.argv[2], sys.argv[3]
scratch_iridescence.register()                    # the extension, enabled in the user's preferences
bpy.ops.wm.open_mainfile(filepath=blend)          # -b file.blend
scene = bpy.context.scene
scene.render.engine = "MITSUBA_SCRATCH"           # -E MITSUBA_SCRATCH
scene.render.filepath = output                    # -o //frames/shot_####
scene.render.image_settings.file_format = "OPEN_EXR"  # -F OPEN_EXR
if frames == "all":                               # -a (the range saved in the file, or -s/-e)
    bpy.ops.render.render(animation=True)
else:                                             # -f N: Blender renders the range N..N
    scene.frame_start = scene.frame_end = int(frames)
    bpy.ops.render.render(animation=True)
print("DONE", scene.render.engine)
"""


@pytest.fixture
def saved_shot(empty_scene, tmp_path):
    """A saved .blend: a glowing square moving left to right over frames 1-3 above a grey floor, 32 x 24 px."""
    scene = empty_scene
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    scene.render.resolution_percentage = 100
    scene.scratch_iridescence.samples = 4
    scene.view_settings.view_transform = "Standard"
    add_camera(scene, location=(0, 0, 5))
    add_plane(scene, size=6, mat=material("Grey", Color=(0.2, 0.2, 0.2, 1)))
    add_light(scene, "SUN", energy=1.0)
    dot = add_plane(scene, size=0.6, location=(-1.5, 0, 0.01), mat=emission(strength=5.0), name="Dot")
    for frame, x in ((1, -1.5), (3, 1.5)):  # Bezier easing is symmetric: x = 0 at frame 2
        dot.location.x = x
        dot.keyframe_insert("location", frame=frame)
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.engine = "BLENDER_EEVEE"  # saved with another engine: -E must switch it
    path = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def run_command_line(blend: Path, output: str, frames: str) -> subprocess.CompletedProcess:
    env = {"PATH": "/usr/bin:/bin", "HOME": str(Path.home()), "TMPDIR": str(blend.parent)}
    if "DRJIT_LIBLLVM_PATH" in os.environ:
        env["DRJIT_LIBLLVM_PATH"] = os.environ["DRJIT_LIBLLVM_PATH"]
    return subprocess.run([sys.executable, "-c", COMMAND_LINE, str(blend), output, frames],
                          capture_output=True, text=True, cwd=ROOT, env=env, timeout=600)


def test_animation_and_single_frame_write_blenders_frame_names(saved_shot):
    folder = saved_shot.parent
    result = run_command_line(saved_shot, "//frames/shot_####", "all")
    assert result.returncode == 0 and "DONE MITSUBA_SCRATCH" in result.stdout, result.stdout + result.stderr
    # '//' is the .blend's folder; '####' becomes the zero-padded frame number, '.exr' is appended.
    assert sorted(p.name for p in (folder / "frames").iterdir()) == ["shot_0001.exr", "shot_0002.exr",
                                                                      "shot_0003.exr"]
    # Each file holds its own frame: the glowing square moves from left to right.
    x1, x2, x3 = (bright_centroid(read_exr(folder / "frames" / f"shot_{n:04d}.exr"), 2.0)[0] for n in (1, 2, 3))
    assert x1 < 12 < x2 < 20 < x3, (x1, x2, x3)

    result = run_command_line(saved_shot, "//single/shot_####", "2")
    assert result.returncode == 0, result.stdout + result.stderr
    assert [p.name for p in (folder / "single").iterdir()] == ["shot_0002.exr"]
    assert 12 < bright_centroid(read_exr(folder / "single" / "shot_0002.exr"), 2.0)[0] < 20
