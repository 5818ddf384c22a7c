"""``make paper``: build and render every reproduced figure, then write the gallery and the benchmark table.

Each picture is made by two fresh processes, so that one scene's memory and
compiled kernels never flatter the next:

1. ``build``: an empty Blender scene, the figure module's ``build_scene`` (the
   add-on's own operators put the scratches on), saved as ``<name>.blend``;
2. ``render``: opens that file and renders it through the Mitsuba Scratch
   engine (``bpy.ops.render.render``), as ``blender -b file.blend -f 1`` would,
   writing ``<name>.exr`` (linear) and ``<name>.png`` (the scene's view
   transform); then, apart from the render, times loading the object's
   scratch set into the BSDF (building its tables: the disk cache off).  Its
   statistics go to ``<name>.json``, with whether the render read its tables
   from the disk cache (``mitsuba_bridge/bsdf/tables/disk_cache.py``), as any render
   after the first of a set does.

Then a third, ``noise``, opens the saved scene once more and finds the samples per pixel at which
the picture rendered with the Footprint Filter is as noisy as the point-sampled one (:mod:`.noise`):
the benchmark table's last column.  ``--no-filtered-noise`` skips it; ``--filtered-noise-only``
measures it for the pictures in ``--output`` that lack it.

Before the first picture and after the last, another worker renders Mitsuba's own Cornell box
(``reference``): the machine reference that the benchmark table divides its rows by.

Afterwards the numerical validation (:mod:`...mitsuba_bridge.validation`)
draws its figure, and :mod:`.pages` writes ``docs/gallery.md``,
``docs/benchmarks.md`` and the small PNGs in ``docs/gallery/``.

    .venv/bin/python -m scratch_iridescence.scenes.paper                 # what `make paper` runs
    .venv/bin/python -m scratch_iridescence.scenes.paper --only fig06_cd --scale 0.25 --no-docs
    .venv/bin/python -m scratch_iridescence.scenes.paper --filtered-noise-only --only fig07_plate
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from unittest import mock

from ..mitsuba_bridge.render.passes import TRACED_NOTE_PREFIX

__all__ = ["FIGURE_MODULES", "figures", "main"]

#: The figure modules, in the gallery's order.
FIGURE_MODULES = ("fig07_plate", "fig06_cd", "fig09_grating", "fig10_base", "fig17_profile", "fig01_table",
                  "fig11_table", "fig01_door", "fig06_spoon", "fig07_disc", "fig08_cd", "fig12_ring", "fig12_plate")

_PACKAGE = __package__  # scratch_iridescence.scenes


def figures(only=None):
    """The :class:`~.figure.Figure` records of the selected modules (all by default)."""
    chosen = []
    for name in FIGURE_MODULES:
        if only and name not in only:
            continue
        module = importlib.import_module(f"{_PACKAGE}.{name}")
        chosen.append((module, module.FIGURE))
    return chosen


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# --------------------------------------------------------------- the workers
def _start_blender():
    import bpy

    from .. import register  # the extension package

    register()
    return bpy


def build_worker(module_name: str, render_name: str, output: Path, resolution, samples: int) -> dict:
    """Build one picture's scene and save it; returns build statistics."""
    started = time.perf_counter()
    bpy = _start_blender()
    module = importlib.import_module(f"{_PACKAGE}.{module_name}")
    render = next(r for r in module.FIGURE.renders if r.name == render_name)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    began = time.perf_counter()
    module.build_scene(bpy.context.scene, resolution=tuple(resolution), samples=samples, **render.options)
    built = time.perf_counter() - began
    blend = output / f"{module_name}-{render_name}.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), compress=False)
    return {"build_s": built, "build_process_s": time.perf_counter() - started, "blend": str(blend)}


#: Build times of scratch sets already measured in this output folder: {set and options digest: seconds}.
BUILD_TIMES_FILE = "scratch_build_times.json"


def _scratch_statistics(bpy, output: Path) -> dict:
    """Scratch count, segments and load time of the scene's scratched objects (after the render).

    The load time is the table build's own (the disk cache off).  Pictures of one run that share a
    scratch set and its options (the views of one object) share the measurement: it is taken once per
    set and options in the output folder (``BUILD_TIMES_FILE``), since a set of millions of pieces takes a
    minute to build.
    """
    import hashlib

    from ..mitsuba_bridge import bsdf, scratch
    from ..addon import storage

    known_path = output / BUILD_TIMES_FILE
    known = json.loads(known_path.read_text()) if known_path.exists() else {}
    count = segments = 0
    load_s = 0.0
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH" or not storage.has_scratches(obj):
            continue
        data = storage.raw_scratch_bytes(obj)
        settings = obj.scratch_iridescence  # as the render loads it (the mode decides what is built)
        options = dict(coherent=bool(settings.coherent), depth_phase=settings.depth_phase,
                       crossings=settings.crossings)
        key = hashlib.sha256(data + json.dumps(options, sort_keys=True).encode()).hexdigest()
        began = time.perf_counter()
        scratches = scratch.loads(data)
        if key not in known:
            # the build's own time, not a file the render may have written (bsdf/tables/disk_cache.py)
            with mock.patch.dict(os.environ, {"SCRATCH_IRIDESCENCE_CACHE_DIR": "off"}):
                loaded = bsdf.load(scratches, unit_scale=1.0, **options)
            known[key] = time.perf_counter() - began
            del loaded
            known_path.write_text(json.dumps(known, indent=1))
        load_s += known[key]
        count += scratches.count
        segments += scratches.vertex_count - scratches.count
    return {"scratches": count, "segments": segments, "scratch_load_s": load_s}


def render_worker(blend: Path, output: Path) -> dict:
    """Open ``blend``, render it through the engine, write EXR and PNG; returns render statistics."""
    started = time.perf_counter()
    bpy = _start_blender()
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    opened = time.perf_counter() - started
    stem = output / blend.stem
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.exr_codec = "OPEN_EXR", "32", "ZIP"
    scene.render.filepath = str(stem) + ".exr"
    wall, cpu = time.perf_counter(), _cpu_seconds()
    bpy.ops.render.render(write_still=True)
    wall, cpu = time.perf_counter() - wall, _cpu_seconds() - cpu
    from ..mitsuba_bridge.bsdf.tables import disk_cache
    tables = disk_cache.statistics()  # whether the render read its scratch tables from an earlier one's file
    peak = _peak_mb()
    # RGB (no alpha channel) at the strongest compression: the gallery commits these files.
    settings.file_format, settings.color_depth, settings.color_mode, settings.compression = "PNG", "8", "RGB", 100
    bpy.data.images["Render Result"].save_render(filepath=str(stem) + ".png", scene=scene)
    width, height = scene.render.resolution_x, scene.render.resolution_y
    return {"open_s": opened, "render_s": wall, "render_cpu_s": cpu, "peak_mb": peak,
            "width": width, "height": height, "spp": scene.scratch_iridescence.samples,
            "exr": str(stem) + ".exr", "png": str(stem) + ".png", "tables_read": tables["hits"],
            "tables_built": tables["misses"], **_scratch_statistics(bpy, output)}


#: The machine reference: Mitsuba's own Cornell box (no scratches, no add-on), this size and spp.
REFERENCE_RESOLUTION, REFERENCE_SPP, REFERENCE_RENDERS = 256, 64, 4


def reference_worker() -> dict:
    """Samples per core-second of Mitsuba's Cornell box on the CPU variant the pictures use.

    The paper's times are fixed numbers, so a picture's ratio against them moves with the machine
    (development machines differ by 1.8x between sessions); this render shares no code with the
    add-on, so rows divided by it compare across runs and machines.  The first render compiles the
    kernel (cached), the next four are timed.
    """
    import drjit as dr
    import mitsuba as mi

    from ..mitsuba_bridge.render.activation import activate

    variant = activate("llvm_ad_spectral")
    description = mi.cornell_box()
    description["sensor"]["film"].update(width=REFERENCE_RESOLUTION, height=REFERENCE_RESOLUTION)
    scene = mi.load_dict(description)
    dr.eval(mi.render(scene, spp=REFERENCE_SPP, seed=0))
    cpu = _cpu_seconds()
    for _ in range(REFERENCE_RENDERS):
        dr.eval(mi.render(scene, spp=REFERENCE_SPP, seed=0))  # the same call replays the cached kernel
    cpu = _cpu_seconds() - cpu
    return {"variant": variant, "resolution": REFERENCE_RESOLUTION, "spp": REFERENCE_SPP,
            "samples_per_core_s": REFERENCE_RENDERS * REFERENCE_RESOLUTION ** 2 * REFERENCE_SPP / cpu}


# --------------------------------------------------------------- the runner
def _run_worker(args: list[str], label: str) -> dict:
    """Run a worker in a fresh interpreter, showing its progress now and then; return its statistics."""
    command = [sys.executable, "-m", f"{_PACKAGE}.paper", *args]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                               env={**os.environ, "PYTHONUNBUFFERED": "1"})
    result, last_shown, tail, passes_s, traced = None, 0.0, [], None, None
    for line in process.stdout:
        tail = (tail + [line])[-40:]
        if line.startswith("RESULT "):
            result = json.loads(line[len("RESULT "):])
        elif line.startswith(TRACED_NOTE_PREFIX):  # the engine could not freeze the passes (speed only)
            traced = line.strip()
            print(f"    {label}: {traced}", flush=True)
        elif line.startswith("Fra:"):
            # The engine's progress: "Fra:1 | Mitsuba Scratch | Sample 64/64 | 62.5 s" (time since the first pass).
            passes_s = float(line.rsplit("|", 1)[-1].strip().rstrip("s"))
            if time.perf_counter() - last_shown > 20:
                print(f"    {label}: {line.split('|', 2)[-1].strip()}", flush=True)
                last_shown = time.perf_counter()
    if process.wait() != 0 or result is None:
        sys.stdout.write("".join(tail))
        raise RuntimeError(f"{label}: worker failed ({' '.join(command)})")
    if passes_s is not None:
        result["passes_s"] = passes_s
    if traced is not None:
        result["traced"] = traced
    return result


def measure_reference() -> float:
    """The machine reference (:func:`reference_worker`) in a fresh process, samples per core-second."""
    print("Machine reference (Mitsuba's Cornell box)", flush=True)
    return _run_worker(["reference"], "reference")["samples_per_core_s"]


def measure_filtered_noise(record: dict, output: Path) -> dict:
    """The filtered column of one rendered picture (:mod:`.noise`, in a fresh process), stored in its record."""
    began = time.perf_counter()
    measured = _run_worker(["noise", record["blend"]], f"{record['name']} (filtered noise)")
    measured.pop("passes_s", None)  # the worker's last render's progress line, not the picture's
    record["filtered_same_noise"] = measured
    (output / f"{record['name']}.json").write_text(json.dumps(record, indent=1))
    print(f"  filtered: {measured['spp']} spp for the noise of {measured['point_spp']} "
          f"({'reached' if measured['reached'] else 'NOT reached'}; {time.perf_counter() - began:.0f} s)", flush=True)
    return record


def filtered_noise_only(output: Path, only=None) -> list[dict]:
    """Measure the filtered column for the selected pictures already rendered into ``output`` that lack it."""
    from . import pages

    records = pages.load_records(output)
    chosen = []
    for module, figure in figures(only):
        for render in figure.renders:
            record = records.get(f"{module.__name__.rsplit('.', 1)[-1]}-{render.name}")
            # pictures re-rendered since their column was measured lost it with their old record
            if record is not None and "filtered_same_noise" not in record:
                print(f"{figure.label} {figure.title}, {render.name}: filtered noise", flush=True)
                chosen.append(measure_filtered_noise(record, output))
    return chosen


def run_all(output: Path, only=None, scale: float = 1.0, samples_scale: float = 1.0,
            filtered_noise: bool = True) -> list[dict]:
    """Build and render every selected picture; returns one statistics record per picture."""
    records = []
    for module, figure in figures(only):
        for render in figure.renders:
            name = f"{module.__name__.rsplit('.', 1)[-1]}-{render.name}"
            resolution = [max(8, round(v * scale)) for v in render.resolution]
            samples = max(1, round(render.samples * samples_scale))
            print(f"{figure.label} {figure.title}, {render.name}: {resolution[0]} x {resolution[1]}, "
                  f"{samples} spp", flush=True)
            began = time.perf_counter()
            built = _run_worker(["build", module.__name__.rsplit(".", 1)[-1], render.name, "--output", str(output),
                                 "--resolution", *map(str, resolution), "--samples", str(samples)], name)
            rendered = _run_worker(["render", built["blend"], "--output", str(output)], name)
            record = {"figure": figure.key, "render": render.name, "name": name,
                      "total_s": time.perf_counter() - began, "samples_scale": samples_scale,
                      "resolution_scale": scale, **built, **rendered}
            (output / f"{name}.json").write_text(json.dumps(record, indent=1))
            print(f"  done in {record['total_s']:.0f} s (render {record['render_s']:.0f} s, "
                  f"peak {record['peak_mb']:.0f} MB)", flush=True)
            if filtered_noise:
                measure_filtered_noise(record, output)
            records.append(record)
    return records


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command")
    build = sub.add_parser("build", help="(worker) build one picture's scene and save it")
    build.add_argument("module")
    build.add_argument("render")
    build.add_argument("--output", type=Path, required=True)
    build.add_argument("--resolution", type=int, nargs=2, required=True)
    build.add_argument("--samples", type=int, required=True)
    render = sub.add_parser("render", help="(worker) render a saved scene")
    render.add_argument("blend", type=Path)
    render.add_argument("--output", type=Path, required=True)
    noise = sub.add_parser("noise", help="(worker) the filtered column of a saved, rendered scene")
    noise.add_argument("blend", type=Path)
    sub.add_parser("reference", help="(worker) time the machine reference render")
    parser.add_argument("--output", type=Path, default=Path("out/paper"), help="renders and statistics")
    parser.add_argument("--docs", type=Path, default=Path("docs"), help="where gallery.md and benchmarks.md go")
    parser.add_argument("--only", nargs="+", choices=FIGURE_MODULES, help="render only these figures")
    parser.add_argument("--scale", type=float, default=1.0, help="resolution factor (quick looks)")
    parser.add_argument("--samples-scale", type=float, default=1.0, help="samples-per-pixel factor")
    parser.add_argument("--no-docs", action="store_true", help="render only; leave docs/ alone")
    parser.add_argument("--no-validation", action="store_true", help="skip the numerical validation figure")
    parser.add_argument("--no-filtered-noise", action="store_true",
                        help="skip the filtered column (the spp at which the Footprint Filter matches each picture's "
                             "noise)")
    parser.add_argument("--filtered-noise-only", action="store_true",
                        help="render no pictures: measure the filtered column of those in --output that lack it")
    parser.add_argument("--pages-only", action="store_true",
                        help="render nothing: rewrite the pages from the statistics already in --output")
    args = parser.parse_args(argv)

    if args.command == "build":
        stats = build_worker(args.module, args.render, args.output.resolve(), args.resolution, args.samples)
        print("RESULT " + json.dumps(stats), flush=True)
        return 0
    if args.command == "render":
        stats = render_worker(args.blend.resolve(), args.output.resolve())
        print("RESULT " + json.dumps(stats), flush=True)
        return 0
    if args.command == "noise":
        from .noise import noise_worker

        print("RESULT " + json.dumps(noise_worker(args.blend.resolve(), _start_blender())), flush=True)
        return 0
    if args.command == "reference":
        print("RESULT " + json.dumps(reference_worker()), flush=True)
        return 0

    started = time.perf_counter()
    output = args.output.resolve()
    output.mkdir(parents=True, exist_ok=True)
    records = []
    if args.filtered_noise_only:
        records = filtered_noise_only(output, args.only)
    elif not args.pages_only:
        # Build times are shared by the pictures of this run only: an earlier run's code may have built slower.
        (output / BUILD_TIMES_FILE).unlink(missing_ok=True)
        # Before and after the pictures: their mean divides the rows, their difference shows the drift.
        before = measure_reference()
        records = run_all(output, args.only, args.scale, args.samples_scale, not args.no_filtered_noise)
        after = measure_reference()
        reference = {"before": before, "after": after, "samples_per_core_s": 0.5 * (before + after)}
        (output / "reference.json").write_text(json.dumps(reference, indent=1))
        # Each picture keeps its own run's reference: a later `--only` run measures another one, which
        # must not divide the pictures it did not render.
        for record in records:
            record["reference"] = reference
            (output / f"{record['name']}.json").write_text(json.dumps(record, indent=1))
    validation = None
    if not (args.no_validation or args.pages_only or args.filtered_noise_only):
        from ..mitsuba_bridge.validation import fig15 as numerics

        print("Numerical validation (supplement Fig. 15)", flush=True)
        validation = numerics.run(output / "validation")
    if not args.no_docs:
        from . import pages

        if validation is None and (output / "validation" / "validation.json").exists():
            validation = json.loads((output / "validation" / "validation.json").read_text())
        pages.write(args.docs.resolve(), pages.load_records(output), validation, figures(), output)
    print(f"paper: {len(records)} pictures in {time.perf_counter() - started:.0f} s; renders in {output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
