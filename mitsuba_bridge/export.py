"""Self-contained export folders: ``scene.xml`` plus meshes, textures and scratch files.

Layout::

    folder/scene.xml          Mitsuba 3 scene (paths relative to the folder)
    folder/meshes/*.ply       one file per mesh, in object space
    folder/textures/*         copied image files, or EXR for packed/generated images
    folder/scratches/*.npz    scratch files, format v1

``python -m scratch_iridescence.mitsuba_bridge render folder -o out.exr`` renders it without Blender.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path

from .scene import RenderSettings, SceneDescription

__all__ = ["SCENE_FILE", "export_folder", "load_folder"]

SCENE_FILE = "scene.xml"


def export_folder(description: SceneDescription, settings: RenderSettings, folder) -> Path:
    """Write ``description`` into ``folder`` (created if needed); returns the scene file.

    A Mitsuba variant must be active (transforms are Mitsuba objects while building).
    """
    from .builder import ToFolder, scene_dict
    from .scenexml import write_xml

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return write_xml(scene_dict(description, settings, ToFolder(folder)), folder / SCENE_FILE)


def load_folder(folder):
    """Load an exported folder's scene (the variant and plugins must be active).

    Mitsuba resolves the XML's relative paths against the folder itself; the
    working directory is moved there too while loading, for plugins that open
    their files with plain Python.
    """
    import mitsuba as mi

    folder = Path(folder)
    scene_file = folder / SCENE_FILE if folder.is_dir() else folder
    if not scene_file.is_file():
        raise FileNotFoundError(f"{scene_file}: no such scene file (expected an exported folder holding {SCENE_FILE})")
    with _working_directory(scene_file.parent):
        return mi.load_file(str(scene_file.resolve()))


@contextlib.contextmanager
def _working_directory(path):
    previous = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(previous)
