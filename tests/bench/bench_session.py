"""Benchmark: the viewport's bpy-free core (``interactive.Session``) on a demo-like plate, CPU or GPU.

``bench_viewport.py`` drives the add-on's viewport and needs Blender; this one drives the
session underneath it directly, so it runs wherever Mitsuba runs (an NVIDIA machine without
Blender too).  The scene is built in code like the demo (``scenes/demo.py``): a 10 cm aluminium
plate carrying 3 000 random scratches (G_W[4, 1.3] µm, G_D[250, 80] nm), a dark table, a sun 35°
high and a constant sky, the camera 12° above the sun's mirror direction.  Prints, per
``--crossings`` option:

* start: building the session and its first full-resolution image (kernels compiled here);
* camera move and pen stroke (a new scratch appended to the set): seconds from the edit to the
  1/4-resolution preview and to the first full-resolution pass (medians over the edits), and the
  kernels compiled during all of them (target 0);
* the settled rate: full-resolution samples per second once the passes carry ``BATCH_SPP``
  samples (wall time: the figure for a GPU; on the CPU both cores work).

Targets (issue 14, on the 2-core CPU): stroke → first updated image ≤ 0.2 s, ≥ 5 full-resolution
1-spp passes per second.

    .venv/bin/python tests/bench/bench_session.py [--variant cuda_ad_spectral] [--size 960 540]
        [--moves 10 --strokes 10] [--crossings additive height_field]
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

PLATE_M = 0.10
SUN_ELEVATION_DEG = 35.0
KEY = "scratched"


def look_at(position, target) -> np.ndarray:
    """A Blender-convention camera matrix (looks along −Z, +Y up) at ``position`` aimed at ``target``."""
    position, target = np.asarray(position, float), np.asarray(target, float)
    back = position - target
    back /= np.linalg.norm(back)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = right, np.cross(back, right), back, position
    return matrix


def square(name: str, size: float):
    from scratch_iridescence.mitsuba_bridge import scene as S

    h = size / 2
    positions = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return S.MeshData(name, positions, faces, None, uvs)


def camera(turn_deg: float = 0.0):
    """The demo's camera, turned about the plate's normal by ``turn_deg``."""
    from scratch_iridescence.mitsuba_bridge import scene as S

    elevation, distance, turn = math.radians(SUN_ELEVATION_DEG + 12.0), 0.24, math.radians(turn_deg)
    position = (math.sin(turn) * math.cos(elevation) * distance, -math.cos(turn) * math.cos(elevation) * distance,
                math.sin(elevation) * distance)
    return S.Camera(look_at(position, (0.0, 0.012, 0.0)), fov_x_deg=39.6)


def demo_scene(width: int, height: int, crossings: str):
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge import scratch

    scratches = scratch.random_scratches(
        3000, seed=7, width=scratch.Gaussian(4e-6, 1.3e-6), depth=scratch.Gaussian(250e-9, 80e-9),
        depth_variation=(1.1, 0.04), length=(0.2, 0.6), region=((0.02, 0.02), (0.98, 0.98)))
    plate_at = np.eye(4)
    plate_at[2, 3] = 0.002
    elevation = math.radians(SUN_ELEVATION_DEG)
    sun = S.SunLight((0.0, -math.cos(elevation), -math.sin(elevation)), (1000.0, 1000.0, 1000.0))
    materials = {KEY: S.ScratchedMetal(scratches, coherence_diameter_m=30e-6, crossings=crossings),
                 "slate": S.Principled(base_color=(0.03, 0.03, 0.035), roughness=0.9)}
    shapes = (S.Shape("plate", square("plate", PLATE_M), plate_at, KEY),
              S.Shape("table", square("table", 2.0), np.eye(4), "slate"))
    return S.SceneDescription(film=S.Film(width, height), camera=camera(), shapes=shapes, materials=materials,
                              lights=(sun,), world=S.ConstantWorld((0.05, 0.06, 0.08))), scratches


def first_full_pass(session) -> float:
    """Render until the first full-resolution pass after a change is shown."""
    while session.stats["spp_done"] < 1:  # (on the CPU a pass is several strips; it shows when all are done)
        session.step(0.0)


def timed_edit(session, edit) -> tuple[float, float, float]:
    """Seconds from ``edit()`` to: its return (the update itself), the preview, the first full-resolution pass."""
    began = time.perf_counter()
    edit()
    updated = time.perf_counter() - began
    session.step(0.0)  # the preview (one render)
    preview = time.perf_counter() - began
    first_full_pass(session)
    return updated, preview, time.perf_counter() - began


def median(edits, column):
    return statistics.median(edit[column] for edit in edits) if edits else float("nan")


def run(args, crossings: str) -> dict:
    from scratch_iridescence.mitsuba_bridge import scratch
    from scratch_iridescence.mitsuba_bridge.render import session as interactive
    from scratch_iridescence.mitsuba_bridge.scene import RenderSettings

    description, scratches = demo_scene(*args.size, crossings)
    began = time.perf_counter()
    session = interactive.Session(description, RenderSettings(seed=1, max_depth=4), samples=1 << 20)
    first_full_pass(session)
    start_s = time.perf_counter() - began
    compiled = session.stats["kernels_compiled"]

    moves = [timed_edit(session, lambda k=k: session.set_camera(camera(0.5 * (k + 1))))
             for k in range(args.moves)]
    after_moves = session.stats["kernels_compiled"]

    def stroke(k):
        nonlocal scratches
        line = scratch.random_scratches(1, seed=100 + k, width=scratch.Constant(4e-6), depth=scratch.Constant(3e-7),
                                        vertices=8, curvature=0.3, length=(0.1, 0.2),
                                        region=((0.2, 0.2), (0.8, 0.8)))
        scratches = scratch.ScratchSet.concatenate([scratches, line])
        session.set_scratches(KEY, scratches)

    strokes = [timed_edit(session, lambda k=k: stroke(k)) for k in range(args.strokes)]
    after_strokes = session.stats["kernels_compiled"]

    single_began, spp_began = time.perf_counter(), session.stats["spp_done"]
    while session.stats["spp_done"] < interactive.SINGLE_SAMPLE_PASSES:  # the rest of the 1-spp passes
        session.step(0.0)
    single_rate = (session.stats["spp_done"] - spp_began) / max(time.perf_counter() - single_began, 1e-9)
    session.step(0.5)  # into the batched passes
    settled_began, spp_began = time.perf_counter(), session.stats["spp_done"]
    session.step(args.seconds)
    settled_s = time.perf_counter() - settled_began
    width, height = args.size
    rate = (session.stats["spp_done"] - spp_began) * width * height / settled_s
    stats = session.stats
    session.close()
    return {"crossings": crossings, "start_s": start_s, "start_kernels": compiled,
            "move_preview_s": median(moves, 1), "move_full_s": median(moves, 2), "move_kernels": after_moves - compiled,
            "stroke_update_s": median(strokes, 0), "stroke_preview_s": median(strokes, 1),
            "stroke_full_s": median(strokes, 2),
            "stroke_kernels": after_strokes - after_moves, "single_passes_per_s": single_rate,
            "settled_samples_per_s": rate, "frozen": stats["frozen"], "freeze_failure": stats["freeze_failure"],
            "strips": stats["strips"]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="auto", help="llvm_ad_spectral, cuda_ad_spectral or auto")
    parser.add_argument("--size", type=int, nargs=2, default=(960, 540), metavar=("W", "H"))
    parser.add_argument("--moves", type=int, default=10)
    parser.add_argument("--strokes", type=int, default=10)
    parser.add_argument("--seconds", type=float, default=3.0, help="time of the settled passes")
    parser.add_argument("--crossings", nargs="+", default=["additive"], choices=["additive", "height_field"])
    args = parser.parse_args()
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    variant = activate(args.variant)
    print(f"{variant}, {args.size[0]} x {args.size[1]}, {args.moves} camera moves, {args.strokes} strokes")
    for crossings in args.crossings:
        r = run(args, crossings)
        print(f"{crossings}: start {r['start_s']:.2f} s ({r['start_kernels']} kernels, {r['strips']} strip(s) a pass, "
              f"frozen {r['frozen']}{'' if r['freeze_failure'] is None else ': ' + str(r['freeze_failure'])})\n"
              f"  camera move -> preview {1e3 * r['move_preview_s']:.0f} ms, first full pass "
              f"{1e3 * r['move_full_s']:.0f} ms; kernels compiled {r['move_kernels']} (target 0)\n"
              f"  pen stroke  -> tables {1e3 * r['stroke_update_s']:.0f} ms, preview {1e3 * r['stroke_preview_s']:.0f} ms, first full pass "
              f"{1e3 * r['stroke_full_s']:.0f} ms (target 200 ms); kernels compiled {r['stroke_kernels']} (target 0)\n"
              f"  1-spp full passes {r['single_passes_per_s']:.1f}/s (target 5), settled "
              f"{r['settled_samples_per_s']:.3g} samples/s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
