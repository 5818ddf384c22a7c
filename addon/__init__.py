"""The Blender side of Scratch Iridescence: storage, operators, tools, overlay, panels, rendering.

Modules that define Blender classes expose ``register()`` / ``unregister()``;
they are listed here in registration order (property groups first).  They are
imported when the add-on registers, not when this package is imported: the
Blender-free helpers next to them (``surface``, ``trace``, ``scatter``,
``brush``, ``uvmap``, ``lines``, ``erase``, ``units``) must stay importable without ``bpy``
so that tests and scripts can use them anywhere.
"""
from __future__ import annotations

import importlib

# Module names relative to this package, in registration order.
_MODULES = (
    "properties",
    "mesh",
    "generate",
    "files",
    "paint",
    "overlay",
    "panels",
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
    for module in _modules():
        module.register()


def unregister():
    """Unregister in reverse order."""
    for module in reversed(_modules()):
        module.unregister()
