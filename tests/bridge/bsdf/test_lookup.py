"""The grid walk (:mod:`mitsuba_bridge.bsdf.lookup`): every piece within the window radius, exactly once.

The kernel's fold over pieces is compared with a float64 brute force over the
whole segment table, for shading points spread over the set, sheared and
rotated UV Jacobians and windows from a fraction of a cell to several cells.
Pieces within 1e-4 of the radius may go either way (float32).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.bsdf.tables import scan
from scratch_iridescence.mitsuba_bridge.bsdf.lookup import Grid, LocalJacobian, for_each_segment
from scratch_iridescence.mitsuba_bridge.bsdf.tables.grid import build_tables
from scratch_iridescence.mitsuba_bridge.bsdf.tables.scan import BUCKET_REFERENCES, offset_buckets
from scratch_iridescence.mitsuba_bridge.scratch import Gaussian, Profile, ScratchSet, random_scratches


def tracks(count=60, pitch=2e-4, vertices=40):
    """Concentric polygonal tracks (a small CD): nearly parallel pieces."""
    angle = np.linspace(0.0, 2 * np.pi, vertices)
    lines = [np.stack([0.5 + r * np.cos(angle), 0.5 + r * np.sin(angle)], axis=1)
             for r in 0.2 + pitch * np.arange(count)]
    return ScratchSet.from_polylines(lines, width=1e-6, depth=1e-7)


def grooves(count=80, pitch=1.5e-4):
    lines = [np.array([[0.1, 0.3 + k * pitch], [0.9, 0.3 + k * pitch + 0.05]]) for k in range(count)]
    return ScratchSet.from_polylines(lines, width=1e-6, depth=1e-7)


SETS = {
    "plate": lambda: random_scratches(300, seed=2, width=Gaussian(4e-6, 1e-6), depth=Gaussian(2e-7, 5e-8),
                                      vertices=4, curvature=2.0, profile=Profile.TRIANGULAR),
    "tracks": tracks,
    "grooves": grooves,
}


def brute_force_counts(tables, uv, jacobians, radius):
    """(surely inside, possibly inside) piece counts per lane, float64."""
    rows = tables.segments[:tables.piece_count].astype(np.float64)
    a, e = rows[:, 0:2] + rows[:, 2:4], rows[:, 4:6]
    sure, possible = [], []
    for x0, jac in zip(uv, jacobians):
        pa, pe = (a - x0) @ jac.T, e @ jac.T
        t = np.clip(-np.einsum("ij,ij->i", pa, pe) / np.maximum(np.einsum("ij,ij->i", pe, pe), 1e-300), 0, 1)
        distance = np.hypot(*(pa + t[:, None] * pe).T)
        sure.append(np.count_nonzero(distance < radius * (1 - 1e-4)))
        possible.append(np.count_nonzero(distance < radius * (1 + 1e-4)))
    return np.array(sure), np.array(possible)


@pytest.mark.parametrize("name", list(SETS))
@pytest.mark.parametrize("window_cells", [0.3, 3.0])
@pytest.mark.parametrize("bucketed", [True, False], ids=["buckets", "cell-starts"])
def test01_every_piece_in_the_window_is_visited_once(name, window_cells, bucketed):
    """Both scans (from offset buckets, as dense sets; from each cell's start, as sparse ones) on every set."""
    scratches = SETS[name]()
    tables = build_tables(scratches)
    grid = Grid.upload(tables)
    if bucketed != grid.bucketed:  # the other scan's arrays: upload as the other kind of set would
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(scan, "BUCKETED_ABOVE", -1 if bucketed else 1e30)
            grid = Grid.upload(tables)
    assert grid.bucketed == bucketed
    rng = np.random.default_rng(7)
    n = 400
    # shading points near pieces (where the pieces are), rotated and sheared Jacobians
    rows = tables.segments[:tables.piece_count].astype(np.float64)
    pick = rng.integers(0, tables.piece_count, n)
    uv = rows[pick, 0:2] + rows[pick, 2:4] + rng.random((n, 1)) * rows[pick, 4:6] \
        + rng.normal(0, 0.5 * window_cells * tables.cell_size, (n, 2))
    theta = rng.uniform(0, 2 * np.pi, n)
    rotation = np.stack([np.cos(theta), -np.sin(theta), np.sin(theta), np.cos(theta)], axis=1).reshape(n, 2, 2)
    shear = np.array([[1.0, 0.4], [0.0, 0.7]])
    micrometres_per_uv = 1e3
    jacobians = micrometres_per_uv * rotation @ shear
    radius = window_cells * tables.cell_size * micrometres_per_uv

    jac = LocalJacobian(uv=mi.Point2f(mi.Float(uv[:, 0]), mi.Float(uv[:, 1])),
                        j00=mi.Float(jacobians[:, 0, 0]), j01=mi.Float(jacobians[:, 0, 1]),
                        j10=mi.Float(jacobians[:, 1, 0]), j11=mi.Float(jacobians[:, 1, 1]))

    def body(segment, piece, state):
        count, = state
        return (count + 1,)

    count, = for_each_segment(grid, jac, mi.Float(radius), (dr.zeros(mi.UInt32, n),), body, mi.Bool(True))
    count = np.array(count)
    sure, possible = brute_force_counts(tables, uv, jacobians, radius)
    assert possible.sum() > n  # the windows do hold pieces
    assert np.all(count >= sure) and np.all(count <= possible), (count - sure)[(count < sure) | (count > possible)]


@pytest.mark.parametrize("name", list(SETS))
def test02_offset_buckets_partition_each_cell_by_offset(name):
    """Bucket k of a cell holds exactly its references with offsets in [lowest + k/scale, lowest + (k+1)/scale)."""
    tables = build_tables(SETS[name]())
    frames, cell_bucket, bucket_start = offset_buckets(tables.cell_start, tables.offsets, tables.cell_frames)
    starts = tables.cell_start.astype(np.int64)
    counts = np.diff(starts)
    buckets = np.diff(np.append(cell_bucket.astype(np.int64), len(bucket_start) - 1))
    assert np.all(buckets == np.maximum(1, counts // BUCKET_REFERENCES))
    assert bucket_start[-1] == starts[-1] and np.all(np.diff(bucket_start.astype(np.int64)) >= 0)
    assert np.array_equal(bucket_start[cell_bucket], tables.cell_start[:-1])  # each cell's first bucket
    assert np.array_equal(frames[:, 0:2], tables.cell_frames[:, 0:2])
    checked = 0
    for cell in np.flatnonzero(counts > 2 * BUCKET_REFERENCES)[:200]:
        lowest = np.float64(tables.offsets[starts[cell]])
        assert frames[cell, 2] == np.float32(lowest + tables.cell_frames[cell, 2])  # lowest + spread
        scale = np.float64(frames[cell, 3])
        for k in range(buckets[cell]):
            first, last = bucket_start[cell_bucket[cell] + k], bucket_start[cell_bucket[cell] + k + 1]
            offsets = tables.offsets[first:last].astype(np.float64)
            assert np.all(offsets >= lowest + k / scale - 1e-6)
            if k + 1 < buckets[cell]:
                assert np.all(offsets < lowest + (k + 1) / scale + 1e-6)
            checked += len(offsets)
    assert checked > 0
