"""The Blender side of Scratch Iridescence: storage, operators, tools, overlay, panels, rendering.

Modules that define Blender classes expose ``register()`` / ``unregister()``;
they are listed here in registration order (property groups first).
"""
from __future__ import annotations

from . import properties
from .render import engine as render_engine
from .render import export as render_export
from .render import panels as render_panels
from .render import settings as render_settings

_MODULES = (properties, render_settings, render_engine, render_panels, render_export)


def register():
    """Register every class of the add-on."""
    for module in _MODULES:
        module.register()


def unregister():
    """Unregister in reverse order."""
    for module in reversed(_MODULES):
        module.unregister()
