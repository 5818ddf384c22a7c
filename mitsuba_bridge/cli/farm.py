"""``render --cluster`` and ``render-frames``: one image or an animation rendered over a Dask cluster.

``render FOLDER -o OUT`` without ``--cluster`` is :func:`.batch.render_command`;
with it, the schedule's chunks run as Dask tasks (:mod:`...cluster.driver`) and
the merged image is the one-machine render, bit for bit.
"""
from __future__ import annotations

import sys
import time

from . import batch
from ..errors import ScratchUserError
from ..files.images import IMAGE_SUFFIXES, check_output_path, write_image

__all__ = ["render_command", "render_on_cluster"]


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
