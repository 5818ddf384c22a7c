"""Colour-space helpers shared by the gather layer (baking node maths on images) and the builder."""
from __future__ import annotations

import numpy as np

__all__ = ["srgb_to_linear"]


def srgb_to_linear(values: np.ndarray) -> np.ndarray:
    """The sRGB transfer function inverted (colour channels only; alpha is left alone)."""
    values = np.asarray(values, dtype=np.float32)
    out = values.copy()
    channels = min(values.shape[-1], 3) if values.ndim == 3 else None
    part = out[..., :channels] if channels else out
    low = part <= 0.04045
    part[...] = np.where(low, part / 12.92, ((np.maximum(part, 0.0) + 0.055) / 1.055) ** 2.4)
    return out
