"""Benchmark: where a CD query's search spends its steps (a float64 replay of the kernel's scan).

``lookup.for_each_segment`` runs two nested loops: the inner one takes one step per reference
tested or cell entered until the lane has found its next piece, the outer one then evaluates it.
SIMD lanes run in packets, and a packet's inner loop runs until its *slowest* lane has found its
next piece.  This replays the scan of ``lookup._cell_scan`` with numpy on random CD shading
points (identity Jacobian, the bench's σ = 5 µm, window radius 4σ) and counts per lane: cells
entered, references skipped below the window's offset interval (inside a bucket), references
tested and what became of them (found; inside the window but owned by another visited cell;
outside the window), and the steps of simulated packets of 8 and 16 lanes (AVX2, AVX-512).

The replay follows the kernel's arithmetic in float64, so a lane may differ from the kernel's by a
reference at the interval's ends; the counts are what matters.  ``--bisect`` replays the scan that
the offset buckets replaced (a bisection over each cell of more than 6 references, the interval
padded by the tables' 0.01-cell dilation, no clipped box) for comparison.

Run: ``.venv/bin/python tests/bench/bench_lookup_steps.py [--points 2000] [--bisect]``.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

SIGMA_UM = 5.0
RADIUS_UM = 4.0 * SIGMA_UM


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=2000)
    parser.add_argument("--bisect", action="store_true", help="replay the bisection scan it replaced")
    args = parser.parse_args()

    from scratch_iridescence.mitsuba_bridge.bsdf.lookup import OFFSET_PADDING
    from scratch_iridescence.mitsuba_bridge.bsdf.tables.scan import BUCKET_REFERENCES, offset_buckets
    from scratch_iridescence.mitsuba_bridge.bsdf.tables.grid import CELL_DILATION, build_tables

    sys.path.insert(0, str(Path(__file__).parent))
    from bench_bsdf_memory import DISC_M, cd_scratches

    tables = build_tables(cd_scratches())
    frames, cell_bucket, bucket_start = offset_buckets(tables.cell_start, tables.offsets, tables.cell_frames)
    rows = tables.segments.astype(np.float64)
    um_per_cell = tables.cell_size * DISC_M * 1e6
    radius_cells = RADIUS_UM / um_per_cell
    rounding = tables.margin - CELL_DILATION
    pad = tables.margin if args.bisect else OFFSET_PADDING + rounding
    rng = np.random.default_rng(3)

    def lane(x0):
        """Per-step outcomes of one lane: 'c' cell entered, 'k' skipped, 'f' found, 'o' other's, 'x' outside."""
        g = (x0 - np.array(tables.origin)) / tables.cell_size
        extent = radius_cells + tables.margin
        u0, u1 = int(math.floor(g[0] - extent)), int(math.floor(g[0] + extent))
        v0, v1 = int(math.floor(g[1] - extent)), int(math.floor(g[1] + extent))
        steps = []
        for v in range(v0, v1 + 1):
            for u in range(u0, u1 + 1):
                steps.append("c")
                cell = v * tables.shape[0] + u
                begin, end = int(tables.cell_start[cell]), int(tables.cell_start[cell + 1])
                n_u, n_v = (float(c) for c in tables.cell_frames[cell, 0:2])
                du, dv = g[0] - u, g[1] - v
                q = n_u * du + n_v * dv
                offsets = tables.offsets[begin:end].astype(np.float64)
                if args.bisect:
                    lo = q - radius_cells - pad - tables.cell_frames[cell, 2]
                    hi = q + radius_cells + pad
                    if end - begin > 6:
                        steps += ["k"] * math.ceil(math.log2(end - begin + 1))
                        first = begin + int(np.searchsorted(offsets, lo))
                    else:
                        first = begin
                else:
                    box_u = (max(du - extent, -pad), min(du + extent, 1 + pad))
                    box_v = (max(dv - extent, -pad), min(dv + extent, 1 + pad))
                    box_lo = n_u * (box_u[0] if n_u >= 0 else box_u[1]) + n_v * (box_v[0] if n_v >= 0 else box_v[1])
                    box_hi = n_u * (box_u[1] if n_u >= 0 else box_u[0]) + n_v * (box_v[1] if n_v >= 0 else box_v[0])
                    hi = min(q + radius_cells, box_hi) + pad
                    lowest_pieces = max(q - radius_cells, box_lo) - pad
                    last_bucket = max((end - begin) // BUCKET_REFERENCES, 1) - 1
                    k = int(np.clip(math.floor((lowest_pieces - frames[cell, 2]) * frames[cell, 3]), 0, last_bucket))
                    first = int(bucket_start[cell_bucket[cell] + k])
                    lo = lowest_pieces - tables.cell_frames[cell, 2]
                index = first
                while index < end and tables.offsets[index] <= hi:
                    if tables.offsets[index] < lo:
                        steps.append("k")
                    else:
                        row = rows[tables.references[index]]
                        a, e = row[0:2] + row[2:4], row[4:6]
                        t = min(max(-np.dot(a - x0, e) / np.dot(e, e), 0.0), 1.0)
                        closest = a - x0 + t * e
                        if np.hypot(*closest) * DISC_M * 1e6 >= RADIUS_UM:
                            steps.append("x")
                        elif np.array_equal(np.floor(g + closest / tables.cell_size), (u, v)):
                            steps.append("f")
                        else:
                            steps.append("o")
                    index += 1
                if index < end:
                    steps.append("e")  # the step that meets the first offset above the interval
        return steps

    radius = rng.uniform(23e-3, 57e-3, args.points) / DISC_M
    angle = rng.uniform(0, 2 * np.pi, args.points)
    lanes = [lane(np.array([0.5 + r * math.cos(a), 0.5 + r * math.sin(a)])) for r, a in zip(radius, angle)]
    kinds = {"c": "cells entered", "e": "scans ended above the interval", "k": "skipped (below the interval)",
             "f": "found", "o": "inside, owned by another cell", "x": "outside the window"}
    print(f"CD, {args.points} random shading points, {'bisection' if args.bisect else 'offset buckets'}: "
          f"steps per lane {np.mean([len(s) for s in lanes]):.1f}")
    for key, label in kinds.items():
        print(f"  {label:32s} {np.mean([s.count(key) for s in lanes]):6.1f}")
    for width in (8, 16):
        packets = [packet_steps(lanes[i:i + width]) for i in range(0, len(lanes) - width + 1, width)]
        print(f"  packets of {width:2d} lanes: {np.mean(packets):.1f} inner steps")


def packet_steps(lanes) -> int:
    """Inner-loop steps of one packet: each round runs until every lane has found a piece or is done."""
    position = [0] * len(lanes)
    total = 0
    while any(p < len(s) for p, s in zip(position, lanes)):
        longest = 0
        for j, steps in enumerate(lanes):
            taken = 0
            while position[j] < len(steps):
                taken += 1
                position[j] += 1
                if steps[position[j] - 1] == "f":
                    break
            longest = max(longest, taken)
        total += longest
    return total


if __name__ == "__main__":
    main()
