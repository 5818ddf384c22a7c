"""Scratch file format v1: round trips and a table of malformed files."""
import io
import os
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.scratch import FORMAT, ScratchFormatError, ScratchSet


def write_npz(path, arrays, compressed=False):
    (np.savez_compressed if compressed else np.savez)(path, **arrays)
    return path


def valid_arrays(scratches):
    return {"format": np.array(FORMAT), **{k: np.array(v) for k, v in scratches.as_dict().items()}}


# ------------------------------------------------------------------ round trips
@pytest.mark.parametrize("compress", [False, True])
def test_save_load_round_trip_is_exact(tmp_path, plate_scratches, compress):
    path = scratch.save(plate_scratches, tmp_path / "plate.npz", compress=compress)
    loaded = scratch.load(path)
    assert loaded == plate_scratches
    for name, array in loaded.as_dict().items():
        assert array.dtype == getattr(plate_scratches, name).dtype
        np.testing.assert_array_equal(array, getattr(plate_scratches, name))


def test_file_has_exactly_the_documented_keys_and_dtypes(tmp_path, two_scratches):
    path = scratch.save(two_scratches, tmp_path / "s.npz")
    with np.load(path) as archive:
        assert sorted(archive.files) == sorted(
            ["format", "uv", "offsets", "width", "depth", "profile", "width_variation",
             "depth_variation", "seed"])
        assert archive["format"].shape == () and str(archive["format"]) == "scratch-iridescence/1"
        assert archive["uv"].dtype == np.float64 and archive["uv"].shape == (5, 2)
        assert archive["offsets"].dtype == np.int64 and list(archive["offsets"]) == [0, 2, 5]
        assert archive["profile"].dtype == np.uint8 and archive["seed"].dtype == np.uint32
        assert archive["depth_variation"].shape == (2, 2)


def test_reads_files_written_by_plain_numpy(tmp_path, two_scratches):
    for compressed in (False, True):
        path = write_npz(tmp_path / f"numpy{compressed}.npz", valid_arrays(two_scratches), compressed)
        assert scratch.load(path) == two_scratches


def test_big_endian_arrays_are_read(tmp_path, two_scratches):
    arrays = valid_arrays(two_scratches)
    arrays["uv"] = arrays["uv"].astype(">f8")
    arrays["offsets"] = arrays["offsets"].astype(">i8")
    loaded = scratch.load(write_npz(tmp_path / "be.npz", arrays))
    assert loaded == two_scratches and loaded.uv.dtype.isnative


def test_empty_set_round_trips(tmp_path):
    loaded = scratch.load(scratch.save(ScratchSet.empty(), tmp_path / "empty.npz"))
    assert loaded.count == 0 and loaded.uv.shape == (0, 2)


def test_dumps_loads_in_memory(plate_scratches):
    assert scratch.loads(scratch.dumps(plate_scratches)) == plate_scratches


@st.composite
def scratch_sets(draw):
    n = draw(st.integers(0, 12))
    counts = draw(st.lists(st.integers(2, 6), min_size=n, max_size=n))
    finite = st.floats(-1e3, 1e3, allow_nan=False)
    positive = st.floats(1e-12, 1e-3, allow_nan=False, exclude_min=False)
    amplitude = st.floats(0, 10, allow_nan=False)  # (the format's bounds: docs/scratch-format.md)
    frequency = st.floats(0, 1, allow_nan=False)
    polylines = [np.array(draw(st.lists(st.tuples(finite, finite), min_size=c, max_size=c)))
                 for c in counts]
    per = lambda strategy: draw(st.lists(strategy, min_size=n, max_size=n))
    return ScratchSet.from_polylines(
        polylines, width=per(positive), depth=per(positive), profile=per(st.integers(0, 1)),
        width_variation=[(a, f) for a, f in zip(per(amplitude), per(frequency))],
        depth_variation=[(a, f) for a, f in zip(per(amplitude), per(frequency))],
        seed=per(st.integers(0, 2**32 - 1)))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(scratch_sets(), st.booleans())
def test_random_valid_sets_round_trip(tmp_path, scratches, compress):
    path = tmp_path / "random.npz"
    scratch.save(scratches, path, compress=compress)
    assert scratch.load(path) == scratches


# --------------------------------------------------------------- malformed files
def _mutations():
    """(name, field named in the error, function turning valid arrays into bad ones)."""
    def set_(key, value):
        def mutate(a):
            a[key] = value(a) if callable(value) else value
        return mutate

    def delete(key):
        return lambda a: a.pop(key)

    return [
        ("missing uv", "uv", delete("uv")),
        ("missing seed", "seed", delete("seed")),
        ("missing format", "format", delete("format")),
        ("extra key", "colour", set_("colour", np.zeros(2))),
        ("uv float32", "uv", set_("uv", lambda a: a["uv"].astype(np.float32))),
        ("uv 3 columns", "uv", set_("uv", lambda a: np.zeros((5, 3)))),
        ("uv flat", "uv", set_("uv", lambda a: a["uv"].ravel())),
        ("offsets int32", "offsets", set_("offsets", lambda a: a["offsets"].astype(np.int32))),
        ("width float32", "width", set_("width", lambda a: a["width"].astype(np.float32))),
        ("profile int64", "profile", set_("profile", lambda a: a["profile"].astype(np.int64))),
        ("seed int32", "seed", set_("seed", lambda a: a["seed"].astype(np.int32))),
        ("depth 2-d", "depth", set_("depth", lambda a: a["depth"][:, None])),
        ("variation 1-d", "width_variation", set_("width_variation", lambda a: a["width_variation"][:, 0].copy())),
        ("NaN in uv", "uv", set_("uv", lambda a: np.where(np.arange(10).reshape(5, 2) == 3, np.nan, a["uv"]))),
        ("inf width", "width", set_("width", np.array([np.inf, 1e-6]))),
        ("NaN variation", "depth_variation", set_("depth_variation", np.array([[np.nan, 0.0], [0.0, 0.0]]))),
        ("zero width", "width", set_("width", np.array([0.0, 1e-6]))),
        ("negative depth", "depth", set_("depth", np.array([1e-7, -1e-7]))),
        ("negative variation", "width_variation", set_("width_variation", np.array([[-0.1, 0.0], [0.0, 0.0]]))),
        # the format's bounds (docs/scratch-format.md): beyond them no renderer's tables fit any machine
        ("uv spread to 1e300", "uv",
         set_("uv", lambda a: np.where(np.arange(10).reshape(5, 2) == 3, 1e300, a["uv"]))),
        ("uv beyond 1e4", "uv", set_("uv", lambda a: a["uv"] - 10_001.0)),
        ("depth variation amplitude 1e300", "depth_variation",
         set_("depth_variation", np.array([[1e300, 0.04], [0.0, 0.0]]))),
        ("width variation frequency 1e300", "width_variation",
         set_("width_variation", np.array([[1.1, 1e300], [0.0, 0.0]]))),
        ("variation frequency 1.5", "depth_variation", set_("depth_variation", np.array([[1.1, 1.5], [0.0, 0.0]]))),
        ("width of a centimetre", "width", set_("width", np.array([1e-2, 1e-6]))),
        ("depth 1e300", "depth", set_("depth", np.array([1e-7, 1e300]))),
        ("offsets not starting at 0", "offsets", set_("offsets", np.array([1, 2, 5]))),
        ("offsets past the end", "offsets", set_("offsets", np.array([0, 2, 6]))),
        ("scratch of one vertex", "offsets", set_("offsets", np.array([0, 1, 5]))),
        ("decreasing offsets", "offsets", set_("offsets", np.array([0, 4, 2, 5]))),
        ("empty offsets", "offsets", set_("offsets", np.zeros(0, dtype=np.int64))),
        ("too few widths", "width", set_("width", np.array([1e-6]))),
        ("unknown profile", "profile", set_("profile", np.array([0, 7], dtype=np.uint8))),
        ("future format", "format", set_("format", np.array("scratch-iridescence/2"))),
        ("wrong format", "format", set_("format", np.array("something-else/1"))),
        ("format not a string", "format", set_("format", np.array(1))),
        ("format as array", "format", set_("format", np.array(["scratch-iridescence/1"]))),
    ]


@pytest.mark.parametrize("name,field,mutate", _mutations(), ids=[m[0] for m in _mutations()])
def test_malformed_file_raises_one_clear_error(tmp_path, two_scratches, name, field, mutate):
    arrays = valid_arrays(two_scratches)
    mutate(arrays)
    path = write_npz(tmp_path / "bad.npz", arrays)
    with pytest.raises(ScratchFormatError) as caught:
        scratch.load(path)
    error = caught.value
    assert error.field == field
    assert error.path == str(path)
    assert str(path) in str(error) and f"'{field}'" in str(error)


def test_future_format_says_newer_version(tmp_path, two_scratches):
    arrays = valid_arrays(two_scratches)
    arrays["format"] = np.array("scratch-iridescence/3")
    with pytest.raises(ScratchFormatError, match="newer version"):
        scratch.load(write_npz(tmp_path / "future.npz", arrays))


@pytest.mark.parametrize("content", [b"", b"hello, not a zip", b"PK\x03\x04garbage"])
def test_non_zip_files_raise(tmp_path, content):
    path = tmp_path / "junk.npz"
    path.write_bytes(content)
    with pytest.raises(ScratchFormatError, match="not a scratch file") as caught:
        scratch.load(path)
    assert caught.value.path == str(path)


def test_single_npy_array_is_refused(tmp_path):
    path = tmp_path / "array.npy"
    np.save(path, np.zeros(3))
    with pytest.raises(ScratchFormatError, match="npz"):
        scratch.load(path)


@pytest.mark.parametrize("compressed", [False, True])
def test_truncated_file_raises(tmp_path, plate_scratches, compressed):
    path = tmp_path / "full.npz"
    scratch.save(plate_scratches, path, compress=compressed)
    data = path.read_bytes()
    for cut in (len(data) // 3, len(data) - 100):
        truncated = tmp_path / f"cut{cut}.npz"
        truncated.write_bytes(data[:cut])
        with pytest.raises(ScratchFormatError) as caught:
            scratch.load(truncated)
        assert caught.value.path == str(truncated)


def test_corrupt_member_names_its_field(tmp_path, two_scratches):
    path = tmp_path / "corrupt.npz"
    scratch.save(two_scratches, path)
    # Rewrite the archive with the depth member replaced by garbage bytes.
    with zipfile.ZipFile(path) as source:
        members = {name: source.read(name) for name in source.namelist()}
    members["depth.npy"] = b"\x93NUMPY garbage"
    with zipfile.ZipFile(path, "w") as target:
        for name, data in members.items():
            target.writestr(name, data)
    with pytest.raises(ScratchFormatError) as caught:
        scratch.load(path)
    assert caught.value.field == "depth"


def test_missing_file_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        scratch.load(tmp_path / "nothing.npz")


# ------------------------------------------------------------------ safe saving
def test_failed_save_leaves_old_file_and_no_temporary(tmp_path, two_scratches, monkeypatch):
    path = tmp_path / "keep.npz"
    scratch.save(two_scratches, path)
    before = path.read_bytes()

    def explode(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", explode)
    with pytest.raises(OSError, match="disk full"):
        scratch.save(two_scratches, path)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["keep.npz"]


def test_save_refuses_other_objects(tmp_path):
    with pytest.raises(TypeError):
        scratch.save({"uv": np.zeros((2, 2))}, tmp_path / "x.npz")
    assert os.listdir(tmp_path) == []


def test_save_keeps_the_given_name(tmp_path, two_scratches):
    path = scratch.save(two_scratches, tmp_path / "scratches.bin")
    assert path.name == "scratches.bin" and scratch.load(path) == two_scratches


@pytest.mark.slow
@settings(max_examples=1500, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(scratch_sets(), st.booleans())
def test_many_random_valid_sets_round_trip_in_memory(scratches, compress):
    assert scratch.loads(scratch.dumps(scratches, compress=compress)) == scratches
