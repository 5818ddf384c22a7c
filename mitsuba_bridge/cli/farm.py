"""``render --cluster`` and ``render-frames``: one image or an animation rendered over a Dask cluster.

``render FOLDER -o OUT`` without ``--cluster`` is :func:`.batch.render_command`;
with it, the schedule's chunks run as Dask tasks (:mod:`...cluster.driver`) and
the merged image is the one-machine render, bit for bit.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from . import batch
from ..errors import ScratchUserError
from ..files.images import IMAGE_SUFFIXES, check_output_path, write_image

__all__ = ["render_command", "render_on_cluster", "render_frames_command", "export_frames_command",
           "merge_command"]


def render_command(args) -> int:
    """``render FOLDER -o OUT [--cluster ADDRESS]``: on a cluster when asked, else on this machine."""
    if getattr(args, "cluster", None):
        return render_on_cluster(args)
    if getattr(args, "chunks_per_task", None):
        raise batch.CommandError("--chunks-per-task needs --cluster", 2)
    return batch.render_command(args)


def _check_samples(args) -> None:
    if args.spp is not None and args.spp < 1:
        raise batch.CommandError(f"--spp must be at least 1 (leave it out for the scene's own), got {args.spp}", 2)
    if args.seed is not None and not 0 <= args.seed < 2 ** 32:
        raise batch.CommandError(f"--seed must be between 0 and {2 ** 32 - 1}, got {args.seed}", 2)
    per_task = getattr(args, "chunks_per_task", None)
    if per_task is not None and (per_task < 1 or per_task & (per_task - 1)):
        raise batch.CommandError(f"--chunks-per-task must be a power of two, got {per_task}", 2)


def _cluster_modules():
    try:
        from ..cluster import driver, progress, scenes
    except ImportError as error:  # the Blender extension leaves the cluster room out
        raise batch.CommandError(f"--cluster is not part of this installation ({error}): pip install "
                                 "'scratch-iridescence[cluster]'", 2) from None
    return driver, progress, scenes


def render_on_cluster(args) -> int:
    """``render FOLDER -o OUT --cluster ADDRESS``: the chunks as Dask tasks, merged here, written once complete."""
    if args.chunk:
        raise batch.CommandError("--chunk and --cluster exclude each other: the cluster renders every chunk", 2)
    _check_samples(args)
    try:
        output = check_output_path(args.output, IMAGE_SUFFIXES)
    except ValueError as error:
        raise batch.CommandError(str(error), 2) from None
    driver, progress_module, scenes = _cluster_modules()
    try:
        bundle = scenes.pack_folder(args.folder)
    except OSError as error:
        raise batch.CommandError(str(error)) from None
    progress = progress_module.ClusterProgress(0, quiet=args.quiet)

    def planned(frame, workers):
        facts, job = frame.facts, frame.job
        print(f"{args.folder}: {facts.width} x {facts.height}, {job.spp} spp in {job.chunk_count} chunks as "
              f"{len(frame.runs)} tasks on {workers} workers ({args.cluster}), {facts.variant}", flush=True)

    try:
        with driver.connect(args.cluster) as cluster:
            result = cluster.render(bundle, variant=args.variant, spp=args.spp, seed=args.seed,
                                    chunks_per_task=getattr(args, "chunks_per_task", None), progress=progress,
                                    on_planned=planned)
    except ScratchUserError as error:
        raise batch.CommandError(str(error)) from None
    try:
        write_image(output, result.image)
    except (OSError, RuntimeError) as error:
        raise batch.CommandError(f"cannot write {output}: {batch.one_line(error)} (any previous file is unchanged)") \
            from None
    if result.traced_note:
        print(result.traced_note, file=sys.stderr)
    print(f"wrote {output} ({result.seconds:.1f} s on the cluster)")
    return 0


#: Frames exported per bpy process when rendering an animation on this machine (one process start per batch).
EXPORT_BATCH = 8


def _frames_and_pattern(args, suffixes):
    from ..files.frames import frame_path, parse_frames

    try:
        frames = parse_frames(args.frames)
        first = frame_path(args.output, frames[0])
        first.parent.mkdir(parents=True, exist_ok=True)  # as Blender makes its output folder
        if suffixes is not None:  # images; export folders may exist already (a re-export replaces them)
            first = check_output_path(first, suffixes)
    except (ValueError, ScratchUserError) as error:
        raise batch.CommandError(str(error), 2) from None
    except OSError as error:
        raise batch.CommandError(f"cannot make the folder of {args.output}: {error}") from None
    if len(frames) > 1 and "#" not in str(args.output):
        raise batch.CommandError(f"-o {args.output}: several frames need a # in the name "
                                 f"(frame_####{first.suffix})", 2)
    return frames


def export_frames_command(args) -> int:
    """``export-frames scene.blend --frames 1-3 -o out/scene_####``: one export folder per frame (pip's bpy)."""
    from ..folder.blend import export_frames

    frames = _frames_and_pattern(args, None)
    try:
        export_frames(args.blend, args.frames, args.output)
    except ScratchUserError as error:
        raise batch.CommandError(str(error)) from None
    print(f"exported {len(frames)} frame{'s' * (len(frames) != 1)} of {args.blend}")
    return 0


def render_frames_command(args) -> int:
    """``render-frames scene.blend --frames 1-240 -o out/frame_####.exr [--cluster ADDRESS]``."""
    import argparse
    import shutil
    import tempfile

    from ..files.frames import frame_path
    from ..folder.blend import export_frames

    _check_samples(args)
    frames = _frames_and_pattern(args, IMAGE_SUFFIXES)
    if args.cluster:
        return _render_frames_on_cluster(args, frames)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="render-frames-") as work:
        for start in range(0, len(frames), EXPORT_BATCH):
            group = frames[start:start + EXPORT_BATCH]
            try:
                export_frames(args.blend, ",".join(map(str, group)), f"{work}/scene_########")
            except ScratchUserError as error:
                raise batch.CommandError(str(error)) from None
            for frame in group:
                folder = frame_path(f"{work}/scene_########", frame)
                batch.render_command(argparse.Namespace(
                    folder=str(folder), output=str(frame_path(args.output, frame)), spp=args.spp, seed=args.seed,
                    chunk=None, variant=args.variant, quiet=args.quiet))
                shutil.rmtree(folder, ignore_errors=True)
    print(f"rendered {len(frames)} frame{'s' * (len(frames) != 1)} in {time.perf_counter() - started:.1f} s")
    return 0


def _render_frames_on_cluster(args, frames) -> int:
    from ..files.frames import frame_path

    driver, progress_module, _ = _cluster_modules()
    from ..cluster.frames import render_frames_on_cluster

    if not Path(args.blend).is_file():
        raise batch.CommandError(f"{args.blend}: no such .blend file", 2)
    progress = progress_module.ClusterProgress(0, quiet=args.quiet)

    def write(frame, image):
        return write_image(frame_path(args.output, frame), image)

    started = time.perf_counter()
    try:
        with driver.connect(args.cluster) as cluster:
            count = render_frames_on_cluster(cluster, args.blend, frames, write, variant=args.variant,
                                             spp=args.spp, seed=args.seed, progress=progress)
    except ScratchUserError as error:
        raise batch.CommandError(str(error)) from None
    except OSError as error:
        raise batch.CommandError(f"cannot write a frame: {batch.one_line(error)}") from None
    print(f"rendered {count} frame{'s' * (count != 1)} on the cluster in {time.perf_counter() - started:.1f} s")
    return 0


def merge_command(args) -> int:
    """``merge PART... -o OUT [--frame N]``: a folder among the parts stands for every ``.exr`` in it, and
    ``--frame`` numbers the ``#`` runs of ``-o`` (job templates cannot list N parts or pad numbers)."""
    from ..files.frames import frame_path

    parts = []
    for part in args.parts:
        path = Path(part)
        parts += sorted(map(str, path.glob("*.exr"))) if path.is_dir() else [part]
    if not parts:
        raise batch.CommandError(f"no parts (.exr files) in {', '.join(args.parts)}")
    args.parts = parts
    if getattr(args, "frame", None) is not None:
        args.output = str(frame_path(args.output, args.frame))
    return batch.merge_command(args)
