"""Rendering with Mitsuba: the engine, its settings and panels, and Export Mitsuba Scene."""
from __future__ import annotations

from . import engine, export, panels, settings

_MODULES = (settings, engine, panels, export)


def register():
    for module in _MODULES:
        module.register()


def unregister():
    for module in reversed(_MODULES):
        module.unregister()
