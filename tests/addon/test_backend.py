"""The bundled modules unusable in this Blender: one clear error for F12, Export and the viewport, never a crash.

Each case runs a fresh Blender (bpy) whose ``drjit`` is a stand-in put first on the path: one whose binary is
for another Python (Blender 4.2.0 installed a zip's CPython 3.13 wheels into its Python 3.11), one whose import
fails with the ``NameError`` that Dr.Jit's own error path raised there.
"""
import importlib.machinery
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("bpy")

ROOT = Path(__file__).resolve().parents[2]
OTHER_PYTHON = "3.13" if sys.version_info[:2] != (3, 13) else "3.11"

F12_EXPORT_AND_VIEWPORT = """
import os, sys
import bpy, scratch_iridescence
scratch_iridescence.register()
from scratch_iridescence.addon.render import backend
bpy.ops.wm.read_factory_settings(use_empty=False)
scene = bpy.context.scene
scene.render.engine = 'MITSUBA_SCRATCH'
scene.render.resolution_x, scene.render.resolution_y = 32, 24
scene.render.filepath = os.path.join(os.getcwd(), 'frame.png')
for attempt in (1, 2):
    try:
        bpy.ops.render.render(write_still=True)
        print('RENDERED')
    except RuntimeError as error:
        print('F12 ERROR', error)
try:
    bpy.ops.scratch.export_mitsuba(directory=os.path.join(os.getcwd(), 'export'))
    print('EXPORTED')
except RuntimeError as error:
    print('EXPORT ERROR', error)
print('VIEWPORT', backend.problem())
print('IMPORTED', open('imported.txt').read().count('x') if os.path.exists('imported.txt') else 0)
"""

#: A stand-in drjit: counts its imports in the working folder, then fails as Dr.Jit 1.5 did in Blender 4.2.0.
FAILING_INIT = """
open('imported.txt', 'a').write('x')
try:
    from . import _drjit_ext
except ImportError:
    filename = _drjit_ext.__file__
"""


def run(tmp_path, site):
    result = subprocess.run([sys.executable, "-c", F12_EXPORT_AND_VIEWPORT], capture_output=True, text=True,
                            cwd=tmp_path, timeout=600, env={"PYTHONPATH": str(site),
                                                            "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)})
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout


def stand_in(tmp_path, binary_python: str | None) -> Path:
    """A site folder whose ``drjit`` has a binary for ``binary_python`` (None: none) and FAILING_INIT."""
    site = tmp_path / "site"
    package = site / "drjit"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text(FAILING_INIT)
    if binary_python is not None:
        ours = next(s for s in importlib.machinery.EXTENSION_SUFFIXES if "311" in s or "313" in s)
        tag = "%d%d" % sys.version_info[:2]
        (package / f"_drjit_ext{ours.replace(tag, binary_python.replace('.', ''))}").write_bytes(b"\x7fELF")
    return site


def test_wheels_of_another_python_are_named_and_never_imported(tmp_path):
    out = run(tmp_path, stand_in(tmp_path, OTHER_PYTHON))
    running = "%d.%d" % sys.version_info[:2]
    message = f"The Mitsuba wheels installed with Scratch Iridescence are for Python {OTHER_PYTHON}, but this " \
              f"Blender runs Python {running} (drjit: _drjit_ext."
    assert out.count(f"F12 ERROR Error: {message}") == 2, out  # both F12 presses
    assert f"EXPORT ERROR Error: Export Mitsuba Scene: {message}" in out and f"VIEWPORT {message}" in out
    assert "install the zip built for your Blender version (scratch_iridescence-<version>-blender" in out
    assert "IMPORTED 0" in out  # the foreign binary module was never imported
    assert not (tmp_path / "frame.png").exists()


def test_any_import_failure_is_one_message_and_is_not_retried(tmp_path):
    out = run(tmp_path, stand_in(tmp_path, None))
    message = "Mitsuba is not available in Blender's Python (NameError: name '_drjit_ext' is not defined)"
    assert out.count(f"F12 ERROR Error: {message}") == 2, out
    assert f"EXPORT ERROR Error: Export Mitsuba Scene: {message}" in out
    assert "IMPORTED 1" in out  # the broken module was imported once, not again on every F12
