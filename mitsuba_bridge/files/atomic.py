"""Writes that never leave a half-written file in place of a good one.

A file is written to a temporary sibling (``.NAME.<8 hex>.tmp``) and renamed
over the target (``os.replace`` is atomic within one file system).  If anything
fails, the previous file is untouched and the temporary one is removed.  New
files get the usual mode (0666 less the umask), and a target that is a symbolic
link is written through (the link stays, its target is replaced).  Folders are
swapped by :mod:`.swap`.

**Killed writers.**  A process killed while writing (``kill -9``, a power cut)
cannot remove its temporary sibling.  The writer holds an exclusive ``flock``
on its temporary file for as long as it writes, so the next write to the same
place removes every sibling of that name that nobody holds
(:func:`remove_stale_temporaries`).  Where there is no ``flock`` (Windows) only
siblings untouched for :data:`STALE_UNLOCKED_SECONDS` are removed.
"""
from __future__ import annotations

import contextlib
import os
import re
import secrets
import stat
import tempfile
import time
from pathlib import Path
from typing import BinaryIO, Callable, Iterator

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None

__all__ = ["write_atomically", "replacing_file", "umask_mode", "remove_stale_temporaries", "sync_folder",
           "STALE_UNLOCKED_SECONDS"]

#: Without ``flock`` (Windows), a temporary sibling this old is taken for a killed writer's.
STALE_UNLOCKED_SECONDS = 24 * 3600.0


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
    """A new hidden file beside ``target``, opened for writing and locked (never follows a planted link).

    What killed writers left beside ``target`` is removed first.  The lock is
    taken after the file exists, so a cleaner may remove the file in between:
    the path is checked to still name the locked file, else another is made.
    """
    folder = target.parent if str(target.parent) else Path(".")
    remove_stale_temporaries(folder, target.name)
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
    for _ in range(100):
        temporary = folder / f".{target.name}.{secrets.token_hex(4)}.tmp{suffix}"
        try:
            handle = os.open(temporary, flags, 0o600)
        except FileExistsError:
            continue
        if _lock(handle, blocking=True) and not _names(temporary, handle):
            os.close(handle)  # removed by a cleaner between the open and the lock
            continue
        return temporary, handle
    raise FileExistsError(f"could not create a temporary file beside {target}")


def _lock(handle: int, *, blocking: bool) -> bool:
    """An exclusive ``flock`` on ``handle``: True when taken (False where busy, or without ``flock``)."""
    if fcntl is None:
        return False
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
        return True
    except OSError:  # busy, or a file system without locks
        return False


def _names(path: Path, handle: int) -> bool:
    """Whether ``path`` still names the file open as ``handle``."""
    try:
        found, held = os.stat(path, follow_symlinks=False), os.fstat(handle)
    except OSError:
        return False
    return (found.st_dev, found.st_ino) == (held.st_dev, held.st_ino)


def remove_stale_temporaries(folder, name: str | None = None, *, name_pattern: str = r".+") -> int:
    """Remove the temporary siblings killed writers left in ``folder`` (of the file ``name``, else of any file
    whose name matches the regular expression ``name_pattern``).

    A sibling counts as a killed writer's when no process holds its lock (or,
    without ``flock``, when untouched for :data:`STALE_UNLOCKED_SECONDS`).
    Returns how many were removed; never raises for a file it cannot remove.
    """
    base = re.escape(name) if name is not None else name_pattern
    pattern = re.compile(rf"\.(?:{base})\.[0-9a-f]{{8}}\.tmp.*", re.DOTALL)
    removed = 0
    try:
        entries = [entry for entry in os.scandir(folder) if pattern.fullmatch(entry.name)]
    except OSError:
        return 0
    for entry in entries:
        try:
            if not entry.is_file(follow_symlinks=False):
                continue
            if fcntl is None:
                if time.time() - entry.stat(follow_symlinks=False).st_mtime > STALE_UNLOCKED_SECONDS:
                    os.unlink(entry.path)
                    removed += 1
                continue
            handle = os.open(entry.path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
                             | getattr(os, "O_NONBLOCK", 0))
        except OSError:
            continue
        try:
            if _lock(handle, blocking=False) and _names(Path(entry.path), handle):
                os.unlink(entry.path)  # (while holding its lock: a writer that locks next sees it gone)
                removed += 1
        except OSError:
            pass
        finally:
            os.close(handle)
    return removed


def sync_folder(folder: Path) -> None:
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
    stream = os.fdopen(handle, "wb")
    try:
        os.chmod(temporary, mode)
        write(stream)
        stream.flush()
        os.fsync(stream.fileno())
        if fcntl is None:  # (Windows renames no open file)
            stream.close()
        os.replace(temporary, target)  # (POSIX: still open and locked, so no cleaner takes it meanwhile)
    except BaseException:
        # Interrupted or failed: remove the partial file, keep any old one intact.
        temporary.unlink(missing_ok=True)
        raise
    finally:
        with contextlib.suppress(OSError):  # (after a failed write, closing would flush the failing buffer again)
            stream.close()
    sync_folder(target.parent)
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
    if fcntl is None:  # (Windows renames no open file; there the lock is no lock anyway)
        os.close(handle)
        handle = None
    try:
        yield temporary
        if not temporary.is_file() or temporary.stat().st_size == 0:
            raise OSError(f"{target}: nothing was written")
        os.chmod(temporary, mode)
        os.replace(temporary, target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    finally:
        if handle is not None:
            os.close(handle)  # the lock that told cleaners this file is being written
    sync_folder(target.parent)
