"""Scratch tables shared between scenes: with a live scene, and kept between final renders (docs/rendering.md).

Building the tables of a dense set is most of a final render's set-up (the CD of
``make paper``: ~17 s of set-up before 10 s of passes).  Two ways avoid building
them twice:

* **Shared with a live scene.**  A ``scratch_diffraction`` BSDF whose scratch set
  and build options equal those of a BSDF alive elsewhere in the process takes
  that BSDF's tables and their Dr.Jit arrays: F12 while the Rendered viewport
  shows the same object, or the viewport opened while a final render's scene is
  kept.  Costs no memory: the entries are weak, the tables live as long as some
  scene holds them, and both scenes read them only.
* **Kept between final renders** (Blender's *Persistent Data*, as in Cycles):
  inside :func:`kept_between_renders` (the builder opens it for a final render)
  the tables a load took or built are also held strongly, so the next F12 finds
  them after the previous scene is gone.  Sets that the load in progress did not
  use are forgotten when it ends, and everything is forgotten by a load with the
  option off, so memory holds at most one scene's kept tables.

The key is a digest of the whole set (every array of the
:class:`~mitsuba_bridge.scratch.ScratchSet`), the build options and the Mitsuba
variant, so an edited set never meets stale tables and a kept LLVM array never
reaches a CUDA render.  Tables a pen stroke extended (:func:`share`) are entered
without a digest, computed only when a new BSDF looks for tables of a set of the
same size and options: a stroke on 300 000 scratches does not pay the ~50 ms of
hashing them.

numpy and hashlib (Mitsuba only for the active variant's name); the values shared are whatever the
plugin builds, in a :class:`Shared` that the BSDF holds.
"""
from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import threading
import weakref

import numpy as np

__all__ = ["Shared", "kept_between_renders", "reuse_or_build", "share", "statistics", "forget", "recording",
           "fingerprint"]


@dataclasses.dataclass(eq=False)
class Shared:
    """One build's value (the plugin's tables and grid); the BSDFs using it hold it, the registry only
    weakly (and strongly while kept)."""

    value: object
    digest: str | None = None  #: :func:`fingerprint`'s digest of the tables, once asked for


@dataclasses.dataclass(eq=False)
class _Entry:
    shared: weakref.ref
    options: tuple
    count: int  #: scratches in the set (a cheap filter before the digest)
    scratches: object | None  #: the set while its digest is not computed yet (then None)
    key: bytes | None


_lock = threading.Lock()
_live: list[_Entry] = []  #: every value built or shared since the start, weakly; dead entries pruned
_kept: dict[bytes, Shared] = {}
#: The keys the persistent load in progress took or built; None when none is open.  Process-wide, not
#: per thread: Mitsuba may construct plugins on its loader threads.  (A viewport scene loaded meanwhile
#: takes part too, harmlessly: the keys are the sets' contents.)
_used: set[bytes] | None = None
_counts = {"built": 0, "reused": 0}  #: tables built and taken by new BSDFs since the start
_recordings: list[list] = []  #: open :func:`recording` blocks: each gets every Shared handed to a BSDF


@contextlib.contextmanager
def recording():
    """Yield a list that collects the :class:`Shared` tables of every scratch BSDF made inside the block
    (taken or built): what a scene loaded there renders with (``render/parts.py`` names them in a part)."""
    found: list[Shared] = []
    with _lock:
        _recordings.append(found)
    try:
        yield found
    finally:
        with _lock:
            _recordings.remove(found)


def fingerprint(shared: list) -> str:
    """A digest of the tables ``shared`` hold (each one's arrays and the code version, in any order); the same
    for every process that renders the same sets with the same code, another for any other tables."""
    from .tables.disk_cache import code_fingerprint, tables_digest

    for entry in shared:
        if entry.digest is None:
            entry.digest = tables_digest(entry.value[0].tables)
    text = ",".join(sorted({entry.digest for entry in shared}))
    return hashlib.sha256(f"{code_fingerprint()}:{text}".encode()).hexdigest()[:32]


@contextlib.contextmanager
def kept_between_renders(enabled: bool):
    """Around a final render's scene load: reuse and keep tables (``enabled``) or forget all kept ones."""
    global _used
    if not enabled:
        forget()
        yield
        return
    with _lock:
        _used = set()
    try:
        yield
    finally:
        with _lock:
            for key in set(_kept) - _used:
                del _kept[key]
            _used = None


def reuse_or_build(scratches, options: tuple, build) -> Shared:
    """Tables for a new BSDF: those of a live or kept BSDF with an equal set and ``options``, else
    ``build(key)``'s (``key``: the digest of the set and options).  Kept when a persistent load is open."""
    options = (_variant(), *options)  # a shared LLVM array cannot serve a CUDA render
    key = _digest(scratches, options)
    with _lock:
        shared = _kept.get(key) or _find_live(key, scratches.count, options)
    reused = shared is not None
    if not reused:
        shared = Shared(build(key))  # (the key also names the build's file in the disk cache, disk_cache.py)
    with _lock:
        if not reused:
            _live.append(_Entry(weakref.ref(shared), options, scratches.count, None, key))
        _counts["reused" if reused else "built"] += 1
        for found in _recordings:
            found.append(shared)
        if _used is not None:
            _kept[key] = shared
            _used.add(key)
    return shared


def share(scratches, options: tuple, value) -> Shared:
    """Enter tables built for an edited set (a stroke's extension) for later BSDFs to find; returns the
    :class:`Shared` the BSDF holds.  The digest waits until a lookup needs it."""
    shared = Shared(value)
    with _lock:
        _prune()  # the tables this stroke replaces
        _live.append(_Entry(weakref.ref(shared), (_variant(), *options), scratches.count, scratches, None))
        for found in _recordings:
            found.append(shared)
    return shared


def statistics() -> dict:
    """``kept`` (scratch sets whose tables are kept now), ``live`` (tables some BSDF holds), ``built`` and
    ``reused`` (tables built and taken by new BSDFs so far)."""
    with _lock:
        _prune()
        return {"kept": len(_kept), "live": len(_live), **_counts}


def forget() -> None:
    """Drop every kept table (their memory goes when no scene uses them any more)."""
    with _lock:
        _kept.clear()


def _find_live(key: bytes, count: int, options: tuple) -> Shared | None:
    _prune()
    for entry in _live:
        if entry.count != count or entry.options != options:
            continue
        if entry.key is None:  # entered by share(): hash it now, once
            entry.key, entry.scratches = _digest(entry.scratches, entry.options), None
        shared = entry.shared()
        if entry.key == key and shared is not None:
            return shared
    return None


def _prune() -> None:
    _live[:] = [entry for entry in _live if entry.shared() is not None]


def _variant() -> str:
    import mitsuba as mi

    return mi.variant()


def _digest(scratches, options: tuple) -> bytes:
    digest = hashlib.blake2b(repr(options).encode(), digest_size=20)
    for field in dataclasses.fields(scratches):
        value = np.ascontiguousarray(getattr(scratches, field.name))
        digest.update(f"{field.name}:{value.dtype.str}:{value.shape}".encode())
        digest.update(value.data)
    return digest.digest()
