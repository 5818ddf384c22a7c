"""Stored scratch sets that change or break underneath: every reader sees the bytes, and errors are one message.

The decode cache is keyed by the bytes (their SHA-256), the token is only a hint:
after the bytes change under an unchanged token, render and Export use the new
bytes; damaged bytes give the same ``StoredScratchesError`` to the overlay, the
eraser, Export, Export Mitsuba Scene and F12, never a traceback or a silent
substitute.
"""

import pytest
from damaged_files import overflowing_offsets_file

bpy = pytest.importorskip("bpy")
from strokes import stroke  # noqa: E402
from render_scenes import add_camera, add_light, setup_render  # noqa: E402
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.addon.ui.overlay import overlay_data, overlay_error  # noqa: E402
from scratch_iridescence.addon.render.gather import GatherError, gather_scene  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scratch  # noqa: E402

FIRST = scratch.random_scratches(40, seed=21, region=((0.1, 0.1), (0.9, 0.9)), length=(0.05, 0.1))
SECOND = scratch.random_scratches(25, seed=22, region=((0.1, 0.1), (0.9, 0.9)), length=(0.05, 0.1))


def replace_bytes_keeping_the_token(obj, data: bytes) -> None:
    """What a damaged .blend or a script does: other bytes under the same token and summary."""
    del obj[storage.DATA_KEY]  # a fresh key keeps bytes after a NUL (see storage.write_scratches)
    obj[storage.DATA_KEY] = data


def damaged(data: bytes) -> bytes:
    """``data`` with one byte of the uv member changed: only the CRC can tell."""
    position = data.index(b"uv.npy") + 300
    return data[:position] + bytes([data[position] ^ 0x40]) + data[position + 1:]


@pytest.fixture
def stored(plane):
    storage.write_scratches(plane, FIRST)
    assert storage.read_scratches(plane) == FIRST  # decoded and cached
    return plane


def gathered_scratches(scene):
    (metal,) = [m for m in gather_scene(bpy.context.evaluated_depsgraph_get()).materials.values()
                if hasattr(m, "scratches")]
    return metal.scratches


# ---------------------------------------------------------------- changed bytes
def test_changed_bytes_under_the_same_token_are_decoded_again(stored):
    token = storage.scratch_token(stored)
    replace_bytes_keeping_the_token(stored, scratch.dumps(SECOND))
    assert storage.scratch_token(stored) == token
    assert storage.read_scratches(stored) == SECOND


def test_render_and_export_use_the_new_bytes(stored, tmp_path):
    add_camera(stored.users_scene[0])
    assert gathered_scratches(stored.users_scene[0]) == FIRST
    replace_bytes_keeping_the_token(stored, scratch.dumps(SECOND))
    assert gathered_scratches(stored.users_scene[0]) == SECOND
    path = tmp_path / "exported.npz"
    assert bpy.ops.scratch.export_file(filepath=str(path)) == {"FINISHED"}
    assert path.read_bytes() == scratch.dumps(SECOND)


def test_damaged_blend_reopened_in_the_same_session_is_refused(stored, tmp_path):
    good, bad = str(tmp_path / "good.blend"), str(tmp_path / "bad.blend")
    bpy.ops.wm.save_as_mainfile(filepath=good)
    replace_bytes_keeping_the_token(stored, damaged(storage.raw_scratch_bytes(stored)))
    bpy.ops.wm.save_as_mainfile(filepath=bad)
    bpy.ops.wm.open_mainfile(filepath=good)
    assert storage.read_scratches(bpy.data.objects["Plane"]) == FIRST  # the good set is in the cache
    bpy.ops.wm.open_mainfile(filepath=bad)
    plane = bpy.data.objects["Plane"]
    with pytest.raises(storage.StoredScratchesError, match="object 'Plane' \\(stored scratches\\)"):
        storage.read_scratches(plane)
    path = tmp_path / "exported.npz"
    with pytest.raises(RuntimeError, match="object 'Plane' \\(stored scratches\\): field 'uv'"):
        bpy.ops.scratch.export_file(filepath=str(path))
    assert not path.exists()


# ------------------------------------------------------- every reader, one error


@pytest.fixture
def broken(stored):
    """The plane whose stored set is the overflowing file (as a damaged .blend would hold it)."""
    replace_bytes_keeping_the_token(stored, overflowing_offsets_file())
    return stored


MESSAGE = r"object 'Plane' \(stored scratches\): field 'offsets': offsets\[1\] is 9223372036854775807, outside"


def test_import_refuses_the_file_and_keeps_the_stored_set(stored, tmp_path):
    path = tmp_path / "overflow.npz"
    path.write_bytes(overflowing_offsets_file())
    before = storage.raw_scratch_bytes(stored)
    with pytest.raises(RuntimeError, match=f"{path}: field 'offsets': offsets\\[1\\] is 9223372036854775807"):
        bpy.ops.scratch.import_file(filepath=str(path), mode="ADD")
    assert storage.raw_scratch_bytes(stored) == before


def test_eraser_reports_the_damaged_set_and_keeps_it(broken):
    before = storage.raw_scratch_bytes(broken)
    points = [(-0.5, 0.0, 0.0), (0.5, 0.0, 0.0)]
    with pytest.raises(RuntimeError, match=MESSAGE):
        bpy.ops.scratch.erase_stroke("EXEC_DEFAULT", True, stroke=stroke(points), radius=0.2)
    assert storage.raw_scratch_bytes(broken) == before


def test_export_reports_the_damaged_set(broken, tmp_path):
    with pytest.raises(RuntimeError, match=MESSAGE):
        bpy.ops.scratch.export_file(filepath=str(tmp_path / "x.npz"))
    assert not (tmp_path / "x.npz").exists()


def test_generate_add_mode_reports_the_damaged_set_and_keeps_it(broken):
    before = storage.raw_scratch_bytes(broken)
    with pytest.raises(RuntimeError, match=MESSAGE):
        bpy.ops.scratch.generate(count=5, mode="ADD")
    assert storage.raw_scratch_bytes(broken) == before


def test_overlay_draws_nothing_and_the_panel_shows_the_error(broken):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    with pytest.raises(storage.StoredScratchesError, match=MESSAGE):
        overlay_data(broken, depsgraph)
    assert overlay_error(broken) is not None and "offsets[1]" in overlay_error(broken)
    storage.write_scratches(broken, SECOND)  # repaired: the error is no longer current
    assert overlay_error(broken) is None
    assert len(overlay_data(broken, depsgraph).positions) > 0


def test_gather_and_f12_refuse_the_damaged_set(broken, tmp_path):
    scene = broken.users_scene[0]
    setup_render(scene)
    add_camera(scene)
    add_light(scene, "POINT")
    with pytest.raises(GatherError, match=MESSAGE):
        gather_scene(bpy.context.evaluated_depsgraph_get())
    scene.render.filepath = str(tmp_path / "frame.exr")
    with pytest.raises(RuntimeError, match=MESSAGE):
        bpy.ops.render.render(write_still=True)
    assert not (tmp_path / "frame.exr").exists()


def test_export_mitsuba_scene_refuses_the_damaged_set(broken, tmp_path):
    add_camera(broken.users_scene[0])
    folder = tmp_path / "scene"
    with pytest.raises(RuntimeError, match=MESSAGE):
        bpy.ops.scratch.export_mitsuba(directory=str(folder))
    assert not (folder / "scene.xml").exists()


def test_property_of_another_type_is_the_same_error(stored):
    replace_bytes_keeping_the_token(stored, "a string, not bytes")
    with pytest.raises(storage.StoredScratchesError, match="holds str, not the bytes"):
        storage.read_scratches(stored)


def test_eraser_maps_the_new_bytes_not_lines_cached_for_the_old_ones(stored):
    line = [(-0.9, 0.0, 0.0), (0.9, 0.0, 0.0)]
    erase = lambda: bpy.ops.scratch.erase_stroke("EXEC_DEFAULT", True, stroke=stroke(line), radius=0.3,  # noqa: E731
                                                 erase_mode="WHOLE")
    assert erase() == {"FINISHED"}  # caches the line pieces of what is stored now
    replace_bytes_keeping_the_token(stored, scratch.dumps(SECOND))
    erase()
    left = storage.read_scratches(stored)
    second = {SECOND.polyline(i).tobytes() for i in range(SECOND.count)}
    assert 0 < left.count < SECOND.count
    assert all(left.polyline(i).tobytes() in second for i in range(left.count))
