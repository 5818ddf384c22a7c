"""Which files a folder's named entries hold (a scene's fingerprint and a cluster's scene bundle read the same list)."""
from __future__ import annotations

from pathlib import Path

__all__ = ["entry_files"]


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
