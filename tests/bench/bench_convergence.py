"""Benchmark: how fast a scratched plate converges with the footprint filter (docs/model.md §11) and without.

The demo's plate (3 000 scratches of the paper's Fig. 7(b) looks, under a sun and sky,
:func:`bench_schedule.scratched_plate`) on a ``--size`` film, rendered through the renderer's own
path (``render.passes.render_image``: the fixed chunk schedule, the footprint sized for the whole
render's samples per pixel) at each of ``--spp``, with ``footprint_filter`` off (every sample sees
one point: today's renders) and on. Each image is compared over the plate's pixels (camera rays
that hit it) with a point-sampled reference of ``--reference-spp``:

* **relative RMSE** = √(mean (image − reference)²) / mean(reference), RGB, plate pixels;
* **corrected** = √(RMSE² − the reference's own variance) / mean(reference): the error against what the
  reference converges to. The reference is itself noisy: it is rendered as two halves of different seeds,
  whose difference has four times the whole reference's variance; an independent image's mean squared
  error is its own plus the reference's, so subtracting the latter leaves the image's (variance + bias²);
* with ``--seeds K`` (K ≥ 2 renders per row, distinct seeds) the corrected error splits into the
  **seed-to-seed** spread √(mean per-pixel variance between the seeds) and the **bias** (signed root of
  mean (mean of the K images − reference)² − spread²/K − the reference's variance: blur, caps and
  approximations of the filter against the point model's expectation);
* **brightest 1 %'s share**: the share of the squared error in the brightest 1 % of the reference's plate
  pixels (the glints: a few pixels carry much of a glinting image's error);
* **mean** = mean(image) / mean(reference) − 1 over the plate (a biased filter would show here);
* **time per sample** = the render's wall time / (pixels × spp), after a render that compiled
  its kernels (a user's second render), and the filter's time over the point render's;
* **equal-error speed-up**: the point render's corrected error falls as a/√spp (a fitted from its rows); the
  samples it would need for the filtered render's corrected error, times its time per sample, over the
  filtered render's time.

**Far view** (``--far-size 90 56``): the same plate on a film that shows it ~60 px wide instead of 160, as
the plate four times farther away would: a sample's footprint covers 7× the plate's length, holding
many more pieces (the footprint's reach is capped where they are dense, docs/model.md §11.8); its
rows compare with its own reference, and a last table divides its time per sample and error by the
close view's.

Run: ``.venv/bin/python tests/bench/bench_convergence.py [--size 240 150] [--far-size 90 56]
[--spp 16 64 256] [--reference-spp 8192] [--seeds 1]`` (prints markdown tables; docs/benchmarks.md has the
figures).
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


def plate_mask(scene) -> np.ndarray:
    """``(height, width)`` bool: the pixels whose centre ray hits a shape (the plate; the rest is sky)."""
    import drjit as dr
    import mitsuba as mi

    sensor = scene.sensors()[0]
    width, height = sensor.film().crop_size()
    y, x = np.mgrid[0:height, 0:width]
    position = mi.Point2f(mi.Float(((x + 0.5) / width).ravel().astype(np.float32)),
                          mi.Float(((y + 0.5) / height).ravel().astype(np.float32)))
    ray, _ = sensor.sample_ray(0.0, 0.5, position, mi.Point2f(0.5, 0.5))
    hit = scene.ray_intersect(ray)
    return np.asarray(dr.detach(hit.is_valid())).reshape(height, width)


def relative_rmse(image, reference, mask) -> float:
    difference = (image - reference)[mask]
    return float(np.sqrt(np.mean(difference ** 2)) / np.mean(reference[mask]))


def error_parts(images, reference, reference_variance, mask) -> dict:
    """The error of ``images`` (renders of one setting, distinct seeds) against a noisy ``reference``, split
    into its parts, each relative to the reference's plate mean (module docstring):

    * ``error``: √(mean over seeds and plate pixels of (image − reference)²), what one render shows;
    * ``corrected``: √(error² − the reference's own variance): the error against the reference's expectation
      (an independent image's mean squared error is its own plus the reference's);
    * ``spread``: √(mean per-pixel variance between seeds) (``nan`` with one seed);
    * ``bias``: the signed root of mean (mean image − reference)² − spread²/seeds − the reference's variance,
      what is left between the images' expectation and the reference's (``nan`` with one seed);
    * ``bright_share``: the share of the squared error in the brightest 1 % of the reference's plate pixels.

    ``reference_variance``: the reference's mean per-pixel variance (absolute, the halves' mean squared
    difference / 4).
    """
    stack = np.stack([image[mask] for image in images])  # (seeds, pixels, channels)
    target = reference[mask]
    scale = float(np.mean(target))
    squared = float(np.mean((stack - target) ** 2))
    parts = dict(error=np.sqrt(squared) / scale,
                 corrected=np.sqrt(max(squared - reference_variance, 0.0)) / scale,
                 spread=float("nan"), bias=float("nan"))
    if len(stack) > 1:
        variance = float(np.mean(np.var(stack, axis=0, ddof=1)))
        bias_squared = float(np.mean((stack.mean(axis=0) - target) ** 2)) - variance / len(stack) - reference_variance
        parts.update(spread=np.sqrt(variance) / scale,
                     bias=np.copysign(np.sqrt(abs(bias_squared)), bias_squared) / scale)
    per_pixel = np.mean((stack - target) ** 2, axis=(0, 2))
    brightness = target.mean(axis=1)
    brightest = brightness >= np.quantile(brightness, 0.99)
    parts["bright_share"] = float(per_pixel[brightest].sum() / per_pixel.sum())
    return parts


def measure(description, size, spp_list, reference_spp, sampler="independent", seeds=1):
    """``(rows, header)``: every spp of ``spp_list`` with the filter off and on, ``seeds`` renders each, against a
    point-sampled reference of ``reference_spp``, the plate on a ``size`` film (module docstring)."""
    from scratch_iridescence.mitsuba_bridge import builder
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge.render.passes import render_image

    width, height = size
    description = dataclasses.replace(description, film=S.Film(width, height))

    def rgb(image):
        return np.asarray(image, dtype=np.float64)[..., :3]

    scenes = {filtered: builder.load_scene(description, S.RenderSettings(footprint_filter=filtered, sampler=sampler))
              for filtered in (False, True)}
    mask = plate_mask(scenes[False])
    for scene in scenes.values():  # compile every kernel once
        render_image(scene, 4, seed=99)

    started = time.perf_counter()
    half = max(reference_spp // 2, 1)
    halves = [rgb(render_image(scenes[False], half, seed=10_000 + k)) for k in range(2)]
    reference_seconds = time.perf_counter() - started
    reference = 0.5 * (halves[0] + halves[1])
    # the halves' difference has twice a half's variance, four times the whole reference's
    reference_variance = float(np.mean((halves[0] - halves[1])[mask] ** 2)) / 4.0
    floor = np.sqrt(reference_variance) / float(np.mean(reference[mask]))

    rows = []
    for spp in spp_list:
        for filtered in (False, True):
            began = time.perf_counter()
            # seed spp first: with one seed the images are those of the bench before --seeds existed
            images = [rgb(render_image(scenes[filtered], spp, seed=spp + 1000 * k)) for k in range(seeds)]
            seconds = (time.perf_counter() - began) / seeds
            rows.append(dict(spp=spp, filtered=filtered, **error_parts(images, reference, reference_variance, mask),
                             mean=float(np.mean([image[mask].mean() for image in images])
                                        / reference[mask].mean() - 1.0),
                             per_sample=seconds / (width * height * spp)))
    columns = np.nonzero(mask.any(axis=0))[0]
    plate_width = int(columns.max() - columns.min() + 1) if columns.size else 0
    header = (f"film {width} × {height} (the plate {plate_width} px wide, {int(mask.sum())} plate pixels); reference "
              f"{2 * half} spp point-sampled ({reference_seconds:.0f} s), its own relative RMSE ≈ {floor:.3f}; "
              f"{seeds} seed{'s' if seeds > 1 else ''} per row")
    return rows, header


def print_table(view, rows, header):
    point_rows = [r for r in rows if not r["filtered"]]
    a = float(np.mean([r["corrected"] * np.sqrt(r["spp"]) for r in point_rows]))  # corrected error ≈ a/√spp
    point_per_sample = {r["spp"]: r["per_sample"] for r in point_rows}
    print(f"**{view} view**: {header}; point error ≈ {a:.2f}/√spp")
    print()
    print("| spp | filter | relative RMSE | corrected | seed to seed | bias | brightest 1 %'s share | "
          "mean vs reference | time / sample (µs) | × point's | point spp for this error | equal-error speed-up |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        ratio = r["per_sample"] / point_per_sample[r["spp"]]
        equal = (a / max(r["corrected"], 1e-9)) ** 2  # a row within the reference's own noise: a huge figure
        speed_up = equal * point_per_sample[r["spp"]] / (r["spp"] * r["per_sample"])
        spread = "–" if np.isnan(r["spread"]) else f"{r['spread']:.3f}"
        bias = "–" if np.isnan(r["bias"]) else f"{r['bias']:+.3f}"
        print(f"| {r['spp']} | {'on' if r['filtered'] else 'off'} | {r['error']:.3f} | {r['corrected']:.3f} | "
              f"{spread} | {bias} | {r['bright_share']:.2f} | {100 * r['mean']:+.1f} % | {1e6 * r['per_sample']:.2f} | "
              f"{ratio:.2f} | {equal:.0f} | {speed_up:.1f}× |")
    print()


def main() -> None:
    from scratch_iridescence.mitsuba_bridge import scene as S

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, nargs=2, default=(240, 150), metavar=("WIDTH", "HEIGHT"))
    parser.add_argument("--far-size", type=int, nargs=2, default=None, metavar=("WIDTH", "HEIGHT"),
                        help="also the far view: the same plate on this film (90 56: the plate ~60 px wide)")
    parser.add_argument("--spp", type=int, nargs="+", default=[16, 64, 256])
    parser.add_argument("--reference-spp", type=int, default=8192)
    parser.add_argument("--sampler", choices=S.SAMPLERS, default=S.RenderSettings().sampler,
                        help="Mitsuba's sampler of every render, the reference's included (default: the renderer's)")
    parser.add_argument("--seeds", type=int, default=1,
                        help="renders per row, distinct seeds: 2 or more split the error into spread and bias")
    args = parser.parse_args()

    from bench_schedule import scratched_plate
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    variant = activate("auto")
    description = scratched_plate(args.size[0])
    views = [("close", tuple(args.size))] + ([("far", tuple(args.far_size))] if args.far_size else [])
    results = {view: measure(description, size, args.spp, args.reference_spp, args.sampler, args.seeds)
               for view, size in views}
    print(f"variant {variant}")
    print()
    for view, (rows, header) in results.items():
        print_table(view, rows, header)
    if "far" in results:
        print("| spp | filter | far view's time / sample ÷ close view's | far view's relative RMSE ÷ close view's |")
        print("|---|---|---|---|")
        for near, far in zip(results["close"][0], results["far"][0]):
            print(f"| {near['spp']} | {'on' if near['filtered'] else 'off'} | "
                  f"{far['per_sample'] / near['per_sample']:.2f} | {far['corrected'] / near['corrected']:.2f} |")


if __name__ == "__main__":
    main()
