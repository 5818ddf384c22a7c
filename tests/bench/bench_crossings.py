"""Validation table of ``crossings = "height_field"`` (docs/bsdf.md, Crossings): relative L2 error of f_r
against the brute-force height field for the crossing sets of tests/bridge/bsdf/heightfield/test_crossings.py, worst over
450/550/650 nm × incidence 0/40/70°, for the additive model, the pair terms alone (the correction before
its overlaps of three and more), the height-field correction with them, and the pair terms alone against the
pairwise inclusion–exclusion of the same raster (what they implement exactly).  With ``--v-grooves``:
the sets with V-grooves instead, against the height field summed per direction (coarser planes); with
``--parallel``: the nearly parallel pairs (parallel.py), the height field with and without their correction,
and those pairs crossed by more scratches (triples.py), with and without the terms of order 3 and more.

    .venv/bin/python tests/bench/bench_crossings.py [--v-grooves | --parallel]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bsdf"))

import mitsuba as mi  # noqa: E402

mi.set_variant("llvm_ad_spectral")

from scratch_iridescence import mitsuba_bridge  # noqa: E402

mitsuba_bridge.register_plugins()

import crossing_sets as cs  # noqa: E402
import test_crossings as tc  # noqa: E402

V_SETS = [(name, scratches, 2.0) for name, scratches in tc.V_PAIRS.items()] + [
    ("10 scratches, W 1-3 µm, half V", cs.with_v_grooves(cs.random_set(10, 1, 15.0, (1.0, 3.0)), 0.5, 101), 2.0),
    ("10 V-grooves, W 0.5-1.5 µm", cs.with_v_grooves(cs.random_set(10, 2, 15.0, (0.5, 1.5)), 1.0, 102), 2.0),
    ("50 scratches, W 0.1-0.3 µm, half V", cs.with_v_grooves(cs.random_set(50, 0, 25.0, (0.1, 0.3)), 0.5, 100), 5.0),
]


def v_grooves():
    print("| set | additive | height field |")
    print("|---|---|---|")
    for name, scratches, sigma in V_SETS:
        started = time.perf_counter()
        out = tc.v_errors(scratches, sigma, tc.ALL_COMBOS, 19, 0.015)
        worst = [max(v[i] for v in out.values()) for i in range(2)]
        print(f"| {name} | {100 * worst[0]:.1f} % | {100 * worst[1]:.2f} % |  ({time.perf_counter() - started:.0f} s)",
              flush=True)


def parallel():
    print("| pair | additive | height field without them | height field |")
    print("|---|---|---|---|")
    for name, scratches in tc.PARALLEL_PAIRS.items():
        parallel_row(name, scratches, "parallel_overlaps")
    print()
    print("| a nearly parallel pair crossed | additive | height field without the terms of order 3+ | height field |")
    print("|---|---|---|---|")
    for name, scratches in tc.CROSSED_PARALLEL.items():
        parallel_row(name, scratches, "triples")


def parallel_row(name, scratches, without):
    started = time.perf_counter()
    out = tc.parallel_errors(scratches, tc.ALL_COMBOS, without=without)
    worst = [max(v[i] for v in out.values()) for i in range(3)]
    print(f"| {name} | {100 * worst[0]:.0f} % | {100 * worst[1]:.0f} % | {100 * worst[2]:.2f} % |"
          f"  ({time.perf_counter() - started:.0f} s)", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--v-grooves", action="store_true")
    parser.add_argument("--parallel", action="store_true")
    args = parser.parse_args()
    if args.v_grooves:
        v_grooves()
        return
    if args.parallel:
        parallel()
        return
    print("| set | crossing share | triple share | additive | pairs only | height field | pairs only vs pairwise raster |")
    print("|---|---|---|---|---|---|---|")
    for name, scratches, sigma in tc.VALIDATED + tc.DENSE:
        started = time.perf_counter()
        raster, out = tc.errors(scratches, sigma, 0.02, tc.ALL_COMBOS)
        worst = [max(v[i] for v in out.values()) for i in range(4)]
        print(f"| {name} | {100 * raster.share:.1f} % | {100 * raster.triple_share:.2f} % | "
              f"{100 * worst[0]:.1f} % | {100 * worst[3]:.2f} % | {100 * worst[1]:.2f} % | {100 * worst[2]:.2f} % |"
              f"  ({time.perf_counter() - started:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
