"""Tablet pressure replayed from the ``stroke`` collection: per-setting toggles scale width, depth, density."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from strokes import stroke  # noqa: E402
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.addon.geometry.brush import MIN_PRESSURE  # noqa: E402

LOOKS = dict(width_distribution="UNIFORM", width_min=2.0, width_max=6.0,
             depth_distribution="UNIFORM", depth_min=200.0, depth_max=300.0)


def paint(points, pressure=None, **kwargs):
    kwargs.setdefault("seed", 1)
    for name in ("use_pressure_width", "use_pressure_depth", "use_pressure_density"):
        kwargs.setdefault(name, False)  # operators remember their last settings
    result = bpy.ops.scratch.paint_stroke("EXEC_DEFAULT", True, stroke=stroke(points, pressure=pressure),
                                          **LOOKS, **kwargs)
    assert result == {"FINISHED"}
    scratches = storage.read_scratches(bpy.context.active_object)
    storage.clear_scratches(bpy.context.active_object)
    return scratches


def line(count=9):
    return np.column_stack([np.linspace(-0.8, 0.8, count), np.zeros(count), np.zeros(count)])


def test_pen_width_and_depth_follow_the_strokes_mean_pressure_only_where_toggled(plane):
    points = line()
    ramp = np.linspace(0.2, 1.0, len(points))  # evenly spaced points: the length-weighted mean is 0.6
    free = paint(points)
    assert np.array_equal(paint(points, ramp).width, free.width)  # toggles off: the pressure is ignored
    both = paint(points, ramp, use_pressure_width=True, use_pressure_depth=True)
    # pressures are float32 in the collection: equal to float32 accuracy
    np.testing.assert_allclose(both.width, 0.6 * free.width, rtol=1e-6)
    np.testing.assert_allclose(both.depth, 0.6 * free.depth, rtol=1e-6)
    width_only = paint(points, ramp, use_pressure_width=True)
    assert np.array_equal(width_only.depth, free.depth)
    light = paint(points, np.zeros(len(points)), use_pressure_width=True)  # a pen lifted to 0 still scratches
    np.testing.assert_allclose(light.width, MIN_PRESSURE * free.width, rtol=1e-6)


def spray_halves(pressure, **kwargs):
    scratches = paint(line(33), pressure, brush_mode="SPRAY", radius=0.1, density=40.0, length_min=0.02,
                      length_max=0.04, **kwargs)
    middle = np.add.reduceat(2 * scratches.uv[:, 0] - 1, scratches.offsets[:-1]) / scratches.vertex_counts
    return scratches, middle


def test_spray_width_follows_the_pressure_at_each_scratch(plane):
    ramp = np.linspace(0.1, 1.0, 33)
    pressed, x = spray_halves(ramp, use_pressure_width=True)
    free, x_free = spray_halves(ramp)
    assert np.array_equal(x, x_free)  # the same centres: only the widths change
    factor = pressed.width / free.width
    # the pressure at the scratch's base point on the stroke; its centre lies within the radius of it
    expected = np.interp(x, np.linspace(-0.8, 0.8, 33), ramp)
    slope = 0.9 / 1.6
    assert np.all(np.abs(factor - expected) <= slope * (0.1 + 0.02) + 1e-9)
    assert np.array_equal(pressed.depth, free.depth)


def test_spray_density_follows_the_pressure_along_the_stroke(plane):
    ramp = np.linspace(0.1, 1.0, 33)
    # expected counts left/right of the middle: mean pressure 0.325 vs 0.775, ratio 0.42; with ~110 and
    # ~260 scratches its standard deviation is ~0.05: 4 sigma either side
    _, x = spray_halves(ramp, use_pressure_density=True)
    ratio = np.count_nonzero(x < 0) / np.count_nonzero(x > 0)
    assert 0.22 < ratio < 0.62, ratio
    _, x = spray_halves(ramp)  # toggle off: even, ratio 1 (sd ~0.08 with ~340 a side)
    ratio = np.count_nonzero(x < 0) / np.count_nonzero(x > 0)
    assert 0.7 < ratio < 1.4, ratio

