"""The Blender side of Scratch Iridescence: storage, operators, tools, overlay, panels, rendering.

Rooms (docs/architecture.md): ``geometry/`` (Blender-free numpy: surfaces,
paths, scattering, overlay lines), ``operators/``, ``tools/`` (the brushes),
``ui/`` (panels, overlay), ``render/`` (engine, gather, export), and next to
them the object data (``storage``, ``object_settings``, ``mesh``, ``versioning``).

Modules that define Blender classes expose ``register()`` / ``unregister()``;
they are listed here in registration order (property groups first).  They are
imported when the add-on registers, not when this package is imported, so that
``geometry`` stays importable without ``bpy``.
"""
from __future__ import annotations

import importlib

# Module names relative to this package, in registration order.
_MODULES = (
    "object_settings",
    "versioning",
    "mesh",
    "operators.generate",
    "operators.files",
    "render.glints",
    "tools.paint",
    "ui.overlay",
    "ui.panels",
    "render.settings",
    "render.engine",
    "render.panels",
    "render.export",
    "render.nodes",
)


def _modules():
    return [importlib.import_module(f".{name}", __package__) for name in _MODULES]


def register():
    """Register every class of the add-on."""
    _use_extension_folder(True)
    for module in _modules():
        module.register()


def unregister():
    """Unregister in reverse order."""
    for module in reversed(_modules()):
        module.unregister()
    _use_extension_folder(False)


def _use_extension_folder(use: bool) -> None:
    """Keep the scratch tables cache in the extension's user folder, Blender's place for an extension's data.

    Set for the bridge explicitly (it never imports ``bpy``; the process
    environment, which Blender shares with every add-on, is left alone):
    ``SCRATCH_IRIDESCENCE_CACHE_DIR`` still wins, and an add-on that is not
    installed as an extension (a source checkout) keeps the platform's cache folder.
    """
    import bpy

    from ..mitsuba_bridge.bsdf.tables import disk_cache

    folder = None
    if use:
        try:
            folder = bpy.utils.extension_path_user(__package__.rpartition(".")[0], create=True)
        except (ValueError, OSError):  # not an extension (bl_ext.<repository>.<id>), or no user folder
            folder = None
    disk_cache.set_root(folder)
