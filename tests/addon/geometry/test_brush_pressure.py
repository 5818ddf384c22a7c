"""Pressure maths of the brushes (no bpy): factors, the pen's mean, the spray's thinning."""
import numpy as np

from scratch_iridescence.addon.geometry.brush import (MIN_PRESSURE, pressure_factor, spray_centres,
                                                      spray_centres_with_pressure, stroke_pressure)


def test_factor_is_the_clipped_pressure_where_toggled_else_one():
    pressure = np.array([-1.0, 0.0, 0.5, 1.0, 2.0])
    np.testing.assert_array_equal(pressure_factor(pressure, True), [MIN_PRESSURE, MIN_PRESSURE, 0.5, 1.0, 1.0])
    np.testing.assert_array_equal(pressure_factor(pressure, False), np.ones(5))


def test_pen_pressure_is_the_length_weighted_mean():
    points = [np.array([[0.0, 0, 0], [1, 0, 0], [3, 0, 0]]), np.array([[5.0, 0, 0]])]
    pressure = [np.array([0.0, 1.0, 1.0]), np.array([0.25])]
    # first run: 0.5 over length 1, 1.0 over length 2; the dab counts as one unit of weight
    assert stroke_pressure(points, pressure) == (0.5 + 2.0 + 0.25) / 4.0
    assert stroke_pressure([np.zeros((1, 3))], [np.array([0.3])]) == 0.3


def test_spray_without_density_pressure_places_the_same_centres_and_reports_the_pressure():
    points = [np.column_stack([np.linspace(0, 1, 11), np.zeros(11), np.zeros(11)])]
    normals = [np.tile([0.0, 0.0, 1.0], (11, 1))]
    ramp = [np.linspace(0.0, 1.0, 11)]
    centres, directions = spray_centres(np.random.default_rng(3), points, normals, 0.05, 20.0, 0.1)
    c, d, p = spray_centres_with_pressure(np.random.default_rng(3), points, normals, ramp, 0.05, 20.0, 0.1, False)
    assert np.array_equal(c, centres) and np.array_equal(d, directions)
    # the pressure at the base point: linear along the stroke, the base within the radius of the centre
    assert np.all(np.abs(p - c[:, 0]) <= 0.05 + 1e-12)


def test_spray_density_pressure_thins_to_the_pressure():
    points = [np.column_stack([np.linspace(0, 1, 11), np.zeros(11), np.zeros(11)])]
    normals = [np.tile([0.0, 0.0, 1.0], (11, 1))]
    half = [np.full(11, 0.5)]
    full = spray_centres(np.random.default_rng(4), points, normals, 0.05, 100.0, 0.1)[0]
    thinned, _, p = spray_centres_with_pressure(np.random.default_rng(4), points, normals, half, 0.05, 100.0, 0.1,
                                                True)
    # expected counts 2 100 and 1 050 (Poisson, then a binomial thinning): 5 sigma is about 0.06 of the ratio
    assert abs(len(thinned) / len(full) - 0.5) < 0.06
    assert np.all(p == 0.5)
