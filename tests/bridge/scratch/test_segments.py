"""Subdivision of scratch sets into straight segments of constant cross-section."""
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.scratch import ScratchSet, subdivide, width_depth_at


def test_constant_scratches_keep_one_segment_per_edge(two_scratches):
    constant = two_scratches.replace(depth_variation=np.zeros((2, 2)))
    segments = subdivide(constant)
    assert len(segments) == 3
    np.testing.assert_array_equal(segments.scratch, [0, 1, 1])
    np.testing.assert_array_equal(segments.a, constant.uv[[0, 2, 3]])
    np.testing.assert_array_equal(segments.b, constant.uv[[1, 3, 4]])
    np.testing.assert_array_equal(segments.width, [1e-6, 2e-6, 2e-6])
    np.testing.assert_array_equal(segments.profile, [0, 1, 1])
    np.testing.assert_allclose(segments.t0, [0, 0, 0.5])
    np.testing.assert_allclose(segments.t1, [1, 0.5, 1])


def test_unsplit_edges_come_out_as_when_other_edges_split(plate_scratches):
    """A set whose edges all stay whole (no variation, no max_length: the CD's chords) skips the gathers of
    the general path; its segments are the general path's bit for bit (same arithmetic, signs of zero too)."""
    rng = np.random.default_rng(3)  # polylines of 20 vertices: t0 + (t1 - t0) is not always t1 to the bit
    polylines = [np.cumsum(rng.normal(0.0, 0.01, (20, 2)), axis=0) + 0.5 for _ in range(200)]
    constant = ScratchSet.from_polylines(polylines, width=1e-6, depth=1e-7)
    varying = plate_scratches.select(np.arange(1))  # one varying scratch: every edge goes the general way
    alone, mixed = subdivide(constant), subdivide(ScratchSet.concatenate([constant, varying]))
    assert len(alone) == 200 * 19
    kept = mixed.scratch < constant.count
    for name in ("a", "b", "t0", "t1", "width", "depth", "scratch", "profile"):
        np.testing.assert_array_equal(getattr(alone, name).view(np.uint8), getattr(mixed, name)[kept].view(np.uint8))


def test_segments_cover_each_polyline_without_gaps(plate_scratches):
    segments = subdivide(plate_scratches, max_length=0.01)
    assert segments.length.max() <= 0.01 + 1e-12
    same = segments.scratch[1:] == segments.scratch[:-1]
    np.testing.assert_array_equal(segments.b[:-1][same], segments.a[1:][same])
    np.testing.assert_allclose(segments.t1[:-1][same], segments.t0[1:][same])
    total = np.bincount(segments.scratch, segments.length)
    from scratch_iridescence.mitsuba_bridge.scratch import scratch_lengths
    np.testing.assert_allclose(total, scratch_lengths(plate_scratches.uv, plate_scratches.offsets))


def test_varying_scratches_follow_the_noise(plate_scratches):
    segments = subdivide(plate_scratches, pieces_per_cell=4)
    per_scratch = np.bincount(segments.scratch)
    # D[1.1, 0.04]: about 10.2 noise cells per scratch, 4 pieces each.
    assert per_scratch.min() >= 40
    mid = 0.5 * (segments.t0 + segments.t1)
    width, depth = width_depth_at(plate_scratches, segments.scratch, mid)
    np.testing.assert_array_equal(segments.depth, depth)
    np.testing.assert_array_equal(segments.width, width)
    assert (segments.depth == 0).any()  # amplitude 1.1 pinches some pieces shut


def test_empty_set_gives_no_segments():
    segments = subdivide(ScratchSet.empty())
    assert len(segments) == 0 and segments.a.shape == (0, 2)


def test_invalid_max_length():
    with pytest.raises(ValueError):
        subdivide(ScratchSet.empty(), max_length=0)
