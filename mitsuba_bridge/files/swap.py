"""Folder entries replaced as a whole: a re-export is the old export or the new one, even after ``kill -9``.

A re-export replaces several entries of a folder (``scene.xml``, ``meshes/``,
``textures/``, ``scratches/``) and keeps the user's other files there, so it
cannot be one rename.  :func:`replacing_folder` makes it a transaction:

1. the new entries are built in a hidden folder inside the target
   (``.export-<random>.tmp``: same file system, so every move is a rename);
2. a *journal* (``.export.journal``, written atomically) names that folder, a
   hidden folder for the old entries (``.export-<random>.old``), the entries in
   their order and which of them the new export has;
3. the old entries move out (``last``, the scene file, first), the new ones in
   (``last`` at the end), and the journal is removed: the swap is done;
4. the hidden folders are removed.

A process killed at any point leaves either no journal (the old entries were
never touched: the hidden folders are litter) or a journal, from which
:func:`recover_folder` *completes* the swap: each step is decided from what
exists (an entry still in the building folder is not moved in yet; what stands
in its place is then the old one), so recovery can itself be killed and run
again.  The next export of the folder and the next render of it (``load_folder``)
run the recovery first; the next export also removes the litter.

Exports of one folder are serialised with an exclusive ``flock`` on the folder
itself (held while building and swapping; no lock file is left beside the
user's files).  A render takes the lock only to recover a journal: an export
in progress finishes its swap first.  Where ``flock`` is missing (Windows) or
refused (some network file systems), the lock is skipped.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Iterator

from .atomic import sync_folder, umask_mode, write_atomically

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None

__all__ = ["JOURNAL", "replacing_folder", "recover_folder", "SwapRecoveryError"]

#: The journal of a swap in progress (in the target folder; removed when the swap is complete).
JOURNAL = ".export.journal"
_LITTER = re.compile(r"\.export-[A-Za-z0-9_]+\.(tmp|old)")


class SwapRecoveryError(OSError):
    """A killed swap's journal was found and the swap could not be completed (a read-only folder, ...)."""


@contextlib.contextmanager
def _folder_lock(folder: Path, *, blocking: bool = True) -> Iterator[bool]:
    """Hold an exclusive ``flock`` on ``folder`` itself; yields whether it is held (False: busy, or no locks)."""
    if fcntl is None:
        yield False
        return
    try:
        handle = os.open(folder, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        yield False
        return
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
            held = True
        except OSError:
            held = False
        yield held
    finally:
        os.close(handle)  # (releases the lock)


def _exists(path: Path) -> bool:
    return os.path.lexists(path)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


def _read_journal(folder: Path) -> dict | None:
    path = folder / JOURNAL
    if not _exists(path):
        return None
    try:
        journal = json.loads(path.read_text(encoding="utf-8"))
        names = [journal["building"], journal["trash"], *journal["entries"], *journal["new"]]
        if not all(isinstance(name, str) and name and "/" not in name and "\\" not in name and name not in (".", "..")
                   for name in names) or not set(journal["new"]) <= set(journal["entries"]) \
                or not _LITTER.fullmatch(journal["building"]) or not _LITTER.fullmatch(journal["trash"]):
            raise ValueError("names outside the folder")
        return journal
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise SwapRecoveryError(f"{path}: a damaged swap journal ({error}); remove it and export again") from None


def _complete(folder: Path, journal: dict) -> None:
    """Finish the swap ``journal`` describes, from whatever step it stopped at (idempotent)."""
    building, trash = folder / journal["building"], folder / journal["trash"]
    entries, new = journal["entries"], set(journal["new"])
    trash.mkdir(exist_ok=True)
    for name in reversed(entries):  # the old entries leave, ``last`` first
        waiting = name in new and _exists(building / name)
        if _exists(folder / name) and (waiting or name not in new):
            _remove(trash / name)
            os.replace(folder / name, trash / name)
    for name in entries:  # the new ones arrive, ``last`` at the end
        if name in new and _exists(building / name):
            if (building / name).is_dir():
                os.chmod(building / name, umask_mode(0o777))
            os.replace(building / name, folder / name)
    os.unlink(folder / JOURNAL)  # the swap is complete
    sync_folder(folder)
    _remove(trash)
    _remove(building)


def _remove_litter(folder: Path) -> None:
    """Hidden building and old-entry folders of swaps that never wrote a journal (or finished it)."""
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            if _LITTER.fullmatch(entry.name):
                _remove(Path(entry.path))


def recover_folder(folder, *, litter: bool = False) -> bool:
    """Complete a swap a killed process left in ``folder``; returns whether there was one.

    ``litter``: also remove hidden folders of killed builds, when no export of
    the folder is in progress (its lock is free).  Raises
    :class:`SwapRecoveryError` when a journal is found but the swap cannot be
    completed (the folder is then as the killed process left it).
    """
    folder = Path(folder)
    if not folder.is_dir():
        return False
    found = _exists(folder / JOURNAL)
    if not found and not litter:
        return False
    with _folder_lock(folder, blocking=found) as held:
        return _recover(folder, litter=litter and (held or fcntl is None))


def _recover(folder: Path, *, litter: bool) -> bool:
    """:func:`recover_folder` with the folder's lock held (or no locks to be had)."""
    journal = _read_journal(folder)  # (read under the lock: a live export may have finished it meanwhile)
    if journal is not None:
        try:
            _complete(folder, journal)
        except OSError as error:
            raise SwapRecoveryError(f"{folder}: an export was interrupted while it replaced its files, and "
                                    f"completing it failed ({error}); export again") from None
    if litter:
        _remove_litter(folder)
    return journal is not None


@contextlib.contextmanager
def replacing_folder(path, entries: tuple[str, ...], *, last: str | None = None) -> Iterator[Path]:
    """Yield an empty temporary folder; when the block succeeds its ``entries`` replace those of ``path``.

    Only the named entries (files or subfolders) of ``path`` are replaced, so
    other files a user keeps in the folder survive; an entry that the block did
    not create is removed from ``path`` too.  ``last`` (an entry, e.g. the scene
    file) leaves first and arrives last, so no reader sees it beside a mix of
    old and new entries.  A failure while building leaves ``path`` untouched; a
    failure while swapping puts the old entries back; a killed process leaves a
    journal that the next :func:`recover_folder` completes (module docstring).
    """
    target = Path(os.path.realpath(path)) if Path(path).is_symlink() else Path(path)
    target.mkdir(parents=True, exist_ok=True)
    order = sorted(entries, key=lambda name: name == last)  # ``last`` at the end
    with _folder_lock(target) as held:
        _recover(target, litter=held or fcntl is None)
        building = Path(tempfile.mkdtemp(prefix=".export-", suffix=".tmp", dir=target))
        trash = None
        try:
            yield building
            trash = Path(tempfile.mkdtemp(prefix=".export-", suffix=".old", dir=target))
            journal = {"building": building.name, "trash": trash.name, "entries": order,
                       "new": [name for name in order if _exists(building / name)]}
            write_atomically(target / JOURNAL, lambda stream: stream.write(json.dumps(journal).encode()))
            try:
                _complete(target, journal)
            except BaseException:
                _roll_back(target, journal)
                raise
        finally:
            _remove(building)
            if trash is not None:
                _remove(trash)


def _roll_back(folder: Path, journal: dict) -> None:
    """Undo a swap that failed in this process (not killed): the new entries back out, the old ones in."""
    building, trash = folder / journal["building"], folder / journal["trash"]
    with contextlib.suppress(OSError):
        for name in journal["entries"]:
            if name in journal["new"] and not _exists(building / name) and _exists(folder / name):
                os.replace(folder / name, building / name)
        for name in reversed(journal["entries"]):
            if _exists(trash / name) and not _exists(folder / name):
                os.replace(trash / name, folder / name)
        os.unlink(folder / JOURNAL)  # (only once everything is back: else the next recovery completes it)
