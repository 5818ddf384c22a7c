"""Simplex noise and the variation of width and depth along a scratch (docs/model.md §7)."""
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.scratch import (GRADIENTS, ScratchSet, noise_offset, simplex_noise,
                                    variation_factor, width_depth_at)


def test_there_are_255_fixed_unit_gradients_of_both_signs():
    assert GRADIENTS.shape == (255,)
    np.testing.assert_array_equal(np.abs(GRADIENTS), 1.0)
    assert 100 < (GRADIENTS > 0).sum() < 155
    assert not GRADIENTS.flags.writeable


def test_noise_is_zero_at_lattice_points_and_bounded():
    assert np.allclose(simplex_noise(np.arange(-300, 600)), 0.0, atol=1e-12)
    x = np.linspace(-10, 600, 400_001)
    n = simplex_noise(x)
    assert np.all(np.abs(n) <= 1.0 + 1e-12)
    assert np.abs(n).max() == pytest.approx(1.0, abs=1e-6)


def test_noise_bound_is_reached_by_opposite_gradients():
    # C = 256/81 normalises the cell centre with gradients +1, -1 to exactly 1.
    falloff = (1 - 0.25) ** 4
    assert 256 / 81 * (falloff * 1 * 0.5 + falloff * -1 * -0.5) == pytest.approx(1.0)


def test_noise_has_period_255():
    x = np.linspace(0, 255, 10_001)
    np.testing.assert_allclose(simplex_noise(x + 255), simplex_noise(x), atol=1e-12)
    np.testing.assert_allclose(simplex_noise(x - 510), simplex_noise(x), atol=1e-12)


def test_noise_is_continuous_and_smooth():
    x = np.linspace(0, 20, 200_001)
    n = simplex_noise(x)
    assert np.abs(np.diff(n)).max() < 1e-3  # no jumps at cell borders
    slope = np.diff(n) / np.diff(x)
    assert np.abs(np.diff(slope)).max() < 1e-2  # continuous derivative


def test_frequency_one_over_255_is_one_cell_along_the_scratch():
    # Over t in [0, 1], 255 * f * t spans f * 255 lattice cells: with f = 1/255 exactly
    # one cell, whose ends (integers + offset) are the noise's zero crossings.
    t = np.linspace(0, 1, 1000)
    for offset in range(255):
        deviation = variation_factor(t, 1.0, 1 / 255, offset=float(offset)) - 1
        assert deviation[0] == pytest.approx(0, abs=1e-12) and deviation[-1] == pytest.approx(0, abs=1e-12)
        signs = np.sign(deviation[1:-1])
        signs = signs[signs != 0]
        assert np.count_nonzero(np.diff(signs)) <= 1  # at most one up-and-down: one oscillation
    # f = 0.04 gives about ten cells: count lattice crossings.
    cells = 255 * 0.04
    assert 10 <= cells <= 11


def test_variation_factor_clamps_at_zero_and_amplitude_zero_is_constant():
    t = np.linspace(0, 1, 5001)
    pinched = variation_factor(t, 1.1, 0.04, 17.3)
    assert pinched.min() == 0.0 and pinched.max() > 1.5  # D[1.1, 0.04] touches zero
    # Over many scratches, about a quarter of the noise cells pinch the depth shut.
    t = np.linspace(0, 255, 255 * 64, endpoint=False)
    cells = variation_factor(t / 255, 1.1, 1.0, 0.0).reshape(255, 64)
    assert 0.15 < (cells.min(axis=1) == 0).mean() < 0.35
    np.testing.assert_array_equal(variation_factor(t, 0.0, 0.04, 17.3), 1.0)


def test_offsets_are_in_range_reproducible_and_differ_for_width_and_depth():
    seeds = np.arange(10_000, dtype=np.uint32)
    w, d = noise_offset(seeds, "width"), noise_offset(seeds, "depth")
    assert w.min() >= 0 and w.max() < 255 and d.min() >= 0 and d.max() < 255
    np.testing.assert_array_equal(w, noise_offset(seeds, "width"))
    assert np.corrcoef(w, d)[0, 1] < 0.05
    assert len(np.unique(np.round(w, 6))) > 9_900


def test_width_depth_at_applies_each_scratchs_own_variation():
    scratches = ScratchSet.from_polylines(
        [np.array([[0, 0], [1, 0]])] * 3, width=[1e-6, 2e-6, 3e-6], depth=[100e-9, 200e-9, 300e-9],
        width_variation=[(0, 0), (0.5, 0.02), (0, 0)], depth_variation=[(0, 0), (0, 0), (1.1, 0.04)],
        seed=[1, 2, 3])
    t = np.linspace(0, 1, 101)
    for k in range(3):
        width, depth = width_depth_at(scratches, np.full(101, k), t)
        expected_w = scratches.width[k] * variation_factor(
            t, *scratches.width_variation[k], noise_offset(scratches.seed[k], "width"))
        expected_d = scratches.depth[k] * variation_factor(
            t, *scratches.depth_variation[k], noise_offset(scratches.seed[k], "depth"))
        np.testing.assert_array_equal(width, expected_w)
        np.testing.assert_array_equal(depth, expected_d)
    w0, d0 = width_depth_at(scratches, np.zeros(101, int), t)
    assert np.all(w0 == 1e-6) and np.all(d0 == 100e-9)
    # all three interleaved in one call (the noise runs only where an amplitude is not 0): the same values
    index = np.tile(np.arange(3), 101)
    width, depth = width_depth_at(scratches, index, np.repeat(t, 3))
    for k in range(3):
        np.testing.assert_array_equal(np.stack([width[k::3], depth[k::3]]),
                                      np.stack(width_depth_at(scratches, np.full(101, k), t)))
