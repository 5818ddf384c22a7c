"""Mitsuba set up for the project's renders: the variant, the project's plugins, the frozen passes.

Every render, export and session starts here (:func:`activate`), so that each runs with the same
set-up: the spectral variant :mod:`..device.variants` chooses (CUDA or Metal when present, else LLVM after
its libLLVM passed the crash check), the CPU kernels' target, the project's plugins registered for
that variant, and the global tables frozen render passes take (:func:`.freezing.calibrate`).
"""
from __future__ import annotations

from ..device.variants import set_variant
from .freezing import calibrate

__all__ = ["activate"]


def activate(requested: str = "auto") -> str:
    """Set the chosen variant and register the project's plugins for it; returns the variant.

    ``requested`` is ``"auto"`` or a variant name (:func:`...device.variants.choose_variant`, whose
    :class:`...device.variants.VariantError` says what to do when none works).  Also finds the global
    tables that frozen render passes take, once per variant and before any scene of it is loaded,
    when that costs a tiny kernel.  Calling again is cheap.
    """
    from .. import register_plugins
    from . import aovs

    variant = set_variant(requested)
    register_plugins()
    aovs.register()  # Blender's data passes (F12's Depth and denoising passes)
    calibrate()
    return variant
