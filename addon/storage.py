"""Where an object's scratches live in the .blend: the bytes of a format-v1 scratch file.

The whole scratch set of an object is one hidden ID property holding exactly the
bytes ``mitsuba_bridge.scratch.dumps`` writes.  That is exact (float64 UV
survives save/reload and undo bit for bit), bulk (one copy, no RNA object per
scratch), part of Blender's global undo like any ID data, independent of whether
the add-on is registered, and exporting is writing those bytes to a file.

Small companions make cheap queries cheap: the scratch count and mean width and
depth for panels, and a random *token* that changes on every write, so caches
(the overlay's batch) can tell whether the data changed without decoding it.
A token and not a counter: undo restores older tokens, so a counter could repeat
with different data.

Decoding is cached by the SHA-256 of the stored bytes, never by the token alone:
the token is only a hint.  Bytes that change under an unchanged token (a damaged
.blend re-opened in the same session, a script writing the ID property) are
decoded and validated again, so render and export never use a stale set, and
damaged bytes always give the same :class:`StoredScratchesError`.  Hashing costs
~30 ms for the paper's largest set (54 MB), against ~300 ms for decoding it.
"""
from __future__ import annotations

import hashlib
import secrets
from collections import OrderedDict
from typing import NamedTuple

from ..mitsuba_bridge import scratch
from ..mitsuba_bridge.scratch import ScratchFormatError, ScratchSet

__all__ = ["DATA_KEY", "StoredScratchesError", "StoredSet", "read_scratches", "read_scratch_file", "write_scratches",
           "clear_scratches", "has_scratches", "scratch_summary", "scratch_token", "raw_scratch_bytes"]

DATA_KEY = "_scratch_iridescence"        # bytes of the scratch file (hidden: leading underscore)
TOKEN_KEY = "_scratch_iridescence_token"  # changes on every write
SUMMARY_KEY = "_scratch_iridescence_summary"  # {count, mean_width, mean_depth}

# SHA-256 of the stored bytes -> their ScratchSet, for the last few decoded sets (least recent first).
_decoded: OrderedDict[bytes, ScratchSet] = OrderedDict()
_CACHE_SIZE = 8


class StoredSet(NamedTuple):
    """An object's decoded scratches with the stored bytes they came from."""

    scratches: ScratchSet
    data: bytes | None  #: None when the object has no scratches
    digest: bytes | None  #: SHA-256 of ``data``: a cache key that follows the bytes, unlike the token


class StoredScratchesError(ScratchFormatError):
    """The scratch file stored in an object is damaged; the message names the object and the field."""

    def __init__(self, object_name: str, error: ScratchFormatError):
        super().__init__(f"{error.problem} (clear the object's scratches or import a good scratch file)",
                         error.field, f"object '{object_name}' (stored scratches)")
        self.object_name = object_name

    def with_path(self, path) -> ScratchFormatError:
        return ScratchFormatError(self.problem, self.field, path)


def has_scratches(obj) -> bool:
    """Whether ``obj`` carries at least one scratch."""
    return scratch_summary(obj)["count"] > 0


def scratch_token(obj) -> str | None:
    """A string that changes whenever the object's scratches change (None: never written)."""
    return obj.get(TOKEN_KEY)


def scratch_summary(obj) -> dict:
    """``{"count", "mean_width", "mean_depth"}`` (metres) without decoding the scratches."""
    summary = obj.get(SUMMARY_KEY)
    if summary is None or DATA_KEY not in obj:
        return {"count": 0, "mean_width": 0.0, "mean_depth": 0.0}
    return {"count": int(summary["count"]), "mean_width": float(summary["mean_width"]),
            "mean_depth": float(summary["mean_depth"])}


def raw_scratch_bytes(obj) -> bytes | None:
    """The stored scratch file, byte for byte (None when the object has none).

    Raises
    ------
    StoredScratchesError
        If the property holds something else than bytes (a damaged file or a script).
    """
    data = obj.get(DATA_KEY)
    if data is None or isinstance(data, bytes):
        return data
    raise StoredScratchesError(obj.name, ScratchFormatError(
        f"the stored property holds {type(data).__name__}, not the bytes of a scratch file"))


def read_scratches(obj) -> ScratchSet:
    """The object's scratches (an empty set when it has none).

    Raises
    ------
    StoredScratchesError
        If the stored bytes are damaged (edited by hand, a damaged .blend, or
        written by a newer version of the add-on).
    """
    return read_scratch_file(obj).scratches


def read_scratch_file(obj) -> StoredSet:
    """The object's scratches, the stored bytes they were decoded from and their digest.

    Export writes exactly these bytes: they are the ones just validated, even
    if the ID property changes afterwards.  Caches of data derived from the
    scratches (the eraser's lines) key on the digest.

    Raises
    ------
    StoredScratchesError
        If the stored bytes are damaged.
    """
    data = raw_scratch_bytes(obj)
    if data is None:
        return StoredSet(ScratchSet.empty(), None, None)
    digest = hashlib.sha256(data).digest()
    scratches = _decoded.get(digest)
    if scratches is None:
        try:
            scratches = scratch.loads(data)
        except ScratchFormatError as error:
            raise StoredScratchesError(obj.name, error) from None
        _remember(digest, scratches)
    else:
        _decoded.move_to_end(digest)
    return StoredSet(scratches, data, digest)


def _remember(digest: bytes, scratches: ScratchSet) -> None:
    _decoded[digest] = scratches
    _decoded.move_to_end(digest)
    while len(_decoded) > _CACHE_SIZE:
        _decoded.popitem(last=False)


def write_scratches(obj, scratches: ScratchSet) -> bytes:
    """Replace the object's scratches with ``scratches`` (an undo step is the caller's); return their digest."""
    if not isinstance(scratches, ScratchSet):
        raise TypeError(f"expected a ScratchSet, got {type(scratches).__name__}")
    data = scratch.dumps(scratches)
    # Blender truncates bytes at the first NUL when an existing string property is
    # re-assigned (a new key keeps them), so always assign a fresh key.
    for key in (DATA_KEY, TOKEN_KEY, SUMMARY_KEY):
        if key in obj:
            del obj[key]
    obj[DATA_KEY] = data
    obj[SUMMARY_KEY] = {
        "count": scratches.count,
        "mean_width": float(scratches.width.mean()) if scratches.count else 0.0,
        "mean_depth": float(scratches.depth.mean()) if scratches.count else 0.0,
    }
    obj[TOKEN_KEY] = secrets.token_hex(8)
    digest = hashlib.sha256(data).digest()
    _remember(digest, scratches)
    _tag(obj)
    return digest


def _tag(obj) -> None:
    # ID properties written from Python tag nothing: without this the depsgraph (and with it the
    # Rendered viewport's view_update) would not hear of the edit.  OBJECT (a transform-level
    # recalc) is the cheapest tag that reaches the engine; the mesh is not re-evaluated.
    obj.update_tag(refresh={"OBJECT"})


def clear_scratches(obj) -> None:
    """Remove every scratch of ``obj``."""
    for key in (DATA_KEY, TOKEN_KEY, SUMMARY_KEY):
        if key in obj:
            del obj[key]
    _tag(obj)
