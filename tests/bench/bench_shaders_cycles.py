"""Measure: shader scenes of tests/addon/shader_scenes.py rendered by this engine and by Cycles, seeds 0 and 1.

Prints, per scene, the sphere's mean-luminance ratio to Cycles (seed 0) and the blurred relative L1 distance
(4 × 4-pixel block means) between the engines, beside each engine's own distance between its two seeds
(the noise floor that ``test_shader_within_the_noise_floor`` holds the distance to). docs/rendering.md's
table of measured ratios comes from here.

Run: ``.venv/bin/python tests/bench/bench_shaders_cycles.py [SCENE ...]`` (default: every scene).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "addon"))


def main(argv=None) -> int:
    import bpy  # noqa: F401  (first: it makes Blender's own modules importable)
    import addon_utils
    import scratch_iridescence
    from shader_scenes import SHADERS, render
    from test_shaders_cycles import SAMPLES, blurred_l1

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=list(SHADERS), help="scene names (shader_scenes.SHADERS)")
    args = parser.parse_args(argv)
    scratch_iridescence.register()
    addon_utils.enable("cycles", default_set=True)
    folder = Path(tempfile.mkdtemp())
    print(f"{'scene':22} {'ratio':>7} {'L1':>7} {'floor ours':>10} {'floor Cycles':>12}")
    for scene in args.scenes:
        results = {(engine, seed): render(engine, scene, folder / f"{engine}{seed}.exr", samples=SAMPLES, seed=seed)
                   for engine in ("MITSUBA_SCRATCH", "CYCLES") for seed in (0, 1)}
        ours, theirs = results["MITSUBA_SCRATCH", 0], results["CYCLES", 0]
        print(f"{scene:22} {ours[0] / theirs[0]:7.3f} {blurred_l1(ours[2], theirs[2]):7.4f} "
              f"{blurred_l1(results['MITSUBA_SCRATCH', 1][2], ours[2]):10.4f} "
              f"{blurred_l1(results['CYCLES', 1][2], theirs[2]):12.4f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
