"""Small unit and system helpers for the user interface (no ``bpy``).

Widths and depths are shown in nanometres or micrometres.  Blender's metric
*length* unit cannot do that: its smallest unit is the micrometre, and anything
below 1 µm is displayed as ``0 m``.  So the operators hold widths and depths as
nanometre numbers displayed with Blender's *wavelength* unit ("250 nm",
"4 µm"), and convert with :data:`NM`.
"""
from __future__ import annotations

import math
import os
import sys

from ...mitsuba_bridge.errors import ScratchUserError

__all__ = ["NM", "format_length", "metres_per_unit", "available_memory", "MemoryLimitError", "check_memory"]

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


class MemoryLimitError(ScratchUserError, MemoryError):
    """An operation would need more memory than the machine has free."""


def available_memory() -> int | None:
    """Free physical memory in bytes (None when the platform does not say)."""
    try:
        with open("/proc/meminfo") as stream:
            for line in stream:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    if sys.platform == "win32":  # pragma: no cover - not run on the Linux CI
        import ctypes

        class _Status(ctypes.Structure):
            _fields_ = [("length", ctypes.c_ulong), ("load", ctypes.c_ulong),
                        ("total", ctypes.c_ulonglong), ("available", ctypes.c_ulonglong),
                        ("total_page", ctypes.c_ulonglong), ("available_page", ctypes.c_ulonglong),
                        ("total_virtual", ctypes.c_ulonglong), ("available_virtual", ctypes.c_ulonglong),
                        ("extended", ctypes.c_ulonglong)]

        status = _Status()
        status.length = ctypes.sizeof(_Status)
        if ctypes.windll.kernel32.GlobalMemoryStatusEx(ctypes.byref(status)):
            return int(status.available)
        return None
    try:  # other POSIX systems
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        return None


def check_memory(needed_bytes: int, what: str, available: int | None = None) -> None:
    """Raise :class:`MemoryLimitError` when ``needed_bytes`` exceeds the free memory."""
    available = available_memory() if available is None else available
    if available is not None and needed_bytes > available:
        raise MemoryLimitError(
            f"{what} needs about {_format_bytes(needed_bytes)} of memory but only "
            f"{_format_bytes(available)} is free; ask for fewer")


def _format_bytes(count: float) -> str:
    """``"1.5 GiB"``, ``"12.0 MiB"``; ``"3.4e+09 GiB"`` for absurd requests."""
    if count >= 2**30:
        gib = count / 2**30
        return f"{gib:.1f} GiB" if gib < 1e6 else f"{gib:.2g} GiB"
    return f"{count / 2**20:.1f} MiB"
