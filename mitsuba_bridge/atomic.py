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
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

__all__ = ["replacing_file", "replacing_folder", "umask_mode"]


def umask_mode(base: int = 0o666) -> int:
    """``base`` less the process's umask (what ``open()`` would give a new file)."""
    mask = os.umask(0)
    os.umask(mask)
    return base & ~mask


def _real_target(path: Path) -> Path:
    # Write through symbolic links: the link keeps pointing at the (new) file.
    return Path(os.path.realpath(path)) if path.is_symlink() else path


@contextlib.contextmanager
def replacing_file(path, *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; when the block succeeds it becomes ``path``.

    ``suffix`` (default: ``path``'s own) ends the temporary name, for writers
    that choose the format by extension.  The folder must exist.
    """
    target = _real_target(Path(path))
    suffix = target.suffix if suffix is None else suffix
    handle, temporary = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=f".tmp{suffix}", dir=target.parent)
    os.close(handle)
    temporary = Path(temporary)
    try:
        yield temporary
        if not temporary.is_file() or temporary.stat().st_size == 0:
            raise OSError(f"{target}: nothing was written")
        os.chmod(temporary, umask_mode())
        os.replace(temporary, target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


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
