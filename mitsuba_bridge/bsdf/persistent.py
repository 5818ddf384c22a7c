"""Scratch tables kept between final renders: Blender's *Persistent Data* (docs/rendering.md).

Building the tables of a dense set is most of a final render's set-up (the CD of
``make paper``: ~17 s of set-up before 10 s of passes).  Cycles' *Persistent
Data* keeps render data between renders at the cost of memory; the engine does
the same for the scratch tables: inside :func:`kept_between_renders` (the
builder opens it for a final render), a ``scratch_diffraction`` BSDF whose
scratch set and build options equal a kept one's takes the kept tables and
their Dr.Jit arrays instead of building them.  The key is a digest of the whole
set (every array of the :class:`~mitsuba_bridge.scratch.ScratchSet`), the build
options and the Mitsuba variant, so an edited set never meets stale tables.
Sets that the load in progress did not use are forgotten when it ends, and
everything is forgotten by a load with the option off, so memory holds at most
one scene's tables.

numpy and hashlib (Mitsuba only for the active variant's name); the values kept are whatever the
plugin builds.
"""
from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import threading

import numpy as np

__all__ = ["kept_between_renders", "reuse_or_build", "statistics", "forget"]

_lock = threading.Lock()
_kept: dict[bytes, object] = {}
#: The keys the persistent load in progress took or built; None when none is open.  Process-wide, not
#: per thread: Mitsuba may construct plugins on its loader threads.  (A viewport scene loaded meanwhile
#: takes part too, harmlessly: the keys are the sets' contents.)
_used: set[bytes] | None = None
_counts = {"built": 0, "reused": 0}  #: tables built and taken inside persistent loads since the start


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


def reuse_or_build(scratches, options: tuple, build):
    """The kept value for ``scratches`` and ``options`` if a persistent load is open and has one, else
    ``build()`` (kept when a persistent load is open)."""
    if _used is None:
        return build()
    key = _digest(scratches, (_variant(), *options))  # a kept LLVM array cannot serve a CUDA render
    with _lock:
        value = _kept.get(key)
    reused = value is not None
    if not reused:
        value = build()
    with _lock:
        if not reused:
            _kept[key] = value
        _counts["reused" if reused else "built"] += 1
        if _used is not None:
            _used.add(key)
    return value


def statistics() -> dict:
    """``kept`` (scratch sets whose tables are kept now), ``built`` and ``reused`` (tables built and taken
    inside persistent loads so far)."""
    with _lock:
        return {"kept": len(_kept), **_counts}


def forget() -> None:
    """Drop every kept table (their memory goes when no scene uses them any more)."""
    with _lock:
        _kept.clear()


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
