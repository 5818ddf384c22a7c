"""Small unit helpers for the user interface (no ``bpy``); the memory check is
:mod:`mitsuba_bridge.device.memory`'s, one for the whole product.

Widths and depths are shown in nanometres or micrometres.  Blender's metric
*length* unit cannot do that: its smallest unit is the micrometre, and anything
below 1 µm is displayed as ``0 m``.  So the operators hold widths and depths as
nanometre numbers displayed with Blender's *wavelength* unit ("250 nm",
"4 µm"), and convert with :data:`NM`.
"""
from __future__ import annotations

import math

__all__ = ["NM", "format_length", "metres_per_unit"]

#: Metres per nanometre.
NM = 1e-9

_PREFIXES = ((1.0, "m"), (1e-3, "mm"), (1e-6, "µm"), (1e-9, "nm"))


def format_length(metres: float, digits: int = 3) -> str:
    """``metres`` with a readable prefix and ``digits`` significant digits ("250 nm", "4.1 µm")."""
    if not math.isfinite(metres):
        return str(metres)
    if metres == 0:
        return "0 m"
    magnitude = abs(metres)
    for scale, unit in _PREFIXES:
        if magnitude >= scale * 0.9995 or unit == "nm":
            value = metres / scale
            return f"{value:.{digits}g} {unit}"
    raise AssertionError("unreachable")


def metres_per_unit(scene) -> float:
    """Metres per scene unit of ``scene`` (its ``unit_settings.scale_length``; 1 where that is 0): the one
    reading of the unit scale, for the editor, the render and old files alike."""
    return float(scene.unit_settings.scale_length) or 1.0
