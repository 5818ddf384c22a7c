"""Rendered images to disk: linear EXR or 8-bit sRGB PNG, always through a temporary sibling.

A failed write (full disk, killed process, a bug) never destroys the previous
good file: the image goes to a temporary file in the same folder, which is
renamed over the target only once complete (:mod:`mitsuba_bridge.files.atomic`).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .atomic import replacing_file
from .exr import write_exr

__all__ = ["IMAGE_SUFFIXES", "check_output_path", "write_image", "write_png"]

#: What ``write_image`` writes, by file name suffix.
IMAGE_SUFFIXES = (".exr", ".png")


def check_output_path(path, suffixes: tuple[str, ...] = IMAGE_SUFFIXES) -> Path:
    """``path`` if an image can be written there, else a ``ValueError`` saying why (before any rendering)."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise ValueError(f"{path}: the output must end in {' or '.join(suffixes)}")
    if path.is_dir():
        raise ValueError(f"{path} is a folder; give a file name")
    folder = path.parent
    if not folder.is_dir():
        raise ValueError(f"{path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{path}: the folder {folder} is not writable")
    return path


def write_png(path, image: np.ndarray) -> Path:
    """``image`` (H, W, 3 or 4), linear, as an 8-bit sRGB PNG (values clipped to [0, 1]).

    Uses Mitsuba's ``Bitmap`` (a variant must be active); the PNG is for
    viewing, the EXR keeps the linear values.
    """
    import mitsuba as mi

    image = np.ascontiguousarray(image, dtype=np.float32)
    layout = mi.Bitmap.PixelFormat.RGBA if image.shape[-1] == 4 else mi.Bitmap.PixelFormat.RGB
    bitmap = mi.Bitmap(np.clip(image, 0.0, 1.0), pixel_format=layout)
    bitmap.convert(layout, mi.Struct.Type.UInt8, srgb_gamma=True).write(str(path))
    return Path(path)


def write_image(path, image: np.ndarray, *, header: dict | None = None, channels: dict | None = None) -> Path:
    """Write ``image`` to ``path`` (.exr linear float32, or .png 8-bit sRGB), replacing any old file atomically.

    ``header`` and ``channels`` (EXR only) add attributes and extra channels.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise ValueError(f"{path}: the output must end in {' or '.join(IMAGE_SUFFIXES)}")
    with replacing_file(path) as temporary:
        if suffix == ".png":
            write_png(temporary, image)
        else:
            write_exr(temporary, image, header=header, channels=channels)
    return path
