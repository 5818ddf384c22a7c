"""Benchmark: what the fixed sample schedule costs next to one long ``mi.render`` call.

The scratched plate of tests/bridge/builder/test_scratched.py (3 000 scratches) at
512² × 64 spp, measured in the same run (the machine is shared, so only the
ratios mean much):

1. one ``mi.render(spp=64)`` call (no progress, no cancel, unbounded memory);
2. ``render_image`` (the schedule: 4 chunks of 16 spp, pairwise float64 sums);
3. the same render split into 4 parts (``render_chunks`` + ``write_part``) and
   ``merge_parts``: the merge alone, and that the result equals (2) bit for bit.

Target: the schedule within 10 % of one call.

Run: ``.venv/bin/python tests/bench/bench_schedule.py [--repeat 3]`` (``make bench`` runs every benchmark).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "bridge"))
sys.path.insert(0, str(ROOT / "tests" / "bridge" / "builder"))


def scratched_plate(size: int, material=None):
    """The plate of tests/bridge/builder/test_scratched.py on a ``size``² film, carrying 3 000 scratches of the
    demo's looks (or wearing ``material``)."""
    import dataclasses

    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge import scratch
    from test_scratched import metal, plate_scene

    if material is None:
        material = metal(scratch.random_scratches(3000, seed=5, width=scratch.Gaussian(4e-6, 1.3e-6),
                                                  length=(0.2, 0.6), depth=scratch.Gaussian(250e-9, 80e-9),
                                                  depth_variation=(1.1, 0.04)))
    return dataclasses.replace(plate_scene(material), film=S.Film(size, size))


def best_of(repeat, function):
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--spp", type=int, default=64)
    args = parser.parse_args()

    import numpy as np

    from scratch_iridescence.mitsuba_bridge import builder
    from scratch_iridescence.mitsuba_bridge.render.activation import activate
    from scratch_iridescence.mitsuba_bridge.render import parts, passes as render, schedule
    from scratch_iridescence.mitsuba_bridge import scene as S

    variant = activate("auto")
    import mitsuba as mi

    scene = builder.load_scene(scratched_plate(args.size), S.RenderSettings())
    chunks = schedule.sample_schedule(args.spp, args.size ** 2, 0)
    mi.render(scene, spp=args.spp, seed=0)  # compile every kernel once (a user's second render finds them cached)
    render.render_image(scene, args.spp)

    t_single, _ = best_of(args.repeat, lambda: np.asarray(mi.render(scene, spp=args.spp, seed=0)))
    t_schedule, image = best_of(args.repeat, lambda: render.render_image(scene, args.spp))
    with tempfile.TemporaryDirectory() as folder:
        identity = parts.RenderIdentity("bench", variant, parts.software(), args.size, args.size, args.spp, 0,
                                        len(chunks), parts.schedule_digest(chunks), "none")
        files = []
        count = min(4, len(chunks))
        for k in range(1, count + 1):
            run = schedule.part_range(k, count, len(chunks))
            progress = list(render.render_chunks(scene, chunks[run.start:run.stop], args.spp))[-1]
            files.append(parts.write_part(Path(folder) / f"part{k}.exr", identity, progress.sums,
                                          sum(c.spp for c in chunks[run.start:run.stop])))
        t_merge, (merged, _) = best_of(args.repeat, lambda: parts.merge_parts(files))
    print(f"{variant}, {args.size}² x {args.spp} spp, {len(chunks)} chunks of {chunks[0].spp} spp "
          f"(best of {args.repeat})")
    print(f"  one mi.render call        {t_single:7.2f} s")
    print(f"  fixed schedule            {t_schedule:7.2f} s   ratio {t_schedule / t_single:.3f} (target < 1.10)")
    print(f"  merge of {count} parts          {t_merge:7.3f} s   ratio {t_merge / t_single:.3f}")
    print(f"  merged == whole, bit for bit: {merged.tobytes() == image.tobytes()}")


if __name__ == "__main__":
    main()
