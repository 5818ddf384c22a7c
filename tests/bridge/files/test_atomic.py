"""Atomic outputs: a temporary sibling renamed into place, folders swapped in whole."""
import os

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.files import atomic, swap
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr
from scratch_iridescence.mitsuba_bridge.files.images import write_image


def test_an_image_replaces_the_old_file_only_when_complete(tmp_path):
    write_image(tmp_path / "a.exr", np.zeros((2, 3, 4), np.float32))
    with pytest.raises(RuntimeError, match="crash"):
        with atomic.replacing_file(tmp_path / "a.exr") as temporary:
            temporary.write_bytes(b"half")
            raise RuntimeError("crash")
    assert read_exr(tmp_path / "a.exr").shape == (2, 3, 4)
    assert [p.name for p in tmp_path.iterdir()] == ["a.exr"]


def test_an_empty_result_is_not_renamed_over_a_good_file(tmp_path):
    (tmp_path / "a.exr").write_bytes(b"good")
    with pytest.raises(OSError, match="nothing was written"):
        with atomic.replacing_file(tmp_path / "a.exr"):
            pass
    assert (tmp_path / "a.exr").read_bytes() == b"good"


def test_new_files_follow_the_umask_and_links_are_written_through(tmp_path):
    previous = os.umask(0o027)
    try:
        write_image(tmp_path / "target.exr", np.ones((2, 2, 3), np.float32))
    finally:
        os.umask(previous)
    assert (tmp_path / "target.exr").stat().st_mode & 0o777 == 0o640
    (tmp_path / "link.exr").symlink_to(tmp_path / "target.exr")
    write_image(tmp_path / "link.exr", np.full((2, 2, 3), 5.0, np.float32))
    assert (tmp_path / "link.exr").is_symlink() and read_exr(tmp_path / "target.exr").max() == 5.0


def test_a_png_is_a_png(variant, tmp_path):
    write_image(tmp_path / "a.png", np.full((4, 5, 4), 0.5, np.float32))
    assert (tmp_path / "a.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_folder_swap_that_fails_midway_puts_the_old_entries_back(tmp_path, monkeypatch):
    folder = tmp_path / "export"
    with swap.replacing_folder(folder, ("scene.xml", "meshes")) as building:
        (building / "scene.xml").write_text("old")
        (building / "meshes").mkdir()
        (building / "meshes" / "a.ply").write_text("old mesh")
    real_replace, calls = os.replace, []

    def failing_replace(source, target):
        calls.append(target)
        if len(calls) == 3:  # both old entries moved aside, the first new one about to arrive
            raise OSError("device unplugged")
        return real_replace(source, target)

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError, match="unplugged"):
        with swap.replacing_folder(folder, ("scene.xml", "meshes"), last="scene.xml") as building:
            (building / "scene.xml").write_text("new")
            (building / "meshes").mkdir()
    assert (folder / "scene.xml").read_text() == "old" and (folder / "meshes" / "a.ply").read_text() == "old mesh"
    assert sorted(p.name for p in folder.iterdir()) == ["meshes", "scene.xml"]  # no temporary folders left
