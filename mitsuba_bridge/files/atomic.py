"""Writes that never leave a half-written file or folder in place of a good one.

A file is written to a temporary sibling and renamed over the target
(``os.replace`` is atomic within one file system); a folder is built beside
the target and swapped in.  If anything fails, the previous file or folder is
untouched and the temporary one is removed.  New files get the usual mode
(0666 less the umask), and a target that is a symbolic link is written through
(the link stays, its target is replaced).
"""
from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import stat
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable, Iterator

__all__ = ["write_atomically", "replacing_file", "replacing_folder", "umask_mode"]


def umask_mode(base: int = 0o666) -> int:
    """``base`` less the process's umask (what ``open()`` would give a new file); the umask is only read."""
    return base & ~_current_umask()


def _current_umask() -> int:
    """The process's umask, read without setting it (``os.umask`` sets it: racy with other threads).

    Linux reports it in ``/proc/self/status``; elsewhere the kernel applies it to a probe file created
    with mode 0o777 in a private temporary folder, and the mode that file got says what it is.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    with tempfile.TemporaryDirectory(prefix=".umask-") as folder:
        probe = os.path.join(folder, "probe")
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o777))
        return 0o777 & ~stat.S_IMODE(os.stat(probe).st_mode)


def _real_target(path: Path) -> Path:
    # Write through symbolic links: the link keeps pointing at the (new) file.
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def _mode_for(target: Path) -> int:
    """The mode the replacement gets: the old file's, else what ``open()`` gives a new file."""
    try:
        return stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        return umask_mode()


def _create_sibling(target: Path, suffix: str = "") -> tuple[Path, int]:
    """A new hidden file beside ``target``, opened for writing (never follows a planted link)."""
    folder = target.parent if str(target.parent) else Path(".")
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
    for _ in range(100):
        temporary = folder / f".{target.name}.{secrets.token_hex(4)}.tmp{suffix}"
        try:
            return temporary, os.open(temporary, flags, 0o600)
        except FileExistsError:
            continue
    raise FileExistsError(f"could not create a temporary file beside {target}")


def _sync_folder(folder: Path) -> None:
    """Make the rename durable (POSIX); folders cannot be opened on Windows."""
    try:
        descriptor = os.open(folder if str(folder) else ".", os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(descriptor)
    except OSError:
        pass
    finally:
        os.close(descriptor)


def write_atomically(path, write: Callable[[BinaryIO], object]) -> Path:
    """Call ``write(stream)`` on a temporary sibling of ``path``, then rename it onto ``path``.

    Parameters
    ----------
    path:
        The file to create or replace.  A symbolic link is followed: its target
        is replaced and the link kept.
    write:
        Writes the whole content to the binary stream it is given.

    Returns
    -------
    Path
        ``path`` as given.

    Raises
    ------
    OSError, or whatever ``write`` raises
        The previous file (if any) is then unchanged and the temporary file removed.
    """
    path = Path(path)
    target = _real_target(path)
    mode = _mode_for(target)
    temporary, handle = _create_sibling(target)
    try:
        os.chmod(temporary, mode)
        with os.fdopen(handle, "wb") as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, target)
    except BaseException:
        # Interrupted or failed: remove the partial file, keep any old one intact.
        temporary.unlink(missing_ok=True)
        raise
    _sync_folder(target.parent)
    return path


@contextlib.contextmanager
def replacing_file(path, *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; when the block succeeds it becomes ``path``.

    For writers that take a file name rather than a stream (``mi.Bitmap.write``,
    OpenEXR).  ``suffix`` (default: ``path``'s own) ends the temporary name, for
    writers that choose the format by extension.  The folder must exist.  An
    empty result is refused: it never replaces a good file.
    """
    target = _real_target(Path(path))
    suffix = target.suffix if suffix is None else suffix
    mode = _mode_for(target)
    temporary, handle = _create_sibling(target, suffix)
    os.close(handle)
    try:
        yield temporary
        if not temporary.is_file() or temporary.stat().st_size == 0:
            raise OSError(f"{target}: nothing was written")
        os.chmod(temporary, mode)
        os.replace(temporary, target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    _sync_folder(target.parent)


@contextlib.contextmanager
def replacing_folder(path, entries: tuple[str, ...], *, last: str | None = None) -> Iterator[Path]:
    """Yield an empty temporary folder; when the block succeeds its ``entries`` replace those of ``path``.

    Only the named entries (files or subfolders) of ``path`` are replaced, so
    other files a user keeps in the folder survive; an entry that the block did
    not create is removed from ``path`` too.  ``last`` (an entry, e.g. the scene
    file) leaves first and arrives last, so no reader sees it beside a mix of
    old and new entries.  The folder is built inside ``path`` (same file
    system: every move is a rename); a failure while building leaves ``path``
    untouched, a failure while swapping puts the old entries back.
    """
    target = _real_target(Path(path))
    target.mkdir(parents=True, exist_ok=True)
    building = Path(tempfile.mkdtemp(prefix=".export-", suffix=".tmp", dir=target))
    try:
        yield building
        order = sorted(entries, key=lambda name: name == last)  # ``last`` at the end
        trash = Path(tempfile.mkdtemp(prefix=".export-", suffix=".old", dir=target))
        moved_out, moved_in = [], []
        try:
            for name in reversed(order):  # ``last`` leaves first
                if os.path.lexists(target / name):
                    os.replace(target / name, trash / name)
                    moved_out.append(name)
            for name in order:
                if os.path.lexists(building / name):
                    if (building / name).is_dir():
                        os.chmod(building / name, umask_mode(0o777))
                    os.replace(building / name, target / name)
                    moved_in.append(name)
        except BaseException:
            for name in moved_in:
                os.replace(target / name, building / name)
            for name in moved_out:
                os.replace(trash / name, target / name)
            raise
        finally:
            shutil.rmtree(trash, ignore_errors=True)
    finally:
        shutil.rmtree(building, ignore_errors=True)
