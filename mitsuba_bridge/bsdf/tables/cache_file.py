"""One file of the scratch tables' disk cache: named arrays and plain values that say what they are and who wrote them.

Layout (all integers little-endian)::

    magic     16 bytes   b"SCRATCH-TABLES" 0x00, then the layout version
    mac       32 bytes   HMAC-SHA-256 of the header, keyed with the cache folder's secret
    length     8 bytes   of the header
    header    JSON       identity (marker, layout, key, options, code), content digest, records, array directory
    data                 the arrays, C order, each at a 64-byte aligned offset of the data

* **Who wrote it.**  The header's MAC is keyed with a secret that only the
  cache's owner can read (``secret.key``, mode 0600, beside the files,
  :mod:`.disk_cache`): a file someone else made (or edited) fails the check,
  whatever it holds.
* **What it holds.**  The header names the scratch set and build options (the
  key: a digest of every array of the set, the options and the Mitsuba variant),
  the options again in words and the code version (a digest of the source that
  builds and reads tables).  A reader asks for a key, options and code version
  and gets a miss unless all three match: another set's file renamed, copied
  or linked under this name never serves it.
* **That it is whole.**  The header holds a digest of the data (SHA-256 of its
  4 MiB blocks' SHA-256, :class:`_BlockDigest`, hashed on all cores); the data is
  hashed while it is read into its arrays, so nothing of a truncated, scaled or
  NaN-filled file is used.

Reading never trusts a size before the MAC is checked: the header is at most
:data:`MAX_HEADER_BYTES`, the file at most what the caller allows, and the array
directory must tile the data exactly.  Every refusal is a :class:`CacheFileError`
saying why (the caller turns it into a miss and a warning).  numpy and the
standard library only.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import math
import os
from typing import BinaryIO

import numpy as np

__all__ = ["MAGIC", "LAYOUT", "MARKER", "MAX_HEADER_BYTES", "CacheFileError", "ForeignFile", "Identity", "write",
           "read", "content_digest"]

LAYOUT = 2
MAGIC = b"SCRATCH-TABLES\x00" + bytes([LAYOUT])
MARKER = "scratch-iridescence scratch tables cache"
MAX_HEADER_BYTES = 1 << 20
_MAX_ARRAYS = 256
_ALIGN = 64
_KINDS = "biuf"  #: numbers only (native order, at most 8 bytes: what the writer writes), no objects or strings
_CHUNK = 1 << 24
_BLOCK = 1 << 22  #: bytes per hashed block (:class:`_BlockDigest`)


class CacheFileError(ValueError):
    """A file that cannot serve the request (damaged, altered, or foreign); the message says which."""


class ForeignFile(CacheFileError):
    """A file this cache did not write for this request: another layout, not signed with the folder's secret, or
    signed but holding another set's (options', code's) tables."""


Identity = dict  #: ``{"key": hex, "options": text, "code": hex}``: what a file holds, compared whole on read


def content_digest(arrays: dict[str, np.ndarray]) -> str:
    """The digest (hex) of the data region :func:`write` lays out for ``arrays`` (as :func:`read` computes it)."""
    with _BlockDigest() as digest:
        for _, _, padding, array in _layout(arrays):
            digest.update(_bytes_of(array))
            digest.update(memoryview(bytes(padding)))
        return digest.hexdigest()


class _BlockDigest:
    """SHA-256 of the SHA-256 digests of a byte stream's :data:`_BLOCK`-byte blocks, in order.

    The blocks are hashed on worker threads as they arrive (``hashlib`` lets go
    of the GIL), while the caller reads on: checking every byte of a file then
    costs what one core hashes divided by the cores (SHA-256 runs at about
    0.4 GB/s on the 2-core development machine).  The views handed to
    :meth:`update` must not change until :meth:`hexdigest`.
    """

    def __init__(self):
        from concurrent.futures import ThreadPoolExecutor

        self._pool = ThreadPoolExecutor(max_workers=min(os.cpu_count() or 1, 8))
        self._blocks = []
        self._carry = bytearray()

    def __enter__(self) -> "_BlockDigest":
        return self

    def __exit__(self, *exc) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def update(self, view: memoryview) -> None:
        if self._carry:  # complete the block a previous view began
            taken = view[:_BLOCK - len(self._carry)]
            self._carry += taken
            view = view[len(taken):]
            if len(self._carry) < _BLOCK:
                return
            self._submit(bytes(self._carry))
            self._carry = bytearray()
        while len(view) >= _BLOCK:
            self._submit(view[:_BLOCK])
            view = view[_BLOCK:]
        self._carry += view

    def _submit(self, block) -> None:
        self._blocks.append(self._pool.submit(lambda data: hashlib.sha256(data).digest(), block))

    def hexdigest(self) -> str:
        if self._carry:
            self._submit(bytes(self._carry))
            self._carry = bytearray()
        combined = hashlib.sha256(_BLOCK.to_bytes(8, "little"))
        for block in self._blocks:
            combined.update(block.result())
        return combined.hexdigest()


def _bytes_of(array: np.ndarray) -> memoryview:
    """The array's bytes in C order, without a copy where it is contiguous (empty arrays included)."""
    return memoryview(np.ascontiguousarray(array).reshape(-1).view(np.uint8))


def _layout(arrays: dict[str, np.ndarray]):
    """``(name, offset, padding after, array)`` in order; offsets within the data region."""
    offset, placed = 0, []
    for name, array in arrays.items():
        size = int(array.nbytes)
        padding = -size % _ALIGN
        placed.append((name, offset, padding, array))
        offset += size + padding
    return placed


def write(stream: BinaryIO, secret: bytes, identity: Identity, records: dict, arrays: dict[str, np.ndarray]) -> str:
    """Write a cache file to ``stream``: ``records`` (JSON values) and ``arrays`` under ``identity``.

    Returns the content digest (hex) of the arrays.
    """
    arrays = {name: np.ascontiguousarray(array) for name, array in arrays.items()}
    directory = [[name, array.dtype.str, list(array.shape), offset, int(array.nbytes)]
                 for name, offset, _, array in _layout(arrays)]
    digest = content_digest(arrays)
    header = json.dumps({"marker": MARKER, "layout": LAYOUT, **identity, "content": digest, "records": records,
                         "arrays": directory}, separators=(",", ":"), allow_nan=False).encode()
    if len(header) > MAX_HEADER_BYTES:
        raise ValueError(f"a header of {len(header):,} bytes; at most {MAX_HEADER_BYTES:,}")
    stream.write(MAGIC)
    stream.write(hmac.new(secret, header, hashlib.sha256).digest())
    stream.write(len(header).to_bytes(8, "little"))
    stream.write(header)
    for _, _, padding, array in _layout(arrays):
        stream.write(_bytes_of(array))
        stream.write(bytes(padding))
    return digest


def read(stream: BinaryIO, secret: bytes, identity: Identity, max_bytes: int) -> tuple[dict, dict, str]:
    """``(records, arrays, content digest)`` of the cache file open as ``stream``, written under ``identity``.

    Raises :class:`CacheFileError` for a file over ``max_bytes``, of another
    layout, with a header this folder's secret did not sign, of another
    identity, or whose data does not match its digest.
    """
    size = os.fstat(stream.fileno()).st_size
    if size > max_bytes:
        raise CacheFileError(f"{size:,} bytes, more than the cache may hold ({max_bytes:,})")
    if _exact(stream, len(MAGIC)) != MAGIC:
        raise ForeignFile("not a scratch tables cache file of this version")
    mac = _exact(stream, 32)
    length = int.from_bytes(_exact(stream, 8), "little")
    if length > MAX_HEADER_BYTES or length > size:
        raise CacheFileError(f"a header of {length:,} bytes")
    header_bytes = _exact(stream, length)
    if not hmac.compare_digest(mac, hmac.new(secret, header_bytes, hashlib.sha256).digest()):
        raise ForeignFile("not written by this cache (its signature does not match the folder's secret)")
    try:
        header = json.loads(header_bytes)
    except ValueError as error:  # (signed, so written by this cache: a bug, but still only a miss)
        raise CacheFileError(f"an unreadable header ({error})") from None
    if header.get("marker") != MARKER or header.get("layout") != LAYOUT:
        raise ForeignFile("not a scratch tables cache file of this version")
    for field, wanted in identity.items():
        if header.get(field) != wanted:
            raise ForeignFile(f"holds the tables of another {_WHAT.get(field, field)} (its {field} "
                                 f"{str(header.get(field))[:24]}…, wanted {str(wanted)[:24]}…)")
    data_start = len(MAGIC) + 32 + 8 + length
    arrays, digest = _read_arrays(stream, header, size - data_start)
    return header["records"], arrays, digest


_WHAT = {"key": "scratch set", "options": "set of build options", "code": "version of the code"}


def _read_arrays(stream: BinaryIO, header: dict, data_bytes: int) -> tuple[dict, str]:
    directory = header.get("arrays")
    if not isinstance(directory, list) or len(directory) > _MAX_ARRAYS:
        raise CacheFileError("a damaged array directory")
    with _BlockDigest() as digest:
        arrays, position = _read_each(stream, directory, data_bytes, digest)
        if position != data_bytes or stream.read(1):
            raise CacheFileError("data beyond the arrays its header lists")
        found = digest.hexdigest()
    if not hmac.compare_digest(found, str(header.get("content"))):
        raise CacheFileError("damaged or altered data (its digest does not match the header's)")
    return arrays, found


def _read_each(stream: BinaryIO, directory: list, data_bytes: int, digest: "_BlockDigest") -> tuple[dict, int]:
    """The arrays of ``directory``, each checked against its place before it is allocated, and where they end."""
    position, arrays = 0, {}
    whole = lambda value: isinstance(value, int) and not isinstance(value, bool)
    for entry in directory:
        try:
            name, dtype_text, shape, offset, nbytes = entry
            if not (isinstance(name, str) and name and name not in arrays and isinstance(dtype_text, str)
                    and isinstance(shape, list) and all(whole(d) for d in shape) and whole(offset) and whole(nbytes)):
                raise TypeError("not a name, a dtype, a shape, an offset and a size")
            dtype = np.dtype(dtype_text)
        except (TypeError, ValueError):
            raise CacheFileError("a damaged array directory") from None
        if dtype.kind not in _KINDS or dtype.itemsize > 8 or dtype.byteorder not in "=|" \
                or any(d < 0 for d in shape) or offset != position \
                or math.prod(shape) * dtype.itemsize != nbytes or offset + nbytes > data_bytes:
            raise CacheFileError(f"array {name!r} does not fit its declared place")
        array = np.empty(shape, dtype=dtype)
        _read_into(stream, memoryview(array.reshape(-1).view(np.uint8)), digest)
        padding = -nbytes % _ALIGN
        _read_into(stream, memoryview(bytearray(padding)), digest)  # (a new buffer: the digest may still read it)
        position = offset + nbytes + padding
        arrays[str(name)] = array
    return arrays, position


def _read_into(stream: BinaryIO, view: memoryview, digest) -> None:
    filled = 0
    while filled < len(view):
        count = stream.readinto(view[filled:filled + _CHUNK])
        if not count:
            raise CacheFileError("truncated")
        digest.update(view[filled:filled + count])
        filled += count


def _exact(stream: BinaryIO, count: int) -> bytes:
    data = stream.read(count)
    if len(data) != count:
        raise CacheFileError("truncated")
    return data
