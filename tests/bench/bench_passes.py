"""Benchmark: what Blender's data passes (Depth, Denoising Albedo and Normal) add to a render.

The scratched plate of tests/bridge/builder/test_scratched.py (3 000 scratches, as bench_schedule.py)
and the same floor without scratches, each rendered through the fixed schedule (``render_image``)
without and with the ``blender_passes`` integrator (``RenderSettings.data_passes``), alternately, best of
``--repeat`` in one process (the machine may be shared: the ratio is the figure).

Run: ``.venv/bin/python tests/bench/bench_passes.py [--repeat 3] [--size 256] [--spp 32]``
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "bridge"))
sys.path.insert(0, str(ROOT / "tests" / "bridge" / "builder"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, default=32)
    args = parser.parse_args()

    import dataclasses

    from scratch_iridescence.mitsuba_bridge import builder, scratch
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge.render import passes
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    variant = activate("auto")
    from test_scratched import metal, plate_scene

    scratches = scratch.random_scratches(3000, seed=5, width=scratch.Gaussian(4e-6, 1.3e-6), length=(0.2, 0.6),
                                         depth=scratch.Gaussian(250e-9, 80e-9), depth_variation=(1.1, 0.04))
    print(f"{variant}, {args.size}² x {args.spp} spp, best of {args.repeat}")
    for label, material in (("scratched plate", metal(scratches)), ("plain floor", S.Diffuse((0.5, 0.5, 0.5)))):
        description = plate_scene(material)
        description = dataclasses.replace(description, film=S.Film(args.size, args.size))
        scenes = {passes_on: builder.load_scene(description, S.RenderSettings(data_passes=passes_on))
                  for passes_on in (False, True)}
        best = {False: float("inf"), True: float("inf")}
        for _ in range(args.repeat + 1):  # the first round compiles the kernels
            for passes_on, scene in scenes.items():
                start = time.perf_counter()
                passes.render_image(scene, args.spp)
                best[passes_on] = min(best[passes_on], time.perf_counter() - start)
        print(f"{label:16} Combined only {best[False]:.3f} s, with the data passes {best[True]:.3f} s "
              f"(ratio {best[True] / best[False]:.3f})")


if __name__ == "__main__":
    main()
