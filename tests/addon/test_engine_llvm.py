"""F12 with only LLVM 15 available: the engine reports what to install and Blender keeps running.

Before the check, this render aborted the process (SIGABRT, exit 134) and the
user's unsaved work was lost.  Runs in a fresh interpreter whose Dr.Jit is
pointed at a real libLLVM 15 (Debian's ``libllvm15``) with an empty kernel cache.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("bpy")

ROOT = Path(__file__).resolve().parents[2]

F12_THEN_SAVE = r"""
import sys
import bpy, scratch_iridescence
output, blend = sys.argv[1], sys.argv[2]
scratch_iridescence.register()
bpy.ops.wm.read_factory_settings(use_empty=False)  # the default cube, camera and light
scene = bpy.context.scene
scene.render.engine = "MITSUBA_SCRATCH"
scene.render.resolution_x, scene.render.resolution_y = 32, 24
scene.scratch_iridescence.samples = 4
scene.render.filepath = output
try:
    bpy.ops.render.render(write_still=True)
    print("RENDERED")
except RuntimeError as error:
    print("ERROR", error)
bpy.ops.wm.save_as_mainfile(filepath=blend)  # the user's work survives
print("SAVED")
"""


def test_f12_with_llvm15_is_an_error_and_the_work_can_still_be_saved(tmp_path, llvm15):
    env = {"PATH": "/usr/bin:/bin", "HOME": str(Path.home()), "TMPDIR": str(tmp_path),
           "DRJIT_CACHE_DIR": str(tmp_path / "drjit-cache"), "DRJIT_LIBLLVM_PATH": llvm15}
    output, blend = tmp_path / "out.png", tmp_path / "work.blend"
    result = subprocess.run([sys.executable, "-c", F12_THEN_SAVE, str(output), str(blend)], capture_output=True,
                            text=True, cwd=ROOT, env=env, timeout=300)
    log = result.stdout + result.stderr
    assert result.returncode == 0, log  # not -SIGABRT
    assert "ERROR Error: Mitsuba's CPU backend found LLVM 15.0" in result.stdout, log
    assert "apt install libllvm19" in result.stdout and "LLVM ERROR" not in log
    assert "SAVED" in result.stdout and blend.is_file() and os.path.getsize(blend) > 0
    assert not output.exists()
