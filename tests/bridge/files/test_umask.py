"""New files get the mode ``open()`` gives them (0o666/0o777 less the umask) without the umask ever being set.

``os.umask`` sets the mask to read it, so a thread creating a file meanwhile (the viewport's worker, another
add-on) would get mode 0o666; atomic.py reads it instead (``/proc/self/status`` on Linux, a probe file
elsewhere).  Here ``os.umask`` is replaced by a function that fails the test if it is called.
"""
import os
import stat

import pytest

from scratch_iridescence.mitsuba_bridge.files import atomic, swap


@pytest.fixture
def umask_027(monkeypatch):
    previous = os.umask(0o027)  # the test's own set-up, before the code under test runs
    calls = []
    monkeypatch.setattr(os, "umask", lambda mask: calls.append(mask) or 0o027)
    yield calls
    monkeypatch.undo()
    os.umask(previous)


def mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("reader", ["proc", "probe file"])
def test_new_files_and_folders_follow_the_umask_which_is_never_set(tmp_path, monkeypatch, umask_027, reader):
    if reader == "probe file":  # macOS and Windows have no /proc: the probe file's mode tells
        def no_proc(path, *args, **kwargs):
            if str(path).startswith("/proc/"):
                raise FileNotFoundError(path)
            return open(path, *args, **kwargs)
        monkeypatch.setattr(atomic, "open", no_proc, raising=False)
    elif not os.path.exists("/proc/self/status"):
        pytest.skip("no /proc on this system")
    assert atomic._current_umask() == 0o027
    atomic.write_atomically(tmp_path / "a.bin", lambda stream: stream.write(b"data"))
    with atomic.replacing_file(tmp_path / "b.exr") as temporary:
        temporary.write_bytes(b"image")
    with swap.replacing_folder(tmp_path / "export", ("meshes",)) as building:
        (building / "meshes").mkdir()
    assert mode(tmp_path / "a.bin") == mode(tmp_path / "b.exr") == 0o640
    assert mode(tmp_path / "export" / "meshes") == 0o750
    assert umask_027 == []  # os.umask never called: nothing changed the process's mask, not even for a moment
