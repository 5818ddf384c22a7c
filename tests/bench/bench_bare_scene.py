"""Benchmark: a saved scene rendered as is and with its scratches removed (how much the BSDF costs).

Opens a ``make paper`` scene (``out/paper/<picture>.blend``), saves a copy whose scratched objects have
their scratches cleared (same camera, lights, materials and samples), renders both through the engine
in fresh processes (``scenes.paper render``) and prints samples per core-second of each and their ratio.
docs/bsdf.md (Performance) uses it to say how far the paper-per-wavelength-sample target is from the
renderer's own cost.

    .venv/bin/python tests/bench/bench_bare_scene.py out/paper/fig09_grating-coherent.blend [--output out/bare]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

CLEAR = """
import bpy
from scratch_iridescence import register
register()
from scratch_iridescence.addon import storage
bpy.ops.wm.open_mainfile(filepath={source!r})
for obj in bpy.context.scene.objects:
    if obj.type == "MESH" and storage.has_scratches(obj):
        storage.clear_scratches(obj)
bpy.ops.wm.save_as_mainfile(filepath={target!r}, compress=False)
"""


def render(blend: Path, output: Path) -> float:
    """Samples per core-second of one render of ``blend`` through the engine, in a fresh process."""
    done = subprocess.run([sys.executable, "-m", "scratch_iridescence.scenes.paper", "render", str(blend),
                           "--output", str(output)], capture_output=True, text=True, check=True)
    stats = json.loads(next(line for line in done.stdout.splitlines() if line.startswith("RESULT "))[7:])
    return stats["width"] * stats["height"] * stats["spp"] / stats["render_cpu_s"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("blend", type=Path)
    parser.add_argument("--output", type=Path, default=Path("out/bare"))
    args = parser.parse_args()
    args.output.mkdir(parents=True, exist_ok=True)
    bare = args.output / f"{args.blend.stem}-bare.blend"
    subprocess.run([sys.executable, "-c", CLEAR.format(source=str(args.blend.resolve()), target=str(bare.resolve()))],
                   check=True, capture_output=True)
    scratched, plain = render(args.blend, args.output), render(bare, args.output)
    print(f"{args.blend.stem}: {scratched:.3g} samples/core-s; without its scratches {plain:.3g}; "
          f"the scratches cost {plain / scratched:.2f}x")


if __name__ == "__main__":
    main()
