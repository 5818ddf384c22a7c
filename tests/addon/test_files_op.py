"""``scratch.clear``, ``scratch.import_file`` and ``scratch.export_file`` in headless Blender."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scratch  # noqa: E402


def test01_export_writes_the_stored_bytes_deterministically(scratched_plane, tmp_path):
    first, second = tmp_path / "a.npz", tmp_path / "b.npz"
    assert bpy.ops.scratch.export_file(filepath=str(first)) == {"FINISHED"}
    assert bpy.ops.scratch.export_file(filepath=str(second)) == {"FINISHED"}
    assert first.read_bytes() == second.read_bytes() == storage.raw_scratch_bytes(scratched_plane)
    assert scratch.load(first) == storage.read_scratches(scratched_plane)


def test02_export_of_an_unscratched_object_is_an_empty_file(plane, tmp_path):
    path = tmp_path / "empty.npz"
    bpy.ops.scratch.export_file(filepath=str(path))
    assert scratch.load(path).count == 0


def test03_import_replaces_or_adds(scratched_plane, tmp_path):
    before = storage.read_scratches(scratched_plane)
    other = scratch.random_scratches(30, seed=9, region=((0.2, 0.2), (0.8, 0.8)), length=(0.05, 0.1))
    path = scratch.save(other, tmp_path / "other.npz")
    assert bpy.ops.scratch.import_file("EXEC_DEFAULT", True, filepath=str(path), mode="ADD") == {"FINISHED"}
    assert storage.read_scratches(scratched_plane) == scratch.ScratchSet.concatenate([before, other])
    bpy.ops.scratch.import_file(filepath=str(path), mode="REPLACE")
    assert storage.read_scratches(scratched_plane) == other
    # and back out, byte for byte
    exported = tmp_path / "again.npz"
    bpy.ops.scratch.export_file(filepath=str(exported))
    assert scratch.load(exported) == other


def test04_import_undo(scratched_plane, tmp_path):
    bpy.ops.ed.undo_push(message="before")
    before = storage.raw_scratch_bytes(scratched_plane)
    path = scratch.save(scratch.random_scratches(5, seed=1), tmp_path / "five.npz")
    bpy.ops.scratch.import_file("EXEC_DEFAULT", True, filepath=str(path))
    bpy.ops.ed.undo()
    assert storage.raw_scratch_bytes(bpy.data.objects["Plane"]) == before


@pytest.mark.parametrize("content, message", [
    (b"not a zip archive", "not a scratch file"),
    (None, "field 'width': must be > 0"),
    ("missing", "No scratch file"),
])
def test05_bad_files_are_refused_and_change_nothing(scratched_plane, tmp_path, content, message):
    before = storage.raw_scratch_bytes(scratched_plane)
    path = tmp_path / "bad.npz"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is None:
        arrays = scratch.random_scratches(3).as_dict()
        arrays["width"] = np.array([1e-6, 0.0, 1e-6])
        np.savez(path, format=np.array(scratch.FORMAT), **arrays)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.scratch.import_file(filepath=str(path))
    assert storage.raw_scratch_bytes(scratched_plane) == before


def one_long_scratch(vertices: int) -> scratch.ScratchSet:
    """One scratch of ``vertices`` vertices zigzagging on the plane (a small file: it compresses well)."""
    uv = np.empty((vertices, 2))
    uv[0::2], uv[1::2] = (0.3, 0.3), (0.7, 0.7)
    return scratch.ScratchSet.from_polylines([uv], width=4e-6, depth=2e-7)


def test05b_a_pathological_file_is_refused_at_once_with_an_estimate(scratched_plane, tmp_path):
    """One scratch of 2**24 vertices (a valid file of under a megabyte) would keep Blender's UI busy for seconds:
    refused from its headers, before anything is inflated, saying what it would cost."""
    import time

    from scratch_iridescence.addon.operators.files import MAX_IMPORT_VERTICES

    path = scratch.save(one_long_scratch(1 << 24), tmp_path / "long.npz", compress=True)
    assert path.stat().st_size < 1 << 20
    before = storage.raw_scratch_bytes(scratched_plane)
    started = time.perf_counter()
    with pytest.raises(RuntimeError, match=r"long.npz holds 16,777,216 vertices in 1 scratch: importing it would keep "
                                           r"Blender busy for about \d+ s and need about 1.5 GiB; at most "
                                           f"{MAX_IMPORT_VERTICES:,} vertices"):
        bpy.ops.scratch.import_file(filepath=str(path))
    assert time.perf_counter() - started < 0.5
    assert storage.raw_scratch_bytes(scratched_plane) == before


def test05c_the_largest_import_stays_near_a_second_and_a_fifo_is_refused(plane, tmp_path):
    import os
    import time

    from scratch_iridescence.addon.operators.files import MAX_IMPORT_VERTICES

    path = scratch.save(one_long_scratch(MAX_IMPORT_VERTICES), tmp_path / "largest.npz", compress=True)
    started = time.perf_counter()
    assert bpy.ops.scratch.import_file(filepath=str(path)) == {"FINISHED"}
    seconds = time.perf_counter() - started
    assert storage.read_scratches(plane).vertex_count == MAX_IMPORT_VERTICES
    assert seconds < 6.0, seconds  # (about 1.2 s on the 2-core machine; the margin is for a loaded one)
    fifo = tmp_path / "pipe.npz"
    os.mkfifo(fifo)
    with pytest.raises(RuntimeError, match="is a FIFO"):
        bpy.ops.scratch.import_file(filepath=str(fifo))


def test06_import_warns_about_scratches_outside_the_uv_map(plane, tmp_path, capsys):
    outside = scratch.ScratchSet.from_polylines([np.array([[1.5, 1.5], [1.6, 1.6]]),
                                                 np.array([[0.2, 0.2], [0.3, 0.3]])], width=1e-6, depth=1e-7)
    path = scratch.save(outside, tmp_path / "outside.npz")
    assert bpy.ops.scratch.import_file(filepath=str(path)) == {"FINISHED"}
    assert "1 scratch of outside.npz lies outside the UV islands" in capsys.readouterr().out


def test06b_import_onto_a_mesh_without_uv_map_warns(scratched_plane, tmp_path, capsys):
    mesh = scratched_plane.data
    while mesh.uv_layers:
        mesh.uv_layers.remove(mesh.uv_layers[0])
    mesh.update()
    other = scratch.random_scratches(7, seed=2)
    path = scratch.save(other, tmp_path / "seven.npz")
    assert bpy.ops.scratch.import_file(filepath=str(path), mode="REPLACE") == {"FINISHED"}
    assert storage.read_scratches(scratched_plane) == other  # stored: they show once the mesh is unwrapped
    out = capsys.readouterr().out
    assert "Warning: 'Plane' has no UV map: the imported scratches are stored but will not show" in out


def test06c_an_empty_file_never_replaces_scratches_silently(scratched_plane, tmp_path, capsys):
    before = storage.raw_scratch_bytes(scratched_plane)
    path = scratch.save(scratch.ScratchSet.empty(), tmp_path / "empty.npz")
    assert bpy.ops.scratch.import_file(filepath=str(path), mode="ADD") == {"CANCELLED"}
    assert storage.raw_scratch_bytes(scratched_plane) == before
    assert "empty.npz holds no scratches: nothing to add to Plane" in capsys.readouterr().out
    # REPLACE does what it is asked (undo brings them back) and says what was lost.
    assert bpy.ops.scratch.import_file(filepath=str(path), mode="REPLACE") == {"FINISHED"}
    assert storage.read_scratches(scratched_plane).count == 0
    assert ("Warning: empty.npz holds no scratches: the 50 scratches of Plane were replaced by none"
            in capsys.readouterr().out)


def test07_export_refuses_damaged_storage_and_non_meshes(plane, tmp_path):
    plane[storage.DATA_KEY] = b"garbage"
    plane[storage.SUMMARY_KEY] = {"count": 1, "mean_width": 1.0, "mean_depth": 1.0}
    with pytest.raises(RuntimeError, match="not a scratch file"):
        bpy.ops.scratch.export_file(filepath=str(tmp_path / "x.npz"))
    assert not (tmp_path / "x.npz").exists()
    bpy.ops.object.empty_add()
    with pytest.raises(RuntimeError, match="mesh objects"):
        bpy.ops.scratch.export_file(filepath=str(tmp_path / "y.npz"))


def test08_clear_and_its_undo(scratched_plane):
    bpy.ops.ed.undo_push(message="before")
    before = storage.raw_scratch_bytes(scratched_plane)
    assert bpy.ops.scratch.clear("EXEC_DEFAULT", True) == {"FINISHED"}
    assert not storage.has_scratches(bpy.data.objects["Plane"])
    assert bpy.ops.scratch.clear() == {"CANCELLED"}  # nothing left to clear
    bpy.ops.ed.undo()
    assert storage.raw_scratch_bytes(bpy.data.objects["Plane"]) == before
