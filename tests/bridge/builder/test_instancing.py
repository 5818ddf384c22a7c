"""Instancing: shapes sharing a mesh become one ``shapegroup`` and one ``instance`` each, and render as copies do."""
import math

import numpy as np
import pytest

from bridge_scenes import camera_at, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge.folder import export
from scratch_iridescence.mitsuba_bridge import scene as S

mi = pytest.importorskip("mitsuba")


def ico_sphere(name="ball") -> S.MeshData:
    """A smooth unit icosahedron subdivided twice (320 triangles) with spherical UVs."""
    t = (1 + 5 ** 0.5) / 2
    vertices = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
                (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    positions = [np.array(v, float) / np.linalg.norm(v) for v in vertices]
    for _ in range(2):
        midpoints, refined = {}, []
        for a, b, c in faces:
            def middle(i, j):
                key = (min(i, j), max(i, j))
                if key not in midpoints:
                    point = positions[i] + positions[j]
                    positions.append(point / np.linalg.norm(point))
                    midpoints[key] = len(positions) - 1
                return midpoints[key]
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            refined += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = refined
    positions = np.array(positions, np.float32)
    uvs = np.stack([0.5 + np.arctan2(positions[:, 1], positions[:, 0]) / (2 * math.pi),
                    0.5 + np.arcsin(np.clip(positions[:, 2], -1, 1)) / math.pi], axis=1).astype(np.float32)
    return S.MeshData(name, positions, np.array(faces, np.uint32), positions.copy(), uvs)


def grid_of_balls(count_per_side=6, mesh=None, material="grey"):
    """Shapes placing one mesh on a grid, each turned and scaled differently (one shared MeshData)."""
    mesh = mesh or ico_sphere()
    shapes = []
    for index in range(count_per_side ** 2):
        row, column = divmod(index, count_per_side)
        angle = 0.7 * index
        matrix = np.diag([0.3, 0.3 + 0.02 * row, 0.3, 1.0])
        rotation = np.array([[math.cos(angle), -math.sin(angle), 0], [math.sin(angle), math.cos(angle), 0], [0, 0, 1]])
        matrix[:3, :3] = rotation @ matrix[:3, :3]
        matrix[:3, 3] = (column - (count_per_side - 1) / 2, row - (count_per_side - 1) / 2, 0.3)
        shapes.append(S.Shape(f"ball{index}", mesh, matrix, material))
    return shapes


def scene_of(shapes, materials=None):
    return simple_scene(film=S.Film(32, 32), camera=S.Camera(camera_at((0, 0, 8)), fov_x_deg=50),
                        shapes=shapes, materials=materials or {"grey": S.Diffuse((0.6, 0.5, 0.4))},
                        lights=[S.SunLight((0.3, 0.2, -0.93), (2, 2, 2))], world=S.ConstantWorld((0.2, 0.2, 0.2)))


def test_shapes_sharing_a_mesh_become_one_shapegroup_and_an_instance_each(variant):
    shapes = grid_of_balls(6)
    result = builder.scene_dict(scene_of(shapes), S.RenderSettings())
    kinds = [value.get("type") for value in result.values() if isinstance(value, dict)]
    assert kinds.count("shapegroup") == 1 and kinds.count("instance") == 36
    group = next(key for key, value in result.items() if isinstance(value, dict) and value.get("type") == "shapegroup")
    mesh = result[group]["mesh"]
    assert mesh.vertex_count() == len(shapes[0].mesh.positions)  # object space, stored once
    copies = builder.scene_dict(scene_of(shapes), S.RenderSettings(), instancing=False)
    assert [v.get("type") for v in copies.values() if isinstance(v, dict)].count("instance") == 0


def test_each_material_gets_its_own_group_and_emitters_stay_meshes(variant):
    mesh = ico_sphere()
    shapes = grid_of_balls(2, mesh, "grey") + grid_of_balls(2, mesh, "red") + grid_of_balls(2, mesh, "glow")
    single = S.Shape("single", ico_sphere("other"), np.eye(4), "grey")
    materials = {"grey": S.Diffuse(), "red": S.Diffuse((1, 0, 0)), "glow": S.Emission((1, 1, 1))}
    result = builder.scene_dict(scene_of(shapes + [single], materials), S.RenderSettings())
    kinds = [value.get("type") if isinstance(value, dict) else "mesh" for key, value in result.items()
             if key.startswith(("shape-", "group-"))]
    assert kinds.count("shapegroup") == 2 and kinds.count("instance") == 8
    assert kinds.count("mesh") == 5  # four emissive balls and the single one


def noise_of_mean(first, second):
    """Standard deviation of the mean of one image, from the difference of two independent renders of it."""
    difference = (first - second).mean(axis=-1)
    return difference.std() / math.sqrt(2 * difference.size)


def test_instances_render_as_copies_do(variant):
    description = scene_of(grid_of_balls(6))
    settings = S.RenderSettings(spp=32)
    copies = [np.asarray(mi.render(builder.load_scene(description, settings, instancing=False), spp=32, seed=seed))
              for seed in (1, 2)]
    instanced = np.asarray(mi.render(builder.load_scene(description, settings), spp=32, seed=3))
    sigma = noise_of_mean(copies[0][..., :3], copies[1][..., :3])
    assert instanced[..., :3].mean() == pytest.approx(copies[0][..., :3].mean(), abs=4 * math.sqrt(2) * sigma)
    # Same picture, not just the same mean: 8×8-pixel blocks agree within their own noise.
    blocks = lambda image: image[..., :3].mean(axis=-1).reshape(4, 8, 4, 8).mean(axis=(1, 3))  # noqa: E731
    block_sigma = sigma * math.sqrt(32 * 32 / 64)
    assert np.abs(blocks(instanced) - blocks(copies[0])).max() < 5 * math.sqrt(2) * block_sigma
    assert instanced[..., 3].sum() == pytest.approx(copies[0][..., 3].sum(), rel=1e-3)  # the same coverage


def test_export_folder_writes_the_mesh_once_and_instances_load_back(variant, tmp_path):
    description = scene_of(grid_of_balls(3))
    export.export_folder(description, S.RenderSettings(), tmp_path)
    text = (tmp_path / "scene.xml").read_text()
    assert text.count('type="shapegroup"') == 1 and text.count('type="instance"') == 9
    assert len(list((tmp_path / "meshes").glob("*.ply"))) == 1
    from_files = np.asarray(mi.render(export.load_folder(tmp_path), spp=16, seed=3))
    in_memory = np.asarray(mi.render(builder.load_scene(description, S.RenderSettings()), spp=16, seed=3))
    assert in_memory[..., :3].mean() > 0.01
    np.testing.assert_allclose(from_files, in_memory, rtol=1e-3, atol=1e-4)


def test_scratched_instances_glint_as_scratched_copies_do(variant):
    from bridge_scenes import quad
    from scratch_iridescence.mitsuba_bridge import scratch

    scratches = scratch.random_scratches(800, seed=4, width=scratch.Gaussian(4e-6, 1.3e-6), length=(0.2, 0.6),
                                         depth=scratch.Gaussian(250e-9, 80e-9))
    plate = quad(0.1, "plate")
    shapes = []
    for index, (x, turn) in enumerate([(-0.06, 0.0), (0.06, 0.6)]):
        matrix = np.eye(4)
        matrix[:2, :2] = [[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]]
        matrix[:3, 3] = (x, 0, 0)
        shapes.append(S.Shape(f"plate{index}", plate, matrix, "metal"))
    camera = np.eye(4)
    elevation = math.radians(47)
    camera[:3, 3] = (0, -0.3 * math.cos(elevation), 0.3 * math.sin(elevation))
    forward = -camera[:3, 3] / np.linalg.norm(camera[:3, 3])
    right = np.cross(forward, (0, 0, 1.0))
    right /= np.linalg.norm(right)
    camera[:3, :3] = np.stack([right, np.cross(right, forward), -forward], axis=1)
    description = simple_scene(film=S.Film(48, 24), camera=S.Camera(camera, fov_x_deg=50), shapes=shapes,
                               materials={"metal": S.ScratchedMetal(scratches, coherence_diameter_m=30e-6)},
                               world=S.SkyWorld((0, math.cos(math.radians(35)), math.sin(math.radians(35)))))
    settings = S.RenderSettings(spp=64)
    copies = [np.asarray(mi.render(builder.load_scene(description, settings, instancing=False), spp=64, seed=seed))
              for seed in (1, 2)]
    instanced = np.asarray(mi.render(builder.load_scene(description, settings), spp=64, seed=3))
    assert "instance" in repr(builder.load_scene(description, settings).shapes()[0]).lower()
    sigma = noise_of_mean(copies[0][..., :3], copies[1][..., :3])
    assert copies[0][..., :3].mean() > 0.01
    assert instanced[..., :3].mean() == pytest.approx(copies[0][..., :3].mean(), abs=4 * math.sqrt(2) * sigma)
