"""Benchmark: a deliberately overcrowded plate against the bound every height field obeys (docs/bsdf.md, Stress).

A true height field has |T| = 1, so |U(ξ)| <= ∫ w = 2πσ² and f_r <= F · 4πσ²/λ² (docs/model.md §3.4).
The height-field correction is a truncated inclusion–exclusion, so a pile of overlaps beyond its orders
can exceed that bound; ``crossings = "height_field"`` then scales the field back to it
(``Model._within_height_field_bound``).  This script measures how often and how far the terms alone exceed
it on a stress set: 3 000 random scratches with W, D ∈ U[0, 6] µm on 4 × 4 mm (Σ W·L ≈ 88 % of the
area, 58 % of it under some scratch), a sheared UV map, shading points spread over the plate, random ω_i, ω_o (cosine-distributed)
and wavelengths in 360–830 nm, a perfect mirror (F = 1).  For each batch of lanes it evaluates the height
field without the clamp (the terms alone), with it (the plugin), and the additive model, and prints the
lanes above the bound, the worst ratio f_r / bound and what the additive model gives there, and whether any
value is not finite.

    .venv/bin/python tests/bench/bench_height_field_bound.py [--batches 6] [--lanes 32768] [--seed 1]
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

#: The plate: 4 mm square (UV 0.3-0.7 at 1 UV = 1 cm), sheared UV map (dp/dv leans by this much in x).
UNIT_SCALE_M = 0.01
REGION = ((0.3, 0.3), (0.7, 0.7))
SHEAR = 0.5
SIGMA_UM = 5.0


def stress_set(seed: int):
    from scratch_iridescence.mitsuba_bridge import scratch

    return scratch.random_scratches(3000, seed=seed, width=scratch.Uniform(0.0, 6e-6),
                                    depth=scratch.Uniform(0.0, 6e-6), length=(0.1, 0.2), region=REGION)


def coverage(scratches, rng, points: int = 20000) -> tuple[float, float]:
    """``(summed, union)``: Σ W·L over the region's area, and the share of random points (in the sheared
    plate's metric) within half a width of some scratch's centre line."""
    (u0, v0), (u1, v1) = REGION
    jac = np.array([[1.0, SHEAR], [0.0, 1.0]]) * UNIT_SCALE_M  # metres per UV
    area = abs(np.linalg.det(jac)) * (u1 - u0) * (v1 - v0)
    starts, ends, widths = [], [], []
    for k in range(scratches.count):
        line = scratches.polyline(k)
        starts.append(line[:-1])
        ends.append(line[1:])
        widths.append(np.full(len(line) - 1, scratches.width[k]))
    a = np.concatenate(starts) @ jac.T
    e = np.concatenate(ends) @ jac.T - a
    w = np.concatenate(widths)
    summed = float(np.sum(np.linalg.norm(e, axis=1) * w) / area)
    uv = np.column_stack([rng.uniform(u0, u1, points), rng.uniform(v0, v1, points)]) @ jac.T
    hit = np.zeros(points, bool)
    for i in range(0, points, 500):
        p = uv[i:i + 500, None, :] - a[None]
        t = np.clip(np.sum(p * e, axis=2) / np.maximum(np.sum(e * e, axis=1), 1e-30), 0.0, 1.0)
        distance = np.linalg.norm(p - t[..., None] * e, axis=2)
        hit[i:i + 500] = np.any(distance < 0.5 * w, axis=1)
    return summed, float(hit.mean())


def lanes(count: int, rng):
    import drjit as dr
    import mitsuba as mi

    (u0, v0), (u1, v1) = REGION
    si = dr.zeros(mi.SurfaceInteraction3f, count)
    si.uv = mi.Point2f(mi.Float(rng.uniform(u0, u1, count)), mi.Float(rng.uniform(v0, v1, count)))
    si.dp_du, si.dp_dv = mi.Vector3f(1, 0, 0), mi.Vector3f(SHEAR, 1, 0)
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.wi = mi.warp.square_to_cosine_hemisphere(mi.Point2f(mi.Float(rng.random(count)), mi.Float(rng.random(count))))
    wavelengths = rng.uniform(360.0, 830.0, (count, 4))
    si.wavelengths = mi.Spectrum(*(mi.Float(wavelengths[:, i]) for i in range(4)))
    wo = mi.warp.square_to_cosine_hemisphere(mi.Point2f(mi.Float(rng.random(count)), mi.Float(rng.random(count))))
    dr.eval(si, wo)
    return si, wo, wavelengths


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=6)
    parser.add_argument("--lanes", type=int, default=32768)
    parser.add_argument("--seed", type=int, default=1, help="of the scratch set; the lanes use seed + 1")
    parser.add_argument("--pairs-only", action="store_true",
                        help="the height field's pair terms alone (Model.triples and parallel_overlaps off: the "
                             "correction before its overlaps of three and more and its nearly parallel pairs)")
    args = parser.parse_args()

    import mitsuba as mi

    mi.set_variant("llvm_ad_spectral")
    from scratch_iridescence import mitsuba_bridge
    from scratch_iridescence.mitsuba_bridge.bsdf import plugin_dict
    from scratch_iridescence.mitsuba_bridge.validation.probe import spectrum_rows

    mitsuba_bridge.register_plugins()
    rng = np.random.default_rng(args.seed + 1)
    scratches = stress_set(args.seed)
    summed, union = coverage(scratches, rng)
    print(f"stress set: {scratches.count} scratches, W, D ∈ U[0, 6] µm, on 4 x 4 mm (sheared UV, dp/dv = "
          f"({SHEAR}, 1)): Σ W·L = {summed:.0%} of the area, {union:.0%} of it scratched; σ = {SIGMA_UM} µm")

    def load(crossings, clamp=True):
        start = time.perf_counter()
        bsdf = mi.load_dict(plugin_dict(scratches, coherence_diameter=6 * SIGMA_UM * 1e-6, unit_scale=UNIT_SCALE_M,
                                        material="none", crossings=crossings))
        if not clamp:
            bsdf.model = dataclasses.replace(bsdf.model, clamp_to_height_field_bound=False)
        if args.pairs_only and crossings == "height_field":
            bsdf.model = dataclasses.replace(bsdf.model, triples=False, parallel_overlaps=False)
        return bsdf, time.perf_counter() - start

    terms, load_s = load("height_field", clamp=False)
    plugin, additive = load("height_field")[0], load("additive")[0]
    print(f"height field tables: {plugin.tables.crossing_count:,} crossing pairs, load {load_s:.1f} s")
    ctx = mi.BSDFContext()
    above = non_finite = 0
    worst = (0.0, 0.0, 0.0)  # (terms, plugin, additive) f_r / bound at the worst lane of the terms alone
    plugin_max = 0.0
    start = time.perf_counter()
    for batch in range(args.batches):
        si, wo, wavelengths = lanes(args.lanes, rng)
        cos_o = np.asarray(wo.z)[:, None]
        bound = 4.0 * math.pi * SIGMA_UM ** 2 / (wavelengths * 1e-3) ** 2
        ratios = [spectrum_rows(b.eval(ctx, si, wo)) / cos_o / bound for b in (terms, plugin, additive)]
        non_finite += int(sum((~np.isfinite(r)).any(axis=1).sum() for r in ratios))
        lane_max = np.nanmax(ratios[0], axis=1)
        above += int((lane_max > 1.0).sum())
        plugin_max = max(plugin_max, float(np.nanmax(ratios[1])))
        k = int(np.nanargmax(lane_max))
        channel = int(np.nanargmax(ratios[0][k]))
        if ratios[0][k, channel] > worst[0]:
            worst = tuple(float(r[k, channel]) for r in ratios)
        print(f"  batch {batch + 1}/{args.batches}: {int((lane_max > 1.0).sum())} lanes above the bound, "
              f"worst {lane_max[k]:.3g}x", flush=True)
    total = args.batches * args.lanes
    print(f"{total:,} lanes ({time.perf_counter() - start:.0f} s): {non_finite} not finite; the terms alone "
          f"above the bound on {above} ({above / total:.2e}), the worst {worst[0]:.3g}x (the additive model "
          f"{worst[2]:.3g}x there); with the clamp (the plugin) at most {plugin_max:.4g}x")


if __name__ == "__main__":
    main()
