"""Arc length, arc-length parameter, resampling."""
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.scratch import (ScratchSet, arc_parameter, edge_lengths, resample,
                                    scratch_lengths, vertex_arc_length)


def test_lengths_of_known_polylines(two_scratches):
    np.testing.assert_allclose(scratch_lengths(two_scratches.uv, two_scratches.offsets),
                               [0.3, 2 * np.sqrt(0.02)])
    np.testing.assert_allclose(edge_lengths(two_scratches.uv, two_scratches.offsets),
                               [0.3, np.sqrt(0.02), np.sqrt(0.02)])
    np.testing.assert_allclose(vertex_arc_length(two_scratches.uv, two_scratches.offsets),
                               [0, 0.3, 0, np.sqrt(0.02), 2 * np.sqrt(0.02)])
    np.testing.assert_allclose(arc_parameter(two_scratches.uv, two_scratches.offsets),
                               [0, 1, 0, 0.5, 1])


def test_zero_length_scratch_gets_even_parameters():
    s = ScratchSet.from_polylines([np.zeros((3, 2)), np.array([[0, 0], [0, 1]])], width=1e-6, depth=1e-7)
    np.testing.assert_allclose(arc_parameter(s.uv, s.offsets), [0, 0.5, 1, 0, 1])
    np.testing.assert_allclose(scratch_lengths(s.uv, s.offsets), [0, 1])


def test_resample_spaces_vertices_evenly_by_arc_length(plate_scratches):
    uv, offsets = resample(plate_scratches.uv, plate_scratches.offsets, 17)
    assert np.all(np.diff(offsets) == 17)
    np.testing.assert_array_equal(uv[offsets[:-1]], plate_scratches.uv[plate_scratches.offsets[:-1]])
    np.testing.assert_array_equal(uv[offsets[1:] - 1], plate_scratches.uv[plate_scratches.offsets[1:] - 1])
    steps = edge_lengths(uv, offsets).reshape(-1, 16)
    # Chords of a slightly bent polyline: equal spacing along the old polyline means nearly
    # equal chords, and the total never exceeds the original length.
    np.testing.assert_allclose(steps / steps.mean(axis=1, keepdims=True), 1.0, rtol=0.02)
    assert np.all(scratch_lengths(uv, offsets) <= scratch_lengths(plate_scratches.uv, plate_scratches.offsets) + 1e-12)


def test_resample_straight_line_exactly():
    s = ScratchSet.from_polylines([np.array([[0, 0], [0.25, 0], [1, 0]])], width=1e-6, depth=1e-7)
    uv, offsets = resample(s.uv, s.offsets, [5])
    np.testing.assert_allclose(uv, [[0, 0], [0.25, 0], [0.5, 0], [0.75, 0], [1, 0]], atol=1e-15)


def test_resample_per_scratch_counts_and_errors(two_scratches):
    uv, offsets = resample(two_scratches.uv, two_scratches.offsets, [2, 9])
    assert list(offsets) == [0, 2, 11]
    with pytest.raises(ValueError):
        resample(two_scratches.uv, two_scratches.offsets, 1)
