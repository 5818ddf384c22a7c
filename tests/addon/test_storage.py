"""Scratches stored in the .blend: exact round trips through save/reload and undo."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scratch  # noqa: E402


@pytest.fixture
def plate_set():
    return scratch.random_scratches(2000, seed=11, width=scratch.Gaussian(4e-6, 1.3e-6),
                                    depth=scratch.Gaussian(250e-9, 80e-9), vertices=6, curvature=1.0,
                                    depth_variation=(1.1, 0.04))


def test_new_object_has_no_scratches(plane):
    assert not storage.has_scratches(plane)
    assert storage.read_scratches(plane).count == 0
    assert storage.scratch_summary(plane) == {"count": 0, "mean_width": 0.0, "mean_depth": 0.0}


def test_write_read_is_exact_and_summarised(plane, plate_set):
    storage.write_scratches(plane, plate_set)
    assert storage.read_scratches(plane) == plate_set
    summary = storage.scratch_summary(plane)
    assert summary["count"] == 2000
    assert summary["mean_width"] == pytest.approx(plate_set.width.mean())
    assert summary["mean_depth"] == pytest.approx(plate_set.depth.mean())
    assert storage.raw_scratch_bytes(plane) == scratch.dumps(plate_set)


def test_rewriting_keeps_every_byte(plane, plate_set):
    # Blender truncates re-assigned byte strings at the first NUL; storage must not.
    storage.write_scratches(plane, plate_set.select(np.arange(10)))
    storage.write_scratches(plane, plate_set)
    assert storage.raw_scratch_bytes(plane) == scratch.dumps(plate_set)


def test_token_changes_on_every_write(plane, plate_set):
    storage.write_scratches(plane, plate_set)
    first = storage.scratch_token(plane)
    storage.write_scratches(plane, plate_set)
    assert storage.scratch_token(plane) not in (None, first)


def test_save_and_reload_is_bit_for_bit(plane, plate_set, tmp_path):
    storage.write_scratches(plane, plate_set)
    path = str(tmp_path / "scratched.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Plane"]
    assert storage.raw_scratch_bytes(obj) == scratch.dumps(plate_set)
    storage._decoded.clear()  # decode from the file, not from the cache
    assert storage.read_scratches(obj) == plate_set


def test_undo_and_redo_restore_scratches(plane, plate_set):
    bpy.ops.ed.undo_push(message="plane")
    storage.write_scratches(plane, plate_set.select(np.arange(5)))
    bpy.ops.ed.undo_push(message="five")
    storage.write_scratches(plane, plate_set)
    bpy.ops.ed.undo_push(message="all")
    bpy.ops.ed.undo()
    assert storage.read_scratches(bpy.data.objects["Plane"]) == plate_set.select(np.arange(5))
    bpy.ops.ed.undo()
    assert not storage.has_scratches(bpy.data.objects["Plane"])
    bpy.ops.ed.redo()
    bpy.ops.ed.redo()
    assert storage.read_scratches(bpy.data.objects["Plane"]) == plate_set


def test_clear(plane, plate_set):
    storage.write_scratches(plane, plate_set)
    storage.clear_scratches(plane)
    assert not storage.has_scratches(plane) and storage.read_scratches(plane).count == 0


def test_damaged_bytes_raise_a_clear_error(plane):
    plane[storage.DATA_KEY] = b"not a scratch file"
    plane[storage.SUMMARY_KEY] = {"count": 1, "mean_width": 1.0, "mean_depth": 1.0}
    with pytest.raises(scratch.ScratchFormatError, match="not a scratch file"):
        storage.read_scratches(plane)


def test_object_settings_have_the_bsdf_defaults(plane):
    from scratch_iridescence.mitsuba_bridge.bsdf.parameters import DEFAULT_COHERENCE_DIAMETER_M
    assert plane.scratch_iridescence.coherence_diameter_um == pytest.approx(DEFAULT_COHERENCE_DIAMETER_M * 1e6)
    assert plane.scratch_iridescence.base_material == "Al" and plane.scratch_iridescence.coherent


def test_a_file_of_version_0_1_loads_with_the_same_settings(plane, tmp_path):
    # Version 0.1 registered Object.scratch (coherence diameter in scene units) and
    # Scene.scratch_iridescence; a saved file holds them as these ID property groups.
    scene = bpy.context.scene
    scene.unit_settings.scale_length = 0.01  # a centimetre scene: 0.004 units = 40 µm
    gold = [item.identifier for item in plane.scratch_iridescence.bl_rna.properties["base_material"].enum_items]
    plane["scratch"] = {"coherence_diameter": 0.004, "coherent": 0, "base_material": gold.index("Au"),
                        "diffuse_reflectance": [0.1, 0.2, 0.3], "overlay_color_by": 1}
    scene["scratch_iridescence"] = {"samples": 7, "max_depth": 3}
    path = tmp_path / "old.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    plane, scene = bpy.data.objects["Plane"], bpy.context.scene
    settings = plane.scratch_iridescence
    assert settings.coherence_diameter_um == pytest.approx(40.0)
    assert settings.base_material == "Au" and not settings.coherent and settings.overlay_color_by == "WIDTH"
    assert tuple(settings.diffuse_reflectance) == pytest.approx((0.1, 0.2, 0.3))
    assert scene.scratch_iridescence.samples == 7 and scene.scratch_iridescence.max_depth == 3
    assert "scratch" not in plane and "scratch_iridescence" not in scene
    # Saved again, it is a current file: nothing left to upgrade.
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert bpy.data.objects["Plane"].scratch_iridescence.coherence_diameter_um == pytest.approx(40.0)


def test_enabling_the_addon_upgrades_the_open_file(plane):
    from scratch_iridescence.addon import versioning

    plane["scratch"] = {"coherence_diameter": 5e-5, "show_overlay": 0}  # metres: scale_length 1
    versioning.register()  # as when the add-on is enabled in the preferences with this file open
    assert plane.scratch_iridescence.coherence_diameter_um == pytest.approx(50.0)
    assert not plane.scratch_iridescence.show_overlay and "scratch" not in plane
    assert bpy.app.handlers.load_post.count(versioning._on_load) == 1
