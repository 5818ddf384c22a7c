"""Benchmark: seed-to-seed noise of a diffuse scene with the stratified sampler (``multijitter``) and the
independent one, through the renderer's own path (the fixed chunk schedule), in one run.

The scene (``tests/bridge/bridge_scenes.diffuse_scene``): two diffuse spheres on a grey floor, a tilted
area light out of view and a dim world, path traced to depth 8. For each ``--size`` and sampler it
renders ``--spp`` samples per pixel with seeds 1 and 2 (``render.passes.render_image``: the schedule's
chunks, each with its own seed) and prints:

* **L1** = mean |image₁ − image₂| / mean(image₁), RGB, every pixel: the issue's "image difference
  between two seeds, relative";
* **RMSE** = √(mean (image₁ − image₂)²) / mean(image₁);
* **mean** = mean(image₂) / mean(image₁) − 1 (both samplers are unbiased: within the noise);
* **s/render**: the wall time of one render (after a render that compiled its kernels);
* the stratified sampler's L1 and RMSE over the independent one's (target: 0.5 or less at 64 spp).

The chunks column is the schedule at that size: a stratified sampler stratifies within a chunk, and chunks
add like independent estimates (docs/rendering.md, The sampler), so the gain shrinks with the chunk.

``--mitsuba-samplers`` also renders the first size in one ``mi.render`` call of ``--spp`` with each of
Mitsuba's samplers that takes that count as it is (64: ``stratified``, ``multijitter``, ``ldsampler``,
``independent``; ``orthogonal`` would render 121), outside the schedule: how they rank at equal samples.

Run: ``.venv/bin/python tests/bench/bench_sampler.py [--size 320 200 --size 640 400] [--spp 64]
[--mitsuba-samplers]`` (prints markdown tables; docs/rendering.md, The sampler, has the figures).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bridge"))


def seed_difference(first: np.ndarray, second: np.ndarray) -> tuple[float, float]:
    """(relative L1, relative RMSE) of two renders of one scene with different seeds."""
    difference = second - first
    return float(np.abs(difference).mean() / first.mean()), float(np.sqrt((difference ** 2).mean()) / first.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, nargs=2, action="append", metavar=("WIDTH", "HEIGHT"),
                        help="film size (repeatable; default 320 200 and 640 400)")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--mitsuba-samplers", action="store_true",
                        help="also rank Mitsuba's samplers in one call each at the first size")
    args = parser.parse_args()

    from bridge_scenes import diffuse_scene
    from scratch_iridescence.mitsuba_bridge import builder
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge.device.variants import on_gpu
    from scratch_iridescence.mitsuba_bridge.render.activation import activate
    from scratch_iridescence.mitsuba_bridge.render.passes import render_image
    from scratch_iridescence.mitsuba_bridge.render.schedule import sample_schedule

    variant = activate("auto")
    print(f"{variant}, {args.spp} spp, seeds 1 and 2\n")
    print("| film | chunks (spp) | sampler | L1 | RMSE | mean | s/render |")
    print("|---|---|---|---|---|---|---|")
    for width, height in args.size or [(320, 200), (640, 400)]:
        sizes = [chunk.spp for chunk in sample_schedule(args.spp, width * height, gpu=on_gpu())]
        chunks = f"{len(sizes)} ({'+'.join(str(s) for s in sorted(set(sizes), reverse=True))})"
        description = diffuse_scene(S.Film(width, height))
        figures = {}
        for sampler in S.SAMPLERS:
            scene = builder.load_scene(description, S.RenderSettings(sampler=sampler))
            render_image(scene, args.spp, seed=99)  # compile every kernel once
            started = time.perf_counter()
            first = np.asarray(render_image(scene, args.spp, seed=1), dtype=np.float64)[..., :3]
            seconds = time.perf_counter() - started
            second = np.asarray(render_image(scene, args.spp, seed=2), dtype=np.float64)[..., :3]
            l1, rmse = seed_difference(first, second)
            figures[sampler] = l1, rmse
            print(f"| {width} × {height} | {chunks} | {sampler} | {l1:.4f} | {rmse:.4f} | "
                  f"{second.mean() / first.mean() - 1:+.4f} | {seconds:.2f} |", flush=True)
        (new_l1, new_rmse), (old_l1, old_rmse) = figures["multijitter"], figures["independent"]
        print(f"| {width} × {height} | | multijitter / independent | **{new_l1 / old_l1:.2f}** | "
              f"**{new_rmse / old_rmse:.2f}** | | |", flush=True)
    if args.mitsuba_samplers:
        width, height = (args.size or [(320, 200)])[0]
        rank_mitsuba_samplers(diffuse_scene(S.Film(width, height)), args.spp)


def rank_mitsuba_samplers(description, spp: int) -> None:
    """One ``mi.render`` call of ``spp`` per Mitsuba sampler that takes ``spp`` as it is, seeds 1 and 2."""
    import mitsuba as mi

    from scratch_iridescence.mitsuba_bridge import builder
    from scratch_iridescence.mitsuba_bridge import scene as S

    print(f"\nOne mi.render call of {spp} spp, {description.film.width} × {description.film.height}\n")
    print("| sampler | L1 | RMSE | s/render |")
    print("|---|---|---|---|")
    for name in ("independent", "stratified", "multijitter", "ldsampler", "orthogonal"):
        probe = mi.load_dict({"type": name})
        level = mi.log_level()
        mi.set_log_level(mi.LogLevel.Error)  # (the rounding's warning: said in the table instead)
        probe.set_sample_count(spp)
        mi.set_log_level(level)
        if probe.sample_count() != spp:
            print(f"| {name} | renders {probe.sample_count()} spp, not {spp} | | |")
            continue
        tree = builder.scene_dict(description, S.RenderSettings(spp=spp), builder.InMemory())
        sensor = next(value for value in tree.values() if isinstance(value, dict) and "sampler" in value)
        sensor["sampler"] = {"type": name, "sample_count": spp}
        scene = builder.load_dict(tree)
        mi.render(scene, spp=spp, seed=99)  # compile
        started = time.perf_counter()
        first = np.asarray(mi.render(scene, spp=spp, seed=1), dtype=np.float64)[..., :3]
        seconds = time.perf_counter() - started
        second = np.asarray(mi.render(scene, spp=spp, seed=2), dtype=np.float64)[..., :3]
        l1, rmse = seed_difference(first, second)
        print(f"| {name} | {l1:.4f} | {rmse:.4f} | {seconds:.2f} |", flush=True)


if __name__ == "__main__":
    main()
