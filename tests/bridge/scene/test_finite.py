"""Meshes with NaN or infinite vertices: their triangles are dropped with a warning, not rendered black."""
import numpy as np

from bridge_scenes import quad, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge.render import passes as render
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.scene.finite import finite_mesh, with_finite_meshes


def grid(n=4, name="grid"):
    """An n × n grid of quads on [-4, 4]² (wider than the test camera sees), facing +Z, with UVs."""
    u, v = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    uvs = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float32)
    positions = np.concatenate([uvs * 8 - 4, np.zeros((len(uvs), 1), np.float32)], axis=1).astype(np.float32)
    faces = []
    for row in range(n):
        for col in range(n):
            a = row * (n + 1) + col
            faces += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    return S.MeshData(name, positions, np.array(faces, np.uint32), None, uvs)


def test_finite_meshes_come_back_unchanged():
    mesh = quad()
    assert finite_mesh(mesh) == (mesh, 0, False)
    description = simple_scene()
    assert with_finite_meshes(description) is description


def test_triangles_touching_a_nan_or_infinite_vertex_or_uv_are_dropped():
    mesh = grid()
    positions, uvs = mesh.positions.copy(), mesh.uvs.copy()
    positions[0, 2] = np.nan       # corner vertex: in 2 triangles of the first quad
    positions[24, 0] = np.inf      # opposite corner (on the same diagonal): in 2 triangles
    uvs[12, 1] = np.nan            # centre vertex: in 6 triangles
    broken = S.MeshData("broken", positions, mesh.faces, np.tile([0, 0, 1.0], (25, 1)).astype(np.float32), uvs)
    fixed, dropped, normals_dropped = finite_mesh(broken)
    assert dropped == 2 + 2 + 6 and fixed.triangle_count == 32 - 10 and not normals_dropped
    assert np.isfinite(fixed.positions[fixed.faces]).all() and np.isfinite(fixed.uvs[fixed.faces]).all()


def test_the_scene_keeps_the_finite_triangles_and_says_what_was_dropped(variant):
    mesh = grid()
    positions = mesh.positions.copy()
    positions[0] = np.nan
    broken = S.MeshData("floor", positions, mesh.faces, None, mesh.uvs)
    lights = [S.PointLight((0, 0, 2), (1.0, 1.0, 1.0))]
    clean = simple_scene(shapes=[S.Shape("floor", mesh, np.eye(4), "grey")], lights=lights)
    description = with_finite_meshes(simple_scene(shapes=[S.Shape("floor", broken, np.eye(4), "grey")], lights=lights))
    assert description.warnings == ("mesh 'floor': 2 of 32 triangles have NaN or infinite vertex positions or UVs "
                                    "and are not rendered",)
    image = render.render_image(builder.load_scene(description, S.RenderSettings()), 16)[..., :3].mean(axis=-1)
    reference = render.render_image(builder.load_scene(clean, S.RenderSettings()), 16)[..., :3].mean(axis=-1)
    # The camera sees the middle of the 8 m floor; the dropped corner quad is out of view: the same image.
    assert reference.mean() > 0.01
    assert np.array_equal(image, reference)


def test_a_mesh_with_only_non_finite_triangles_is_left_out():
    positions = np.full((4, 3), np.nan, np.float32)
    gone = S.MeshData("gone", positions, quad().faces, None, None)
    description = with_finite_meshes(simple_scene(shapes=[S.Shape("gone", gone, np.eye(4), "grey"),
                                                          S.Shape("floor", quad(), np.eye(4), "grey")]))
    assert [shape.name for shape in description.shapes] == ["floor"]
    assert "2 of 2 triangles" in description.warnings[0]
