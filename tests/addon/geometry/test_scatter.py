"""Generator, spray and pen on numpy meshes: statistics against the requested distributions (no Blender)."""
import numpy as np
import pytest
from scipy import stats

from meshes import grid, ring, torus, unequal_quads
from scratch_iridescence.addon.geometry.brush import pen_scratches, spray_centres
from scratch_iridescence.addon.geometry.scatter import (MAX_SEGMENTS, SAGITTA_FRACTION, Looks, ScatterSpec,
                                                        estimate_bytes, scatter, scratches_from_centres)
from scratch_iridescence.addon.geometry.surface import Surface
from scratch_iridescence.addon.geometry.uvmap import UVLocator
from scratch_iridescence.mitsuba_bridge.scratch import Constant, Gaussian, Profile, Uniform

P_MIN = 1e-3  # fixed seeds: these p-values are deterministic; the threshold only guards against bad luck
LOOKS = Looks(width=Constant(2e-6), depth=Constant(300e-9))


def first_last(placed):
    offsets = placed.scratches.offsets
    return placed.point[offsets[:-1]], placed.point[offsets[1:] - 1]


def spec(count, **kwargs):
    kwargs.setdefault("looks", LOOKS)
    kwargs.setdefault("length_min", 0.01)
    kwargs.setdefault("length_max", 0.02)
    return ScatterSpec(count=count, **kwargs)


def test01_same_seed_same_scratches_other_seed_others():
    surface = Surface.from_arrays(*torus())
    a = scatter(surface, spec(300, length_min=0.5, length_max=1.0), np.random.default_rng(7)).scratches
    b = scatter(surface, spec(300, length_min=0.5, length_max=1.0), np.random.default_rng(7)).scratches
    c = scatter(surface, spec(300, length_min=0.5, length_max=1.0), np.random.default_rng(8)).scratches
    assert a == b and not a == c


def test02_scratches_are_uniform_per_surface_area():
    surface = Surface.from_arrays(*unequal_quads())  # 3D areas 1 : 3, equal UV areas
    placed = scatter(surface, spec(20000, length_min=0.001, length_max=0.002), np.random.default_rng(1))
    first, last = first_last(placed)
    in_small_quad = 0.5 * (first[:, 0] + last[:, 0]) < 1.0
    counts = np.array([in_small_quad.sum(), (~in_small_quad).sum()])
    assert stats.chisquare(counts, counts.sum() * np.array([0.25, 0.75])).pvalue > P_MIN
    assert stats.chisquare(counts, counts.sum() * np.array([0.5, 0.5])).pvalue < 1e-6  # UV-uniform is rejected


def test03_lengths_on_the_surface_follow_the_requested_uniform_distribution():
    surface = Surface.from_arrays(*torus())  # closed: no scratch is cut short
    placed = scatter(surface, spec(3000, length_min=0.5, length_max=1.5), np.random.default_rng(2))
    total = np.bincount(placed.source, weights=placed.piece_length, minlength=3000)
    assert stats.kstest(total, "uniform", args=(0.5, 1.0)).pvalue > P_MIN
    assert stats.kstest(total, "uniform", args=(0.5, 1.1)).pvalue < P_MIN  # a 10 % error would show


def test04_centred_scratches_have_exactly_the_requested_length():
    surface = Surface.from_arrays(*torus())
    rng = np.random.default_rng(3)
    triangle, bary = surface.sample_points(rng, 200)
    length = rng.uniform(0.2, 4.0, 200)
    placed = scratches_from_centres(surface, triangle, bary, surface.direction(triangle, rng.uniform(0, 6, 200)),
                                    length, LOOKS.sample(rng, 200))
    total = np.bincount(placed.source, weights=placed.piece_length, minlength=200)
    np.testing.assert_allclose(total, length, rtol=1e-9)


@pytest.mark.parametrize("uv_size", [(1.0, 1.0), (1.0, 0.25)])
def test05_fixed_orientation_is_uniform_within_the_spread_in_tangent_space(uv_size):
    surface = Surface.from_arrays(*grid(1, 1, size=(100.0, 100.0), uv_size=uv_size))
    angle, spread = np.radians(40), np.radians(10)
    placed = scatter(surface, spec(3000, length_min=0.5, length_max=1.0, angle=angle, angle_spread=spread),
                     np.random.default_rng(4))
    first, last = first_last(placed)
    heading = np.arctan2(*(last - first)[:, 1::-1].T)
    assert stats.kstest(heading, "uniform", args=(angle - spread, 2 * spread)).pvalue > P_MIN
    uv = placed.scratches.uv
    offsets = placed.scratches.offsets
    uv_heading = np.arctan2(*(uv[offsets[1:] - 1] - uv[offsets[:-1]])[:, 1::-1].T)
    if uv_size[1] != uv_size[0]:  # in UV the angles are distorted: the tangent frame is what counts
        assert stats.kstest(uv_heading, "uniform", args=(angle - spread, 2 * spread)).pvalue < 1e-6


def test06_random_orientation_is_uniform():
    surface = Surface.from_arrays(*grid(1, 1, size=(100.0, 100.0), uv_size=(1.0, 0.3)))
    placed = scatter(surface, spec(3000, length_min=0.5, length_max=1.0), np.random.default_rng(5))
    first, last = first_last(placed)
    heading = np.mod(np.arctan2(*(last - first)[:, 1::-1].T), np.pi)  # a scratch has no head or tail
    assert stats.kstest(heading, "uniform", args=(0.0, np.pi)).pvalue > P_MIN


@pytest.mark.parametrize("what", ["width", "depth"])
def test07_widths_and_depths_follow_uniform_and_gaussian(what):
    surface = Surface.from_arrays(*grid(1, 1, size=(100.0, 100.0)))
    uniform, gaussian = Uniform(1e-7, 6e-6), Gaussian(250e-9, 80e-9)
    for distribution, reference in (
            (uniform, stats.uniform(1e-7, 6e-6 - 1e-7)),
            (gaussian, stats.truncnorm(-250 / 80, np.inf, loc=250e-9, scale=80e-9))):
        looks = Looks(width=distribution if what == "width" else Constant(1e-6),
                      depth=distribution if what == "depth" else Constant(1e-7))
        placed = scatter(surface, spec(3000, looks=looks), np.random.default_rng(6))
        values = getattr(placed.scratches, what)
        assert placed.scratches.count == 3000
        assert stats.kstest(values, reference.cdf).pvalue > P_MIN
        shifted = stats.norm(260e-9, 80e-9) if distribution is gaussian else stats.uniform(1e-7, 5e-6)
        assert stats.kstest(values, shifted.cdf).pvalue < P_MIN


def test08_profile_and_variation_reach_every_scratch():
    looks = Looks(width=Constant(1e-6), depth=Constant(1e-7), profile=Profile.TRIANGULAR,
                  width_variation=(0.5, 0.02), depth_variation=(1.1, 0.04))
    placed = scatter(Surface.from_arrays(*grid(1, 1, size=(100.0, 100.0))), spec(500, looks=looks),
                     np.random.default_rng(7))
    s = placed.scratches
    assert np.all(s.profile == Profile.TRIANGULAR)
    np.testing.assert_allclose(s.depth_variation, np.tile([1.1, 0.04], (500, 1)))
    np.testing.assert_allclose(s.width_variation, np.tile([0.5, 0.02], (500, 1)))
    assert len(np.unique(s.seed)) == 500


def test09_seams_cut_scratches_into_pieces_that_stay_in_uv():
    surface = Surface.from_arrays(*torus())
    looks = Looks(width=Constant(1e-6), depth=Constant(1e-7), depth_variation=(1.0, 0.05))
    placed = scatter(surface, spec(2000, length_min=1.0, length_max=3.0, looks=looks), np.random.default_rng(8))
    s = placed.scratches
    assert s.count > 2000  # torus seams cut some scratches
    # No piece jumps across the seam: UV steps stay small.
    step = np.linalg.norm(np.diff(s.uv, axis=0), axis=1)
    inside = np.ones(len(step), dtype=bool)
    inside[s.offsets[1:-1] - 1] = False
    assert step[inside].max() < 0.25
    # Every vertex maps back through UV to where it was traced.
    triangle, bary = UVLocator(surface.uv).locate(s.uv)
    assert np.all(triangle >= 0)
    np.testing.assert_allclose(surface.point(triangle, bary), placed.point, atol=1e-9)
    # Pieces share their scratch's noise: frequencies scale with the piece's share of the length.
    total = np.bincount(placed.source, weights=s.depth_variation[:, 1])
    np.testing.assert_allclose(total[np.unique(placed.source)], 0.05, rtol=1e-9)
    assert len(np.unique(s.seed)) == s.count


def test10_arcs_turn_by_their_bend_with_a_small_sagitta():
    surface = Surface.from_arrays(*grid(1, 1, size=(10.0, 10.0)))
    rng = np.random.default_rng(9)
    count = 50
    triangle, bary = surface.sample_points(rng, count)
    triangle[:], bary[:] = 0, [0.3, 0.3, 0.4]
    bend = rng.uniform(-1.0, 1.0, count)
    length = rng.uniform(1e-3, 5e-3, count)  # metres, unit scale 1
    params = Looks(width=Uniform(1e-6, 5e-6), depth=Constant(1e-7)).sample(rng, count)
    placed = scratches_from_centres(surface, triangle, bary, surface.direction(triangle, np.zeros(count)),
                                    length, params, bend=bend)
    s = placed.scratches
    assert s.count == count
    for i in range(count):
        points = placed.point[s.offsets[i]:s.offsets[i + 1]]
        steps = np.diff(points, axis=0)
        heading = np.unwrap(np.arctan2(steps[:, 1], steps[:, 0]))
        segments = len(steps)
        assert segments <= MAX_SEGMENTS + 1
        assert abs((heading[-1] - heading[0]) - bend[i]) <= abs(bend[i]) / max(segments - 1, 1) + 1e-9
        curvature = abs(bend[i]) / length[i]
        longest = np.linalg.norm(steps, axis=1).max()
        assert longest ** 2 * curvature / 8 <= SAGITTA_FRACTION * s.width[i] * (1 + 1e-6)


def test11_pen_follows_the_hits_and_splits_at_the_seam():
    surface = Surface.from_arrays(*ring())
    # A horizontal stroke at z = 0.2 from face x = -1 across the seam corner (-1, -1) onto face y = -1.
    points = np.array([[-1.0, y, 0.2] for y in (-0.5, -0.8)] + [[x, -1.0, 0.2] for x in (-0.7, -0.4, -0.1)])
    hits = [_locate(surface, p) for p in points]
    triangle = np.array([h[0] for h in hits])
    bary = np.array([h[1] for h in hits])
    params = LOOKS.sample(np.random.default_rng(0), 1)
    placed = pen_scratches(surface, [(triangle, bary)], params)
    s = placed.scratches
    assert s.count == 2
    first, second = placed.point[:s.offsets[1]], placed.point[s.offsets[1]:]
    np.testing.assert_allclose(first[-1], [-1.0, -1.0, 0.2], atol=1e-12)
    np.testing.assert_allclose(second[0], [-1.0, -1.0, 0.2], atol=1e-12)
    assert s.uv[s.offsets[1] - 1][0] == pytest.approx(1.0) and s.uv[s.offsets[1]][0] == pytest.approx(0.0)
    for p in points:  # every stroke point is on the painted path
        assert min(np.linalg.norm(placed.point - p, axis=1)) < 1e-12
    assert np.all(s.width == params["width"][0]) and len(set(s.seed)) == 2


def test12_pen_runs_are_separate_and_single_points_paint_nothing():
    surface = Surface.from_arrays(*grid(4, 4, size=(2.0, 2.0)))
    line = [_locate(surface, [x, 0.1, 0.0]) for x in np.linspace(-0.9, 0.9, 7)]
    t = np.array([h[0] for h in line])
    b = np.array([h[1] for h in line])
    params = LOOKS.sample(np.random.default_rng(0), 1)
    placed = pen_scratches(surface, [(t[:3], b[:3]), (t[4:], b[4:]), (t[3:4], b[3:4])], params)
    assert placed.scratches.count == 2
    assert pen_scratches(surface, [(t[:1], b[:1])], params).scratches.count == 0


def test13_spray_scatters_around_the_stroke():
    rng = np.random.default_rng(11)
    stroke = np.column_stack([np.linspace(0, 1, 50), np.zeros(50), np.zeros(50)])
    normal = np.tile([0.0, 0.0, 1.0], (50, 1))
    radius, density, jitter = 0.05, 4.0, np.radians(20)
    counts = [len(spray_centres(rng, [stroke], [normal], radius, density, jitter)[0]) for _ in range(200)]
    expected = density * (1.0 / radius + 1)
    assert abs(np.mean(counts) - expected) < 4 * np.sqrt(expected / 200)
    centres, directions = spray_centres(rng, [stroke], [normal], radius, density, jitter)
    assert np.all(np.abs(centres[:, 1]) <= radius) and np.all(centres[:, 2] == 0)
    assert np.all(centres[:, 0] >= -radius) and np.all(centres[:, 0] <= 1 + radius)
    angle = np.arctan2(directions[:, 1], directions[:, 0])
    assert np.all(np.abs(angle) <= jitter + 1e-12)
    dab, dab_directions = spray_centres(rng, [stroke[:1]], [normal[:1]], radius, 50.0, jitter)
    assert np.all(np.linalg.norm(dab - stroke[0], axis=1) <= radius) and not dab_directions.any()


def test14_memory_estimate_grows_with_the_request():
    assert estimate_bytes(300_000) < 2**30 < estimate_bytes(2**31 - 1)


def _locate(surface, point):
    point = np.asarray(point, dtype=float)
    for t in range(surface.triangle_count):
        b = surface.barycentric(np.array([t]), point[None])[0]
        if np.all(b >= -1e-12) and abs(np.dot(point - surface.corners[t, 0], surface.normal[t])) < 1e-12:
            return t, b
    raise AssertionError(point)


def test_scratches_centred_exactly_on_a_fold_keep_their_length():
    # Sprayed centres snapped onto an edge lie on it exactly; the triangle they were found in may be on
    # the side whose plane does not hold the direction (it then has no component there).  Each must
    # still give its full length, on both sides of the fold, continuous in UV on either side.
    surface = Surface.from_arrays(*ring())  # the cube's side faces; x = 1, y = -1 is a right-angle fold
    heights = np.linspace(-0.8, 0.8, 9)
    points = np.column_stack([np.ones(9), -np.ones(9), heights])
    found = []
    for p in points:  # the point in a triangle of each face
        for t in range(surface.triangle_count):
            b = surface.barycentric(np.array([t]), p[None])[0]
            if np.all(b >= -1e-12) and abs(np.dot(p - surface.corners[t, 0], surface.normal[t])) < 1e-12:
                found.append((t, np.maximum(b, 0.0)))
    triangle = np.array([t for t, _ in found])
    bary = np.array([b for _, b in found])
    normal = surface.normal[triangle]
    # Directions lying in the *other* face's plane, across the fold: (0, 1, 0) on face x = 1, (-1, 0, 0) on y = -1.
    direction = np.where(np.abs(normal[:, [0]]) > 0.5, [[-1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    count = len(triangle)
    length = np.full(count, 1.0)
    params = LOOKS.sample(np.random.default_rng(0), count)
    placed = scratches_from_centres(surface, triangle, bary, direction, length, params)
    assert set(placed.source) == set(range(count))
    np.testing.assert_allclose(np.bincount(placed.source, weights=placed.piece_length), 1.0, rtol=1e-9)
    s = placed.scratches
    tri, b = UVLocator(surface.uv).locate(s.uv)
    assert np.all(tri >= 0)
    np.testing.assert_allclose(surface.point(tri, b), placed.point, atol=1e-9)  # UV maps back onto the path
