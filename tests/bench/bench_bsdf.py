"""Benchmark: evaluations per second of ``scratch_diffraction`` against Mitsuba's own BSDFs.

Target (issue 3): within 3x of ``conductor`` at 1 segment in the window, and
cost linear in the number of segments.  ``conductor`` is a delta BSDF, so its
``eval`` returns zero without doing any work; its ``sample`` (conductor Fresnel
at four wavelengths) and ``roughconductor`` (GGX + Fresnel, a glossy BSDF like
this one) are the meaningful references.  All calls run on 2^20 lanes in the
same process and variant (llvm_ad_spectral); each figure is the best of
``--repeat`` runs after a warm-up that compiles the kernels.

Dense sets (issue 12): ``--dense`` adds the time per query on the paper's CD
(3.1 million chords on tracks of pitch 1.6 µm, built as in
``bench_bsdf_memory.py``) and on the Fig. 9 grating (1 600 grooves of 7 cm at a
2.5 µm pitch), coherent and incoherent, at shading points spread over the tracks/bands in every
orientation, as wall time per lane (all cores) and as a ratio to
``roughconductor.eval`` measured in the same run (the machine is shared), the time of the search
alone (the fold over the pieces in the window with a body that only counts them), the share of
lanes whose window lies in a periodic family (summed in closed form, no search: docs/model.md §3.5)
and ``eval`` with the families switched off (``Model.periodic = False``: every lane scans).

Crossings (issue 12 item 1): ``--crossings`` times ``eval`` with ``crossings =
"additive"`` and ``"height_field"`` on the Fig. 7(b) plate (3 000 scratches,
G_W[4, 1.3] µm on a 10 cm plate) and on a worn plate (30 000 scratches,
U_W[0.5, 6] µm), at shading points on the scratches (every lane has pieces in
its window), alternately, as the ratio of the two; with the table build time
and the number of crossing pairs.  ``height_field`` is timed twice: with its
overlap terms of order 3 and more (triples.py, the plugin's behaviour) and
with the pair terms alone (``Model.triples = False``, the version before them), and a third
time without the nearly parallel overlaps (``Model.parallel_overlaps = False``, parallel.py).
The worn plate only with ``--worn``: its crossing pairs (~100x the plate's) need more
than the 23 GB of the development machine.

Run: ``.venv/bin/python tests/bench/bench_bsdf.py [--dense] [--crossings]``.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lanes", type=int, default=1 << 20)
    parser.add_argument("--variant", default="llvm_ad_spectral", help="cuda_ad_spectral: on an NVIDIA GPU")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--segments", type=int, nargs="*", default=[0, 1, 4, 16])
    parser.add_argument("--dense", action="store_true", help="also time queries on the CD and the grating")
    parser.add_argument("--dense-lanes", type=int, default=1 << 17)
    parser.add_argument("--crossings", action="store_true", help="time crossings = height_field against additive")
    parser.add_argument("--worn", action="store_true", help="with --crossings: the worn plate too (> 23 GB)")
    parser.add_argument("--depth-phases", nargs="*", default=["kirchhoff"],
                        help="time the segment rows under these depth phases (e.g. kirchhoff bounded)")
    args = parser.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    from scratch_iridescence import mitsuba_bridge
    from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf
    from scratch_iridescence.mitsuba_bridge.scratch import ScratchSet

    mitsuba_bridge.register_plugins()
    n = args.lanes
    rng = np.random.default_rng(1)
    sigma_um = 5.0  # default coherence diameter 30 µm
    unit_scale = 0.1  # 1 UV unit = 10 cm (a plate)

    def interaction():
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        # shading points spread along u only: every lane sees the same segments
        si.uv = mi.Point2f(mi.Float(0.5 + rng.uniform(-0.04, 0.04, n)), 0.5)
        si.dp_du, si.dp_dv = mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0)
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        si.wi = mi.warp.square_to_cosine_hemisphere(mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n))))
        si.wavelengths = mi.Spectrum(*(mi.Float(rng.uniform(360, 830, n)) for _ in range(4)))
        return si

    si = interaction()
    wo = mi.warp.square_to_cosine_hemisphere(mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n))))
    s1 = mi.Float(rng.random(n))
    s2 = mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n)))
    ctx = mi.BSDFContext()
    dr.eval(si, wo, s1, s2)

    def timed(call):
        best = float("inf")
        for i in range(args.repeat + 1):
            start = time.perf_counter()
            dr.eval(call())
            dr.sync_thread()
            if i:  # the first run compiles
                best = min(best, time.perf_counter() - start)
        return n / best

    def measure(bsdf):
        return (timed(lambda: bsdf.eval(ctx, si, wo)),
                timed(lambda: bsdf.sample(ctx, si, s1, s2)[1]),
                timed(lambda: bsdf.eval_pdf(ctx, si, wo)))

    def parallel_set(count):
        """``count`` long scratches along u, all within 3σ of the line v = 0.5."""
        if count == 0:
            return ScratchSet.empty()
        offsets_um = np.linspace(-3 * sigma_um, 3 * sigma_um, count) if count > 1 else np.array([0.7])
        v = 0.5 + offsets_um * 1e-6 / unit_scale
        lines = [np.array([[0.45, y], [0.55, y]]) for y in v]
        return ScratchSet.from_polylines(lines, width=2e-6, depth=250e-9)

    print(f"lanes per call: {n}; machine: {os.cpu_count()} cores; best of {args.repeat}; evaluations/s")
    print(f"{'BSDF':34s} {'eval':>12s} {'sample':>12s} {'eval_pdf':>12s}")
    references = {}
    for name, d in (("conductor (Al, delta)", {"type": "conductor", "material": "Al"}),
                    ("roughconductor (Al, GGX 0.1)", {"type": "roughconductor", "material": "Al",
                                                       "alpha": 0.1})):
        references[name] = measure(mi.load_dict(d))
        print(f"{name:34s} " + " ".join(f"{v:12.3e}" for v in references[name]))
    results = {}
    for phase in args.depth_phases:
        for count in args.segments:
            bsdf = mi.load_dict(scratch_bsdf.plugin_dict(parallel_set(count), unit_scale=unit_scale,
                                                         depth_phase=phase))
            timings = measure(bsdf)
            if phase == args.depth_phases[0]:
                results[count] = timings
            label = f"scratch, {count} segments" + ("" if phase == "kirchhoff" else f", {phase}")
            print(f"{label:34s} " + " ".join(f"{v:12.3e}" for v in timings), flush=True)

    if args.dense:
        dense_sets(args, rng)
    if args.crossings:
        crossing_sets(args, rng)

    conductor = references["conductor (Al, delta)"]
    rough = references["roughconductor (Al, GGX 0.1)"]
    if 1 in results:
        one = results[1]
        print("\nat 1 segment (slowdown factors; target: within 3x of conductor):")
        print(f"  scratch.eval   vs conductor.sample     {conductor[1] / one[0]:5.2f}x  "
              "(conductor.eval is a no-op for a delta BSDF: the Fresnel work is in its sample)")
        print(f"  scratch.sample vs conductor.sample     {conductor[1] / one[1]:5.2f}x")
        print(f"  scratch.eval   vs roughconductor.eval  {rough[0] / one[0]:5.2f}x")
        print(f"  scratch.sample vs roughconductor.sample {rough[1] / one[1]:4.2f}x")
    counts = sorted(c for c in args.segments if c > 0)
    # each count against the next lower one measured (0 segments where it was): what one more segment
    # in the window adds
    pairs = [(b, c) for b, c in zip([0 if 0 in results else None, *counts[:-1]], counts) if b is not None]
    if pairs:
        per = [(1 / results[c][0] - 1 / results[b][0]) / (c - b) * 1e9 for b, c in pairs]
        print("eval time per segment [ns per lane]: "
              + ", ".join(f"{b}→{c}: {p:.1f}" for (b, c), p in zip(pairs, per)) + " (linear: roughly constant)")


def dense_sets(args, rng):
    """Time per ``eval`` query on the CD and the grating; ratio to roughconductor.eval of this run."""
    import drjit as dr
    import mitsuba as mi

    from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf
    from scratch_iridescence.mitsuba_bridge.bsdf.lookup import for_each_segment, jacobian
    from scratch_iridescence.mitsuba_bridge.bsdf.model import WINDOW_RADIUS_SIGMAS
    from scratch_iridescence.mitsuba_bridge.scratch import ScratchSet

    sys.path.insert(0, str(Path(__file__).parent))
    from bench_bsdf_memory import DISC_M, cd_scratches

    n = args.dense_lanes

    def interaction(u, v):
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        si.uv = mi.Point2f(mi.Float(u), mi.Float(v))
        si.dp_du, si.dp_dv = mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0)
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        si.wi = mi.warp.square_to_cosine_hemisphere(mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n))))
        si.wavelengths = mi.Spectrum(*(mi.Float(rng.uniform(360, 830, n)) for _ in range(4)))
        return si

    rough = mi.load_dict({"type": "roughconductor", "material": "Al", "alpha": 0.1})

    def time_eval(bsdf, si):
        """Best time per lane of ``bsdf.eval``, of ``roughconductor.eval`` and of the search alone
        (the fold over the pieces in the window with a body that only counts them), measured alternately."""
        wo = mi.warp.square_to_cosine_hemisphere(mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n))))
        dr.eval(si, wo)
        ctx = mi.BSDFContext()
        model = bsdf.model
        radius = WINDOW_RADIUS_SIGMAS * model.sigma

        def search():
            return for_each_segment(model.grid, jacobian(si, model.micrometres_per_unit), radius,
                                    (dr.zeros(mi.UInt32, n),), lambda segment, piece, state: (state[0] + 1,),
                                    mi.Bool(True))[0]

        def scanned():
            model.periodic = False
            try:
                return bsdf.eval(ctx, si, wo)
            finally:
                model.periodic = True

        calls = (lambda: bsdf.eval(ctx, si, wo), lambda: rough.eval(ctx, si, wo), search, scanned)
        best = [float("inf")] * len(calls)
        for i in range(args.repeat + 1):
            for k, call in enumerate(calls):
                start = time.perf_counter()
                dr.eval(call())
                dr.sync_thread()
                if i:
                    best[k] = min(best[k], time.perf_counter() - start)
        pieces = float(np.mean(np.asarray(search())))
        family = model._family(jacobian(si, model.micrometres_per_unit), True)
        closed = 0.0 if family is None else float(np.mean(np.asarray(family.eligible)))
        return best[0] / n, best[1] / n, best[2] / n, pieces, closed, best[3] / n

    times = {}

    def both_modes(name, scratches, unit_scale, si):
        """The set's times coherent and incoherent (one BSDF at a time: the CD's take 1 GB each)."""
        for coherent in (True, False):
            start = time.perf_counter()
            bsdf = mi.load_dict(scratch_bsdf.plugin_dict(scratches, unit_scale=unit_scale, coherent=coherent))
            print(f"\n{name}: {bsdf} (load {time.perf_counter() - start:.1f} s)")
            times[f"{name} {'coherent' if coherent else 'incoherent'}"] = time_eval(bsdf, si)
            del bsdf

    # the CD: points on the program area, every track orientation
    radius = rng.uniform(23e-3, 57e-3, n) / DISC_M
    angle = rng.uniform(0, 2 * np.pi, n)
    both_modes("CD", cd_scratches(), DISC_M, interaction(0.5 + radius * np.cos(angle), 0.5 + radius * np.sin(angle)))

    # the Fig. 9 grating: four bands of 400 grooves, pitch 2.5 µm, 7 cm long, on a 10 cm plate (UV = plate)
    plate_m, pitch_m = 0.10, 2.5e-6
    bands = np.array([0.0, 0.005, 0.010, 0.015])
    y = (bands[:, None] + pitch_m * np.arange(400)[None, :]).ravel() / plate_m + 0.4
    grooves = [np.array([[0.15, yy], [0.85, yy]]) for yy in y]
    band = rng.integers(0, 4, n)
    v = 0.4 + (bands[band] + rng.uniform(0, 400 * pitch_m, n)) / plate_m
    both_modes("grating", ScratchSet.from_polylines(grooves, width=1e-6, depth=1e-6), plate_m,
               interaction(rng.uniform(0.2, 0.8, n), v))

    print(f"time per eval query (wall per lane, {os.cpu_count()} cores, {n} lanes, best of {args.repeat}; "
          "roughconductor.eval on the same lanes, measured alternately):")
    for name, (query, reference, search, pieces, closed, scanned) in times.items():
        print(f"  {name:19s} {query * 1e9:8.0f} ns  = {query / reference:6.1f} x roughconductor.eval "
              f"({reference * 1e9:.1f} ns); {closed:.1%} of the lanes in a periodic family; every lane "
              f"scanning {scanned * 1e9:.0f} ns, the search alone {search * 1e9:.0f} ns for {pieces:.1f} pieces")


def plate_scratches(profile=None):
    """The Fig. 7(b) plate's 3 000 scratches (G_W[4, 1.3] µm on 0.4² UV of a 10 cm plate)."""
    from scratch_iridescence.mitsuba_bridge import scratch

    return scratch.random_scratches(
        3000, seed=7, width=scratch.Gaussian(4e-6, 1.3e-6), depth=scratch.Gaussian(250e-9, 80e-9),
        depth_variation=(1.1, 0.04), region=((0.2, 0.2), (0.6, 0.6)),
        profile=scratch.Profile.RECTANGULAR if profile is None else profile)


def points_on_pieces(tables, n, rng):
    """``(si, wo)``: ``n`` shading points at random places on random pieces of ``tables`` (a flat unit
    Jacobian), random ω_i, ω_o (cosine-distributed) and wavelengths in 360-830 nm."""
    import drjit as dr
    import mitsuba as mi

    pieces = tables.segments[rng.integers(0, tables.piece_count, n)].astype(np.float64)
    point = pieces[:, 0:2] + pieces[:, 2:4] + rng.random(n)[:, None] * pieces[:, 4:6]
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.uv = mi.Point2f(mi.Float(point[:, 0]), mi.Float(point[:, 1]))
    si.dp_du, si.dp_dv = mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0)
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.wi = mi.warp.square_to_cosine_hemisphere(mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n))))
    si.wavelengths = mi.Spectrum(*(mi.Float(rng.uniform(360, 830, n)) for _ in range(4)))
    wo = mi.warp.square_to_cosine_hemisphere(mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n))))
    dr.eval(si, wo)
    return si, wo


def crossing_sets(args, rng):
    """``eval`` with the height-field crossing correction against the additive model, same lanes."""
    import drjit as dr
    import mitsuba as mi

    from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf
    from scratch_iridescence.mitsuba_bridge import scratch

    n = args.dense_lanes
    plate_m = 0.10
    sets = {
        "Fig. 7(b) plate, 3 000": plate_scratches(),
        "the same, V-grooves": plate_scratches(scratch.Profile.TRIANGULAR),
        "worn plate, 30 000": scratch.random_scratches(
            30000, seed=8, width=scratch.Uniform(0.5e-6, 6e-6), depth=scratch.Uniform(0.1e-6, 1e-6),
            region=((0.2, 0.2), (0.6, 0.6))),
    }
    if not args.worn:  # ~100x the plate's 2.2 M crossing pairs (N²): their build exceeded a 23 GB machine
        del sets["worn plate, 30 000"]
    print(f"\ncrossings: time per eval query, {n} lanes on the scratches, best of {args.repeat}, alternately")
    for name, scratches in sets.items():
        loaded, seconds = {}, {}
        for mode in ("additive", "height_field"):
            start = time.perf_counter()
            loaded[mode] = mi.load_dict(scratch_bsdf.plugin_dict(scratches, unit_scale=plate_m, crossings=mode))
            seconds[mode] = time.perf_counter() - start
        # the pair terms alone: the same tables, the model without its overlaps of three and more
        # and without the nearly parallel overlaps (parallel.py)
        models = {"height_field": loaded["height_field"].model,
                  "pairs only": dataclasses.replace(loaded["height_field"].model, triples=False),
                  "no parallel": dataclasses.replace(loaded["height_field"].model, parallel_overlaps=False)}
        tables = loaded["height_field"].tables
        si, wo = points_on_pieces(tables, n, rng)
        ctx = mi.BSDFContext()
        best = {mode: float("inf") for mode in ("additive", "height_field", "pairs only", "no parallel")}
        for i in range(args.repeat + 1):
            for mode in best:
                bsdf = loaded["additive" if mode == "additive" else "height_field"]
                if mode != "additive":
                    bsdf.model = models[mode]
                start = time.perf_counter()
                dr.eval(bsdf.eval(ctx, si, wo))
                dr.sync_thread()
                if i:
                    best[mode] = min(best[mode], time.perf_counter() - start)
        print(f"  {name:24s} {tables.crossing_count:7d} pairs ({tables.piece_count} pieces); load "
              f"{seconds['additive']:.2f} s / {seconds['height_field']:.2f} s; eval "
              f"{best['additive'] / n * 1e9:6.0f} ns / {best['height_field'] / n * 1e9:6.0f} ns per query "
              f"= {best['height_field'] / best['additive']:.2f} x; pairs only {best['pairs only'] / n * 1e9:6.0f} ns "
              f"= {best['pairs only'] / best['additive']:.2f} x; with higher orders / pairs only "
              f"{best['height_field'] / best['pairs only']:.2f} x; without the nearly parallel overlaps "
              f"{best['no parallel'] / n * 1e9:6.0f} ns (height field / that "
              f"{best['height_field'] / best['no parallel']:.2f} x)")


if __name__ == "__main__":
    main()
