"""Files saved by older versions of the add-on, upgraded when they load (``load_post``).

Version 0.1 stored its settings as ``Object.scratch`` and ``Scene.scratch_iridescence``,
generic names another add-on could take; they are now ``Object.scratch_iridescence``
and ``Scene.scratch_iridescence``.  It also stored the coherence diameter as a
length in scene units (metres × ``unit_settings.scale_length``); it is now a
physical size in micrometres (``coherence_diameter_um``).

Blender keeps the ID properties of unregistered names in the file, so an old
file still carries the groups ``obj["scratch"]`` and ``scene["scratch_iridescence"]``:
:func:`upgrade_file` copies them into the new groups with the same meaning and
removes them, when a file loads and when the add-on is enabled with a file
open.  Values never changed from a default were never stored and take
the new default (for the diameter: 30 µm, where 0.1 gave 30 µm times the scene's
unit scale).  Upgrading twice does nothing.
"""
from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

from .geometry import units

__all__ = ["OLD_OBJECT_KEY", "OLD_SCENE_KEY", "upgrade_file", "upgrade_object", "upgrade_scene"]

OLD_OBJECT_KEY = "scratch"          # Object.scratch (version 0.1)
OLD_SCENE_KEY = "scratch_iridescence"    # Scene.scratch_iridescence (version 0.1)
NEW_KEY = "scratch_iridescence"


def _scale_length(obj) -> float:
    """Metres per scene unit of the scene that shows ``obj`` (the first one; 1 when none does)."""
    scenes = list(obj.users_scene) or list(bpy.data.scenes)
    return units.metres_per_unit(scenes[0]) if scenes else 1.0


def upgrade_object(obj) -> bool:
    """Move ``obj``'s version-0.1 settings into ``obj.scratch_iridescence``; whether there were any."""
    old = obj.get(OLD_OBJECT_KEY)
    if old is None or not hasattr(old, "keys"):
        return False
    settings = getattr(obj, NEW_KEY)
    for key in old.keys():
        value = old[key]
        if key == "coherence_diameter":  # scene units -> micrometres
            settings["coherence_diameter_um"] = float(value) * _scale_length(obj) * 1e6
        else:  # same name and stored form (enums as their index, colours as arrays)
            settings[key] = value
    del obj[OLD_OBJECT_KEY]
    return True


def upgrade_scene(scene) -> bool:
    """Move ``scene``'s version-0.1 render settings into ``scene.scratch_iridescence``."""
    old = scene.get(OLD_SCENE_KEY)
    if old is None or not hasattr(old, "keys"):
        return False
    settings = getattr(scene, NEW_KEY)
    for key in old.keys():
        settings[key] = old[key]
    del scene[OLD_SCENE_KEY]
    return True


def upgrade_file() -> int:
    """Upgrade every object and scene of the open file; returns how many were upgraded."""
    count = sum(upgrade_object(obj) for obj in bpy.data.objects)
    return count + sum(upgrade_scene(scene) for scene in bpy.data.scenes)


@persistent
def _on_load(_filepath, *_args):
    upgrade_file()


def register():
    if _on_load not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(_on_load)
    try:
        upgrade_file()  # the add-on enabled while an old file is open
    except AttributeError:  # bpy.data is restricted while Blender starts; load_post handles that file
        pass


def unregister():
    if _on_load in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_on_load)
