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

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, default=32)
    args = parser.parse_args()

    from bench_schedule import scratched_plate
    from scratch_iridescence.mitsuba_bridge import builder
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge.render import passes
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    variant = activate("auto")
    print(f"{variant}, {args.size}² x {args.spp} spp, best of {args.repeat}")
    for label, material in (("scratched plate", None), ("plain floor", S.Diffuse((0.5, 0.5, 0.5)))):
        description = scratched_plate(args.size, material)
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
