"""Benchmark: the Rendered viewport on the demo plate (3 000 scratches) at 960 × 540.

Drives the engine's own viewport code (``addon.render.viewport.ViewportRender``:
the classifier on the main thread, the session in its worker thread) with the
demo scene of ``addon/scenes/demo.py``, looking through the demo camera, and prints

* first image after a camera change and after a pen stroke: the 1/4-resolution
  preview and the first full-resolution 1-spp pass (seconds after the edit);
* full-resolution passes per second (1 spp, and samples per second with the
  4-spp passes that follow);
* main-thread time per ``view_update``/``view_draw`` call (max and median),
  without the texture upload, which needs a window (``gpu`` raises headless);
* kernels compiled during 50 camera moves and 20 strokes (target 0).

Targets (issue 14) on the 2-core CPU: stroke → first updated image ≤ 0.2 s,
≥ 5 full-resolution 1-spp passes/s, main-thread blocking ≤ 50 ms.

Run: ``.venv/bin/python tests/bench/bench_viewport.py [--moves 50 --strokes 20]``; ``--full-builds``
rebuilds the whole scratch tables on every stroke (the reference for ``bsdf/tables/incremental.py``),
``--crossings height_field`` paints with the height-field crossings (strokes extend the pair list too),
``--strip-pixels 0`` renders whole passes instead of strips (the reference for the strips): run
them back to back and compare.
"""
from __future__ import annotations

import argparse
import math
import os
import time
from types import SimpleNamespace

import numpy as np


class Engine:
    """What view_draw calls on the engine; drawing itself needs a window."""

    def update_stats(self, stats, info):
        pass

    def tag_redraw(self):
        pass


def view_of(bpy, camera, width, height):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    region_data = SimpleNamespace(view_matrix=camera.matrix_world.inverted(),
                                  window_matrix=camera.calc_matrix_camera(depsgraph, x=width, y=height),
                                  is_perspective=True)
    return SimpleNamespace(region=SimpleNamespace(width=width, height=height), region_data=region_data)


def stroke(points):
    return [{"name": "", "location": tuple(map(float, p)), "mouse": (0.0, 0.0), "mouse_event": (0.0, 0.0),
             "pressure": 1.0, "size": 0.0, "x_tilt": 0.0, "y_tilt": 0.0, "time": float(i), "is_start": i == 0}
            for i, p in enumerate(points)]


def updates_of(viewport) -> int:
    stats = viewport.latest()[4]
    return stats.get("updates", 0) + stats.get("rebuilds", 0)


def wait_for(viewport, updates: int, *, full: bool, timeout=600.0):
    """Seconds until an image rendered after the session's ``updates``-th update exists (``full``: at full
    resolution).  Images of the pass that was in flight when the edit came do not count."""
    began = time.perf_counter()
    while time.perf_counter() - began < timeout:
        progress, newest, _, error, stats = viewport.latest()
        if error:
            raise RuntimeError(error)
        done = stats.get("updates", 0) + stats.get("rebuilds", 0)
        if progress is not None and done >= updates and (not full or progress.spp_done > 0):
            return time.perf_counter() - began, newest
        time.sleep(0.0005)
    raise TimeoutError("no image")


def wait_finished(viewport, timeout=600.0):
    end = time.perf_counter() + timeout
    while not viewport.latest()[2] and time.perf_counter() < end:
        time.sleep(0.01)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=960)
    parser.add_argument("--height", type=int, default=540)
    parser.add_argument("--moves", type=int, default=50)
    parser.add_argument("--strokes", type=int, default=20)
    parser.add_argument("--no-freeze", action="store_true", help="trace every pass (no dr.freeze)")
    parser.add_argument("--full-builds", action="store_true",
                        help="rebuild the whole scratch tables on each stroke (the reference for bsdf/tables/incremental.py)")
    parser.add_argument("--crossings", default="additive", choices=("additive", "height_field"),
                        help="the plate's Crossings setting (height_field: strokes also extend the crossing pairs)")
    parser.add_argument("--strip-pixels", type=int, default=None,
                        help="pixels per strip of a CPU pass (0: whole passes, the reference for the strips)")
    args = parser.parse_args()
    if args.strip_pixels is not None:
        from scratch_iridescence.mitsuba_bridge.render import session as interactive

        interactive.CPU_STRIP_PIXELS = args.strip_pixels
    if args.full_builds:
        from scratch_iridescence.mitsuba_bridge.bsdf import plugin
        from scratch_iridescence.mitsuba_bridge.bsdf.tables import incremental

        plugin.update_tables = lambda previous, scratches, cell_size, crossings=False: incremental.update_tables(
            None, scratches, cell_size, crossings=crossings)

    import bpy

    import scratch_iridescence
    from scratch_iridescence.addon.render.viewport import ViewportRender, stats_of
    from scratch_iridescence.scenes.demo import PLATE_SIZE_M, build_scene

    scratch_iridescence.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    plate = build_scene(scene, resolution=(args.width, args.height))
    scene.scratch_iridescence.viewport_freeze = not args.no_freeze
    plate.scratch_iridescence.crossings = args.crossings
    scene.scratch_iridescence.viewport_samples = 16  # enough for 4 single-sample and 3 four-sample passes
    bpy.context.view_layer.objects.active = plate
    camera = scene.camera
    engine, viewport = Engine(), ViewportRender()
    # Headless, gpu raises: time the CPU side of drawing instead (the copy into the texture's buffer).
    viewport.draw = lambda engine, scene, region, progress, version, rect: rect.copy()

    def sync(scene_, depsgraph):  # Blender calls view_update from the depsgraph update
        viewport.view_update(view_of(bpy, camera, args.width, args.height), depsgraph)

    started = time.perf_counter()
    viewport.view_update(view_of(bpy, camera, args.width, args.height), bpy.context.evaluated_depsgraph_get())
    build_seconds = viewport.main_thread_seconds[-1]
    preview, _ = wait_for(viewport, 0, full=False)
    first_full, _ = wait_for(viewport, 0, full=True)
    wait_finished(viewport)
    print(f"scene build: view_update (gather) {build_seconds * 1e3:.0f} ms, preview after {preview:.2f} s, "
          f"first full-resolution pass after {preview + first_full:.2f} s, 16 spp after "
          f"{time.perf_counter() - started:.1f} s (kernels compiled or loaded from the disk cache: "
          f"{viewport.latest()[4]['kernels_compiled']})")
    viewport.main_thread_seconds.clear()
    kernels_before = viewport.latest()[4]["kernels_compiled"]

    # ---- camera moves: an orbit around the plate, each posted by view_draw as in a window
    depsgraph = bpy.context.evaluated_depsgraph_get()
    centre = np.array(camera.location)
    camera_previews, camera_fulls = [], []
    for move in range(args.moves):
        angle = math.radians(0.5 * (move + 1))
        camera.location = (centre[0] + 0.24 * math.sin(angle) * 0.2, centre[1], centre[2])
        bpy.context.view_layer.update()
        target = updates_of(viewport) + 1
        began = time.perf_counter()
        viewport.view_draw(engine, view_of(bpy, camera, args.width, args.height), depsgraph)
        wait_for(viewport, target, full=False)
        camera_previews.append(time.perf_counter() - began)
        wait_for(viewport, target, full=True)
        camera_fulls.append(time.perf_counter() - began)
    # ---- a continuous orbit: a view_draw every 33 ms for 3 s, as while dragging the view
    orbit_began, orbit_version = time.perf_counter(), viewport.latest()[1]
    step = 0
    while time.perf_counter() - orbit_began < 3.0:
        step += 1
        camera.location.x = centre[0] + 0.01 * math.sin(0.05 * step)
        bpy.context.view_layer.update()
        viewport.view_draw(engine, view_of(bpy, camera, args.width, args.height), depsgraph)
        time.sleep(max(0.0, orbit_began + step / 30.0 - time.perf_counter()))
    orbit_images = viewport.latest()[1] - orbit_version
    kernels_camera = viewport.latest()[4]["kernels_compiled"] - kernels_before

    # ---- pen strokes across the plate, each reaching the viewport through view_update
    bpy.app.handlers.depsgraph_update_post.append(sync)
    stroke_previews, stroke_fulls, stroke_ops, stroke_updates = [], [], [], []
    half = 0.4 * PLATE_SIZE_M
    try:
        for index in range(args.strokes):
            y = -half + 2 * half * (index + 0.5) / args.strokes
            points = [(-half, y, 0.002), (0.0, y + 0.005, 0.002), (half, y, 0.002)]
            target = updates_of(viewport) + 1
            began = time.perf_counter()
            bpy.ops.scratch.paint_stroke("EXEC_DEFAULT", True, stroke=stroke(points), seed=index)
            stroke_ops.append(time.perf_counter() - began)
            wait_for(viewport, target, full=False)
            stroke_previews.append(time.perf_counter() - began)
            wait_for(viewport, target, full=True)
            stroke_fulls.append(time.perf_counter() - began)
            stroke_updates.append(viewport.latest()[4]["last_update_seconds"])
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(sync)
    stats = stats_of(viewport)
    kernels_stroke = stats["kernels_compiled"] - kernels_before - kernels_camera
    assert stats["last_update"] == "scratches", stats["last_update"]

    # ---- full-resolution throughput: let the last stroke's refinement run
    wait_finished(viewport)
    timings = {"single": [], "batch": []}
    for _ in range(3):
        camera.location.z += 1e-4
        bpy.context.view_layer.update()
        viewport.view_draw(engine, view_of(bpy, camera, args.width, args.height), depsgraph)
        version, last_time, last_spp = viewport.latest()[1], time.perf_counter(), 0
        while not viewport.latest()[2]:
            progress, newest = viewport.latest()[:2]
            # a pass ends when spp_done grows (on the CPU a pass is several strips, each an image)
            if newest > version and progress.spp_done > last_spp:
                now = time.perf_counter()
                if last_spp > 0:
                    kind = "single" if progress.spp_done - last_spp == 1 else "batch"
                    timings[kind].append((now - last_time) / (progress.spp_done - last_spp))
                last_time, last_spp = now, progress.spp_done
            version = newest
            time.sleep(0.0005)
    viewport.stop()
    viewport.join(30.0)

    # ---- per-pass cost of tracing: frozen and traced sessions side by side, interleaved (same load)
    import dataclasses

    from scratch_iridescence.addon.render.gather import gather_scene, gather_settings
    from scratch_iridescence.mitsuba_bridge.render import session as interactive

    camera_now, film = viewport._view
    description = gather_scene(bpy.context.evaluated_depsgraph_get(), view=(camera_now, film))
    # whole passes (no strips): the figures are per full-resolution pass
    sessions = {freeze: interactive.Session(description, gather_settings(scene), samples=64, freeze=freeze,
                                            strip_pixels=0) for freeze in (True, False)}
    pass_times = {(freeze, kind): [] for freeze in sessions for kind in ("preview", "full")}
    for round_index in range(7):
        for freeze, session in sessions.items():
            moved = np.array(camera_now.to_world)
            moved[0, 3] += 1e-4 * round_index
            session.set_camera(dataclasses.replace(camera_now, to_world=moved))
            for kind in ("preview", "full"):
                began = time.perf_counter()
                session.step(0.0)
                if round_index:  # the first round records (frozen) or compiles
                    pass_times[freeze, kind].append(time.perf_counter() - began)
    for session in sessions.values():
        session.close()

    median = lambda values: float(np.median(values))  # noqa: E731
    print(f"camera change -> preview (1/4 res) {median(camera_previews) * 1e3:.0f} ms median, "
          f"-> full res 1 spp {median(camera_fulls) * 1e3:.0f} ms median ({args.moves} moves)")
    print(f"continuous orbit (30 view changes per second for 3 s): {orbit_images / 3.0:.1f} images per second")
    print(f"scratch table update in the session (median of the strokes): "
          f"{median(stroke_updates) * 1e3:.0f} ms")
    print(f"pen stroke    -> preview (1/4 res) {median(stroke_previews) * 1e3:.0f} ms median, "
          f"-> full res 1 spp {median(stroke_fulls) * 1e3:.0f} ms median ({args.strokes} strokes; "
          f"the operator itself {median(stroke_ops) * 1e3:.0f} ms)   target <= 200 ms")
    batch = f", {1 / median(timings['batch']):.1f} samples/s in 4-spp passes" if timings["batch"] else ""
    print(f"full resolution {args.width} x {args.height}: {1 / median(timings['single']):.1f} passes/s at 1 spp"
          f"{batch} ({stats['strips']} strips a pass)   target >= 5 passes/s")
    print(f"main thread per view_update/view_draw: max {stats['main_thread_max_s'] * 1e3:.1f} ms, median "
          f"{stats['main_thread_median_s'] * 1e3:.2f} ms (texture upload not included)   target <= 50 ms")
    print(f"kernels compiled: {kernels_camera} during {args.moves} camera moves, {kernels_stroke} during "
          f"{args.strokes} strokes   target 0")
    for kind, label in (("preview", "1/4-res preview pass"), ("full", "full-res 1-spp pass")):
        frozen, traced = median(pass_times[True, kind]), median(pass_times[False, kind])
        print(f"{label}: frozen {frozen * 1e3:.0f} ms, traced {traced * 1e3:.0f} ms (ratio {frozen / traced:.2f}, "
              f"tracing costs {(traced - frozen) * 1e3:.0f} ms per pass)")
    print(f"frozen passes: {stats['frozen']} ({stats['recordings']} recordings, failure: {stats['freeze_failure']}); "
          f"load average during the run: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    scratch_iridescence.unregister()


if __name__ == "__main__":
    main()
