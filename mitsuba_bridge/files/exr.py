"""Linear OpenEXR images through the ``OpenEXR`` package (no Mitsuba needed)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_exr", "read_exr"]

_LAYOUTS = {1: "Y", 3: "RGB", 4: "RGBA"}


def write_exr(path, image: np.ndarray, *, half: bool = False, header: dict | None = None,
              channels: dict | None = None) -> Path:
    """Write ``image`` (H, W), (H, W, 3) or (H, W, 4), row 0 at the top, as a ZIP-compressed EXR.

    Channels are R, G, B (and A); values are stored as given (linear).
    ``header`` adds attributes (str, int or float values); ``channels`` adds
    (H, W) arrays under other names (float32, float16 or uint32).
    """
    import OpenEXR

    image = np.asarray(image)
    if image.ndim == 2:
        image = image[..., None]
    count = image.shape[2]
    if count not in _LAYOUTS:
        raise ValueError(f"expected 1, 3 or 4 channels, got {count}")
    pixels = np.ascontiguousarray(image, dtype=np.float16 if half else np.float32)
    if count == 1:
        pixels = pixels[..., 0]
    attributes = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **(header or {})}
    path = Path(path)
    OpenEXR.File(attributes, {_LAYOUTS[count]: pixels, **(channels or {})}).write(str(path))
    return path


def read_exr(path) -> np.ndarray:
    """The R, G, B (and A) channels of an EXR file as float32 (H, W, C), row 0 at the top."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as file:
        channels = file.channels()
        names = [name for name in ("R", "G", "B", "A") if name in channels]
        if not names:
            raise ValueError(f"{path}: no R, G, B or A channel (found {sorted(channels)})")
        return np.stack([np.asarray(channels[name].pixels, dtype=np.float32) for name in names], axis=-1)
