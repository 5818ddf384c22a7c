"""Eraser hit test, unit formatting.  (That the helpers need no Blender: tests/test_layout.py.)"""
import numpy as np
import pytest

from scratch_iridescence.addon.geometry.erase import cut_scratches, densify, near_stroke, touched_scratches
from scratch_iridescence.addon.geometry.units import format_length


def brute_force(a, b, scratch, stroke, radius, count):
    """Exact segment–segment distances between every scratch piece and every stroke segment."""
    hit = np.zeros(count, dtype=bool)
    s0, s1 = stroke[:-1], stroke[1:]
    ts = np.linspace(0, 1, 401)
    for i in range(len(a)):
        # Dense sampling of the piece against exact point-to-segment distances of the stroke.
        points = a[i] + ts[:, None] * (b[i] - a[i])
        d = s1 - s0
        t = np.clip(np.einsum("pki,ki->pk", points[:, None, :] - s0[None], d) / np.einsum("ki,ki->k", d, d), 0, 1)
        closest = s0[None] + t[..., None] * d[None]
        if np.linalg.norm(points[:, None, :] - closest, axis=2).min() <= radius:
            hit[scratch[i]] = True
    return hit


def test01_eraser_touches_what_lies_within_the_radius():
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 1, (400, 3)) * [1, 1, 0]
    b = a + rng.normal(0, 0.05, (400, 3)) * [1, 1, 0]
    scratch = np.repeat(np.arange(200), 2)
    stroke = np.column_stack([np.linspace(0.1, 0.9, 9), 0.5 + 0.2 * np.sin(np.linspace(0, 3, 9)), np.zeros(9)])
    radius = 0.04
    expected = brute_force(a, b, scratch, stroke, radius, 200)
    got = touched_scratches(a, b, scratch, [stroke], radius, 200)
    # Differences only where a piece grazes the tube within the sampling tolerance.
    disagree = np.flatnonzero(got != expected)
    looser = brute_force(a, b, scratch, stroke, radius * (1 + 1 / 64), 200)
    tighter = brute_force(a, b, scratch, stroke, radius * (1 - 1 / 64), 200)
    assert np.all(looser[disagree] & ~tighter[disagree])
    assert 0 < expected.sum() < 200


def test02_eraser_edge_cases():
    a = np.array([[0.0, 0.0, 0.0]])
    b = np.array([[1.0, 0.0, 0.0]])
    far = [np.array([[0.5, 1.0, 0.0], [0.6, 1.0, 0.0]])]
    assert not touched_scratches(a, b, [0], far, 0.5, 1).any()
    assert touched_scratches(a, b, [0], far, 1.0, 1).all()
    assert touched_scratches(a, b, [0], [np.array([[0.5, 0.2, 0.0]])], 0.3, 1).all()  # a single dab
    assert not touched_scratches(np.zeros((0, 3)), np.zeros((0, 3)), [], far, 1.0, 0).any()


def test03_densify_spacing_and_ends():
    points = np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 2.0, 0]])
    dense = densify(points, 0.3)
    assert np.linalg.norm(np.diff(dense, axis=0), axis=1).max() <= 0.3 + 1e-12
    np.testing.assert_allclose(dense[[0, -1]], points[[0, -1]])
    assert any(np.allclose(p, points[1]) for p in dense)


@pytest.mark.parametrize("metres, text", [
    (250e-9, "250 nm"), (4e-6, "4 µm"), (1.3e-6, "1.3 µm"), (999.9e-9, "1 µm"), (0.0123, "12.3 mm"),
    (2.0, "2 m"), (0.0, "0 m"), (5e-12, "0.005 nm"),
])
def test04_lengths_read_naturally(metres, text):
    assert format_length(metres) == text


def test07_near_stroke_matches_exact_distances():
    rng = np.random.default_rng(5)
    points = rng.uniform(0, 1, (3000, 3)) * [1, 1, 0.1]
    runs = [np.array([[0.1, 0.1, 0.0], [0.9, 0.8, 0.05]]), np.array([[0.5, 0.2, 0.0]])]
    near = near_stroke(points, runs, 0.1)
    a, b = runs[0]
    t = np.clip((points - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
    distance = np.minimum(np.linalg.norm(a + t[:, None] * (b - a) - points, axis=1),
                          np.linalg.norm(points - runs[1][0], axis=1))
    assert np.array_equal(near, distance <= 0.1)


def test08_cut_keeps_the_parts_outside_the_brush():
    from scratch_iridescence.mitsuba_bridge.scratch import ScratchSet

    scratches = ScratchSet.from_polylines([np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]),
                                           np.array([[0.0, 0.9], [1.0, 0.9]])],
                                          width=[1e-6, 2e-6], depth=1e-7, width_variation=(0.5, 0.02))
    to_surface = lambda uv: (np.column_stack([uv, np.zeros(len(uv))]), np.ones(len(uv), bool))  # noqa: E731
    stroke = [np.array([[0.3, -1.0, 0.0], [0.3, 0.5, 0.0]])]
    result, touched = cut_scratches(scratches, to_surface, stroke, 0.1)
    assert list(touched) == [True, False]
    assert result.count == 3 and result.select([0]) == scratches.select([1])
    left, right = result.polyline(1), result.polyline(2)
    assert left[0, 0] == 0.0 and 0.175 <= left[-1, 0] <= 0.2 + 1e-12
    assert right.tolist()[-2:] == [[0.5, 0.0], [1.0, 0.0]] and 0.4 - 1e-12 <= right[0, 0] <= 0.425  # vertices kept
    np.testing.assert_allclose(result.width_variation[1:, 1].sum(), 0.02 * 0.8, atol=0.02 * 0.05)
    untouched, none = cut_scratches(scratches, to_surface, [np.array([[5.0, 5.0, 0.0]])], 0.1)
    assert untouched is scratches and not none.any()
