"""The Surface: adjacency, seams, islands, tangent frames, area sampling (no Blender needed)."""
import numpy as np
import pytest
from scipy import stats

from meshes import grid, ring, torus, unequal_quads
from scratch_iridescence.addon.geometry.surface import Surface, SurfaceError


def test01_neighbours_are_mutual():
    surface = Surface.from_arrays(*torus(8, 6))
    t, k = np.nonzero(surface.neighbour >= 0)
    assert len(t) == 3 * surface.triangle_count  # closed surface: every edge has a neighbour
    other, other_edge = surface.neighbour[t, k], surface.neighbour_edge[t, k]
    assert np.array_equal(surface.neighbour[other, other_edge], t)
    assert np.array_equal(surface.seam[t, k], surface.seam[other, other_edge])


def test02_ring_has_one_seam_edge_and_open_ends():
    surface = Surface.from_arrays(*ring())
    assert surface.seam.sum() == 2  # one edge, seen from both sides
    assert (surface.neighbour < 0).sum() == 8  # four bottom and four top edges
    assert np.all(surface.island == 0)  # the seam does not disconnect the strip


def test03_split_vertices_are_welded():
    positions, triangles, uv = ring()
    # Give every triangle its own three vertices, as OBJ/glTF imports split UV seams.
    split_positions = positions[triangles].reshape(-1, 3)
    split_triangles = np.arange(len(split_positions)).reshape(-1, 3)
    welded = Surface.from_arrays(split_positions, split_triangles, uv)
    assert np.array_equal(welded.neighbour >= 0, Surface.from_arrays(positions, triangles, uv).neighbour >= 0)
    assert welded.seam.sum() == 2
    loose = Surface.from_arrays(split_positions, split_triangles, uv, weld=False)
    assert np.all(loose.neighbour < 0)


def test04_separate_pieces_are_separate_islands():
    a = grid(2, 2)
    b = grid(1, 1)
    positions = np.vstack([a[0], b[0] + [10.0, 0.0, 0.0]])
    triangles = np.vstack([a[1], b[1] + len(a[0])])
    surface = Surface.from_arrays(positions, triangles, np.vstack([a[2], b[2]]))
    assert len(np.unique(surface.island)) == 2
    assert len(set(surface.island[:8])) == 1 and len(set(surface.island[8:])) == 1


def test05_faces_without_uv_area_are_unusable():
    positions, triangles, uv = grid(2, 1)
    uv = uv.copy()
    uv[0] = uv[0, 0]  # collapse the first triangle's UVs to a point
    surface = Surface.from_arrays(positions, triangles, uv)
    assert not surface.usable[0] and surface.usable[1:].all()
    assert np.all(surface.neighbour[0] < 0) and not np.any(surface.neighbour == 0)
    assert surface.island[0] == -1
    triangle, _ = surface.sample_points(np.random.default_rng(0), 1000)
    assert not np.any(triangle == 0)
    uv[:] = 0.5
    with pytest.raises(SurfaceError, match="no usable faces"):
        Surface.from_arrays(positions, triangles, uv).sample_points(np.random.default_rng(0), 1)


def test06_no_faces_is_an_error():
    with pytest.raises(SurfaceError, match="no faces"):
        Surface.from_arrays(np.zeros((3, 3)), np.zeros((0, 3), dtype=int), np.zeros((0, 3, 2)))


@pytest.mark.parametrize("uv_map, tangent, bitangent", [
    (lambda x, y: np.column_stack([x, y]), [1, 0, 0], [0, 1, 0]),
    (lambda x, y: np.column_stack([y, x]), [0, 1, 0], [1, 0, 0]),     # swapped axes (mirrored)
    (lambda x, y: np.column_stack([-y, 3 * x]), [0, -1, 0], [1, 0, 0]),  # rotated, scaled
])
def test07_tangent_frame_follows_the_uv_axes(uv_map, tangent, bitangent):
    positions, triangles, _ = grid(2, 2)
    uv = uv_map(positions[:, 0], positions[:, 1])[triangles]
    surface = Surface.from_arrays(positions, triangles, uv)
    np.testing.assert_allclose(surface.tangent, np.broadcast_to(tangent, surface.tangent.shape), atol=1e-12)
    np.testing.assert_allclose(surface.bitangent, np.broadcast_to(bitangent, surface.bitangent.shape), atol=1e-12)


def test08_barycentric_round_trip():
    surface = Surface.from_arrays(*torus(10, 7))
    rng = np.random.default_rng(2)
    triangle, bary = surface.sample_points(rng, 500)
    np.testing.assert_allclose(surface.barycentric(triangle, surface.point(triangle, bary)), bary, atol=1e-12)


def test09_points_are_uniform_per_3d_area_not_per_uv_area():
    surface = Surface.from_arrays(*unequal_quads())  # 3D areas 1 : 3, UV areas 1 : 1
    triangle, _ = surface.sample_points(np.random.default_rng(3), 20000)
    counts = np.bincount(triangle // 2, minlength=2)
    assert stats.chisquare(counts, 20000 * np.array([0.25, 0.75])).pvalue > 1e-3
    assert stats.chisquare(counts, 20000 * np.array([0.5, 0.5])).pvalue < 1e-6  # the test has power


def test10_points_are_uniform_inside_a_triangle():
    surface = Surface.from_arrays(*grid(1, 1))
    triangle, bary = surface.sample_points(np.random.default_rng(4), 20000)
    # Within a triangle, b1 + b2 = 1 - b0 has density 2s on [0, 1], i.e. s**2 is uniform.
    s = 1.0 - bary[:, 0]
    assert stats.kstest(s ** 2, "uniform").pvalue > 1e-3
