"""Export folders made from a .blend without Blender's executable: the add-on's frame export, run with pip's ``bpy``.

The bridge never imports ``bpy`` (tests/test_layout.py): it runs the add-on's
:mod:`addon.render.frames` as a subprocess of this Python, which must have the
``bpy`` module (``pip install bpy==5.0.1`` on CPython 3.11).  ``render-frames``
exports with it on the driver, and each Dask worker exports the frames it is
given (no shared disk needed).
"""
from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

from ..errors import ScratchUserError

__all__ = ["FrameExportError", "export_frames", "EXPORT_MODULE"]

#: The add-on module that exports frames (run with ``python -m``).
EXPORT_MODULE = "scratch_iridescence.addon.render.frames"


class FrameExportError(ScratchUserError):
    """Frames of a .blend could not be exported (no bpy module, a broken file, a scene without a camera)."""


def export_frames(blend, frames: str, pattern, *, timeout_s: float | None = None) -> None:
    """Export ``frames`` (``"1-3,7"``) of ``blend`` into the folders ``pattern`` names (``#`` = frame number).

    Raises :class:`FrameExportError` with the exporter's own last error line.
    """
    if importlib.util.find_spec("bpy") is None:
        raise FrameExportError("exporting frames from a .blend needs the bpy module in this Python "
                               f"({sys.executable}): pip install bpy==5.0.1 (CPython 3.11)")
    blend = Path(blend)
    if not blend.is_file():
        raise FrameExportError(f"{blend}: no such .blend file")
    command = [sys.executable, "-m", EXPORT_MODULE, "export", frames, "-o", str(pattern), "--blend", str(blend)]
    try:
        result = subprocess.run(command, capture_output=True, text=True, timeout=timeout_s,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
    except subprocess.TimeoutExpired:
        raise FrameExportError(f"exporting frames {frames} of {blend} took more than {timeout_s:.0f} s") from None
    if result.returncode != 0:
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        errors = [line for line in lines if line.startswith("error:")]
        reason = (errors or lines or [f"exit status {result.returncode}"])[-1].removeprefix("error: ")
        raise FrameExportError(f"cannot export frames {frames} of {blend}: {reason}")
