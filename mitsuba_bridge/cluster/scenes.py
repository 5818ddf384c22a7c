"""Scene folders shipped to cluster workers once: content-addressed bundles and the worker's cache of them.

No shared filesystem is assumed.  The driver packs what an export owns
(``scene.xml``, ``meshes/``, ``textures/``, ``scratches/``) into a zip whose
name is the folder's :func:`~mitsuba_bridge.render.parts.scene_fingerprint` (the
SHA-256 a render part already carries as ``render.scene``).  A worker unpacks
it once into its cache, ``<cache>/<digest>/``, and every later render of the
same files finds it there: nothing is sent again, whichever driver asks.

* **Where**: ``SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR``, else the platform's cache
  folder (``platformdirs``: ``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux,
  ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on Windows) under
  ``scratch-iridescence/scenes``, beside the scratch tables' cache
  (:mod:`...bsdf.tables.disk_cache`).  Workers on one machine share it.
* **Size**: at most ``SCRATCH_IRIDESCENCE_SCENE_CACHE_MB`` (default
  :data:`DEFAULT_LIMIT_MB`); the least recently used scenes go first.
* **Safety**: a bundle is unpacked into a temporary sibling, its fingerprint is
  checked against its name, and only then renamed into place, so a worker never
  renders half a scene or the wrong one; entries that would leave the folder
  (absolute paths, ``..``) are refused.
"""
from __future__ import annotations

import io
import os
import shutil
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from ..files.entries import entry_files
from ..folder.export import EXPORTED_ENTRIES, SCENE_FILE
from ..render.parts import scene_fingerprint

__all__ = ["SceneBundle", "pack_folder", "pack_file", "cache_directory", "cached_scene", "store_bundle",
           "DEFAULT_LIMIT_MB", "BundleError"]

#: Default size limit of a worker's scene cache (MB).
DEFAULT_LIMIT_MB = 8192


class BundleError(ValueError):
    """A bundle that does not unpack into the scene its name promises."""


@dataclass(frozen=True)
class SceneBundle:
    """The bytes of a scene folder (or of one file, ``entry``) and the digest that names them."""

    digest: str
    data: bytes
    #: For a single file (a .blend): its name inside the cached folder; None for an export folder.
    entry: str | None = None

    @property
    def size_bytes(self) -> int:
        return len(self.data)


def _zip(folder: Path, files: list[Path]) -> bytes:
    stream = io.BytesIO()
    # Level 1: PLY meshes and scratch files shrink by about half at a fraction of level 6's time.
    with zipfile.ZipFile(stream, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as archive:
        for path in files:
            info = zipfile.ZipInfo(path.relative_to(folder).as_posix(), date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, path.read_bytes())
    return stream.getvalue()


def pack_folder(folder) -> SceneBundle:
    """The bundle of an export folder (or of the folder of a ``scene.xml``): the entries an export owns."""
    folder = Path(folder)
    folder = folder.parent if folder.is_file() else folder
    if not (folder / SCENE_FILE).is_file():
        raise FileNotFoundError(f"{folder / SCENE_FILE}: no such scene file (expected an exported folder holding "
                                f"{SCENE_FILE})")
    return SceneBundle(scene_fingerprint(folder, EXPORTED_ENTRIES), _zip(folder, entry_files(folder, EXPORTED_ENTRIES)))


def pack_file(path) -> SceneBundle:
    """The bundle of one file (a .blend that workers export frames from), named by its SHA-256."""
    import hashlib

    path = Path(path)
    data = path.read_bytes()
    return SceneBundle(hashlib.sha256(data).hexdigest(), _zip(path.parent, [path]), entry=path.name)


def cache_directory() -> Path:
    """The worker's scene cache: ``SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR``, else the platform's cache folder."""
    chosen = os.environ.get("SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR", "")
    if chosen:
        return Path(chosen)
    import platformdirs  # the cluster extra's; ~/.cache/scratch-iridescence on Linux, as the tables' cache

    return platformdirs.user_cache_path("scratch-iridescence", appauthor=False, opinion=False) / "scenes"


def cached_scene(digest: str) -> Path | None:
    """The cached folder of ``digest`` (its use time refreshed), or None when this machine lacks it."""
    folder = cache_directory() / digest
    if not folder.is_dir():
        return None
    try:
        os.utime(folder)  # the eviction's "recently used"
    except OSError:
        pass
    return folder


def _safe_names(archive: zipfile.ZipFile) -> list[str]:
    names = archive.namelist()
    for name in names:
        path = PurePosixPath(name)
        if path.is_absolute() or ".." in path.parts or "\\" in name:
            raise BundleError(f"bundle entry {name!r} would leave the scene folder")
    return names


def store_bundle(bundle: SceneBundle) -> Path:
    """Unpack ``bundle`` into the cache (once; concurrent stores of one digest are harmless); returns its folder.

    Raises :class:`BundleError` when the unpacked files do not have the bundle's digest.
    """
    found = cached_scene(bundle.digest)
    if found is not None:
        return found
    root = cache_directory()
    root.mkdir(parents=True, exist_ok=True)
    building = Path(tempfile.mkdtemp(prefix=f".{bundle.digest[:12]}.", dir=root))
    try:
        with zipfile.ZipFile(io.BytesIO(bundle.data)) as archive:
            _safe_names(archive)
            archive.extractall(building)
        if bundle.entry is None:
            digest = scene_fingerprint(building, EXPORTED_ENTRIES)
        else:
            import hashlib
            digest = hashlib.sha256((building / bundle.entry).read_bytes()).hexdigest()
        if digest != bundle.digest:
            raise BundleError(f"bundle {bundle.digest[:12]} unpacked into files of digest {digest[:12]}")
        try:
            os.rename(building, root / bundle.digest)
        except OSError:  # another worker of this machine stored it first: theirs is the same files
            if not (root / bundle.digest).is_dir():
                raise
    finally:
        shutil.rmtree(building, ignore_errors=True)
    _evict(root, keep=bundle.digest)
    return root / bundle.digest


def _folder_bytes(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def _evict(root: Path, keep: str) -> None:
    """Remove the least recently used scenes until the cache fits its limit (never ``keep``)."""
    try:
        limit = float(os.environ.get("SCRATCH_IRIDESCENCE_SCENE_CACHE_MB", DEFAULT_LIMIT_MB)) * 1e6
    except ValueError:
        limit = DEFAULT_LIMIT_MB * 1e6
    folders = [p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")]
    sizes = {p: _folder_bytes(p) for p in folders}
    total = sum(sizes.values())
    for folder in sorted(folders, key=lambda p: p.stat().st_mtime):
        if total <= limit:
            break
        if folder.name != keep:
            shutil.rmtree(folder, ignore_errors=True)
            total -= sizes[folder]
