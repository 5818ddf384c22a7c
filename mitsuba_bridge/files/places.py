"""Where the project keeps files between runs, and which files a folder's named entries hold."""
from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["user_cache_folder", "entry_files"]


def user_cache_folder(name: str) -> Path:
    """``<the platform's cache folder>/scratch-iridescence/<name>``: ``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux,
    ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on Windows."""
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "scratch-iridescence" / name


def entry_files(folder, entries: tuple[str, ...]) -> list[Path]:
    """The files of ``folder``'s named ``entries`` (a file, or every file under a folder, sorted), in entry order."""
    folder = Path(folder)
    files = []
    for name in entries:
        path = folder / name
        if path.is_dir():
            files += sorted(p for p in path.rglob("*") if p.is_file())
        elif path.is_file():
            files.append(path)
    return files
