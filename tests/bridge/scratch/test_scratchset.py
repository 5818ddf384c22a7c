"""The in-memory scratch set: validation on construction, selection, concatenation."""
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.scratch import (Gaussian, Profile, ScratchFormatError, ScratchSet,
                                                      random_scratches)


def test_arrays_are_read_only(two_scratches):
    assert not any(a.flags.writeable for a in two_scratches.as_dict().values())
    with pytest.raises(ValueError):
        two_scratches.width[0] = 1.0


def test_from_polylines_copies_its_input_and_the_constructor_does_not():
    source = np.array([[0.0, 0.0], [1.0, 0.0]])
    s = ScratchSet.from_polylines([source], width=1e-6, depth=1e-7)
    source[0, 0] = 5
    assert s.uv[0, 0] == 0
    shared = ScratchSet(**{k: np.array(v) for k, v in s.as_dict().items()})
    assert source.flags.writeable  # the caller's arrays are left writeable
    assert np.shares_memory(shared.uv, shared.uv.base)


def test_construction_validates(two_scratches):
    with pytest.raises(ScratchFormatError, match="'width'") as caught:
        two_scratches.replace(width=np.array([1e-6, -1.0]))
    assert caught.value.path is None and "scratch set" in str(caught.value)


def test_select_and_concatenate_are_inverse(plate_scratches):
    first, rest = plate_scratches.select(np.arange(100)), plate_scratches.select(np.arange(100, 500))
    assert ScratchSet.concatenate([first, rest]) == plate_scratches
    mask = np.zeros(500, bool)
    mask[[3, 9]] = True
    picked = plate_scratches.select(mask)
    np.testing.assert_array_equal(picked.polyline(1), plate_scratches.polyline(9))
    assert picked.seed[0] == plate_scratches.seed[3]


def test_concatenate_nothing_is_empty():
    assert ScratchSet.concatenate([]).count == 0


def test_summary_properties(two_scratches):
    assert two_scratches.count == len(two_scratches) == 2
    assert two_scratches.vertex_count == 5
    np.testing.assert_array_equal(two_scratches.vertex_counts, [2, 3])
    np.testing.assert_array_equal(two_scratches.scratch_index_of_vertices(), [0, 0, 1, 1, 1])
    assert "2 scratches" in repr(two_scratches)


def test_random_scratches_are_reproducible_and_inside_the_region():
    kwargs = dict(seed=5, width=Gaussian(4e-6, 1.3e-6), depth=Gaussian(250e-9, 80e-9), length=(0.05, 0.1),
                  vertices=8, curvature=3.0, region=((0.2, 0.3), (0.6, 0.9)), profile=Profile.TRIANGULAR)
    a, b = random_scratches(1000, **kwargs), random_scratches(1000, **kwargs)
    assert a == b and a != random_scratches(1000, **{**kwargs, "seed": 6})
    assert a.uv[:, 0].min() >= 0.2 - 1e-12 and a.uv[:, 0].max() <= 0.6 + 1e-12
    assert a.uv[:, 1].min() >= 0.3 - 1e-12 and a.uv[:, 1].max() <= 0.9 + 1e-12
    assert np.all(a.profile == Profile.TRIANGULAR)
    from scratch_iridescence.mitsuba_bridge.scratch import scratch_lengths
    lengths = scratch_lengths(a.uv, a.offsets)
    assert lengths.min() >= 0.05 * 0.99 and lengths.max() <= 0.1 * 1.0001


def test_random_directions_are_isotropic():
    s = random_scratches(20_000, seed=1, length=(0.01, 0.01))
    d = s.uv[1::2] - s.uv[0::2]
    angle = np.arctan2(d[:, 1], d[:, 0])
    histogram, _ = np.histogram(angle, bins=12, range=(-np.pi, np.pi))
    expected = len(angle) / 12
    chi2 = ((histogram - expected) ** 2 / expected).sum()
    assert chi2 < 40  # 11 degrees of freedom; p ~ 1e-5
