"""``scratch.save_bytes``: writing a scratch file kept as bytes, atomically."""
import os

import pytest

from scratch_iridescence.mitsuba_bridge import scratch


def test_saved_bytes_are_the_file(tmp_path, plate_scratches):
    data = scratch.dumps(plate_scratches)
    path = scratch.save_bytes(data, tmp_path / "plate.npz")
    assert path.read_bytes() == data
    assert scratch.load(path) == plate_scratches


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path, monkeypatch, two_scratches):
    path = tmp_path / "kept.npz"
    scratch.save(two_scratches, path)
    old = path.read_bytes()

    def broken_replace(*_):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        scratch.save_bytes(b"new content", path)
    assert path.read_bytes() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.npz"]
