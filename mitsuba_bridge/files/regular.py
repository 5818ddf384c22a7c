"""Opening a file for reading only when it is a regular file: never a FIFO, a device or a folder.

``open(path)`` on a FIFO waits until some process opens the other end, which
may be never: ``info``, ``render`` or ``merge`` given a FIFO (or an export
folder whose ``scratches/*.npz`` is one) would hang with no message.  A device
(``/dev/zero``) reads forever.  :func:`open_regular` opens without blocking
(``O_NONBLOCK``: a FIFO's open returns at once), asks the open descriptor what
it is (``fstat``: the very file that will be read, no window for a swap between
a check and the open) and refuses anything but a regular file, naming its kind.
:func:`check_regular` says the same of a path that another library will open
(Mitsuba's PLY and texture readers).
"""
from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import BinaryIO

from ..errors import ScratchUserError

__all__ = ["NotARegularFile", "open_regular", "check_regular", "kind_of"]

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a symbolic link"))


class NotARegularFile(ScratchUserError, OSError):
    """A path that names something other than a regular file where a file is read (a FIFO, a device, a folder)."""


def kind_of(mode: int) -> str:
    """``"a FIFO (named pipe)"``, ``"a folder"``, ... for an ``st_mode`` (``"a regular file"`` for one)."""
    if stat.S_ISREG(mode):
        return "a regular file"
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def open_regular(path, *, follow_symlinks: bool = True) -> BinaryIO:
    """``open(path, "rb")`` for a regular file; :class:`NotARegularFile` for anything else, without waiting.

    ``follow_symlinks=False`` also refuses a symbolic link (``O_NOFOLLOW``), for
    folders whose files only their writer may place (the tables cache).
    ``FileNotFoundError`` and ``PermissionError`` come through as ``open``'s.
    """
    path = Path(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
    if not follow_symlinks:
        flags |= getattr(os, "O_NOFOLLOW", 0)
        if not hasattr(os, "O_NOFOLLOW") and path.is_symlink():  # (Windows: no O_NOFOLLOW)
            raise NotARegularFile(f"{path}: is a symbolic link, not a regular file")
    try:
        descriptor = os.open(path, flags)
    except OSError as error:
        if not follow_symlinks and path.is_symlink():  # ELOOP from O_NOFOLLOW
            raise NotARegularFile(f"{path}: is a symbolic link, not a regular file") from None
        if isinstance(error, IsADirectoryError):  # (Windows cannot open folders)
            raise NotARegularFile(f"{path}: is a folder, not a regular file") from None
        raise
    try:
        mode = os.fstat(descriptor).st_mode
        if not stat.S_ISREG(mode):
            raise NotARegularFile(f"{path}: is {kind_of(mode)}, not a regular file")
        if getattr(os, "O_NONBLOCK", 0):
            os.set_blocking(descriptor, True)  # (no effect on a regular file's reads; restored for clarity)
        return os.fdopen(descriptor, "rb")
    except BaseException:
        os.close(descriptor)
        raise


def check_regular(path) -> None:
    """:class:`NotARegularFile` unless ``path`` (symbolic links followed) is a regular file; never opens it."""
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        raise NotARegularFile(f"{path}: is {kind_of(mode)}, not a regular file")
