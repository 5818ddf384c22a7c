"""Saving scratch files: modes follow the umask, symlinks are written through, failures keep the old file."""
import os
import stat
import subprocess
import sys
import textwrap

import pytest

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.files.atomic import write_atomically

posix_only = pytest.mark.skipif(os.name != "posix", reason="file modes and symlinks as POSIX has them")


@pytest.fixture
def umask():
    """Set the process umask for one test (restored afterwards)."""
    saved = os.umask(0o022)
    os.umask(saved)
    yield lambda value: os.umask(value)
    os.umask(saved)


def mode_of(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


@posix_only
@pytest.mark.parametrize("mask", [0o022, 0o027, 0o002])
def test_new_file_mode_follows_the_umask(tmp_path, two_scratches, umask, mask):
    umask(mask)
    path = scratch.save(two_scratches, tmp_path / "new.npz")
    plain = tmp_path / "plain.txt"
    plain.write_bytes(b"x")  # what open() gives any other file under this umask
    assert mode_of(path) == 0o666 & ~mask == mode_of(plain)


@posix_only
def test_overwriting_keeps_the_file_mode(tmp_path, two_scratches, umask):
    umask(0o022)
    path = scratch.save(two_scratches, tmp_path / "private.npz")
    os.chmod(path, 0o600)
    scratch.save_bytes(scratch.dumps(two_scratches.select([1])), path)
    assert mode_of(path) == 0o600 and scratch.load(path) == two_scratches.select([1])


@posix_only
def test_saving_onto_a_symlink_writes_the_target(tmp_path, two_scratches):
    target_folder = tmp_path / "library"
    target_folder.mkdir()
    target = target_folder / "plate.npz"
    scratch.save(two_scratches.select([0]), target)
    link = tmp_path / "link.npz"
    link.symlink_to(os.path.relpath(target, tmp_path))
    scratch.save(two_scratches, link)
    assert link.is_symlink() and os.readlink(link) == os.path.relpath(target, tmp_path)
    assert scratch.load(target) == two_scratches
    assert sorted(p.name for p in target_folder.iterdir()) == ["plate.npz"]  # no temporary left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["library", "link.npz"]


@posix_only
def test_saving_onto_a_chain_of_symlinks_and_a_dangling_one(tmp_path, two_scratches):
    final = tmp_path / "final.npz"
    (tmp_path / "middle.npz").symlink_to("final.npz")
    (tmp_path / "first.npz").symlink_to("middle.npz")
    scratch.save(two_scratches, tmp_path / "first.npz")  # final.npz does not exist yet
    assert (tmp_path / "first.npz").is_symlink() and (tmp_path / "middle.npz").is_symlink()
    assert not final.is_symlink() and scratch.load(final) == two_scratches


def test_write_failing_midway_keeps_the_old_file(tmp_path, two_scratches):
    path = scratch.save(two_scratches, tmp_path / "kept.npz")
    before = path.read_bytes()

    def write_half_then_fail(stream):
        stream.write(before[:len(before) // 2])
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space left"):
        write_atomically(path, write_half_then_fail)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.npz"]


@posix_only
def test_a_real_write_failure_keeps_the_old_file(tmp_path, two_scratches):
    """The kernel refuses the write (file size limit, as a full disk would): the old file survives."""
    path = scratch.save(two_scratches, tmp_path / "kept.npz")
    before = path.read_bytes()
    script = textwrap.dedent(f"""
        import resource, signal, sys
        from scratch_iridescence.mitsuba_bridge import scratch
        big = scratch.random_scratches(2000, seed=1)
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # get EFBIG instead of being killed
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, resource.RLIM_INFINITY))
        try:
            scratch.save(big, {str(path)!r})
        except OSError as error:
            print("refused", error.errno)
            sys.exit(0)
        sys.exit("the write did not fail")
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("refused")
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.npz"]
