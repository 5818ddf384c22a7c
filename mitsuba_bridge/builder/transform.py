"""Small matrix helpers shared by the builder modules (numpy 4×4, column vectors)."""
from __future__ import annotations

import numpy as np

__all__ = ["FLIP_YZ", "FLIP_XZ", "scale", "translate", "to_mitsuba"]

#: Rotation by 180° about X: maps a frame looking along −Z to one looking along +Z
#: (Blender's lights shine along −Z, Mitsuba's along +Z).
FLIP_YZ = np.diag([1.0, -1.0, -1.0, 1.0])
#: Rotation by 180° about Y: Blender's camera frame (−Z forward, +X right) to
#: Mitsuba's (+Z forward, +X left); both keep +Y up.
FLIP_XZ = np.diag([-1.0, 1.0, -1.0, 1.0])


def scale(x: float, y: float, z: float) -> np.ndarray:
    return np.diag([float(x), float(y), float(z), 1.0])


def translate(x: float, y: float, z: float) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, 3] = (x, y, z)
    return matrix


def to_mitsuba(matrix: np.ndarray):
    """A ``mi.ScalarTransform4f`` of a numpy 4×4 matrix (needs an active variant)."""
    import mitsuba as mi

    return mi.ScalarTransform4f(np.asarray(matrix, dtype=np.float64).tolist())
