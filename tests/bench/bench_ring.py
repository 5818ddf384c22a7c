"""Benchmark: the paper's largest curved set, Fig. 12's ring (547 381 scratches), against the Fig. 1 table.

The ring of ``scenes/fig12_ring.py`` (a closed band, ~5 million segments after the
mesh's edges and seams cut the scratches) and, as the reference measured in the
same run, the Fig. 1 dining table of ``scenes/fig01_table.py`` (300 000 scratches on
a flat top, one segment each).  Per scene, each stage runs in a fresh interpreter
started from this small one — ``ru_maxrss`` survives ``execve``, so a child of a
large process would report its parent's peak — and reports its time and its peak
resident memory (``ru_maxrss``: the interpreter, Blender or Mitsuba included; the
figure before the stage's work is printed beside it):

* **generate**: build the scene with the add-on's operators (Spray strokes and
  Generate for the ring; Spray, Pen and Generate for the table), in Blender;
* **save**: the scene as a ``.blend`` (the scratches are stored on the object as
  the bytes of a scratch file) and the scratch file alone (``scratch.save``);
* **reload**: open the ``.blend`` and decode the object's scratches, in Blender;
  then, without Blender, ``scratch.load`` of the file;
* **tables**: ``scratch_diffraction``'s table build (``bsdf.load``, disk cache off), without Blender;
* **viewport**: the Rendered viewport's own code (``addon.render.viewport.ViewportRender``, as in
  ``bench_viewport.py``) on the saved scene at ``--size``: the session's start (its tables built, the
  disk cache off), then ``--strokes`` Pen strokes across the object, each reaching the session through
  ``view_update``: the operator's time, the session's table update, and the time from the stroke to
  the 1/4-resolution preview and to the first full-resolution pass (medians).

The last lines print each figure of the ring as a ratio to the table's.

``--max-cached-pieces 16777216`` lets the viewport extend the ring's tables stroke by stroke (its 4.6
million pieces are above ``bsdf/tables/incremental.py``'s ``MAX_CACHED_PIECES``, so by default every stroke
rebuilds them): the figure to compare with the default's.

    .venv/bin/python tests/bench/bench_ring.py [--strokes 5] [--size 960 540] [--only fig12_ring]
        [--max-cached-pieces N]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENES = ("fig12_ring", "fig01_table")
#: The scratched object each scene module's build_scene returns, by name (for the stages that reopen the file).
OBJECTS = {"fig12_ring": "Ring", "fig01_table": "Table top"}


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _blender():
    import bpy

    import scratch_iridescence

    scratch_iridescence.register()
    return bpy


# ------------------------------------------------------------------ stages
def stage_generate(scene_name: str, folder: Path, size) -> dict:
    """Build, then save the .blend and the scratch file (both timed)."""
    import importlib

    bpy = _blender()
    from scratch_iridescence.addon import storage
    from scratch_iridescence.mitsuba_bridge import scratch

    bpy.ops.wm.read_factory_settings(use_empty=True)
    before = peak_mb()
    module = importlib.import_module(f"scratch_iridescence.scenes.{scene_name}")
    began = time.perf_counter()
    obj = module.build_scene(bpy.context.scene, resolution=tuple(size), samples=16)
    generate_s = time.perf_counter() - began
    generate_mb = peak_mb()
    scratches = storage.read_scratches(obj)
    blend, npz = folder / f"{scene_name}.blend", folder / f"{scene_name}.npz"
    began = time.perf_counter()
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), compress=False)
    blend_s = time.perf_counter() - began
    began = time.perf_counter()
    scratch.save(scratches, npz)
    npz_s = time.perf_counter() - began
    return {"scratches": scratches.count, "segments": scratches.vertex_count - scratches.count,
            "before_mb": before, "generate_s": generate_s, "generate_mb": generate_mb,
            "save_blend_s": blend_s, "blend_mb": blend.stat().st_size / 2**20,
            "save_file_s": npz_s, "file_mb": npz.stat().st_size / 2**20, "peak_mb": peak_mb()}


def stage_reload(scene_name: str, folder: Path) -> dict:
    """Open the .blend and decode the scratches (Blender)."""
    bpy = _blender()
    from scratch_iridescence.addon import storage

    before = peak_mb()
    began = time.perf_counter()
    bpy.ops.wm.open_mainfile(filepath=str(folder / f"{scene_name}.blend"))
    open_s = time.perf_counter() - began
    began = time.perf_counter()
    count = storage.read_scratches(bpy.data.objects[OBJECTS[scene_name]]).count
    return {"before_mb": before, "open_s": open_s, "decode_s": time.perf_counter() - began, "count": count,
            "peak_mb": peak_mb()}


def stage_tables(scene_name: str, folder: Path) -> dict:
    """scratch.load of the file, then the BSDF's tables built (no Blender; the disk cache off)."""
    os.environ["SCRATCH_IRIDESCENCE_CACHE_DIR"] = "off"
    from scratch_iridescence.mitsuba_bridge import bsdf, scratch
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    activate("llvm_ad_spectral")
    before = peak_mb()
    began = time.perf_counter()
    scratches = scratch.load(folder / f"{scene_name}.npz")
    load_s = time.perf_counter() - began
    load_mb = peak_mb()
    began = time.perf_counter()
    loaded = bsdf.load(scratches, unit_scale=1.0)
    tables_s = time.perf_counter() - began
    return {"before_mb": before, "load_s": load_s, "load_mb": load_mb, "tables_s": tables_s, "peak_mb": peak_mb(),
            "bsdf": str(loaded)}


def _stroke_points(scene_name: str, index: int, strokes: int):
    """World points of the ``index``-th bench stroke: across the part of the object the camera sees."""
    import numpy as np

    if scene_name == "fig12_ring":
        from scratch_iridescence.scenes import fig12_ring, shapes

        ring = fig12_ring.RING
        # on the band's outer face towards the camera (azimuth 180°: -Y, u = 0.75), from edge to edge
        u = 0.72 + 0.06 * (index + 0.5) / strokes + np.linspace(0.0, 0.01, 5)
        v = np.linspace(0.44, 0.56, 5)
        points = shapes.ring_surface(u, v, ring["radius_m"], ring["width_m"], ring["thickness_m"])
        points[:, 2] += 0.5 * ring["width_m"]  # the ring lies on the velvet (build_scene lifts it)
        return points
    from scratch_iridescence.scenes import fig01_table

    x0, y0 = fig01_table.LAMP_REFLECTION
    y = y0 - 0.1 + 0.2 * (index + 0.5) / strokes
    return [(x0 - 0.15, y, 0.0), (x0, y + 0.02, 0.0), (x0 + 0.15, y, 0.0)]


def stage_viewport(scene_name: str, folder: Path, size, strokes: int, max_cached_pieces: int | None) -> dict:
    """The Rendered viewport on the saved scene: its start and Pen strokes (stroke → preview)."""
    import statistics

    os.environ["SCRATCH_IRIDESCENCE_CACHE_DIR"] = "off"  # the session builds the tables, as on a first open
    if max_cached_pieces is not None:
        from scratch_iridescence.mitsuba_bridge.bsdf.tables import incremental

        incremental.MAX_CACHED_PIECES = max_cached_pieces
    bpy = _blender()
    sys.path.insert(0, str(Path(__file__).parent))
    from bench_viewport import stroke, updates_of, view_of, wait_for

    from scratch_iridescence.addon.render.viewport import ViewportRender, stats_of
    from scratch_iridescence.scenes import fig01_table, fig12_ring

    bpy.ops.wm.open_mainfile(filepath=str(folder / f"{scene_name}.blend"))
    before = peak_mb()
    scene = bpy.context.scene
    obj = bpy.data.objects[OBJECTS[scene_name]]
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    camera = scene.camera
    width, height = size
    viewport = ViewportRender()
    viewport.draw = lambda engine, scene, region, progress, version, rect: rect.copy()  # gpu raises headless
    began = time.perf_counter()
    viewport.view_update(view_of(bpy, camera, width, height), bpy.context.evaluated_depsgraph_get())
    preview, _ = wait_for(viewport, 0, full=False, timeout=1800.0)
    full, _ = wait_for(viewport, 0, full=True, timeout=1800.0)
    start = {"start_preview_s": preview, "start_full_s": preview + full, "start_mb": peak_mb()}

    def sync(scene_, depsgraph):  # Blender calls view_update from the depsgraph update
        viewport.view_update(view_of(bpy, camera, width, height), depsgraph)

    looks = fig12_ring.LOOKS if scene_name == "fig12_ring" else fig01_table.LOOKS
    operator_s, updates, previews, fulls = [], [], [], []
    bpy.app.handlers.depsgraph_update_post.append(sync)
    try:
        for index in range(strokes):
            target = updates_of(viewport) + 1
            began = time.perf_counter()
            result = bpy.ops.scratch.paint_stroke("EXEC_DEFAULT", True, stroke=stroke(
                _stroke_points(scene_name, index, strokes)), brush_mode="PEN", seed=index, **looks)
            assert "FINISHED" in result, result
            operator_s.append(time.perf_counter() - began)
            wait_for(viewport, target, full=False, timeout=600.0)
            previews.append(time.perf_counter() - began)
            wait_for(viewport, target, full=True, timeout=600.0)
            fulls.append(time.perf_counter() - began)
            updates.append(viewport.latest()[4]["last_update_seconds"])
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(sync)
    stats = stats_of(viewport)
    viewport.stop()
    viewport.join(60.0)
    median = statistics.median
    return {"before_mb": before, **start, "stroke_operator_s": median(operator_s),
            "stroke_update_s": median(updates), "stroke_preview_s": median(previews),
            "stroke_full_s": median(fulls), "last_update": stats["last_update"],
            "main_thread_max_s": stats["main_thread_max_s"], "peak_mb": peak_mb()}


# ------------------------------------------------------------------ runner
def run_stage(stage: str, scene_name: str, folder: Path, args) -> dict:
    """One stage in a fresh interpreter started from this (small) process."""
    command = [sys.executable, __file__, "--stage", stage, "--scene", scene_name, "--folder", str(folder),
               "--size", *map(str, args.size), "--strokes", str(args.strokes)]
    if args.max_cached_pieces is not None:
        command += ["--max-cached-pieces", str(args.max_cached_pieces)]
    done = subprocess.run(command, capture_output=True, text=True)
    results = [line for line in done.stdout.splitlines() if line.startswith("RESULT ")]
    if done.returncode != 0 or not results:
        sys.stdout.write(done.stdout[-4000:] + done.stderr[-4000:])
        raise RuntimeError(f"{stage} of {scene_name} failed")
    return json.loads(results[-1][len("RESULT "):])


def report(name: str, r: dict) -> None:
    g, t, rl, v = r["generate"], r["tables"], r["reload"], r["viewport"]
    print(f"{name}: {g['scratches']:,} scratches, {g['segments']:,} segments")
    print(f"  generate {g['generate_s']:.1f} s, peak {g['generate_mb']:.0f} MB "
          f"(Blender before: {g['before_mb']:.0f} MB)")
    print(f"  save .blend {g['save_blend_s']:.2f} s ({g['blend_mb']:.0f} MB), scratch file {g['save_file_s']:.2f} s "
          f"({g['file_mb']:.0f} MB); process peak {g['peak_mb']:.0f} MB")
    print(f"  reload: open .blend {rl['open_s']:.2f} s + decode {rl['decode_s']:.2f} s, peak {rl['peak_mb']:.0f} MB "
          f"(before {rl['before_mb']:.0f}); scratch.load without Blender {t['load_s']:.2f} s")
    print(f"  tables: {t['tables_s']:.1f} s, peak {t['peak_mb']:.0f} MB (Mitsuba and the set before: "
          f"{t['load_mb']:.0f} MB)\n    {t['bsdf']}")
    print(f"  viewport: first preview {v['start_preview_s']:.1f} s, first full pass {v['start_full_s']:.1f} s "
          f"(tables built), peak {v['start_mb']:.0f} MB; pen stroke: operator {v['stroke_operator_s'] * 1e3:.0f} ms, "
          f"table update {v['stroke_update_s'] * 1e3:.0f} ms, -> preview {v['stroke_preview_s'] * 1e3:.0f} ms, "
          f"-> full pass {v['stroke_full_s'] * 1e3:.0f} ms (medians; target for the demo plate 200 ms); "
          f"main thread max {v['main_thread_max_s'] * 1e3:.0f} ms; process peak {v['peak_mb']:.0f} MB")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stage", choices=("generate", "reload", "tables", "viewport"), help=argparse.SUPPRESS)
    parser.add_argument("--scene", default="fig12_ring", help=argparse.SUPPRESS)
    parser.add_argument("--folder", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--size", type=int, nargs=2, default=(960, 540), metavar=("W", "H"),
                        help="viewport size (pixels)")
    parser.add_argument("--strokes", type=int, default=5, help="pen strokes timed in the viewport")
    parser.add_argument("--only", nargs="+", choices=SCENES, default=list(SCENES))
    parser.add_argument("--max-cached-pieces", type=int, default=None,
                        help="the viewport's strokes extend the tables of sets up to this many pieces "
                             "(bsdf/tables/incremental.py's MAX_CACHED_PIECES, 2^20; above it every stroke rebuilds them)")
    args = parser.parse_args()
    if args.stage:
        stage = {"generate": lambda: stage_generate(args.scene, args.folder, args.size),
                 "reload": lambda: stage_reload(args.scene, args.folder),
                 "tables": lambda: stage_tables(args.scene, args.folder),
                 "viewport": lambda: stage_viewport(args.scene, args.folder, args.size, args.strokes,
                                                    args.max_cached_pieces)}[args.stage]
        print("RESULT " + json.dumps(stage()), flush=True)
        return 0

    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start; this process "
          f"{peak_mb():.0f} MB (every stage runs in a fresh child of it)", flush=True)
    results = {}
    with tempfile.TemporaryDirectory() as temporary:
        for scene_name in args.only:
            results[scene_name] = {}
            for stage in ("generate", "reload", "tables", "viewport"):
                results[scene_name][stage] = run_stage(stage, scene_name, Path(temporary), args)
            report(scene_name, results[scene_name])
    if len(results) == 2:
        ring, table = results["fig12_ring"], results["fig01_table"]
        ratios = [("generate", "generate", "generate_s"), ("generate peak", "generate", "generate_mb"),
                  ("scratch file", "generate", "file_mb"), ("reload (.blend)", "reload", "open_s"),
                  ("tables", "tables", "tables_s"), ("tables peak", "tables", "peak_mb"),
                  ("viewport start", "viewport", "start_full_s"), ("stroke -> preview", "viewport", "stroke_preview_s"),
                  ("stroke -> full pass", "viewport", "stroke_full_s"), ("viewport peak", "viewport", "peak_mb")]
        print("ring / table: " + ", ".join(f"{label} {ring[s][k] / table[s][k]:.2f}x" for label, s, k in ratios))
    print(f"load average at the end: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
