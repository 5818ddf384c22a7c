"""Scratch file format v1: a NumPy ``.npz`` archive (see docs/scratch-format.md).

Reading accepts ``np.savez`` and ``np.savez_compressed`` archives and validates
everything before returning; writing goes to a temporary file in the target
folder that is renamed into place, so a failed save never leaves a half-written
file behind.
"""
from __future__ import annotations

import io
import math
import re
from pathlib import Path

import numpy as np

from .archive import ArchiveReader
from ..files.atomic import write_atomically
from ..files.regular import open_regular
from .scratchset import (FIELD_SPECS, MAX_SCRATCHES, MAX_VERTICES, ScratchFormatError, ScratchSet,
                         validate_offsets)

__all__ = ["FORMAT", "FORMAT_VERSION", "load", "save", "save_bytes", "loads", "dumps", "declared_counts"]

FORMAT_NAME = "scratch-iridescence"
FORMAT_VERSION = 1
FORMAT = f"{FORMAT_NAME}/{FORMAT_VERSION}"
KEYS = ("format",) + tuple(FIELD_SPECS)
#: Longest format string read (``"scratch-iridescence/1"`` has 21 characters).
MAX_FORMAT_CHARS = 64


def load(path) -> ScratchSet:
    """Read and validate a scratch file.

    Raises
    ------
    ScratchFormatError
        Naming the file and the field, for any file that is not a valid
        format-v1 scratch file (missing key, wrong dtype or shape, NaN, bad
        offsets, unknown profile, wrong or future format, not a zip archive ...).
    FileNotFoundError
        When ``path`` does not exist.
    NotARegularFile
        When ``path`` is a FIFO, a device or a folder (refused at once: a FIFO's reader would wait forever).
    """
    path = Path(path)
    try:
        with open_regular(path) as stream:
            return _read(stream)
    except ScratchFormatError as error:
        raise error.with_path(path) from None


def loads(data: bytes) -> ScratchSet:
    """Read and validate a scratch file held in memory (the bytes of an ``.npz``)."""
    return _read(io.BytesIO(data))


def save(scratches: ScratchSet, path, *, compress: bool = False) -> Path:
    """Write ``scratches`` to ``path`` atomically and return the path.

    ``compress=True`` writes ``np.savez_compressed`` (smaller, several times
    slower for large sets).  The path is used as given (no ``.npz`` is added).
    """
    if not isinstance(scratches, ScratchSet):  # fail before creating any file
        raise TypeError(f"expected a ScratchSet, got {type(scratches).__name__}")
    return write_atomically(path, lambda stream: _write(scratches, stream, compress))


def save_bytes(data: bytes, path) -> Path:
    """Write the bytes of a scratch file (from :func:`dumps`) to ``path`` atomically.

    For callers that keep scratch files as bytes (the Blender add-on stores them
    in the .blend): exporting is then writing those bytes, byte for byte.  The
    bytes are written as given, not validated.
    """
    data = bytes(data)
    return write_atomically(path, lambda stream: stream.write(data))


def dumps(scratches: ScratchSet, *, compress: bool = False) -> bytes:
    """The bytes of the scratch file of ``scratches``."""
    stream = io.BytesIO()
    _write(scratches, stream, compress)
    return stream.getvalue()


# ------------------------------------------------------------------ internals
def _write(scratches: ScratchSet, stream, compress: bool) -> None:
    if not isinstance(scratches, ScratchSet):
        raise TypeError(f"expected a ScratchSet, got {type(scratches).__name__}")
    writer = np.savez_compressed if compress else np.savez
    writer(stream, format=np.array(FORMAT), **scratches.as_dict())


def _read(stream) -> ScratchSet:
    with ArchiveReader(stream) as archive:
        headers = _checked_headers(archive)
        # Cheap members first: offsets must fit uv before uv, the largest member, is inflated.
        offsets = _native(archive.array("offsets", headers["offsets"]))
        validate_offsets(offsets, headers["uv"].shape[0])
        arrays = {"offsets": offsets}
        for key in FIELD_SPECS:
            if key not in arrays:
                arrays[key] = _native(archive.array(key, headers[key]))
    return ScratchSet(**arrays)  # validates every field


def _checked_headers(archive: ArchiveReader) -> dict:
    """The format string and every field's header checked (nothing but the format string inflated)."""
    if "format" not in archive.members:
        raise ScratchFormatError("missing (not a scratch-iridescence file?)", "format")
    _check_format(archive.array("format", _format_header(archive)))
    for key in KEYS:
        if key not in archive.members:
            raise ScratchFormatError("missing", key)
    unknown = sorted(set(archive.members) - set(KEYS))
    if unknown:
        raise ScratchFormatError(f"unexpected key(s) {unknown} in a format-v{FORMAT_VERSION} file", unknown[0])
    return _field_headers(archive)


def declared_counts(path) -> tuple[int, int]:
    """``(scratches, vertices)`` a scratch file declares, from its zip directory and ``.npy`` headers alone.

    Nothing is inflated but the format string, so a caller can estimate what
    loading the file will cost before it does (the add-on's Import).  Raises
    what :func:`load` raises for a file whose headers break the format.
    """
    path = Path(path)
    try:
        with open_regular(path) as stream, ArchiveReader(stream) as archive:
            headers = _checked_headers(archive)
    except ScratchFormatError as error:
        raise error.with_path(path) from None
    return headers["offsets"].shape[0] - 1, headers["uv"].shape[0]


def _format_header(archive: ArchiveReader):
    header = archive.header("format", max_data_bytes=4 * MAX_FORMAT_CHARS)
    if header.shape != () or header.dtype.kind != "U":
        raise ScratchFormatError(f"must be a 0-d string, got dtype {header.dtype} shape {header.shape}",
                                 "format")
    return header


def _field_headers(archive: ArchiveReader) -> dict:
    """The ``.npy`` headers of the eight fields, checked against the format before any data is inflated.

    The counts come from ``offsets`` (S + 1 entries) and ``uv`` (P rows), each
    bounded by the format's limits; every other field must then declare exactly S
    rows, so the archive's total inflated size is bounded by the counts.
    """
    limits = {"offsets": MAX_SCRATCHES + 1, "uv": MAX_VERTICES}
    headers = {key: _checked_header(archive, key, limits[key]) for key in ("offsets", "uv")}
    count = headers["offsets"].shape[0] - 1
    if count < 0:
        raise ScratchFormatError("needs at least one entry (offsets[0] = 0)", "offsets")
    if headers["uv"].shape[0] < 2 * count:
        raise ScratchFormatError(f"describe {count:,} scratches but uv has {headers['uv'].shape[0]:,} vertices "
                                 "(each scratch needs at least 2)", "offsets")
    for key in FIELD_SPECS:
        if key not in headers:
            headers[key] = _checked_header(archive, key, count)
            if headers[key].shape[0] != count:
                raise ScratchFormatError(
                    f"has {headers[key].shape[0]:,} entries but offsets describe {count:,} scratches", key)
    return headers


def _checked_header(archive: ArchiveReader, key: str, max_rows: int):
    """The header of field ``key``: dtype (any byte order) and shape as FIELD_SPECS says, at most ``max_rows``."""
    dtype, trailing = FIELD_SPECS[key]
    header = archive.header(key, max_data_bytes=max_rows * dtype.itemsize * math.prod(trailing))
    if header.dtype.newbyteorder("=") != dtype:
        raise ScratchFormatError(f"dtype is {header.dtype}, expected {dtype}", key)
    if len(header.shape) != 1 + len(trailing) or header.shape[1:] != trailing:
        expected = "(N" + "".join(f", {t}" for t in trailing) + ")"
        raise ScratchFormatError(f"shape is {header.shape}, expected {expected}", key)
    return header


def _check_format(value: np.ndarray) -> None:
    try:
        text = str(value)
    except (ValueError, UnicodeError):  # code points beyond Unicode
        raise ScratchFormatError("is not a valid Unicode string", "format") from None
    if text == FORMAT:
        return
    # Only the exact spelling written by a newer version (ASCII digits, no leading zero) is called newer.
    newer = re.fullmatch(rf"{re.escape(FORMAT_NAME)}/([1-9][0-9]{{0,8}})", text)
    if newer and int(newer.group(1)) > FORMAT_VERSION:
        raise ScratchFormatError(
            f"is {text!r}: written by a newer version of Scratch Iridescence; "
            f"this version reads format {FORMAT_VERSION}", "format")
    raise ScratchFormatError(f"is {text!r}, expected exactly {FORMAT!r}", "format")


def _native(array: np.ndarray) -> np.ndarray:
    """Byte-swapped arrays (written on a big-endian machine) in native order."""
    return array if array.dtype.isnative else array.astype(array.dtype.newbyteorder("="))
