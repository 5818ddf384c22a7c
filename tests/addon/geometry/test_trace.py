"""Paths traced on surfaces: geodesic unfolding, boundaries, seams, turns, assembly (no Blender)."""
import numpy as np
import pytest

from meshes import grid, ring, torus
from scratch_iridescence.addon.geometry.surface import Surface
from scratch_iridescence.addon.geometry.trace import (BOUNDARY, EDGE, END, SEAM_IN, SEAM_OUT, START, TURN, assemble, enter_towards,
                                             trace_paths)


def locate(surface, point):
    """(triangle, bary) of a 3D point lying on the surface."""
    for t in range(surface.triangle_count):
        b = surface.barycentric(np.array([t]), np.array([point]))[0]
        on_plane = abs(np.dot(np.asarray(point) - surface.corners[t, 0], surface.normal[t])) < 1e-12
        if on_plane and np.all(b >= -1e-12):
            return t, b
    raise AssertionError(f"{point} is not on the surface")


@pytest.fixture
def ring_surface():
    return Surface.from_arrays(*ring())


def start(surface, point):
    t, b = locate(surface, point)
    return np.array([t]), b[None]


def test01_path_unfolds_over_a_fold_like_a_straight_line(ring_surface):
    # Around the cube's side faces, a geodesic is a straight line of the unrolled strip.
    triangle, bary = start(ring_surface, [0.0, -1.0, -0.5])
    theta = np.radians(30)
    trace = trace_paths(ring_surface, triangle, bary, [[np.cos(theta), 0.0, np.sin(theta)]], [2.0])
    horizontal, rise = 2.0 * np.cos(theta), 2.0 * np.sin(theta)
    expected = [1.0, -1.0 + (horizontal - 1.0), -0.5 + rise]  # one unit on face y=-1, the rest on x=+1
    np.testing.assert_allclose(trace.point[-1], expected, atol=1e-12)
    assert trace.kind[-1] == END and trace.travelled[0] == pytest.approx(2.0)
    assert list(trace.kind) == [START, EDGE, END]  # the fold is a vertex of the polyline


def test02_path_stops_at_the_mesh_boundary(ring_surface):
    triangle, bary = start(ring_surface, [0.0, -1.0, -0.5])
    theta = np.radians(30)
    trace = trace_paths(ring_surface, triangle, bary, [[np.cos(theta), 0.0, np.sin(theta)]], [10.0])
    assert trace.kind[-1] == BOUNDARY
    assert trace.travelled[0] == pytest.approx(1.5 / np.sin(theta))
    assert trace.point[-1][2] == pytest.approx(1.0)


def test03_a_seam_is_recorded_on_both_sides(ring_surface):
    triangle, bary = start(ring_surface, [0.0, -1.0, -0.5])
    trace = trace_paths(ring_surface, triangle, bary, [[-1.0, 0.0, 0.0]], [8.0])  # once around
    out, into = np.flatnonzero(trace.kind == SEAM_OUT), np.flatnonzero(trace.kind == SEAM_IN)
    assert len(out) == len(into) == 1
    np.testing.assert_allclose(trace.point[out[0]], trace.point[into[0]], atol=1e-12)
    np.testing.assert_allclose(trace.point[out[0]], [-1.0, -1.0, -0.5], atol=1e-12)
    assert trace.uv[out[0]][0] == pytest.approx(0.0) and trace.uv[into[0]][0] == pytest.approx(1.0)
    np.testing.assert_allclose(trace.point[-1], [0.0, -1.0, -0.5], atol=1e-12)  # back at the start


def test04_uv_follows_the_surface_not_a_uv_length(ring_surface):
    # U is squeezed (a face is 2 m wide but 0.25 in U): a 1 m horizontal path moves 0.125 in U.
    triangle, bary = start(ring_surface, [-0.5, -1.0, 0.2])
    trace = trace_paths(ring_surface, triangle, bary, [[1.0, 0.0, 0.0]], [1.0])
    np.testing.assert_allclose(trace.uv[-1] - trace.uv[0], [0.125, 0.0], atol=1e-12)


def test05_turns_make_a_regular_polygon():
    surface = Surface.from_arrays(*grid(1, 1, size=(100.0, 100.0)))
    triangle, bary = start(surface, [0.0, 0.1, 0.0])
    trace = trace_paths(surface, triangle, bary, [[1.0, 0.0, 0.0]], [10.0], turn_angle=[0.05], turn_every=[1.0],
                        first_turn=[0.5])
    turns = trace.point[trace.kind == TURN]
    assert len(turns) == 10  # at 0.5, 1.5, ..., 9.5
    steps = np.diff(trace.point, axis=0)
    heading = np.arctan2(steps[:, 1], steps[:, 0])
    np.testing.assert_allclose(np.diff(heading), 0.05, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(np.diff(turns, axis=0), axis=1), 1.0, atol=1e-12)



def test06_every_path_walks_its_full_length_on_a_closed_surface():
    surface = Surface.from_arrays(*torus())
    rng = np.random.default_rng(5)
    triangle, bary = surface.sample_points(rng, 400)
    direction = surface.direction(triangle, rng.uniform(0, 2 * np.pi, 400))
    length = rng.uniform(0.1, 5.0, 400)
    trace = trace_paths(surface, triangle, bary, direction, length)
    np.testing.assert_allclose(trace.travelled, length, rtol=1e-12)
    assert not np.any(trace.kind == BOUNDARY)
    # Every record lies in its triangle's plane, inside it.
    b = surface.barycentric(trace.triangle, trace.point)
    assert b.min() > -1e-9
    offset = np.einsum("ni,ni->n", trace.point - surface.corners[trace.triangle, 0],
                       surface.normal[trace.triangle])
    assert np.abs(offset).max() < 1e-9


def test07_assemble_orders_cuts_and_cleans():
    group = np.array([1, 0, 0, 1, 0, 0, 2])
    order = np.array([0, 3, 1, 1, 2, 4, 0])
    uv = np.array([[0, 0], [3, 0], [1, 0], [1, 1], [1, 0], [4, 0], [9, 9]], dtype=float)
    point = np.column_stack([uv, np.zeros(7)])
    breaks = np.array([False, True, False, False, False, False, False])  # group 0 breaks before order 3
    pieces = assemble(group, order, uv, point, breaks)
    # group 0: orders 1, 2 (duplicate of 1: dropped) | 3, 4 ; group 1: 0, 1 ; group 2: a single vertex (dropped)
    assert pieces.count == 2
    polylines = [pieces.uv[a:b].tolist() for a, b in zip(pieces.offsets[:-1], pieces.offsets[1:])]
    assert polylines == [[[3, 0], [4, 0]], [[0, 0], [1, 1]]]
    assert list(pieces.source) == [0, 1]
    np.testing.assert_allclose(pieces.length, [1.0, np.sqrt(2)])


def test08_assemble_drops_short_pieces():
    uv = np.array([[0, 0], [1e-12, 0], [0, 0], [1, 0]])
    pieces = assemble([0, 0, 1, 1], [0, 1, 0, 1], uv, np.column_stack([uv, np.zeros(4)]),
                      np.zeros(4, dtype=bool), min_length=1e-9)
    assert pieces.count == 1 and list(pieces.source) == [1]


def test_a_start_on_a_fold_begins_in_the_face_the_direction_enters(ring_surface):
    # On the edge x = 1, y = -1 of the ring (faces y = -1 and x = +1 at a right angle), a direction into
    # face x = +1 has no component in face y = -1's plane: traced from there it would not move.
    on_edge = np.array([1.0, -1.0, 0.2])
    into_x_face = np.array([[0.0, 1.0, 0.0]])
    def holds(t, b):
        return np.all(b >= -1e-12) and abs(np.dot(on_edge - ring_surface.corners[t, 0], ring_surface.normal[t])) < 1e-12

    starts = [(t, b) for t in range(ring_surface.triangle_count)
              for b in [ring_surface.barycentric(np.array([t]), on_edge[None])[0]] if holds(t, b)]
    assert len(starts) == 2  # the point lies in one triangle of each face
    for t, b in starts:
        triangle, bary = enter_towards(ring_surface, np.array([t]), np.maximum(b, 0)[None], into_x_face)
        assert ring_surface.normal[triangle[0]] == pytest.approx([1.0, 0.0, 0.0])
        np.testing.assert_allclose(ring_surface.point(triangle, bary)[0], on_edge, atol=1e-12)
        trace = trace_paths(ring_surface, triangle, bary, into_x_face, [0.5])
        np.testing.assert_allclose(trace.point[-1], [1.0, -0.5, 0.2], atol=1e-12)
    # A point inside a face, or a direction its own face can take, keeps its triangle.
    t, b = locate(ring_surface, [0.5, -1.0, 0.2])
    assert enter_towards(ring_surface, np.array([t]), b[None], into_x_face)[0][0] == t
    t, b = starts[0]
    along_edge = np.array([[0.0, 0.0, 1.0]])
    assert enter_towards(ring_surface, np.array([t]), np.maximum(b, 0)[None], along_edge)[0][0] == t
