"""Frames of a .blend exported as Mitsuba folders, and the bridge's command line inside Blender.

The Blender side of ``render-frames`` and of the farm job definitions (``farm/``):
the bridge never imports ``bpy``, so it runs this module in a subprocess with
pip's ``bpy`` module (no Blender binary), and a farm worker runs it inside its
Blender with the extension enabled on a ``--factory-startup`` command line::

    # pip's bpy (what render-frames and export-frames run)
    python -m scratch_iridescence.addon.render.frames export 1-3 -o out/scene_#### --blend shot.blend
    # a Blender with the extension installed: export the open file's frame 7, or run any bridge command
    blender -b --factory-startup --addons bl_ext.user_default.scratch_iridescence shot.blend \\
        --python-expr "import bl_ext.user_default.scratch_iridescence.addon.render.frames as f; f.main()" \\
        -- export 7 -o /mnt/render/job/scene_####
    blender -b --factory-startup --addons bl_ext.user_default.scratch_iridescence \\
        --python-expr "import bl_ext.user_default.scratch_iridescence.addon.render.frames as f; f.main()" \\
        -- render /mnt/render/job/scene_0007 -o /mnt/render/job/part_1.exr --chunk 1/4

Inside Blender the arguments after ``--`` are read, and Blender exits with the
command's status (before loading a .blend named later on its command line).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import bpy

__all__ = ["export_frames", "main"]


def export_frames(scene, frames, pattern) -> list[Path]:
    """Export ``scene`` at each of ``frames`` into the folder ``frame_path(pattern, frame)``; returns the folders.

    A ``pattern`` without ``#`` names the folder of a single frame as it is.
    """
    from ...mitsuba_bridge.files.frames import frame_path
    from ...mitsuba_bridge.folder import export as bridge_export
    from ...mitsuba_bridge.render.activation import activate
    from .gather import gather_scene, gather_settings

    folders = []
    for frame in frames:
        scene.frame_set(frame)
        settings = gather_settings(scene)
        activate(settings.variant)  # the builder makes Mitsuba transforms while writing the folder
        description = gather_scene(bpy.context.evaluated_depsgraph_get())
        for warning in description.warnings:
            print(f"warning: frame {frame}: {warning}", file=sys.stderr)
        folder = frame_path(pattern, frame) if "#" in str(pattern) else Path(pattern)  # one frame: the folder named
        bridge_export.export_folder(description, settings, folder)
        print(f"exported frame {frame} to {folder}", flush=True)
        folders.append(folder)
    return folders


def _open(blend: str) -> None:
    """Open ``blend`` with the add-on registered (pip's bpy does not enable extensions by itself)."""
    if not hasattr(bpy.types.Scene, "scratch_iridescence"):
        from ... import register

        register()
    bpy.ops.wm.open_mainfile(filepath=str(Path(blend).resolve()))


def _export(argv) -> int:
    from ...mitsuba_bridge.errors import ScratchUserError
    from ...mitsuba_bridge.files.frames import parse_frames
    from .gather import GatherError

    parser = argparse.ArgumentParser(prog="frames export", description="export frames of a .blend as Mitsuba folders")
    parser.add_argument("frames", help="frames: 7, 1-240, 1,5,10-12")
    parser.add_argument("-o", "--output", required=True, help="folder per frame; each run of # is the frame number")
    parser.add_argument("--blend", help="the .blend to open (default: the file Blender opened)")
    args = parser.parse_args(argv)
    try:
        frames = parse_frames(args.frames)
        if len(frames) > 1 and "#" not in args.output:
            raise GatherError(f"-o {args.output}: several frames need a # in the folder name (scene_####)")
        if args.blend:
            _open(args.blend)
        export_frames(bpy.context.scene, frames, args.output)
    except (ScratchUserError, GatherError, OSError, RuntimeError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


def main(argv=None) -> int:
    """``export FRAMES -o FOLDER_#### [--blend FILE]``, or any command of the bridge's command line.

    Inside Blender (``--python-expr``) the arguments after ``--`` are used and Blender exits with the status.
    """
    inside_blender = argv is None  # called from --python-expr: Blender's own arguments precede "--"
    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    if argv[:1] == ["export"]:
        status = _export(argv[1:])
    else:
        from ...mitsuba_bridge.cli import main as bridge_main

        status = bridge_main(argv)
    if inside_blender:
        sys.stdout.flush()
        sys.exit(status)
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
