"""Blender-free half of Scratch Iridescence: scratch sets, the diffraction BSDF, scene building.

Importing this package never imports ``bpy``; Mitsuba is imported only by the
functions that need it.  Its one side effect: where the extension bundles a
libLLVM and the user has not set ``DRJIT_LIBLLVM_PATH``, it has Dr.Jit load the
bundled library (see :mod:`.device.llvm_library`; the environment stays as it was), which must happen before ``drjit``
is first imported.

Its one import name is ``scratch_iridescence.mitsuba_bridge`` (inside Blender:
``bl_ext.<repository>.scratch_iridescence.mitsuba_bridge``, reached relatively by
the add-on).  Imported as a top-level ``mitsuba_bridge`` (a Python started in the
repository root puts it on the path) it would be a second copy of every class,
whose scene objects the first copy rejects, so that name is refused.
"""
from __future__ import annotations

if "." not in __name__:
    raise ImportError(f"import the bridge as 'scratch_iridescence.mitsuba_bridge', not '{__name__}' "
                      "(one name, one copy of every class; docs/architecture.md)")

from .device import llvm_library  # noqa: E402  (after the name check: nothing to configure for a refused copy)

llvm_library.configure()

__version__ = "0.1.0"

__all__ = ["__version__", "register_plugins"]


def register_plugins() -> None:
    """Register every Mitsuba plugin of the project for the active Mitsuba variant.

    Call after ``mi.set_variant(...)``; calling again (or after switching
    variants) is harmless.
    """
    from .bsdf import generated, translucent
    from .bsdf import register  # Mitsuba is imported here, not at package import

    register()
    translucent.register()
    generated.register()
