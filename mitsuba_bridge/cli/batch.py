"""The ``render`` and ``merge`` commands of ``python -m scratch_iridescence.mitsuba_bridge``: export folder → image, parts → image.

Everything that can be checked before rendering is checked first (arguments,
output folder and format, scene file, scene contents, memory), each problem
ends in one line ``error: ...`` and a non-zero exit status, and the output is
written only once complete (:mod:`mitsuba_bridge.files.atomic`).
"""
from __future__ import annotations

import re
import sys
import time
from pathlib import Path


from ..files.images import IMAGE_SUFFIXES, check_output_path, write_image

__all__ = ["CommandError", "render_command", "merge_command", "parse_chunk"]


class CommandError(Exception):
    """A problem to report as one line; ``status`` is the exit code."""

    def __init__(self, message: str, status: int = 1):
        super().__init__(message)
        self.status = status


def one_line(error: BaseException) -> str:
    """An exception's message on one line.

    Mitsuba's load errors name the file and line, then (for a Python plugin)
    embed the plugin's whole traceback: keep the location and the traceback's
    last line, the plugin's own message.
    """
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    if not lines:
        return type(error).__name__
    for number, line in enumerate(lines):
        if "Traceback (most recent call last)" in line:
            head = line.split("Traceback (most recent call last)")[0].strip()
            lines = [" ".join(lines[:number] + [head]), lines[-1]]
            break
    return re.sub(r"\[[\w.]+\.cpp:\d+\]\s*", "", " ".join(part for part in lines if part))


def parse_chunk(text: str) -> tuple[int, int]:
    """``"K/N"`` → (K, N) with 1 ≤ K ≤ N."""
    try:
        part, parts = (int(v) for v in text.split("/"))
    except ValueError:
        raise CommandError(f"--chunk expects K/N (part K of N, e.g. 2/8), got {text!r}", 2) from None
    if not 1 <= part <= parts:
        raise CommandError(f"--chunk {text}: K must be between 1 and N", 2)
    return part, parts


def _load(folder):
    from ..folder.export import check_folder, load_folder
    from ..render.interrupts import interruption_in

    folder = Path(folder)
    try:
        scene_file = check_folder(folder)  # (a killed re-export completed; FIFOs refused before Mitsuba waits on one)
    except OSError as error:
        raise CommandError(str(error)) from None
    try:
        return load_folder(folder), scene_file
    except (OSError, RuntimeError, ValueError, TypeError) as error:
        if interruption_in(error):  # Ctrl-C while a Python plugin was being built: main's 130, not a load error
            raise KeyboardInterrupt from error
        # Mitsuba repeats the file's path ("At /path/scene.xml (line 3, col 6): ..."): keep the line only.
        message = one_line(error).replace(f"At {scene_file.resolve()} ", "")
        raise CommandError(f"cannot load {scene_file}: {message}") from None


def render_command(args) -> int:
    """``render FOLDER -o OUT [--spp N] [--seed S] [--chunk K/N]``."""
    from ..device.variants import VariantError
    from ..folder.export import EXPORTED_ENTRIES, scene_seed
    from ..render.activation import activate
    from ..render.memory import NotEnoughMemory
    from ..render.parts import (RenderIdentity, recording_tables, scene_fingerprint, schedule_digest, software,
                                tables_fingerprint, write_part)
    from ..render.passes import Refresh, plan_render, render_chunks

    if args.spp is not None and args.spp < 1:
        raise CommandError(f"--spp must be at least 1 (leave it out for the scene's own), got {args.spp}", 2)
    if args.seed is not None and not 0 <= args.seed < 2 ** 32:
        raise CommandError(f"--seed must be between 0 and {2 ** 32 - 1}, got {args.seed}", 2)
    chunk = parse_chunk(args.chunk) if args.chunk else None
    try:
        output = check_output_path(args.output, (".exr",) if chunk else IMAGE_SUFFIXES)
    except ValueError as error:
        raise CommandError(f"{error}{' (a part is always an EXR)' if chunk else ''}", 2) from None
    try:
        variant = activate(args.variant)
    except (ImportError, VariantError) as error:
        raise CommandError(str(error), 2) from None

    started = time.perf_counter()
    with recording_tables() as tables:  # (what the scratch BSDFs render with: a part names it)
        scene, scene_file = _load(args.folder)
    sensors = scene.sensors()
    if not sensors:
        raise CommandError(f"{scene_file}: the scene has no sensor (camera)")
    if not scene.shapes() and not scene.emitters():
        print(f"warning: {scene_file} holds no shapes and no lights: the image is black", file=sys.stderr)
    spp = args.spp or int(sensors[0].sampler().sample_count())
    seed = scene_seed(scene_file) if args.seed is None else args.seed  # F12 renders with the scene's seed too
    try:
        plan = plan_render(scene, spp, seed=seed)
    except ValueError as error:
        raise CommandError(str(error), 2) from None
    if chunk:
        try:
            plan = plan.part(*chunk)
        except ValueError as error:
            raise CommandError(f"--chunk {args.chunk}: {error}", 2) from None
    try:
        plan.check_memory()
    except NotEnoughMemory as error:
        raise CommandError(str(error)) from None
    chunks, selected, samples, width, height = plan.chunks, plan.selected, plan.samples, plan.width, plan.height
    what = f"chunks {selected[0].index}-{selected[-1].index} of {len(chunks)} ({samples} of {spp} spp)" \
        if chunk else f"{spp} spp in {len(chunks)} chunk{'s' * (len(chunks) != 1)}"
    print(f"{args.folder}: {width} x {height}, {what}, {variant}, loaded in {time.perf_counter() - started:.2f} s",
          flush=True)
    refresh, progress = Refresh(1.0), None
    try:
        for progress in render_chunks(scene, selected, samples, render_spp=spp):
            if not args.quiet and refresh.due(progress):
                print(f"  {progress.spp_done:6d}/{samples} spp  {100 * progress.fraction:5.1f} %  "
                      f"{progress.seconds:7.1f} s", flush=True)
    except (RuntimeError, ValueError) as error:  # a plugin failing inside a kernel, Dr.Jit out of memory
        raise CommandError(f"rendering failed: {one_line(error)} (nothing was written)") from None
    try:
        if chunk:
            identity = RenderIdentity(scene_fingerprint(scene_file.parent, EXPORTED_ENTRIES), variant, software(),
                                      width, height, spp, seed, len(chunks), schedule_digest(chunks),
                                      tables_fingerprint(tables))
            write_part(output, identity, progress.sums, samples)
        else:
            write_image(output, progress.image)
    except (OSError, RuntimeError) as error:
        raise CommandError(f"cannot write {output}: {one_line(error)} (any previous file is unchanged)") from None
    if progress.traced_note:
        print(progress.traced_note, file=sys.stderr)
    print(f"wrote {output} ({progress.seconds:.1f} s of rendering)")
    return 0


def merge_command(args) -> int:
    """``merge PART... -o OUT``: the parts of one render → its image, bit for bit the single-machine one."""
    from ..render.parts import PartError, merge_parts

    try:
        output = check_output_path(args.output)
    except ValueError as error:
        raise CommandError(str(error), 2) from None
    try:
        image, identity = merge_parts(args.parts)
    except PartError as error:
        raise CommandError(str(error)) from None
    try:
        write_image(output, image)
    except (OSError, RuntimeError, ValueError) as error:
        raise CommandError(f"cannot write {output}: {one_line(error)} (any previous file is unchanged)") from None
    print(f"wrote {output}: {identity.width} x {identity.height}, {identity.spp} spp from {len(args.parts)} parts")
    return 0
