"""Kernel compile time of ``crossings = "height_field"``: the first (compiling) and second ``eval`` and the first
``sample`` on the Fig. 7(b) plate (3 000 scratches, 2^16 shading points on them), without and with the nearly
parallel overlaps (``Model.parallel_overlaps``, parallel.py).  Meaningful on a machine without Dr.Jit's kernel
cache (a fresh GPU machine, or after moving ~/.drjit away); docs/bsdf.md, Cost.

    .venv/bin/python tests/bench/bench_height_field_compile.py [llvm_ad_spectral | cuda_ad_spectral]
"""
import dataclasses
import sys
import time

import numpy as np
import drjit as dr
import mitsuba as mi
variant = sys.argv[1] if len(sys.argv) > 1 else "llvm_ad_spectral"
mi.set_variant(variant)
from scratch_iridescence import mitsuba_bridge
mitsuba_bridge.register_plugins()
from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf, scratch
s = scratch.random_scratches(3000, seed=7, width=scratch.Gaussian(4e-6, 1.3e-6), depth=scratch.Gaussian(250e-9, 80e-9),
                             depth_variation=(1.1, 0.04), region=((0.2, 0.2), (0.6, 0.6)))
b = mi.load_dict(scratch_bsdf.plugin_dict(s, unit_scale=0.1, crossings="height_field"))
n = 1 << 16
rng = np.random.default_rng(1)
t = b.tables
pieces = t.segments[rng.integers(0, t.piece_count, n)].astype(np.float64)
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
for parallel in (False, True):
    b.model = dataclasses.replace(b.model, parallel_overlaps=parallel)
    for k in range(2):
        t0 = time.perf_counter()
        dr.eval(b.eval(mi.BSDFContext(), si, wo))
        dr.sync_thread()
        print(f"{variant} parallel_overlaps={parallel} eval #{k + 1}: {time.perf_counter() - t0:.2f} s", flush=True)
    t0 = time.perf_counter()
    dr.eval(b.sample(mi.BSDFContext(), si, mi.Float(rng.random(n)),
                     mi.Point2f(mi.Float(rng.random(n)), mi.Float(rng.random(n)))))
    dr.sync_thread()
    print(f"{variant} parallel_overlaps={parallel} first sample: {time.perf_counter() - t0:.2f} s", flush=True)
