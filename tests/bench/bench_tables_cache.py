"""Benchmark: a scratch BSDF's set-up with its tables built, and read from the disk cache (bsdf/tables/disk_cache.py).

Each load runs in a fresh process (as a new Blender session or a ``make paper``
worker would), alternately: with the cache off (the build), and with a cache
folder that the first load filled (the read).  Prints the best times, the file
size and the ratio.  The default set is the Fig. 9 grating (1 600 grooves of
7 cm, 72 000 pieces); ``--set`` takes any scratch file, e.g. an exported
scene's ``scratches/*.npz`` (the CD's: ``out/scenes/fig06_cd-incoherent``).
Target: reading costs at most a fifth of building for sets that take over 0.2 s.

    .venv/bin/python tests/bench/bench_tables_cache.py [--set FILE] [--coherent] [--repeat 3]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = """
import json, sys, time
from scratch_iridescence.mitsuba_bridge.render.activation import activate
activate("llvm_ad_spectral")
from scratch_iridescence.mitsuba_bridge import bsdf, scratch
from scratch_iridescence.mitsuba_bridge.bsdf.tables import disk_cache
scratches = {make}
began = time.perf_counter()
loaded = bsdf.load(scratches, unit_scale={unit_scale}, coherent={coherent})
print("RESULT " + json.dumps({{"seconds": time.perf_counter() - began, **disk_cache.statistics()}}))
"""

GRATING = """scratch.ScratchSet.from_polylines(
    [__import__("numpy").array([[0.15, v], [0.85, v]]) for v in
     __import__("numpy").concatenate([0.5 + (y0 + 2.5e-6 * __import__("numpy").arange(400)) / 0.1
                                      for y0 in (0.0, 0.005, 0.010, 0.015)])],
    width=1e-6, depth=1e-6)"""


def load_once(make: str, unit_scale: float, coherent: bool, cache: str) -> dict:
    code = CHILD.format(make=make, unit_scale=unit_scale, coherent=coherent)
    env = {**os.environ, "SCRATCH_IRIDESCENCE_CACHE_DIR": cache}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    return json.loads(next(line for line in out.splitlines() if line.startswith("RESULT "))[7:])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", type=Path, help="a scratch file (default: the Fig. 9 grating, built here)")
    parser.add_argument("--unit-scale", type=float, default=0.1, help="metres per UV unit (the grating's plate: 0.1)")
    parser.add_argument("--coherent", action="store_true")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    make = GRATING if args.set is None else f"scratch.loads(open({str(args.set)!r}, 'rb').read())"
    with tempfile.TemporaryDirectory(prefix="bench-tables-cache-") as folder:
        first = load_once(make, args.unit_scale, args.coherent, folder)  # fills the cache
        if not first["writes"]:
            print("the build was not written (shorter than disk_cache.MIN_BUILD_SECONDS)")
            return 1
        built, read = [], []
        for _ in range(args.repeat):
            built.append(load_once(make, args.unit_scale, args.coherent, "off")["seconds"])
            result = load_once(make, args.unit_scale, args.coherent, folder)
            assert result["hits"] == 1, result
            read.append(result["seconds"])
        size_mb = sum(p.stat().st_size for p in Path(folder).rglob("*.scratch-tables")) / 2 ** 20
    print(f"set: {args.set or 'Fig. 9 grating'} ({'coherent' if args.coherent else 'incoherent'})")
    print(f"bsdf.load, tables built: best {min(built):.3f} s of {', '.join(f'{t:.3f}' for t in built)}")
    print(f"bsdf.load, tables read:  best {min(read):.3f} s of {', '.join(f'{t:.3f}' for t in read)}"
          f" ({size_mb:.1f} MB file)")
    ratio = min(read) / min(built)
    print(f"read / built = {ratio:.3f} (target <= 0.2 where the build takes over 0.2 s)")
    return 0 if min(built) <= 0.2 or ratio <= 0.2 else 1


if __name__ == "__main__":
    sys.exit(main())
