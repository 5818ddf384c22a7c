"""The brushes replayed from ``stroke`` collections: pen, spray, seams, gaps, eraser, errors, undo."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from strokes import stroke  # noqa: E402
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.addon.mesh import world_surface  # noqa: E402
from scratch_iridescence.addon.geometry.uvmap import UVLocator  # noqa: E402
from scratch_iridescence.mitsuba_bridge.scratch import ScratchSet  # noqa: E402


def paint(points, starts=(), **kwargs):
    kwargs.setdefault("seed", 1)
    return bpy.ops.scratch.paint_stroke("EXEC_DEFAULT", True, stroke=stroke(points, starts), **kwargs)


def erase(points, **kwargs):
    return bpy.ops.scratch.erase_stroke("EXEC_DEFAULT", True, stroke=stroke(points), **kwargs)


def plane_points(scratches):
    """3D points of the 2 m plane's scratch vertices (UV [0, 1]² covers x, y in [-1, 1])."""
    return np.column_stack([2 * scratches.uv - 1, np.zeros(scratches.vertex_count)])


def distance_to_polyline(points, path):
    a, b = path[:-1], path[1:]
    ab = b - a
    result = []
    for p in np.atleast_2d(points):
        t = np.clip(np.einsum("ni,ni->n", p - a, ab) / np.maximum(np.einsum("ni,ni->n", ab, ab), 1e-300), 0, 1)
        result.append(np.linalg.norm(a + t[:, None] * ab - p, axis=1).min())
    return np.array(result)


def test01_pen_paints_one_scratch_through_the_stroke(plane):
    points = np.column_stack([np.linspace(-0.8, 0.6, 15), 0.3 * np.sin(np.linspace(0, 3, 15)), np.zeros(15)])
    assert paint(points, depth_distribution="UNIFORM", depth_min=200.0, depth_max=300.0) == {"FINISHED"}
    scratches = storage.read_scratches(plane)
    assert scratches.count == 1
    np.testing.assert_allclose(plane_points(scratches), points, atol=1e-6)
    assert 200e-9 <= scratches.depth[0] <= 300e-9


def test02_points_near_the_surface_are_snapped_onto_it(plane):
    points = np.column_stack([np.linspace(-0.5, 0.5, 6), np.zeros(6), np.full(6, 0.003)])
    paint(points)
    np.testing.assert_allclose(plane_points(storage.read_scratches(plane)), points * [1, 1, 0], atol=1e-6)


def test03_points_off_the_surface_split_the_stroke(plane):
    points = np.column_stack([np.linspace(-0.8, 0.8, 9), np.zeros(9), np.zeros(9)])
    points[4, 2] = 1.0  # lifted far above the plane: missed
    points[5, 0] = 5.0  # beside the plane: missed
    paint(points)
    scratches = storage.read_scratches(plane)
    assert scratches.count == 2
    assert list(scratches.vertex_counts) == [4, 3]


def test04_is_start_begins_a_new_scratch(plane):
    points = np.column_stack([np.linspace(-0.8, 0.8, 8), np.zeros(8), np.zeros(8)])
    paint(points, starts=(4,))
    assert storage.read_scratches(plane).count == 2


def cube_seam_stroke(cube, seam: bool):
    """Points crossing a cube edge that is (or is not) a UV seam, 0.6 m into each face."""
    surface = world_surface(cube, bpy.context.evaluated_depsgraph_get())
    t, k = np.argwhere((surface.neighbour >= 0) & (surface.seam == seam) & ~surface.flat)[0]
    other, other_k = surface.neighbour[t, k], surface.neighbour_edge[t, k]
    a, b = surface.corners[t, (k + 1) % 3], surface.corners[t, (k + 2) % 3]
    middle = 0.5 * (a + b)
    into_here, into_there = -surface.edge_out[t, k], -surface.edge_out[other, other_k]
    offsets = np.linspace(0.6, 0.05, 6)
    points = np.vstack([middle + s * into_here for s in offsets]
                       + [middle + s * into_there for s in offsets[::-1]])
    return surface, points, middle


@pytest.mark.parametrize("seam", [True, False])
def test05_pen_across_a_cube_edge(cube, seam):
    surface, points, middle = cube_seam_stroke(cube, seam)
    paint(points)
    scratches = storage.read_scratches(cube)
    assert scratches.count == (2 if seam else 1)
    triangle, bary = UVLocator(surface.uv).locate(scratches.uv)
    assert np.all(triangle >= 0)
    on_surface = surface.point(triangle, bary)
    path = np.vstack([points[:6], middle, points[6:]])
    assert distance_to_polyline(on_surface, path).max() < 1e-5  # every scratch stays on the stroke's path
    for i in range(scratches.count):  # and each is continuous in UV: UV steps = surface steps / 8
        uv = scratches.polyline(i)
        p = on_surface[scratches.offsets[i]:scratches.offsets[i + 1]]
        np.testing.assert_allclose(np.linalg.norm(np.diff(uv, axis=0), axis=1),
                                   np.linalg.norm(np.diff(p, axis=0), axis=1) / 8, rtol=1e-5, atol=1e-7)
    total = sum(np.linalg.norm(np.diff(on_surface[a:b], axis=0), axis=1).sum()
                for a, b in zip(scratches.offsets[:-1], scratches.offsets[1:]))
    assert total == pytest.approx(1.2, rel=1e-5)


def test06_spray_scatters_around_the_stroke(plane):
    points = np.column_stack([np.linspace(-0.5, 0.5, 30), np.zeros(30), np.zeros(30)])
    radius, jitter = 0.05, np.radians(10)
    paint(points, brush_mode="SPRAY", radius=radius, density=10.0, jitter=jitter, length_min=0.01,
          length_max=0.02)
    scratches = storage.read_scratches(plane)
    expected = 10.0 * (1.0 / radius + 1)
    assert abs(scratches.count - expected) < 5 * np.sqrt(expected)
    p = plane_points(scratches)
    centre = 0.5 * (p[scratches.offsets[:-1]] + p[scratches.offsets[1:] - 1])
    assert distance_to_polyline(centre, points).max() <= radius + 1e-6
    chord = p[scratches.offsets[1:] - 1] - p[scratches.offsets[:-1]]
    heading = np.arctan2(chord[:, 1], chord[:, 0])
    heading = np.mod(heading + np.pi / 2, np.pi) - np.pi / 2  # a scratch has no head or tail
    assert np.abs(heading).max() <= jitter + 1e-6


def test07_spray_click_sprays_a_dab(plane):
    paint([(0.2, 0.1, 0.0)], brush_mode="SPRAY", radius=0.1, density=40.0)
    scratches = storage.read_scratches(plane)
    assert 15 < scratches.count < 70


def test07b_absurd_spray_density_is_refused(scratched_plane):
    before = storage.raw_scratch_bytes(scratched_plane)
    with pytest.raises(RuntimeError, match="Spraying about .* needs about .* GiB"):
        paint([(-0.5, 0.0, 0.0), (0.5, 0.0, 0.0)], brush_mode="SPRAY", radius=1e-6, density=1e6)
    assert storage.raw_scratch_bytes(scratched_plane) == before


def test08_stroke_entirely_off_the_mesh(scratched_plane):
    before = storage.raw_scratch_bytes(scratched_plane)
    with pytest.raises(RuntimeError, match="The stroke misses 'Plane'"):
        paint([(5.0, 5.0, 0.0), (6.0, 5.0, 0.0)])
    with pytest.raises(RuntimeError, match="The stroke misses"):
        erase([(0.0, 0.0, 3.0)])
    with pytest.raises(RuntimeError, match="The stroke is empty"):
        paint([])
    assert storage.raw_scratch_bytes(scratched_plane) == before


def test09_a_single_pen_point_paints_nothing(scratched_plane):
    before = storage.raw_scratch_bytes(scratched_plane)
    assert paint([(0.1, 0.1, 0.0)]) == {"CANCELLED"}
    assert storage.raw_scratch_bytes(scratched_plane) == before


def test10_brushes_refuse_bad_objects(empty_scene):
    bpy.ops.object.empty_add()
    with pytest.raises(RuntimeError, match="mesh objects"):
        paint([(0, 0, 0), (1, 0, 0)])
    with pytest.raises(RuntimeError, match="mesh objects"):
        erase([(0, 0, 0), (1, 0, 0)])
    bpy.ops.mesh.primitive_plane_add()
    mesh = bpy.context.active_object.data
    mesh.uv_layers.remove(mesh.uv_layers[0])
    mesh.update()
    with pytest.raises(RuntimeError, match="no UV map"):
        paint([(0, 0, 0), (0.5, 0, 0)])


def test11_eraser_removes_exactly_the_scratches_under_the_stroke(plane):
    rng = np.random.default_rng(4)
    a = rng.uniform(0.05, 0.95, (300, 2))
    b = a + rng.normal(0, 0.03, (300, 2))
    scratches = ScratchSet.from_polylines([np.array([p, q]) for p, q in zip(a, np.clip(b, 0, 1))],
                                          width=1e-6, depth=1e-7)
    storage.write_scratches(plane, scratches)
    stroke_points = np.column_stack([np.linspace(-0.7, 0.7, 8), np.linspace(-0.3, 0.4, 8), np.zeros(8)])
    radius = 0.08
    assert erase(stroke_points, radius=radius, erase_mode="WHOLE") == {"FINISHED"}
    # Independent check on the plane's exact geometry: sampled segment-to-stroke distances.
    p = plane_points(scratches)
    distance = np.array([distance_to_polyline(np.linspace(p[2 * i], p[2 * i + 1], 200), stroke_points).min()
                         for i in range(300)])
    kept = storage.read_scratches(plane)
    survivors = {tuple(x) for x in kept.uv.reshape(-1, 4).round(12).tolist()}
    was_kept = np.array([tuple(scratches.polyline(i).reshape(-1).round(12)) in survivors for i in range(300)])
    assert kept == scratches.select(was_kept)  # the others untouched, in order
    expected_kept = distance > radius
    assert 10 < (~expected_kept).sum() < 290
    clear = np.abs(distance - radius) > 0.01 * radius  # the sampled check is exact up to 1 %
    assert np.array_equal(was_kept[clear], expected_kept[clear])


def test12_cutting_eraser_removes_only_what_is_under_the_brush(plane):
    line = ScratchSet.from_polylines([np.array([[0.1, 0.5], [0.9, 0.5]]), np.array([[0.1, 0.1], [0.2, 0.1]])],
                                     width=[1e-6, 2e-6], depth=1e-7, depth_variation=(1.1, 0.04), seed=[3, 4])
    storage.write_scratches(plane, line)  # in 3D: y = 0, x from -0.8 to 0.8; and a short one far away
    radius = 0.1
    assert erase([(0.0, -0.5, 0.0), (0.0, 0.5, 0.0)], radius=radius) == {"FINISHED"}
    result = storage.read_scratches(plane)
    assert result.count == 3
    assert result.select([0]) == line.select([1])  # untouched, unchanged
    left, right = plane_points(result.select([1])), plane_points(result.select([2]))
    np.testing.assert_allclose([left[0, 0], right[-1, 0]], [-0.8, 0.8], atol=1e-9)
    assert -1.25 * radius <= left[-1, 0] <= -radius + 1e-9 and radius - 1e-9 <= right[0, 0] <= 1.25 * radius
    assert np.all(result.width[1:] == 1e-6) and len(set(result.seed)) == 3
    np.testing.assert_allclose(result.depth_variation[1:, 1].sum(), 0.04 * (1 - 2 * radius / 1.6), rtol=0.05)


def test13_erasing_nothing_changes_nothing(scratched_plane):
    before = storage.raw_scratch_bytes(scratched_plane)
    assert erase([(0.99, 0.99, 0.0)], radius=0.001) == {"CANCELLED"}
    assert storage.raw_scratch_bytes(scratched_plane) == before


def test14_paint_and_erase_undo(scratched_plane):
    bpy.ops.ed.undo_push(message="before")
    before = storage.raw_scratch_bytes(scratched_plane)
    paint([(-0.5, 0.0, 0.0), (0.5, 0.0, 0.0)])
    painted = storage.raw_scratch_bytes(bpy.data.objects["Plane"])
    erase([(-1.0, 0.0, 0.0), (1.0, 0.0, 0.0)], radius=0.5)
    bpy.ops.ed.undo()
    assert storage.raw_scratch_bytes(bpy.data.objects["Plane"]) == painted
    bpy.ops.ed.undo()
    assert storage.raw_scratch_bytes(bpy.data.objects["Plane"]) == before


def test15_invoke_without_a_viewport_replays_the_stroke(plane):
    points = [(-0.5, 0.2, 0.0), (0.5, 0.2, 0.0)]
    bpy.ops.scratch.paint_stroke("INVOKE_DEFAULT", stroke=stroke(points), seed=3)
    assert storage.read_scratches(plane).count == 1


# ------------------------------------------------------------------ strokes through edges and vertices
def assert_pen_follows(surface, scratches, path, pieces):
    """``pieces`` scratches (a count or a set of allowed counts), each continuous in UV, together
    covering ``path`` exactly once."""
    assert scratches.count in (pieces if isinstance(pieces, set) else {pieces})
    triangle, bary = UVLocator(surface.uv).locate(scratches.uv)
    assert np.all(triangle >= 0)
    on_surface = surface.point(triangle, bary)
    assert distance_to_polyline(on_surface, path).max() < 1e-5
    total = 0.0
    for i in range(scratches.count):  # the cube's unwrap maps 2 m faces to 0.25 UV: UV steps = steps / 8
        p = on_surface[scratches.offsets[i]:scratches.offsets[i + 1]]
        steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
        np.testing.assert_allclose(np.linalg.norm(np.diff(scratches.polyline(i), axis=0), axis=1), steps / 8,
                                   rtol=1e-5, atol=1e-7)
        total += steps.sum()
    assert total == pytest.approx(np.linalg.norm(np.diff(path, axis=0), axis=1).sum(), rel=1e-5)


def cube_edges(surface):
    """One (triangle, edge) per edge of the cube between two faces (no face diagonals)."""
    t, k = np.nonzero((surface.neighbour >= 0) & ~surface.flat)
    keep = t < surface.neighbour[t, k]
    return list(zip(t[keep], k[keep]))


@pytest.mark.parametrize("where", [0.5, 0.3])
def test16_a_stroke_sample_exactly_on_a_cube_edge(cube, where):
    # The sample on the edge belongs to both faces; on a seam the scratch must be cut there
    # (one piece per side, each continuous in UV), elsewhere it goes on as one scratch.
    surface = world_surface(cube, bpy.context.evaluated_depsgraph_get())
    edges = cube_edges(surface)
    assert len(edges) == 12 and sum(surface.seam[t, k] for t, k in edges) == 7
    for t, k in edges:
        other, other_k = surface.neighbour[t, k], surface.neighbour_edge[t, k]
        a, b = surface.corners[t, (k + 1) % 3], surface.corners[t, (k + 2) % 3]
        on_edge = a + where * (b - a)
        here, there = -surface.edge_out[t, k], -surface.edge_out[other, other_k]
        path = np.vstack([on_edge + 0.6 * here, on_edge + 0.3 * here, on_edge, on_edge + 0.3 * there,
                          on_edge + 0.6 * there])
        for points in (path, path[1:4]):  # with and without neighbours beside the edge
            storage.clear_scratches(cube)
            assert paint(points) == {"FINISHED"}
            assert_pen_follows(surface, storage.read_scratches(cube), points, 2 if surface.seam[t, k] else 1)


def test17_a_stroke_sample_exactly_on_a_cube_vertex(cube):
    # Through every corner from each face to each other face meeting there: cut wherever the two
    # faces give the corner different UVs (where they agree, the UV polyline is continuous whether
    # or not it is cut: the faces' edge may still be a seam elsewhere).
    surface = world_surface(cube, bpy.context.evaluated_depsgraph_get())
    corners = np.unique(surface.corners.reshape(-1, 3), axis=0)
    assert len(corners) == 8
    strokes = 0
    for corner in corners:
        # The three faces at the corner: their triangles with a corner there, grouped by normal.
        at = np.flatnonzero((surface.corners == corner).all(axis=2).any(axis=1))
        faces = {tuple(np.round(surface.normal[t]).astype(int)): t for t in at}
        assert len(faces) == 3
        for (normal_a, ta), (normal_b, tb) in [(x, y) for x in faces.items() for y in faces.items() if x != y]:
            # Into each face, off its diagonals: 0.6 m along one of its edges, 0.3 m along the other.
            inward_a = -corner * (1 - np.abs(normal_a))
            inward_b = -corner * (1 - np.abs(normal_b))
            into_a = inward_a * np.where(np.abs(normal_b) > 0, 0.6, 0.3)
            into_b = inward_b * np.where(np.abs(normal_a) > 0, 0.6, 0.3)
            points = np.vstack([corner + into_a, corner, corner + into_b])
            uv_a = surface.uv[ta][(surface.corners[ta] == corner).all(axis=1)][0]
            uv_b = surface.uv[tb][(surface.corners[tb] == corner).all(axis=1)][0]
            storage.clear_scratches(cube)
            assert paint(points) == {"FINISHED"}
            assert_pen_follows(surface, storage.read_scratches(cube), points,
                               {1, 2} if np.allclose(uv_a, uv_b, atol=1e-6) else 2)
            strokes += 1
    assert strokes == 48


# ------------------------------------------------------------------ invalid parameters
LINE = [(-0.5, 0.0, 0.0), (0.5, 0.0, 0.0)]


@pytest.mark.parametrize("operator, points, settings, message", [
    ("paint", LINE, dict(brush_mode="SPRAY", density=0.0), "Density is 0: the spray would paint nothing"),
    ("paint", LINE, dict(brush_mode="SPRAY", density=np.nan), "Density is not a number"),
    ("paint", LINE, dict(brush_mode="SPRAY", density=np.inf), r"Spraying about 1.74e\+40 scratches needs about"),
    ("paint", LINE, dict(brush_mode="SPRAY", radius=np.inf), r"Radius \(3.403e\+38\) is more than 100 times"),
    ("paint", LINE, dict(brush_mode="SPRAY", jitter=np.nan), "Direction Jitter is not a number"),
    ("paint", LINE, dict(brush_mode="SPRAY", length_max=np.inf), r"Length Max \(3.403e\+38\) is more than 100"),
    ("paint", LINE, dict(brush_mode="SPRAY", bend=np.nan), "Bend is not a number"),
    ("paint", LINE, dict(width_mean=np.inf), "width G.* reaches 3.4e\\+29 m, beyond 0.001 m"),
    ("paint", LINE, dict(depth_variation_frequency=np.nan), "Depth Frequency is not a number"),
    ("paint", [(np.nan, 0.0, 0.0), (0.5, 0.0, 0.0)], {}, "1 stroke point of 2 is not a finite location"),
    ("erase", LINE, dict(radius=np.nan), "Radius is not a number"),
    ("erase", LINE, dict(radius=np.inf), r"Radius \(3.403e\+38\) is more than 100 times the object's size"),
    ("erase", LINE * 500, dict(radius=1e-7), "Erasing with a radius of 1e-07 needs about .* GiB"),
])
def test18_invalid_brush_parameters_are_refused(scratched_plane, operator, points, settings, message):
    before = storage.raw_scratch_bytes(scratched_plane)
    with pytest.raises(RuntimeError, match=message):
        (paint if operator == "paint" else erase)(points, **settings)
    assert storage.raw_scratch_bytes(scratched_plane) == before


def test19_a_tiny_cutting_radius_is_checked_against_memory(scratched_plane, monkeypatch):
    # A short stroke with a tiny radius is cheap to sample, but cutting resamples every touched scratch
    # along its whole length every radius / 4: that is estimated before it is done.
    import scratch_iridescence.addon.tools.paint as paint_module
    from scratch_iridescence.mitsuba_bridge.device.memory import MemoryLimit, check_memory

    def ten_megabytes(needed, what, **keywords):  # (a cgroup of 10 MiB, as the real check would read it)
        check_memory(needed, what, **keywords, limit=MemoryLimit(10 * 2**20, "cgroup v2 memory.max"))

    monkeypatch.setattr(paint_module, "check_memory", ten_megabytes)
    scratches = storage.read_scratches(scratched_plane)
    click = [tuple(plane_points(scratches)[:2].mean(axis=0))]  # on the first scratch (0.1-0.2 m long)
    before = storage.raw_scratch_bytes(scratched_plane)
    message = r"Cutting 1 scratch with a radius of 1e-05 needs about \d\d.\d MiB of memory but only 10.0 MiB"
    with pytest.raises(RuntimeError, match=message):
        erase(click, radius=1e-5)
    assert storage.raw_scratch_bytes(scratched_plane) == before
    assert erase(click, radius=1e-5, erase_mode="WHOLE") == {"FINISHED"}
    assert storage.read_scratches(scratched_plane) == scratches.select(np.arange(1, 50))
