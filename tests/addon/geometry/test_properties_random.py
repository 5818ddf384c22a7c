"""Property-based checks of the tracer, the assembly and the UV locator on random bumpy meshes."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from meshes import grid
from scratch_iridescence.addon.geometry.scatter import Looks, ScatterSpec, scatter
from scratch_iridescence.addon.geometry.surface import Surface
from scratch_iridescence.addon.geometry.trace import BOUNDARY, trace_paths
from scratch_iridescence.addon.geometry.uvmap import UVLocator
from scratch_iridescence.mitsuba_bridge.scratch import Constant


def bumpy(seed: int, n: int, amplitude: float):
    """A grid with random heights and a jittered (still valid) UV layout."""
    positions, triangles, uv = grid(n, n, size=(2.0, 2.0))
    rng = np.random.default_rng(seed)
    positions = positions.copy()
    positions[:, 2] = amplitude * rng.normal(size=len(positions))
    vertex_uv = (positions[:, :2] + 1.0) / 2.0 + rng.uniform(-0.2, 0.2, (len(positions), 2)) / n
    return positions, triangles, vertex_uv[triangles]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 6), amplitude=st.floats(0.0, 0.5),
       length=st.floats(0.01, 5.0))
def test_paths_stay_on_the_surface_and_walk_their_length(seed, n, amplitude, length):
    surface = Surface.from_arrays(*bumpy(seed, n, amplitude))
    rng = np.random.default_rng(seed)
    triangle, bary = surface.sample_points(rng, 50)
    direction = surface.direction(triangle, rng.uniform(0, 2 * np.pi, 50))
    trace = trace_paths(surface, triangle, bary, direction, np.full(50, length))
    assert np.all(trace.travelled <= length * (1 + 1e-9))
    stopped = np.zeros(50, dtype=bool)
    stopped[trace.path[trace.kind == BOUNDARY]] = True
    np.testing.assert_allclose(trace.travelled[~stopped], length, rtol=1e-9)
    b = surface.barycentric(trace.triangle, trace.point)
    assert b.min() > -1e-7
    # A stopped path ends on the mesh boundary.
    ends = trace.point[np.isin(trace.kind, [BOUNDARY])]
    assert np.all(np.isclose(np.abs(ends[:, :2]), 1.0, atol=1e-9).any(axis=1))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 5), amplitude=st.floats(0.0, 0.5))
def test_generated_scratches_map_back_to_where_they_were_traced(seed, n, amplitude):
    surface = Surface.from_arrays(*bumpy(seed, n, amplitude))
    looks = Looks(width=Constant(1e-6), depth=Constant(1e-7))
    placed = scatter(surface, ScatterSpec(count=100, length_min=0.1, length_max=1.0, looks=looks),
                     np.random.default_rng(seed))
    triangle, bary = UVLocator(surface.uv).locate(placed.scratches.uv)
    assert np.all(triangle >= 0)
    np.testing.assert_allclose(surface.point(triangle, bary), placed.point, atol=1e-7)
    total = np.bincount(placed.source, weights=placed.piece_length)
    assert np.all(total <= 1.0 + 1e-9)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 8))
def test_locator_agrees_with_a_search_of_every_triangle(seed, n):
    _, _, uv = bumpy(seed, n, 0.0)
    rng = np.random.default_rng(seed)
    points = rng.uniform(-0.1, 1.1, (300, 2))
    triangle, bary = UVLocator(uv).locate(points)
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    rel = points[:, None, :] - uv[None, :, 0]
    b1 = (rel[..., 0] * e2[:, 1] - rel[..., 1] * e2[:, 0]) / det
    b2 = (e1[:, 0] * rel[..., 1] - e1[:, 1] * rel[..., 0]) / det
    inside_any = ((b1 >= -1e-9) & (b2 >= -1e-9) & (b1 + b2 <= 1 + 1e-9)).any(axis=1)
    assert np.array_equal(triangle >= 0, inside_any)
    found = triangle >= 0
    np.testing.assert_allclose(np.einsum("nk,nki->ni", bary[found], uv[triangle[found]]), points[found],
                               atol=1e-12)
