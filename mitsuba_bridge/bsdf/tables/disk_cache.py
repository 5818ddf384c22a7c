"""Built scratch tables kept on disk, so that the next process renders a set without building them again.

Building the tables (:mod:`.tables`, :mod:`.periodic`) is a final render's
set-up: 0.3 s for the Fig. 9 grating, seconds for the Fig. 1 table and the
CD.  :mod:`.persistent` shares them between the scenes of one process; this
module keeps them between processes: every F12 in a new Blender session,
every ``blender -b`` frame of a render farm job, every ``make paper`` worker
finds the tables a previous one built for the same set.

* **Key**: a digest of the whole scratch set and the build options (as
  :mod:`.persistent`'s), of the source of every module that builds or reads
  the tables (``bsdf/`` and ``scratch/``: an edited module never meets tables
  of the old code) and of numpy's version.  No variant: the files hold numpy
  arrays, uploaded to the active variant after loading.
* **Files**: one ``.npz`` per set (numpy's own format, read with
  ``allow_pickle=False``: a file in the cache can hold arrays only), written to a
  temporary sibling and renamed, so another process never reads half a file.
  Only builds that took at least ``MIN_BUILD_SECONDS`` are written.
* **Size**: at most ``SCRATCH_IRIDESCENCE_CACHE_MB`` (default ``DEFAULT_LIMIT_MB``)
  in all; the least recently used files go first (a hit touches its file).
* **Where**: ``SCRATCH_IRIDESCENCE_CACHE_DIR``, else the platform's cache
  folder (``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux, ``~/Library/Caches`` on
  macOS, ``%LOCALAPPDATA%`` on Windows) under ``scratch-iridescence/tables``.
  ``SCRATCH_IRIDESCENCE_CACHE_DIR=off`` turns the cache off.  Deleting the folder is
  always safe.

Nothing here ever fails a render: an unreadable or damaged file counts as a miss
(and is removed), a failed write (full disk, read-only folder) as no write.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

__all__ = ["directory", "code_fingerprint", "load", "store", "load_tables", "store_tables", "statistics", "DEFAULT_LIMIT_MB",
           "MIN_BUILD_SECONDS"]

#: Default size limit of the cache folder (MB).
DEFAULT_LIMIT_MB = 2048
#: Builds faster than this are not written (reading a file costs about as much).
MIN_BUILD_SECONDS = 0.05
#: The file layout; part of the key.
FORMAT = 1

_log = logging.getLogger(__name__)
_lock = threading.Lock()
_fingerprint: str | None = None
_counts = {"hits": 0, "misses": 0, "writes": 0, "damaged": 0, "failed_writes": 0}


def directory() -> Path | None:
    """The cache folder (created when first written), or None where the cache is off."""
    chosen = os.environ.get("SCRATCH_IRIDESCENCE_CACHE_DIR", "")
    if chosen.strip().lower() == "off":
        return None
    if chosen:
        return Path(chosen)
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "scratch-iridescence" / "tables"


def limit_bytes() -> int:
    """The folder's size limit (``SCRATCH_IRIDESCENCE_CACHE_MB``; a malformed value: the default)."""
    try:
        megabytes = float(os.environ.get("SCRATCH_IRIDESCENCE_CACHE_MB", DEFAULT_LIMIT_MB))
    except ValueError:
        megabytes = DEFAULT_LIMIT_MB
    return int(max(megabytes, 0.0) * 1024 * 1024)


def fingerprinted_sources() -> list[Path]:
    """The sources :func:`code_fingerprint` digests: every module of ``bsdf/`` and ``scratch/``, subfolders included."""
    package = Path(__file__).resolve().parents[2]  # mitsuba_bridge
    return [source for folder in ("bsdf", "scratch") for source in sorted((package / folder).rglob("*.py"))]


def code_fingerprint() -> str:
    """A digest of the source of the modules that build and read scratch tables, and numpy's version."""
    global _fingerprint
    if _fingerprint is None:
        digest = hashlib.blake2b(f"{FORMAT}:{np.__version__}".encode(), digest_size=16)
        package = Path(__file__).resolve().parents[2]
        for source in fingerprinted_sources():
            digest.update(source.relative_to(package).as_posix().encode())
            digest.update(source.read_bytes())
        _fingerprint = digest.hexdigest()
    return _fingerprint


def _path(key: bytes) -> Path | None:
    folder = directory()
    if folder is None:
        return None
    name = hashlib.blake2b(key + code_fingerprint().encode(), digest_size=20).hexdigest()
    return folder / f"{name}.npz"


def load(key: bytes) -> dict | None:
    """The records :func:`store` wrote under ``key`` (``{name: dataclass fields}``), or None (a miss)."""
    path = _path(key)
    if path is None or not path.is_file():
        _count("misses")
        return None
    try:
        with np.load(path, allow_pickle=False) as archive:
            meta = json.loads(str(archive["meta.json"]))
            records = {}
            for name, fields in meta["records"].items():
                records[name] = {field: (archive[f"{name}.{field}"] if kind == "array" else value)
                                 for field, (kind, value) in fields.items()}
    except Exception as error:  # a damaged or foreign file: build again, and replace it
        # (the message as text: a handler that keeps records must not keep the traceback's frames alive)
        _log.warning("scratch tables cache: %s unreadable (%s: %s); building the tables again",
                     path, type(error).__name__, str(error))
        _count("damaged")
        _remove(path)
        return None
    try:
        os.utime(path)  # recently used (the size limit removes the least recently used first)
    except OSError:  # a read-only cache (shared by a farm's machines) still serves its files
        pass
    _count("hits")
    return records


def store(key: bytes, records: dict) -> bool:
    """Write ``records`` (``{name: dataclass instance or dict}``; values: numpy arrays, None, numbers, tuples) under
    ``key``; False where the cache is off or the write failed (nothing is left behind then)."""
    path = _path(key)
    if path is None:
        return False
    temporary = None
    try:
        arrays, meta = {}, {}
        for name, record in records.items():
            fields = {}
            for field, value in _fields_of(record):
                if isinstance(value, np.ndarray):
                    arrays[f"{name}.{field}"] = value
                    fields[field] = ("array", None)
                else:
                    fields[field] = ("value", _plain(value))
            meta[name] = fields
        arrays["meta.json"] = np.array(json.dumps({"format": FORMAT, "records": meta}))
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=".writing-", suffix=".tmp", delete=False) as file:
            temporary = Path(file.name)
            np.savez(file, **arrays)
        os.replace(temporary, path)
    except (OSError, ValueError, TypeError) as error:
        _log.warning("scratch tables cache: could not write %s (%s); the render goes on", path, str(error))
        _count("failed_writes")
        if temporary is not None:
            _remove(temporary)
        return False
    _count("writes")
    _prune(path.parent, keep=path)
    return True


def load_tables(key: bytes, scratches):
    """``(TableCache, ScanArrays)`` of ``scratches`` stored under ``key`` by :func:`store_tables`, or None."""
    from .incremental import TableCache
    from .scan import ScanArrays
    from .grid import GridTables

    records = load(key)
    if records is None:
        return None
    try:
        tables = _restore(GridTables, records["tables"])
        cache = _restore(TableCache, {**records["cache"], "scratches": scratches, "tables": tables})
        return cache, _restore(ScanArrays, records["scan"])
    except (KeyError, TypeError, ValueError) as error:  # written by other code under the same key: never
        _log.warning("scratch tables cache: unexpected records (%s); building the tables again", str(error))
        _count("damaged")
        return None


def store_tables(key: bytes, cache, scan) -> bool:
    """Keep a build (:class:`.incremental.TableCache` and :class:`.scan.ScanArrays`) under ``key``."""
    cache_fields = {f.name: getattr(cache, f.name) for f in dataclasses.fields(cache)
                    if f.name not in ("scratches", "tables")}  # (the set is the caller's; its tables a record)
    return store(key, {"tables": cache.tables, "scan": scan, "cache": cache_fields})


def _fields_of(record) -> list[tuple[str, object]]:
    """A record's named values: a dict's items or a dataclass's fields."""
    if isinstance(record, dict):
        return list(record.items())
    return [(field.name, getattr(record, field.name)) for field in dataclasses.fields(record)]


def _restore(cls, fields: dict):
    """An instance of the dataclass ``cls`` from stored fields (JSON lists back to tuples)."""
    return cls(**{name: tuple(value) if isinstance(value, list) else value for name, value in fields.items()})


def statistics() -> dict:
    """``hits``, ``misses``, ``writes``, ``damaged`` (files removed as unreadable), ``failed_writes``."""
    with _lock:
        return dict(_counts)


def _plain(value):
    """A JSON value of a dataclass field (numpy scalars and tuples of them as Python's)."""
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise ValueError(f"cannot store a {type(value).__name__} in the tables cache")


def _prune(folder: Path, keep: Path) -> None:
    """Remove the least recently used files until the folder holds at most :func:`limit_bytes`, and what
    writes that never finished (a killed process) left behind over an hour ago."""
    try:
        files = [(entry.stat().st_mtime, entry.stat().st_size, entry) for entry in folder.glob("*.npz")]
        now = time.time()
        for entry in folder.glob(".writing-*.tmp"):
            if now - entry.stat().st_mtime > 3600.0:
                _remove(entry)
    except OSError:
        return
    total, limit = sum(size for _, size, _ in files), limit_bytes()
    for _, size, entry in sorted(files, key=lambda f: f[0]):
        if total <= limit:
            break
        if entry != keep:
            _remove(entry)
            total -= size


def _remove(path: Path) -> None:
    try:
        path.unlink()
    except OSError:
        pass


def _count(what: str) -> None:
    with _lock:
        _counts[what] += 1

