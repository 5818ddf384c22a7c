"""Built scratch tables kept on disk, so that the next process renders a set without building them again.

Building the tables (:mod:`.grid`, :mod:`.periodic`) is a final render's
set-up: 0.3 s for the Fig. 9 grating, seconds for the Fig. 1 table and the
CD.  :mod:`..persistent` shares them between the scenes of one process; this
module keeps them between processes: every F12 in a new Blender session,
every ``blender -b`` frame of a render farm job, every ``make paper`` worker
finds the tables a previous one built for the same set.

* **Key**: a digest of the whole scratch set, the build options and the Mitsuba
  variant (as :mod:`..persistent`'s).  The file name is a digest of the key and
  of the *code version*: the source of every module that builds or reads tables
  (``bsdf/`` and ``scratch/``, subfolders included), numpy's version and the
  file layout.  An edited module never meets tables of the old code.
* **Files** (:mod:`.cache_file`): each carries what it holds (the key, the
  options in words and the code version) and a digest of its data, and is
  signed with the folder's secret.  A read checks all of it: a file of another
  set copied, renamed or linked under a set's name, tables scaled or set to NaN,
  a truncated or foreign file are each a miss with a warning (then built again
  and the file replaced), never a wrong image.  Symbolic links are never followed.
* **Whose**: the cache lives in its own subfolder (``tables/``), marked with a
  ``CACHEDIR.TAG`` (the Cache Directory Tagging convention, so backups skip it),
  and touches nothing there but its own files: ``<40 hex>.scratch-tables``,
  their temporary siblings and ``secret.key``.  A ``tables/`` folder that holds
  other files and no tag is not used (one warning); the first version's folder
  (its ``<40 hex>.npz`` files and ``.writing-*.tmp`` only) is taken over, those
  files removed.  The secret (32 random bytes, mode 0600) must belong to this
  user and be readable by no one else; a cache folder shared by a farm is shared
  by one user account.
* **Size**: at most ``SCRATCH_IRIDESCENCE_CACHE_MB`` (default ``DEFAULT_LIMIT_MB``)
  in all; the least recently used files go first (a hit touches its file).  A
  value that is not a finite number ≥ 0 (``nan``, ``inf``, ``1e400``, text)
  means the default, with a warning.
* **Where**: ``SCRATCH_IRIDESCENCE_CACHE_DIR`` (``off`` turns the cache off), else
  the folder the host application set (:func:`set_root`: Blender's
  ``bpy.utils.extension_path_user(__package__, create=True)``, the add-on sets it
  when it registers), else the platform's cache folder (``$XDG_CACHE_HOME`` or
  ``~/.cache`` on Linux, ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on
  Windows) under ``scratch-iridescence``; the files go in its ``tables/``
  subfolder.  Deleting the folder is always safe.

Nothing here ever fails a render: a file that cannot serve is a miss, a failed
write (full disk, read-only folder) one warning and no write.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import math
import os
import re
import secrets
import stat
import sys
import threading
import time
from pathlib import Path

import numpy as np

from . import cache_file
from ...files.atomic import remove_stale_temporaries, write_atomically
from ...files.regular import NotARegularFile, open_regular

__all__ = ["directory", "set_root", "code_fingerprint", "fingerprinted_sources", "limit_bytes", "load", "store",
           "load_tables", "store_tables", "tables_digest", "statistics", "DEFAULT_LIMIT_MB", "MIN_BUILD_SECONDS",
           "SUBFOLDER"]

#: Default size limit of the cache folder (MB).
DEFAULT_LIMIT_MB = 2048
#: Builds faster than this are not written (reading a file costs about as much).
MIN_BUILD_SECONDS = 0.05
#: The cache's own subfolder of its root.
SUBFOLDER = "tables"
_SUFFIX = ".scratch-tables"
_NAME = re.compile(r"[0-9a-f]{40}" + re.escape(_SUFFIX))
_SECRET, _TAG = "secret.key", "CACHEDIR.TAG"
_TAG_SIGNATURE = "Signature: 8a477f597d28d172789f06886806bc55"
_TAG_TEXT = (f"{_TAG_SIGNATURE}\n# This folder is the scratch tables cache of Scratch Iridescence (any file here may "
             "be deleted at any time).\n"
             "# For information about cache directory tags see https://bford.info/cachedir/\n")
_OWN = re.compile(rf"{_NAME.pattern}|{re.escape(_SECRET)}|{re.escape(_TAG)}|\..+\.[0-9a-f]{{8}}\.tmp")
#: What the cache's first version left in the same default folder (``<40 hex>.npz`` with a ``meta.json`` member,
#: ``.writing-<8>.tmp`` of killed writes; no tag, no signature): the folder is taken over and those files removed.
_LEGACY = re.compile(r"[0-9a-f]{40}\.npz|\.writing-[a-z0-9_]{8}\.tmp")

_log = logging.getLogger(__name__)
_lock = threading.Lock()
_fingerprint: str | None = None
_host_root: Path | None = None
_warned: set = set()
_counts = {"hits": 0, "misses": 0, "writes": 0, "damaged": 0, "foreign": 0, "failed_writes": 0}


# ------------------------------------------------------------------ settings
def set_root(folder) -> None:
    """The folder the host application keeps its data in (Blender: its extension's user folder); None: the
    platform default.  ``SCRATCH_IRIDESCENCE_CACHE_DIR`` still wins; the process environment is not changed."""
    global _host_root
    _host_root = None if folder is None else Path(folder)


def _root() -> Path | None:
    chosen = os.environ.get("SCRATCH_IRIDESCENCE_CACHE_DIR", "")
    if chosen.strip().lower() == "off":
        return None
    if chosen:
        return Path(chosen)
    if _host_root is not None:
        return _host_root
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "scratch-iridescence"


def directory() -> Path | None:
    """The cache's own folder (created when first written), or None where the cache is off."""
    root = _root()
    return None if root is None else root / SUBFOLDER


def limit_bytes() -> int:
    """The folder's size limit (``SCRATCH_IRIDESCENCE_CACHE_MB``; anything but a finite number ≥ 0: the default,
    with a warning)."""
    text = os.environ.get("SCRATCH_IRIDESCENCE_CACHE_MB")
    megabytes = DEFAULT_LIMIT_MB
    if text is not None:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if math.isfinite(value) and value >= 0.0:
            megabytes = value
        else:
            _warn_once(("limit", text), "scratch tables cache: SCRATCH_IRIDESCENCE_CACHE_MB=%r is not a size in MB "
                                        "(a finite number >= 0); using the default, %d MB", text, DEFAULT_LIMIT_MB)
    return int(megabytes * 1024 * 1024)


def code_fingerprint() -> str:
    """A digest of the source of the modules that build and read scratch tables, numpy's version and the layout."""
    global _fingerprint
    if _fingerprint is None:
        _fingerprint = _source_digest(Path(__file__).resolve().parents[2])  # mitsuba_bridge
    return _fingerprint


def fingerprinted_sources(package: Path | None = None) -> list[Path]:
    """The sources :func:`code_fingerprint` digests: every module of ``bsdf/`` and ``scratch/``, subfolders included."""
    package = Path(__file__).resolve().parents[2] if package is None else package  # mitsuba_bridge
    return sorted((source for folder in ("bsdf", "scratch") for source in (package / folder).rglob("*.py")),
                  key=lambda source: source.relative_to(package).as_posix())


def _source_digest(package: Path) -> str:
    digest = hashlib.sha256(f"{cache_file.LAYOUT}:{np.__version__}".encode())
    for source in fingerprinted_sources(package):
        digest.update(source.relative_to(package).as_posix().encode() + b"\0")
        digest.update(source.read_bytes())
    return digest.hexdigest()


# ------------------------------------------------------------------ the folder and its secret
def _warn_once(what, message: str, *arguments) -> None:
    with _lock:
        if what in _warned:
            return
        _warned.add(what)
    _log.warning(message, *arguments)


def _prepared(create: bool) -> tuple[Path, bytes] | None:
    """The cache folder and its secret, made when ``create``; None where the cache is off, not made yet, or not
    usable (a foreign folder or secret: warned once).  ``OSError`` where the folder cannot be made."""
    folder = directory()
    if folder is None:
        return None
    if create:
        folder.mkdir(parents=True, exist_ok=True)
    if not folder.is_dir() or not _tagged(folder, create):
        return None
    secret = _secret(folder, create)
    return None if secret is None else (folder, secret)


def _tagged(folder: Path, create: bool) -> bool:
    """Whether ``folder`` is the cache's own (its tag is there); an empty folder is tagged when ``create``."""
    tag = folder / _TAG
    try:
        with open_regular(tag, follow_symlinks=False) as stream:
            if stream.read(len(_TAG_SIGNATURE)).decode("ascii", "replace") == _TAG_SIGNATURE:
                return True
    except (FileNotFoundError, NotARegularFile):
        pass
    names = [entry.name for entry in os.scandir(folder)]
    legacy = [name for name in names if _LEGACY.fullmatch(name) and _written_by_the_first_version(folder / name)]
    foreign = sorted(name for name in names if not _OWN.fullmatch(name) and name not in legacy)
    if foreign:
        _warn_once(("foreign", str(folder)), "scratch tables cache: %s holds files the cache did not write (%s) and "
                   "no %s; it is not used (point SCRATCH_IRIDESCENCE_CACHE_DIR at a folder of its own)",
                   folder, ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else ""), _TAG)
        return False
    if create:
        for name in legacy:  # (tables no version of this code reads again)
            (folder / name).unlink(missing_ok=True)
        write_atomically(tag, lambda stream: stream.write(_TAG_TEXT.encode()))
        return True
    return False


def _written_by_the_first_version(path: Path) -> bool:
    """Whether ``path`` is what the cache's first version wrote: a killed write's temporary file, or a regular
    zip file (``np.savez``) holding its ``meta.json`` record."""
    import zipfile

    if path.name.startswith(".writing-"):
        return path.is_file() and not path.is_symlink()
    try:
        with open_regular(path, follow_symlinks=False) as stream, zipfile.ZipFile(stream) as archive:
            return "meta.json.npy" in archive.namelist()
    except (OSError, NotARegularFile, zipfile.BadZipFile, ValueError):
        return False


def _secret(folder: Path, create: bool) -> bytes | None:
    """The folder's signing secret: read (it must be this user's own, readable by no one else) or made."""
    path = folder / _SECRET
    if create and not os.path.lexists(path):
        temporary = folder / f".{_SECRET}.{secrets.token_hex(4)}.tmp"
        handle = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o600)
        try:
            with os.fdopen(handle, "wb") as stream:
                stream.write(secrets.token_bytes(32))
                stream.flush()
                os.fsync(stream.fileno())
            try:
                os.link(temporary, path)  # (never replaces: a secret another process made meanwhile wins)
            except FileExistsError:
                pass
        finally:
            temporary.unlink(missing_ok=True)
    try:
        with open_regular(path, follow_symlinks=False) as stream:
            status = os.fstat(stream.fileno())
            secret = stream.read(33)
    except (FileNotFoundError, NotARegularFile):
        return None
    if hasattr(os, "geteuid") and (status.st_uid != os.geteuid() or stat.S_IMODE(status.st_mode) & 0o077):
        _warn_once(("secret", str(path)), "scratch tables cache: %s belongs to another user or others may read it; "
                   "the cache is not used (a cache folder is shared by one user account)", path)
        return None
    return secret if len(secret) == 32 else None


# ------------------------------------------------------------------ reading and writing
def _name(key: bytes) -> str:
    return hashlib.sha256(key + code_fingerprint().encode()).hexdigest()[:40] + _SUFFIX


def _identity(key: bytes, options: str) -> dict:
    return {"key": key.hex(), "options": options, "code": code_fingerprint()}


def load(key: bytes, options: str = "") -> tuple[dict, str] | None:
    """``(records, content digest)`` that :func:`store` wrote under ``key`` and ``options``, or None (a miss)."""
    try:
        prepared = _prepared(create=False)
    except OSError:
        prepared = None
    if prepared is None:
        _count("misses")
        return None
    folder, secret = prepared
    path = folder / _name(key)
    try:
        with open_regular(path, follow_symlinks=False) as stream:
            meta, arrays, digest = cache_file.read(stream, secret, _identity(key, options), limit_bytes())
        records = {name: {field: (arrays[f"{name}.{field}"] if kind == "array" else value)
                          for field, (kind, value) in fields.items()} for name, fields in meta.items()}
    except FileNotFoundError:
        _count("misses")
        return None
    except (NotARegularFile, cache_file.CacheFileError, OSError, KeyError, TypeError, ValueError) as error:
        # (the message as text: a handler that keeps records must not keep the traceback's frames alive)
        foreign = isinstance(error, (NotARegularFile, cache_file.ForeignFile))
        _log.warning("scratch tables cache: %s is not used: %s; building the tables again", path, str(error))
        _count("foreign" if foreign else "damaged")
        return None
    try:
        os.utime(path, follow_symlinks=False)  # recently used (the size limit removes the least recently used first)
    except (OSError, NotImplementedError):  # a read-only cache (shared by a farm's machines) still serves its files
        pass
    _count("hits")
    return records, digest


def store(key: bytes, records: dict, options: str = "") -> str | None:
    """Write ``records`` (``{name: dataclass instance or dict}``; values: numpy arrays, None, numbers, tuples) under
    ``key`` and ``options``; returns the content digest, or None where the cache is off or the write failed
    (nothing is left behind then)."""
    folder = directory()
    if folder is None:
        return None
    path = folder / _name(key)
    written = []
    try:
        prepared = _prepared(create=True)
        if prepared is None:
            return None
        secret = prepared[1]
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
        json.dumps(meta, allow_nan=False)  # (a value JSON cannot hold fails here, before any file exists)
        if path.is_symlink():  # planted: replaced by a file, never written through
            path.unlink()
        write_atomically(path, lambda stream: written.append(
            cache_file.write(stream, secret, _identity(key, options), meta, arrays)))
    except (OSError, ValueError, TypeError) as error:
        _log.warning("scratch tables cache: could not write %s (%s); the render goes on", path, str(error))
        _count("failed_writes")
        return None
    _count("writes")
    _prune(folder, keep=path)
    return written[0]


def load_tables(key: bytes, scratches, options: str = ""):
    """``(TableCache, ScanArrays, content digest)`` of ``scratches`` stored under ``key`` by :func:`store_tables`,
    or None."""
    from .incremental import TableCache
    from .scan import ScanArrays
    from .grid import GridTables

    found = load(key, options)
    if found is None:
        return None
    records, digest = found
    try:
        tables = _restore(GridTables, records["tables"])
        cache = _restore(TableCache, {**records["cache"], "scratches": scratches, "tables": tables})
        return cache, _restore(ScanArrays, records["scan"]), digest
    except (KeyError, TypeError, ValueError) as error:  # written by other code under the same key: never
        _log.warning("scratch tables cache: unexpected records (%s); building the tables again", str(error))
        _count("damaged")
        return None


def store_tables(key: bytes, cache, scan, options: str = "") -> str | None:
    """Keep a build (:class:`.incremental.TableCache` and :class:`.scan.ScanArrays`) under ``key``; its digest."""
    return store(key, _table_records(cache, scan), options)


def tables_digest(tables) -> str:
    """A digest of a build's :class:`.grid.GridTables` (its arrays' bytes and its plain values) and of the code
    version: what render parts carry to tell tables apart (``render/parts.py``)."""
    arrays = {field: value for field, value in _fields_of(tables) if isinstance(value, np.ndarray)}
    values = {field: _plain(value) for field, value in _fields_of(tables) if not isinstance(value, np.ndarray)}
    digest = hashlib.sha256(cache_file.content_digest(arrays).encode())
    digest.update(json.dumps(values, sort_keys=True).encode() + code_fingerprint().encode())
    return digest.hexdigest()


def _table_records(cache, scan) -> dict:
    cache_fields = {f.name: getattr(cache, f.name) for f in dataclasses.fields(cache)
                    if f.name not in ("scratches", "tables")}  # (the set is the caller's; its tables a record)
    return {"tables": cache.tables, "scan": scan, "cache": cache_fields}


def _fields_of(record) -> list[tuple[str, object]]:
    """A record's named values: a dict's items or a dataclass's fields."""
    if isinstance(record, dict):
        return list(record.items())
    return [(field.name, getattr(record, field.name)) for field in dataclasses.fields(record)]


def _restore(cls, fields: dict):
    """An instance of the dataclass ``cls`` from stored fields (JSON lists back to tuples)."""
    return cls(**{name: tuple(value) if isinstance(value, list) else value for name, value in fields.items()})


def statistics() -> dict:
    """``hits``, ``misses``, ``writes``, ``damaged`` (unreadable, truncated or altered files), ``foreign`` (files
    of another set, options or code, not signed by this cache, or not regular files), ``failed_writes``."""
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
    """Remove the least recently used of the cache's own files until they hold at most :func:`limit_bytes`, and what
    writes that never finished (a killed process) left behind."""
    remove_stale_temporaries(folder, name_pattern=_NAME.pattern)
    files = []
    try:
        for entry in os.scandir(folder):
            if _NAME.fullmatch(entry.name) and entry.is_file(follow_symlinks=False):
                status = entry.stat(follow_symlinks=False)
                files.append((status.st_mtime, status.st_size, Path(entry.path)))
    except OSError:
        return
    total, limit = sum(size for _, size, _ in files), limit_bytes()
    for _, size, entry in sorted(files, key=lambda f: f[0]):
        if total <= limit:
            break
        if entry != keep:
            try:
                entry.unlink()
            except OSError:
                continue
            total -= size


def _count(what: str) -> None:
    with _lock:
        _counts[what] += 1
