"""Blender-free half of Scratch Iridescence: scratch sets, the diffraction BSDF, scene building.

Importing this package has no side effects and never imports ``bpy``; Mitsuba is
imported only by the functions that need it.
"""
from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__", "register_plugins"]


def register_plugins() -> None:
    """Register every Mitsuba plugin of the project for the active Mitsuba variant.

    Call after ``mi.set_variant(...)``; calling again (or after switching
    variants) is harmless.
    """
    from . import translucent
    from .bsdf import register  # Mitsuba is imported here, not at package import

    register()
    translucent.register()
