"""Self-contained export folders: ``scene.xml`` plus meshes, textures and scratch files.

Layout::

    folder/scene.xml          Mitsuba 3 scene (paths relative to the folder)
    folder/meshes/*.ply       one file per mesh, in object space
    folder/textures/*         copied image files, or EXR for packed/generated images
    folder/scratches/*.npz    scratch files, format v1

``python -m scratch_iridescence.mitsuba_bridge render folder -o out.exr`` renders it without Blender.
"""
from __future__ import annotations

from pathlib import Path

import os

from ..files.regular import check_regular
from ..files.swap import SwapRecoveryError, recover_folder, replacing_folder
from ..scene import RenderSettings, SceneDescription

__all__ = ["SCENE_FILE", "EXPORTED_ENTRIES", "export_folder", "load_folder", "check_folder", "scene_seed",
           "SwapRecoveryError"]

SCENE_FILE = "scene.xml"

#: What an export owns in its folder; a re-export replaces exactly these (other files stay).
EXPORTED_ENTRIES = (SCENE_FILE, "meshes", "textures", "scratches")


def export_folder(description: SceneDescription, settings: RenderSettings, folder) -> Path:
    """Write ``description`` into ``folder`` (created if needed); returns the scene file.

    The export is built in a temporary folder and swapped in as a whole
    (:func:`~mitsuba_bridge.files.swap.replacing_folder`): a failed re-export leaves
    the previous export intact, never an old ``scene.xml`` beside new scratch
    files, and one killed while swapping is completed by the next export or
    render of the folder.  A Mitsuba variant must be active (transforms are Mitsuba objects
    while building).
    """
    from ..builder import scene_dict
    from .resources import ToFolder
    from .scenexml import write_xml

    folder = Path(folder)
    with replacing_folder(folder, EXPORTED_ENTRIES, last=SCENE_FILE) as building:
        write_xml(scene_dict(description, settings, ToFolder(building)), building / SCENE_FILE)
    return folder / SCENE_FILE


def load_folder(folder):
    """Load an exported folder's scene (the variant and plugins must be active).

    Mitsuba resolves the XML's relative paths (meshes, textures, scratch files)
    against the scene file's folder; the working directory is left alone (it is
    global state shared with Blender).  A re-export killed while it swapped its
    files in is completed first (:func:`check_folder`); every exported file must
    be a regular file (a FIFO would make Mitsuba's readers wait forever).
    """
    import mitsuba as mi

    scene_file = check_folder(folder)
    # Serial (as builder.load_dict): with Mitsuba's parallel loader a plugin that fails on a worker thread (a
    # corrupt scratch file) could surface as "Child object at index 9 has not been instantiated yet" instead
    # of its own message, and the lights' and the world's emitter numbers (a kernel literal) vary by run.
    return mi.load_file(str(scene_file.resolve()), parallel=False)


def check_folder(folder) -> Path:
    """The scene file of an export folder (or of ``folder`` naming the file itself), ready to be read.

    Completes a re-export that a killed process left half swapped
    (:func:`~mitsuba_bridge.files.swap.recover_folder`), then checks that the scene file
    and every file of the exported entries are regular files.  Raises
    ``FileNotFoundError`` (no scene file), :class:`~mitsuba_bridge.files.regular.NotARegularFile`
    or :class:`~mitsuba_bridge.files.swap.SwapRecoveryError`.
    """
    folder = Path(folder)
    scene_file = folder / SCENE_FILE if folder.is_dir() else folder
    recover_folder(scene_file.parent)
    if not os.path.lexists(scene_file):
        raise FileNotFoundError(f"{scene_file}: no such scene file (expected an exported folder holding {SCENE_FILE})")
    check_regular(scene_file)
    for name in EXPORTED_ENTRIES[1:]:
        for root, folders, files in os.walk(scene_file.parent / name):  # (links to folders are not followed)
            for entry in files + [f for f in folders if os.path.islink(os.path.join(root, f))]:
                check_regular(os.path.join(root, entry))
    return scene_file


def scene_seed(scene_file) -> int:
    """The seed an exported scene renders with (its sampler's ``seed``; 0 where it has none).

    The export writes the render settings' seed there (:func:`...builder.camera.sensor_dict`), so
    the command line renders the image F12 gives.  Read from the XML, which the scene was just
    loaded from: Mitsuba's sampler does not expose its base seed.
    """
    import xml.etree.ElementTree as ElementTree

    root = ElementTree.parse(scene_file).getroot()
    for sensor in root.iter("sensor"):
        for sampler in sensor.iter("sampler"):
            for value in sampler:
                if value.get("name") == "seed":
                    return int(value.get("value"))
        break
    return 0
