"""Benchmark: where a footprint-filtered render's seed-to-seed noise comes from (docs/model.md §11.2).

The demo's plate of ``bench_convergence`` (3 000 scratches under a sun and sky), the filter sized for
``--spp`` samples per pixel, rendered by a loop of its own around the scene's integrator
(``integrator.sample`` on camera rays this script places; one call of pixels × spp lanes per image) so
that one source of randomness at a time can be held still:

* ``uniform``: every sample at a uniform position in its pixel with its own wavelengths, as a render's
  box filter and independent sampler place them (the spread a render shows);
* ``centre``: every sample at its pixel's centre: the footprint-filtered BSDF sees the same patch in all
  of them, what is left is the wavelengths', the lights' and the BSDF sampling's noise;
* ``centre-fixed-wavelengths``: at the centre and with the same wavelengths in every sample (a fixed
  wavelength sample): the lights' and the BSDF sampling's noise alone.

Each mode renders ``--seeds`` images; the spread is √(mean per-pixel variance between them) over the
plate's pixels, relative to the plate's mean in the ``uniform`` images. Differences of variances then
give the parts: positions = uniform² − centre², wavelengths = centre² − fixed², the rest = fixed².
Holding the wavelengths changes the image (its colour and mean: a fixed set of four wavelengths), not
what the lights' sampling does, so the split is an estimate. ``--lights sun`` or ``sky`` renders with one
of the two (the other's scale 0) to say which carries the rest.

Run: ``.venv/bin/python tests/bench/bench_error_parts.py [--size 240 150] [--spp 16] [--seeds 3]
[--lights both|sun|sky]`` (prints a markdown table; docs/benchmarks.md has the figures).
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

MODES = ("uniform", "centre", "centre-fixed-wavelengths")


def render(scene, mode: str, spp: int, seed: int) -> np.ndarray:
    """``(height, width, 3)`` linear sRGB: the mean of ``spp`` samples per pixel placed as ``mode`` says."""
    import mitsuba as mi

    sensor, integrator = scene.sensors()[0], scene.integrator()
    width, height = sensor.film().crop_size()
    lanes = width * height * spp
    pixel = np.repeat(np.arange(width * height), spp)
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed, lanes)
    offset = sampler.next_2d()
    if mode == "uniform":
        dx, dy = np.asarray(offset.x), np.asarray(offset.y)
    else:
        dx = dy = np.full(lanes, 0.5, dtype=np.float32)
    position = mi.Point2f(mi.Float(((pixel % width + dx) / width).astype(np.float32)),
                          mi.Float(((pixel // width + dy) / height).astype(np.float32)))
    wavelength_sample = mi.Float(0.37) if mode == "centre-fixed-wavelengths" else sampler.next_1d()
    ray, weight = sensor.sample_ray_differential(0.0, wavelength_sample, position, mi.Point2f(0.5, 0.5))
    spectrum, _, _ = integrator.sample(scene, sampler, ray, None, True)
    colour = mi.spectrum_to_srgb(weight * spectrum, ray.wavelengths)
    values = np.stack([np.asarray(colour[channel]) for channel in range(3)], axis=1)
    return values.reshape(width * height, spp, 3).mean(axis=1).reshape(height, width, 3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, nargs=2, default=(240, 150), metavar=("WIDTH", "HEIGHT"))
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--lights", choices=("both", "sun", "sky"), default="both")
    args = parser.parse_args()

    from bench_convergence import plate_mask
    from bench_schedule import scratched_plate
    from scratch_iridescence.mitsuba_bridge import builder
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge.render.activation import activate
    from scratch_iridescence.mitsuba_bridge.render.filtering import set_footprint

    variant = activate("auto")
    width, height = args.size
    description = dataclasses.replace(scratched_plate(width), film=S.Film(width, height))
    if args.lights != "both":
        off = "sky_scale" if args.lights == "sun" else "sun_scale"
        description = dataclasses.replace(description, world=dataclasses.replace(description.world, **{off: 0.0}))
    scene = builder.load_scene(description, S.RenderSettings(footprint_filter=True))
    set_footprint(scene, args.spp)
    mask = plate_mask(scene)

    spreads, scale = {}, None
    for mode in MODES:
        began = time.perf_counter()
        stack = np.stack([render(scene, mode, args.spp, seed)[mask] for seed in range(1, args.seeds + 1)])
        scale = float(stack.mean()) if scale is None else scale  # the uniform images' plate mean
        spreads[mode] = float(np.mean(np.var(stack, axis=0, ddof=1)))
        print(f"{mode}: {time.perf_counter() - began:.0f} s", file=sys.stderr)

    def relative(variance):
        return np.copysign(np.sqrt(abs(variance)), variance) / scale

    print(f"variant {variant}; film {width} × {height}, {int(mask.sum())} plate pixels; footprint filter sized for "
          f"{args.spp} spp; {args.spp} spp per image, {args.seeds} seeds; lights: {args.lights}")
    print()
    print("| samples placed | seed-to-seed spread | part | its share of the variance |")
    print("|---|---|---|---|")
    total = spreads["uniform"]
    parts = {"uniform": ("positions in the pixel", spreads["uniform"] - spreads["centre"]),
             "centre": ("wavelengths", spreads["centre"] - spreads["centre-fixed-wavelengths"]),
             "centre-fixed-wavelengths": ("lights and BSDF sampling", spreads["centre-fixed-wavelengths"])}
    for mode in MODES:
        name, variance = parts[mode]
        print(f"| {mode} | {relative(spreads[mode]):.3f} | {name}: {relative(variance):.3f} | "
              f"{variance / total:.0%} |")


if __name__ == "__main__":
    main()
