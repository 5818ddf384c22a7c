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


# Blender clamps an infinity to the property's limit (the largest float where it has none) and passes
# NaN through: both must be refused by name, in either mode, and leave the stored bytes as they were.
@pytest.mark.parametrize("settings, message", [
    (dict(length_max=np.inf), r"Length Max \(3.403e\+38\) is more than 100 times the object's size"),
    (dict(length_max=300.0), r"Length Max \(300\) is more than 100 times the object's size \(2.828"),
    (dict(length_min=np.nan), "Length Min is not a number"),
    (dict(orientation="FIXED", angle=np.nan), "Angle is not a number"),
    (dict(orientation="FIXED", angle=np.inf), "Angle must lie within ±360°"),
    (dict(orientation="FIXED", angle_spread=np.nan), "Spread is not a number"),
    (dict(bend=np.nan), "Bend is not a number"),
    (dict(count=0), "Count is 0: nothing to generate"),
    (dict(count=-5), "Count is 0: nothing to generate"),
    (dict(width_mean=np.inf), r"width G\[3.40282e\+29, 1.3e-06\] \(metres\) reaches 3.4e\+29 m, beyond 0.001 m"),
    (dict(width_std=np.inf), "width G.* reaches .* beyond 0.001 m"),
    (dict(depth_distribution="UNIFORM", depth_max=np.inf), r"depth U\[1e-07, 3.40282e\+29\] .* beyond 0.001 m"),
    (dict(width_distribution="UNIFORM", width_min=np.nan), "Width Min.* is not a number"),
    (dict(depth_mean=np.nan), "Depth Mean.* is not a number"),
    (dict(depth_variation_amplitude=np.inf), r"depth variation: amplitude 3.40282e\+38 must lie in \[0, 10\]"),
    (dict(width_variation_frequency=np.inf), r"width variation: frequency 3.40282e\+38 must lie in \[0, 1\]"),
    (dict(width_variation_amplitude=np.nan), "Width Variation is not a number"),
])
@pytest.mark.parametrize("mode", ["REPLACE", "ADD"])
def test15b_invalid_parameters_are_refused_before_anything_changes(empty_scene, settings, message, mode, capsys):
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    assert generate(count=200, seed=3) == {"FINISHED"}  # the case: an object with 200 scratches
    before = storage.raw_scratch_bytes(plane)
    with pytest.raises(RuntimeError, match=message):
        generate(**{"count": 10, "mode": mode, **settings})
    assert unchanged(plane, before) and storage.scratch_summary(plane)["count"] == 200
    errors = [line for line in capsys.readouterr().out.splitlines() if line.startswith("Error")]
    assert len(errors) == 1 and "generated" not in errors[0]  # one clear report, no success message


def test15c_nothing_placed_is_an_error_not_an_empty_replacement(scratched_plane, monkeypatch):
    import scratch_iridescence.addon.operators.generate as generate_module
    from scratch_iridescence.addon.geometry.scatter import empty_placed

    before = storage.raw_scratch_bytes(scratched_plane)
    monkeypatch.setattr(generate_module, "scatter", lambda *_args, **_kwargs: empty_placed())
    with pytest.raises(RuntimeError, match="None of the 10 scratches could be placed on 'Plane'; its scratches "
                                           "are unchanged"):
        generate(count=10, mode="REPLACE")
    assert unchanged(scratched_plane, before)


def test15d_extreme_but_valid_parameters_work(plane):
    # The limits refuse only the absurd: 1 mm wide, 10x variation at 255 oscillations, 100x the object's size.
    assert generate(count=3, width_distribution="UNIFORM", width_min=1e6, width_max=1e6, depth_mean=1e5,
                    depth_std=3e5, depth_variation_amplitude=10.0, depth_variation_frequency=1.0,
                    length_min=282.0, length_max=282.8, orientation="FIXED", angle=2 * np.pi) == {"FINISHED"}
    scratches = storage.read_scratches(plane)
    assert scratches.count == 3 and np.all(scratches.width == pytest.approx(1e-3))


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
