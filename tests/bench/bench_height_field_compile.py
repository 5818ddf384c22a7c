"""Kernel compile time of ``crossings = "height_field"``: the first (compiling) and second ``eval`` and the first
``sample`` on the Fig. 7(b) plate (3 000 scratches, 2^16 shading points on them), without and with the nearly
parallel overlaps (``Model.parallel_overlaps``, parallel.py).  Meaningful on a machine without Dr.Jit's kernel
cache (a fresh GPU machine, or after moving ~/.drjit away); docs/bsdf.md, Cost.

    .venv/bin/python tests/bench/bench_height_field_compile.py [llvm_ad_spectral | cuda_ad_spectral]
"""
import dataclasses
import sys
import time

import drjit as dr
import mitsuba as mi
import numpy as np

mi.set_variant(sys.argv[1] if len(sys.argv) > 1 else "llvm_ad_spectral")

from scratch_iridescence import mitsuba_bridge  # noqa: E402
from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf  # noqa: E402

from bench_bsdf import plate_scratches, points_on_pieces  # noqa: E402  (this folder)

mitsuba_bridge.register_plugins()
bsdf = mi.load_dict(scratch_bsdf.plugin_dict(plate_scratches(), unit_scale=0.1, crossings="height_field"))
n = 1 << 16
rng = np.random.default_rng(1)
si, wo = points_on_pieces(bsdf.tables, n, rng)
for parallel in (False, True):
    bsdf.model = dataclasses.replace(bsdf.model, parallel_overlaps=parallel)
    for k in range(2):
        start = time.perf_counter()
        dr.eval(bsdf.eval(mi.BSDFContext(), si, wo))
        dr.sync_thread()
        print(f"{mi.variant()} parallel_overlaps={parallel} eval #{k + 1}: {time.perf_counter() - start:.2f} s",
              flush=True)
    start = time.perf_counter()
    dr.eval(bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(n)),
                        mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n)))))
    dr.sync_thread()
    print(f"{mi.variant()} parallel_overlaps={parallel} first sample: {time.perf_counter() - start:.2f} s", flush=True)
