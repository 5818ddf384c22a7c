"""The command line, ``python -m scratch_iridescence.mitsuba_bridge`` (or ``scratch-iridescence``):
scratch files (``info``, ``generate``), export folders (``render``, ``merge``) and ``validate``.
"""
from __future__ import annotations

from .main import main

__all__ = ["main"]
