"""Benchmark: resident memory and time of loading the paper's CD (3.1 million scratches).

The supplement's CD has 3 128 400 scratches of W = 1 µm, D = 120 nm (Fig. 6).
Here: concentric tracks of pitch 1.6 µm between radii 22.5 and 58 mm of a
120 mm disc mapped onto the UV square, each track cut into equal arcs so that
the total is 3 128 400 scratches of ``--vertices`` vertices each.  The file is
written by one process; a fresh process then loads it through
``mi.load_dict({"type": "scratch_diffraction", "filename": ...})``, evaluates the
BSDF once on a CD-like view, and reports its peak resident memory (ru_maxrss,
interpreter and Mitsuba included) and the load time.  Target (issue 3): < 2 GB.

Run: ``.venv/bin/python tests/bench/bench_bsdf_memory.py``.
"""
from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SCRATCHES = 3_128_400
PITCH_M, DISC_M = 1.6e-6, 0.12


def cd_scratches(count=SCRATCHES, vertices=2):
    from scratch_iridescence.mitsuba_bridge import scratch

    radii = np.arange(22.5e-3, 58e-3, PITCH_M) / DISC_M  # UV units
    per_track = int(np.ceil(count / len(radii)))
    track = np.repeat(np.arange(len(radii)), per_track)[:count]
    arc = np.arange(count) - track * per_track
    t = (arc[:, None] + np.linspace(0.0, 1.0, vertices)[None, :]) * (2 * np.pi / per_track)
    r = radii[track][:, None]
    uv = np.empty((count, vertices, 2))
    np.cos(t, out=uv[..., 0])
    np.sin(t, out=uv[..., 1])
    uv *= r[..., None]
    uv += 0.5
    del t, r
    offsets = np.arange(count + 1, dtype=np.int64) * vertices
    return scratch.ScratchSet(
        uv=uv.reshape(-1, 2), offsets=offsets, width=np.full(count, 1e-6), depth=np.full(count, 120e-9),
        profile=np.zeros(count, np.uint8), width_variation=np.zeros((count, 2)),
        depth_variation=np.zeros((count, 2)), seed=np.arange(count, dtype=np.uint32))


def load_run(path: str) -> None:
    """In a fresh process: load, evaluate once, print peak RSS and timings."""
    start = time.perf_counter()
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_spectral")
    from scratch_iridescence import mitsuba_bridge

    mitsuba_bridge.register_plugins()
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    loaded = time.perf_counter()
    bsdf = mi.load_dict({"type": "scratch_diffraction", "filename": path, "unit_scale": DISC_M})
    load_time = time.perf_counter() - loaded
    count = 1 << 16
    si = dr.zeros(mi.SurfaceInteraction3f, count)
    si.uv = mi.Point2f(0.5 + 40e-3 / DISC_M, mi.Float(np.linspace(0.5, 0.5001, count)))
    si.dp_du, si.dp_dv = mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.wi = mi.Vector3f(0.3, 0.0, 0.954)
    si.wavelengths = mi.Spectrum(450, 520, 600, 680)
    wo = mi.Vector3f(-0.1, 0.05, 0.994)
    dr.eval(bsdf.eval(mi.BSDFContext(), si, wo))  # compiles
    evaluated = time.perf_counter()
    value = bsdf.eval(mi.BSDFContext(), si, wo)
    dr.eval(value)
    dr.sync_thread()
    eval_time = (time.perf_counter() - evaluated) / count
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"  {bsdf}")
    print(f"  load_dict: {load_time:.1f} s; peak resident memory {peak:.0f} MB "
          f"({base:.0f} MB before loading: interpreter, Mitsuba, Dr.Jit); "
          f"total {time.perf_counter() - start:.1f} s")
    print(f"  eval on the tracks: {eval_time * 1e9:.0f} ns per evaluation (wall, all cores; ~25 tracks per window)")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, default=2, help="vertices per scratch (2: straight chords)")
    parser.add_argument("--load-run", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.load_run:
        return load_run(args.load_run)

    from scratch_iridescence.mitsuba_bridge import scratch

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "cd.npz"
        start = time.perf_counter()
        scratches = cd_scratches(vertices=args.vertices)
        scratch.save(scratches, path)
        print(f"CD: {scratches!r}, file {path.stat().st_size / 2**20:.0f} MB, "
              f"made in {time.perf_counter() - start:.1f} s")
        del scratches
        subprocess.run([sys.executable, __file__, "--load-run", str(path)], check=True)
    print("target: < 2048 MB resident")


if __name__ == "__main__":
    main()
