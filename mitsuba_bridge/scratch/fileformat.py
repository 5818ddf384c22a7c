"""Scratch file format v1: a NumPy ``.npz`` archive (see docs/scratch-format.md).

Reading accepts ``np.savez`` and ``np.savez_compressed`` archives and validates
everything before returning; writing goes to a temporary file in the target
folder that is renamed into place, so a failed save never leaves a half-written
file behind.
"""
from __future__ import annotations

import io
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from .scratchset import FIELD_SPECS, ScratchFormatError, ScratchSet, validate_arrays

__all__ = ["FORMAT", "FORMAT_VERSION", "load", "save", "save_bytes", "loads", "dumps"]

FORMAT_NAME = "scratch-iridescence"
FORMAT_VERSION = 1
FORMAT = f"{FORMAT_NAME}/{FORMAT_VERSION}"
KEYS = ("format",) + tuple(FIELD_SPECS)


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
    """
    path = Path(path)
    try:
        with open(path, "rb") as stream:
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
    return _write_atomically(path, lambda stream: _write(scratches, stream, compress))


def save_bytes(data: bytes, path) -> Path:
    """Write the bytes of a scratch file (from :func:`dumps`) to ``path`` atomically.

    For callers that keep scratch files as bytes (the Blender add-on stores them
    in the .blend): exporting is then writing those bytes, byte for byte.  The
    bytes are written as given, not validated.
    """
    data = bytes(data)
    return _write_atomically(path, lambda stream: stream.write(data))


def _write_atomically(path, write) -> Path:
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(handle, "wb") as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException:
        # Interrupted or failed: remove the partial file, keep any old one intact.
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        raise
    return path


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
    try:
        archive = np.load(stream, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as error:
        raise ScratchFormatError(f"not a scratch file (expected an .npz archive): {error}") from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ScratchFormatError("not a scratch file (a single .npy array, expected an .npz archive)")

    with archive:
        names = set(archive.files)
        if "format" not in names:
            raise ScratchFormatError("missing (not a scratch-iridescence file?)", "format")
        _check_format(_read_member(archive, "format"))
        for key in KEYS:
            if key not in names:
                raise ScratchFormatError("missing", key)
        unknown = sorted(names - set(KEYS))
        if unknown:
            raise ScratchFormatError(f"unexpected key(s) {unknown} in a format-v{FORMAT_VERSION} file",
                                     unknown[0])
        arrays = {key: _native(_read_member(archive, key)) for key in FIELD_SPECS}

    validate_arrays(arrays)
    return ScratchSet(**arrays)


def _read_member(archive, key: str) -> np.ndarray:
    """One array of the archive; a truncated or corrupt member names its key."""
    try:
        return archive[key]
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError) as error:
        raise ScratchFormatError(f"cannot be read (truncated or corrupt file?): {error}", key) from None


def _check_format(value: np.ndarray) -> None:
    if value.shape != () or value.dtype.kind != "U":
        raise ScratchFormatError(f"must be a 0-d string, got dtype {value.dtype} shape {value.shape}",
                                 "format")
    text = str(value)
    name, _, version = text.partition("/")
    if name != FORMAT_NAME or not version.isdigit():
        raise ScratchFormatError(f"is {text!r}, expected {FORMAT!r}", "format")
    if int(version) > FORMAT_VERSION:
        raise ScratchFormatError(
            f"is {text!r}: written by a newer version of Scratch Iridescence; "
            f"this version reads format {FORMAT_VERSION}", "format")
    if int(version) != FORMAT_VERSION:
        raise ScratchFormatError(f"is {text!r}, expected {FORMAT!r}", "format")


def _native(array: np.ndarray) -> np.ndarray:
    """Byte-swapped arrays (written on a big-endian machine) in native order."""
    return array if array.dtype.isnative else array.astype(array.dtype.newbyteorder("="))
