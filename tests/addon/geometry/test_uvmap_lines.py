"""UV → surface mapping and the overlay's line data (no Blender needed)."""
import numpy as np
import pytest

from meshes import grid, ring, torus
from scratch_iridescence.addon.geometry.lines import COLOUR_MAP, line_colours, overlay_arrays, scratch_lines
from scratch_iridescence.addon.geometry.scatter import Looks, ScatterSpec, scatter
from scratch_iridescence.addon.geometry.surface import Surface
from scratch_iridescence.addon.geometry.uvmap import UVLocator
from scratch_iridescence.mitsuba_bridge.scratch import ScratchSet, Uniform, subdivide


def brute_force(triangle_uv, points):
    """First triangle (lowest index) containing each point, by testing all of them."""
    result = np.full(len(points), -1)
    for t in range(len(triangle_uv) - 1, -1, -1):
        a, b, c = triangle_uv[t]
        m = np.column_stack([b - a, c - a])
        if abs(np.linalg.det(m)) < 1e-300:
            continue
        b12 = np.linalg.solve(m, (points - a).T).T
        inside = (b12 >= -1e-9).all(axis=1) & (b12.sum(axis=1) <= 1 + 1e-9)
        result[inside] = t
    return result


def test01_locate_finds_the_containing_triangle():
    positions, triangles, uv = grid(7, 5)
    rng = np.random.default_rng(0)
    locator = UVLocator(uv)
    points = rng.uniform(-0.2, 1.2, (5000, 2))
    triangle, bary = locator.locate(points)
    expected = brute_force(uv, points)
    inside = expected >= 0
    assert np.array_equal(triangle >= 0, inside)
    # Where two triangles share an edge either is right: check containment instead of equality.
    back = np.einsum("nk,nki->ni", bary[inside], uv[triangle[inside]])
    np.testing.assert_allclose(back, points[inside], atol=1e-12)
    assert bary[inside].min() >= -1e-7


def test02_locate_on_an_irregular_mesh_and_its_corners():
    positions, triangles, uv = torus(13, 9)
    locator = UVLocator(uv)
    corners = uv.reshape(-1, 2)
    triangle, _ = locator.locate(corners)
    assert np.all(triangle >= 0)
    points = np.random.default_rng(1).uniform(0, 1, (3000, 2))
    triangle, bary = locator.locate(points)
    assert np.all(triangle >= 0)
    np.testing.assert_allclose(np.einsum("nk,nki->ni", bary, uv[triangle]), points, atol=1e-12)


def test03_degenerate_and_empty_inputs():
    uv = np.zeros((2, 3, 2))
    assert np.all(UVLocator(uv).locate([[0.0, 0.0]])[0] == -1)
    _, _, good = grid(1, 1)
    assert len(UVLocator(good).locate(np.zeros((0, 2)))[0]) == 0


@pytest.fixture
def ring_scratches():
    surface = Surface.from_arrays(*ring())
    looks = Looks(width=Uniform(1e-6, 3e-6), depth=Uniform(1e-7, 5e-7), depth_variation=(1.1, 0.04))
    placed = scatter(surface, ScatterSpec(count=400, length_min=0.5, length_max=2.0, looks=looks),
                     np.random.default_rng(2))
    return surface, placed


def test04_lines_lie_on_the_path_that_was_traced(ring_scratches):
    surface, placed = ring_scratches
    lines = scratch_lines(placed.scratches, UVLocator(surface.uv), surface.corners)
    assert lines.unplaced == 0
    segments = subdivide(placed.scratches, max_length=UVLocator(surface.uv).cell_size)
    assert len(lines) == len(segments)
    # Each piece end lies on the traced polyline of its scratch (the overlay shows the real path).
    s = placed.scratches
    for i in np.random.default_rng(3).choice(s.count, 40, replace=False):
        path = placed.point[s.offsets[i]:s.offsets[i + 1]]
        for end in np.vstack([lines.a[lines.scratch == i], lines.b[lines.scratch == i]]):
            assert _distance_to_polyline(end, path) < 1e-9
    np.testing.assert_array_equal(lines.depth, segments.depth)
    np.testing.assert_array_equal(lines.width, segments.width)


def test05_lines_are_lifted_along_the_normals(ring_scratches):
    surface, placed = ring_scratches
    locator = UVLocator(surface.uv)
    flat = scratch_lines(placed.scratches, locator, surface.corners)
    lifted = scratch_lines(placed.scratches, locator, surface.corners, surface.normal, offset=0.01)
    np.testing.assert_allclose(np.linalg.norm(lifted.a - flat.a, axis=1), 0.01)


def test06_scratches_outside_the_uv_map_are_counted_not_drawn():
    _, _, uv = grid(1, 1, uv_size=(0.5, 0.5))
    scratches = ScratchSet.from_polylines([np.array([[0.1, 0.1], [0.2, 0.2]]), np.array([[0.8, 0.8], [0.9, 0.9]])],
                                          width=1e-6, depth=1e-7)
    positions, triangles, _ = grid(1, 1)
    lines = scratch_lines(scratches, UVLocator(uv), positions[triangles])
    assert lines.unplaced == 1 and set(lines.scratch) == {0}
    assert len(scratch_lines(ScratchSet.empty(), UVLocator(uv), positions[triangles])) == 0


def test07_colours_run_along_the_ramp():
    colours = line_colours([1.0, 2.0, 3.0])
    np.testing.assert_allclose(colours[0, :3], COLOUR_MAP[0], atol=1e-6)
    np.testing.assert_allclose(colours[-1, :3], COLOUR_MAP[-1], atol=1e-6)
    np.testing.assert_allclose(colours[1, :3], COLOUR_MAP[2], atol=1e-6)
    assert colours.dtype == np.float32 and np.all(colours[:, 3] == 1)
    np.testing.assert_allclose(line_colours([5.0, 5.0])[:, :3], [COLOUR_MAP[2]] * 2, atol=1e-6)
    clipped = line_colours([0.0, 10.0], 2.0, 4.0)
    np.testing.assert_allclose(clipped[:, :3], COLOUR_MAP[[0, -1]], atol=1e-6)


def test08_overlay_arrays_interleave_ends_and_colour_by_choice(ring_scratches):
    surface, placed = ring_scratches
    lines = scratch_lines(placed.scratches, UVLocator(surface.uv), surface.corners)
    positions, colours, value_range = overlay_arrays(lines, "WIDTH")
    assert positions.shape == (2 * len(lines), 3) and positions.dtype == np.float32
    np.testing.assert_allclose(positions[0::2], lines.a, rtol=1e-6)
    np.testing.assert_allclose(positions[1::2], lines.b, rtol=1e-6)
    assert value_range == (lines.width.min(), lines.width.max())
    assert np.array_equal(colours[0::2], colours[1::2])
    widest = np.argmax(lines.width)
    np.testing.assert_allclose(colours[2 * widest, :3], COLOUR_MAP[-1], atol=1e-6)
    _, by_depth, depth_range = overlay_arrays(lines, "DEPTH")
    assert depth_range == (lines.depth.min(), lines.depth.max()) and not np.array_equal(by_depth, colours)


def _distance_to_polyline(point, path):
    a, b = path[:-1], path[1:]
    ab = b - a
    t = np.clip(np.einsum("ni,ni->n", point - a, ab) / np.maximum(np.einsum("ni,ni->n", ab, ab), 1e-300), 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - point, axis=1).min()


def test09_removing_scratches_keeps_the_other_lines(ring_scratches):
    surface, placed = ring_scratches
    locator = UVLocator(surface.uv)
    lines = scratch_lines(placed.scratches, locator, surface.corners)
    removed = np.random.default_rng(4).uniform(size=placed.scratches.count) < 0.3
    direct = scratch_lines(placed.scratches.select(~removed), locator, surface.corners)
    filtered = lines.without(removed)
    np.testing.assert_array_equal(filtered.scratch, direct.scratch)
    for name in ("a", "b", "width", "depth"):  # equal up to the rounding of the noise's arc parameter
        np.testing.assert_allclose(getattr(filtered, name), getattr(direct, name), rtol=1e-9, atol=0)
