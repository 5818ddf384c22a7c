"""Blender-free half of Scratch Iridescence: scratch sets, the diffraction BSDF, scene building.

Importing this package never imports ``bpy``; Mitsuba is imported only by the
functions that need it.  Its one side effect: where the extension bundles a
libLLVM and the user has not set ``DRJIT_LIBLLVM_PATH``, it points Dr.Jit at the
bundled library (see :mod:`.llvm_library`), which must happen before ``drjit``
is first imported.
"""
from __future__ import annotations

from . import llvm_library

llvm_library.configure()

__version__ = "0.1.0"

__all__ = ["__version__", "register_plugins"]


def register_plugins() -> None:
    """Register every Mitsuba plugin of the project for the active Mitsuba variant.

    Call after ``mi.set_variant(...)``; calling again (or after switching
    variants) is harmless.
    """
    from .bsdf import register  # Mitsuba is imported here, not at package import

    register()
