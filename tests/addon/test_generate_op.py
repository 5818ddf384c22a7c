"""``scratch.generate`` in headless Blender: placement, statistics, units, undo, reload, errors."""
import numpy as np
import pytest
from scipy import stats

bpy = pytest.importorskip("bpy")
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.addon.mesh import world_surface  # noqa: E402
from scratch_iridescence.addon.geometry.uvmap import UVLocator  # noqa: E402

P_MIN = 1e-3


def generate(**kwargs):
    kwargs.setdefault("seed", 1)
    return bpy.ops.scratch.generate("EXEC_DEFAULT", True, **kwargs)


def uv_lengths(scratches):
    step = np.linalg.norm(np.diff(scratches.uv, axis=0), axis=1)
    step = np.r_[0.0, step]
    step[scratches.offsets[:-1]] = 0.0
    return np.add.reduceat(step, scratches.offsets[:-1])


def test01_replace_and_add(scratched_plane):
    before = storage.read_scratches(scratched_plane)
    assert generate(count=200, mode="REPLACE") == {"FINISHED"}
    replaced = storage.read_scratches(scratched_plane)
    assert replaced.count == 200  # a flat plane has no seam: one scratch per request
    assert generate(count=200, mode="ADD", seed=2) == {"FINISHED"}
    added = storage.read_scratches(scratched_plane)
    assert added.count == 400 and added.select(np.arange(200)) == replaced
    assert before.count == 50


def test02_same_seed_same_bytes(plane):
    generate(count=300, seed=7)
    first = storage.raw_scratch_bytes(plane)
    generate(count=300, seed=7)
    assert storage.raw_scratch_bytes(plane) == first
    generate(count=300, seed=8)
    assert storage.raw_scratch_bytes(plane) != first


@pytest.mark.parametrize("angle, metres_per_uv", [(0.0, 6.0), (90.0, 2.0)])
def test03_lengths_are_measured_on_the_scaled_surface(plane, angle, metres_per_uv):
    plane.scale = (3.0, 1.0, 1.0)  # world 6 m x 2 m; UV 1 x 1
    bpy.context.view_layer.update()
    generate(count=500, length_min=0.05, length_max=0.1, orientation="FIXED", angle=np.radians(angle),
             angle_spread=0.0)
    scratches = storage.read_scratches(plane)
    length = uv_lengths(scratches) * metres_per_uv
    ends = scratches.uv[np.r_[scratches.offsets[:-1], scratches.offsets[1:] - 1]]
    on_border = np.isclose(ends, 0.0) | np.isclose(ends, 1.0)
    cut = on_border.any(axis=1).reshape(2, -1).any(axis=0)
    assert np.all(length <= 0.1 + 1e-9)
    assert np.all(length[~cut] >= 0.05 - 1e-9)
    assert stats.kstest(length[~cut], "uniform", args=(0.05, 0.05)).pvalue > P_MIN


def test04_widths_and_depths_are_nanometres_whatever_the_unit_scale(plane):
    bpy.context.scene.unit_settings.scale_length = 0.001  # a millimetre scene
    generate(count=2000, depth_distribution="UNIFORM", depth_min=100.0, depth_max=500.0,
             width_distribution="GAUSSIAN", width_mean=4000.0, width_std=1300.0)
    scratches = storage.read_scratches(plane)
    assert stats.kstest(scratches.depth, "uniform", args=(100e-9, 400e-9)).pvalue > P_MIN
    reference = stats.truncnorm(-4000 / 1300, np.inf, loc=4e-6, scale=1.3e-6)
    assert stats.kstest(scratches.width, reference.cdf).pvalue > P_MIN
    assert stats.kstest(scratches.width, stats.norm(4.2e-6, 1.3e-6).cdf).pvalue < P_MIN
    summary = storage.scratch_summary(plane)
    assert summary["mean_depth"] == pytest.approx(300e-9, rel=0.05)


def test05_profile_variation_and_bend_reach_the_file(plane):
    generate(count=100, profile="TRIANGULAR", depth_variation_amplitude=1.1, depth_variation_frequency=0.04,
             width_variation_amplitude=0.3, width_variation_frequency=0.01, bend=np.radians(40))
    scratches = storage.read_scratches(plane)
    assert np.all(scratches.profile == 1)
    np.testing.assert_allclose(scratches.depth_variation, np.tile([1.1, 0.04], (100, 1)), rtol=1e-6)
    np.testing.assert_allclose(scratches.width_variation, np.tile([0.3, 0.01], (100, 1)), rtol=1e-6)
    assert scratches.vertex_counts.min() > 3  # arcs are polylines


def test06_cube_scratches_are_uniform_over_faces_and_cut_at_seams(cube):
    generate(count=3000, length_min=0.02, length_max=0.05)
    scratches = storage.read_scratches(cube)
    surface = world_surface(cube, bpy.context.evaluated_depsgraph_get())
    triangle, bary = UVLocator(surface.uv).locate(scratches.uv[scratches.offsets[:-1]])
    assert np.all(triangle >= 0)
    start = surface.point(triangle, bary)
    axis = np.argmax(np.abs(start), axis=1)
    face = axis * 2 + (start[np.arange(len(start)), axis] > 0)
    counts = np.bincount(face, minlength=6)
    assert stats.chisquare(counts).pvalue > P_MIN


def test07_seams_become_separate_scratches_that_stay_on_the_surface(cube):
    generate(count=300, length_min=0.8, length_max=1.6)
    scratches = storage.read_scratches(cube)
    assert scratches.count > 300
    surface = world_surface(cube, bpy.context.evaluated_depsgraph_get())
    triangle, bary = UVLocator(surface.uv).locate(scratches.uv)
    assert np.all(triangle >= 0)
    points = surface.point(triangle, bary)
    # Along every scratch, UV steps and surface steps agree (the default cube maps 2 m to 0.25 in UV).
    inside = np.ones(len(points) - 1, dtype=bool)
    inside[scratches.offsets[1:-1] - 1] = False
    step_3d = np.linalg.norm(np.diff(points, axis=0), axis=1)[inside]
    step_uv = np.linalg.norm(np.diff(scratches.uv, axis=0), axis=1)[inside]
    np.testing.assert_allclose(step_uv, step_3d / 8.0, rtol=1e-6, atol=1e-9)


def test08_fixed_direction_is_in_each_face_s_tangent_space(cube):
    generate(count=400, length_min=0.02, length_max=0.04, orientation="FIXED", angle=np.radians(30),
             angle_spread=0.0)
    scratches = storage.read_scratches(cube)
    first, last = scratches.uv[scratches.offsets[:-1]], scratches.uv[scratches.offsets[1:] - 1]
    heading = np.degrees(np.mod(np.arctan2(*(last - first)[:, ::-1].T), np.pi))
    assert np.mean(np.abs(heading - 30.0) < 1e-4) > 0.9  # all but scratches bent over a cube edge


def test09_undo_and_redo(scratched_plane):
    bpy.ops.ed.undo_push(message="before")
    before = storage.raw_scratch_bytes(scratched_plane)
    generate(count=100)
    after = storage.raw_scratch_bytes(bpy.data.objects["Plane"])
    bpy.ops.ed.undo()
    assert storage.raw_scratch_bytes(bpy.data.objects["Plane"]) == before
    bpy.ops.ed.redo()
    assert storage.raw_scratch_bytes(bpy.data.objects["Plane"]) == after


def test10_save_and_reload_keep_every_byte(plane, tmp_path):
    generate(count=1000, depth_variation_amplitude=1.1, bend=0.3)
    data = storage.raw_scratch_bytes(plane)
    path = str(tmp_path / "generated.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    assert storage.raw_scratch_bytes(bpy.data.objects["Plane"]) == data


# ------------------------------------------------------------------ errors
def unchanged(obj, before):
    return storage.raw_scratch_bytes(bpy.data.objects[obj.name]) == before


def test11_mesh_without_uv_map(scratched_plane):
    before = storage.raw_scratch_bytes(scratched_plane)
    mesh = scratched_plane.data
    while mesh.uv_layers:
        mesh.uv_layers.remove(mesh.uv_layers[0])
    mesh.update()
    with pytest.raises(RuntimeError, match="has no UV map"):
        generate(count=10)
    assert unchanged(scratched_plane, before)


def test12_object_that_is_not_a_mesh(empty_scene):
    bpy.ops.object.empty_add()
    empty = bpy.context.active_object
    with pytest.raises(RuntimeError, match="is a empty object; scratches can only be put on mesh objects"):
        generate(count=10)
    assert storage.raw_scratch_bytes(empty) is None
    bpy.ops.curve.primitive_bezier_curve_add()
    with pytest.raises(RuntimeError, match="curve object"):
        generate(count=10)


def test12b_no_active_object(empty_scene):
    with pytest.raises(RuntimeError, match="No active object"):
        generate(count=10)


def test12c_arcs_too_long_for_the_segment_limit_are_reported(plane, capsys):
    generate(count=5, length_min=1.0, length_max=1.5, bend=np.radians(90), width_distribution="UNIFORM",
             width_min=100.0, width_max=200.0)
    assert "5 arcs would need more than 256 straight segments" in capsys.readouterr().out
    assert storage.read_scratches(plane).vertex_counts.max() <= 258


def test13_faces_without_uv_area(scratched_plane):
    before = storage.raw_scratch_bytes(scratched_plane)
    layer = scratched_plane.data.uv_layers.active
    layer.data.foreach_set("uv", [0.5] * (2 * len(layer.data)))
    scratched_plane.data.update()
    with pytest.raises(RuntimeError, match="zero area in UV map 'UVMap'"):
        generate(count=10)
    assert unchanged(scratched_plane, before)


def test13b_some_faces_without_uv_area_are_skipped_with_a_warning(empty_scene, capsys):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=3, y_subdivisions=3, size=2.0)  # 2 x 2 quads
    grid = bpy.context.active_object
    layer = grid.data.uv_layers.active
    for loop in grid.data.polygons[0].loop_indices:
        layer.data[loop].uv = (0.1, 0.1)
    grid.data.update()
    assert generate(count=400, length_min=0.01, length_max=0.02) == {"FINISHED"}
    assert "2 faces without area in 3D or in the UV map got no scratches" in capsys.readouterr().out
    scratches = storage.read_scratches(grid)
    surface = world_surface(grid, bpy.context.evaluated_depsgraph_get())
    triangle, bary = UVLocator(surface.uv, surface.usable).locate(scratches.uv)
    assert np.all(triangle >= 0) and np.all(surface.usable[triangle])
    corners = np.array([grid.data.vertices[v].co[:2] for v in grid.data.polygons[0].vertices])
    middle = surface.point(triangle, bary)[:, :2]
    inside = np.all((middle > corners.min(axis=0) + 1e-9) & (middle < corners.max(axis=0) - 1e-9), axis=1)
    assert not inside.any()


def test14_count_beyond_memory(scratched_plane):
    before = storage.raw_scratch_bytes(scratched_plane)
    with pytest.raises(RuntimeError, match="needs about .* GiB of memory"):
        generate(count=2**31 - 1)
    assert unchanged(scratched_plane, before)


def test14b_running_out_of_memory_midway(scratched_plane, monkeypatch):
    import scratch_iridescence.addon.operators.generate as generate_module

    def exhausted(*_args, **_kwargs):
        raise MemoryError()

    before = storage.raw_scratch_bytes(scratched_plane)
    monkeypatch.setattr(generate_module, "scatter", exhausted)
    with pytest.raises(RuntimeError, match="Not enough memory"):
        generate(count=10)
    assert unchanged(scratched_plane, before)


@pytest.mark.parametrize("settings, message", [
    (dict(depth_distribution="UNIFORM", depth_min=500.0, depth_max=100.0), "Depth: the maximum"),
    (dict(width_distribution="GAUSSIAN", width_mean=0.0, width_std=0.0), "no positive values"),
    (dict(length_min=0.2, length_max=0.1), "Length Max is below Length Min"),
])
def test15_impossible_settings(scratched_plane, settings, message):
    before = storage.raw_scratch_bytes(scratched_plane)
    with pytest.raises(RuntimeError, match=message):
        generate(count=10, **settings)
    assert unchanged(scratched_plane, before)


def test16_edit_mode_is_refused(plane):
    bpy.ops.object.mode_set(mode="EDIT")
    with pytest.raises(RuntimeError, match="Object Mode"):
        generate(count=10)
    bpy.ops.object.mode_set(mode="OBJECT")


def test17_the_evaluated_mesh_is_scratched(plane):
    modifier = plane.modifiers.new("Array", "ARRAY")
    modifier.count = 3
    modifier.use_merge_vertices = True
    modifier.offset_u = 1.0
    bpy.context.view_layer.update()
    generate(count=3000, length_min=0.01, length_max=0.02)
    scratches = storage.read_scratches(plane)
    # The array's copies share the plane's UVs, each at an offset of 1 in U: scratches on all three.
    u = scratches.uv[scratches.offsets[:-1], 0]
    counts = np.histogram(u, bins=[0, 1, 2, 3])[0]
    assert stats.chisquare(counts).pvalue > P_MIN


@pytest.mark.slow
def test18_the_dining_table_scale(plane, tmp_path):
    # The paper's dining table: 300 000 scratches, stored, reloaded and drawn.
    from scratch_iridescence.addon.ui.overlay import overlay_data

    assert generate(count=300_000, length_min=0.005, length_max=0.03) == {"FINISHED"}
    data = storage.raw_scratch_bytes(plane)
    assert storage.scratch_summary(plane)["count"] == 300_000
    path = str(tmp_path / "table.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    table = bpy.data.objects["Plane"]
    assert storage.raw_scratch_bytes(table) == data
    lines = overlay_data(table, bpy.context.evaluated_depsgraph_get())
    assert lines.unplaced == 0 and len(lines.positions) >= 2 * 300_000
