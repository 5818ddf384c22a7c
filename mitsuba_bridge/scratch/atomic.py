"""Writing a file so that a failure never destroys the previous one.

The data goes to a temporary sibling in the target's folder, is flushed to
disk, then renamed over the target: readers see the old file or the new one,
never a half-written one.  Unlike ``tempfile.mkstemp`` (always mode 0600), the
temporary file is created with mode 0666 filtered by the process's umask, like
any file a program creates; when the target already exists its mode is kept.
A target that is a symbolic link is written through: the link stays and the
file it points to is replaced.
"""
from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path
from typing import BinaryIO, Callable

__all__ = ["write_atomically"]


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
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    folder = target.parent if str(target.parent) else Path(".")
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        mode = None
    temporary, handle = _create_sibling(folder, target.name)
    try:
        if mode is not None:
            os.chmod(temporary, mode)
        with os.fdopen(handle, "wb") as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, target)
    except BaseException:
        # Interrupted or failed: remove the partial file, keep any old one intact.
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        raise
    _sync_folder(folder)
    return path


def _create_sibling(folder: Path, name: str) -> tuple[Path, int]:
    """A new hidden file beside ``name``, opened for writing, with mode 0666 & ~umask."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
    for _ in range(100):
        temporary = folder / f".{name}.{secrets.token_hex(4)}.tmp"
        try:
            return temporary, os.open(temporary, flags, 0o666)
        except FileExistsError:
            continue
    raise FileExistsError(f"could not create a temporary file beside {folder / name}")


def _sync_folder(folder: Path) -> None:
    """Make the rename durable (POSIX); folders cannot be opened on Windows."""
    try:
        descriptor = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(descriptor)
    except OSError:
        pass
    finally:
        os.close(descriptor)
