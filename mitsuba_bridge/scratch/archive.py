"""Reading the ``.npz`` archive of a scratch file without trusting it.

A scratch file is a zip archive of ``.npy`` members (docs/scratch-format.md).
``numpy.load`` would inflate a member before anything about it is checked, and
lets ``zlib``, ``zipfile`` and ``MemoryError`` exceptions through.  This module
checks, in order and before any member data is inflated:

1. the zip container: the end record is the last thing in the file (no trailing
   bytes), the members tile the file from offset 0 up to the central directory
   (no leading or hidden bytes), every name appears once, the compression method
   is stored or deflate, no encryption;
2. each member's ``.npy`` header (a few hundred bytes inflated per member): its
   dtype and shape;
3. the declared counts (scratches S from ``offsets``, vertices P from ``uv``)
   against :data:`MAX_SCRATCHES` and :data:`MAX_VERTICES`, and every member's
   declared inflated size against the exact size its header implies.

Only then are members inflated, in chunks, into buffers of exactly the
declared size; a stream that inflates to more or less, or fails its CRC, is
refused.  Every failure is a :class:`ScratchFormatError` naming the field.
"""
from __future__ import annotations

import io
import math
import struct
import tokenize
import warnings
import zipfile
import zlib
from dataclasses import dataclass

import numpy as np

from .scratchset import ScratchFormatError

__all__ = ["MemberHeader", "ArchiveReader", "ACCEPTED_COMPRESSION"]

#: Zip compression methods a scratch file may use: what ``np.savez`` and ``np.savez_compressed`` write.
ACCEPTED_COMPRESSION = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate"}

# Zip general-purpose flag bits that may be set: 3 (sizes in a data descriptor),
# 11 (UTF-8 names).  Bit 0 (encryption), 6 (strong encryption) and 13 (masked
# central directory) are refused, as are bits the zip format reserves.
_ALLOWED_FLAGS = (1 << 3) | (1 << 11) | (1 << 1) | (1 << 2)  # bits 1-2: deflate speed hints
_END_RECORD = struct.Struct("<4s4H2LH")
_END_SIGNATURE = b"PK\x05\x06"
_LOCAL_HEADER = struct.Struct("<4s5H3L2H")
_LOCAL_SIGNATURE = b"PK\x03\x04"
_DESCRIPTOR_SIZES = (12, 16, 20, 24)  # crc + sizes (32 or 64 bit), with or without a signature
_MAX_MEMBERS = 64
#: numpy's own limit on an ``.npy`` header (``numpy.lib.format``); numpy writes 128 bytes.
_MAX_NPY_HEADER_BYTES = 10_000
_CHUNK_BYTES = 1 << 22

# What the zip and zlib modules raise on damaged input (besides BadZipFile).
_ZIP_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, EOFError, OSError, ValueError,
               struct.error, UnicodeDecodeError, NotImplementedError, RuntimeError, OverflowError,
               KeyError, IndexError)
# What numpy's header parser raises on a damaged header: its tokenize filter for
# Python-2 headers, literal_eval and descr_to_dtype (TokenError found by tests/bridge/scratch/test_fuzz_files.py).
_NPY_HEADER_ERRORS = (ValueError, SyntaxError, TypeError, KeyError, IndexError, OverflowError,
                      RecursionError, UnicodeDecodeError, MemoryError, tokenize.TokenError, Warning)


@dataclass(frozen=True)
class MemberHeader:
    """The ``.npy`` header of one member: what the member declares, before its data is read."""

    dtype: np.dtype
    shape: tuple[int, ...]
    fortran_order: bool
    header_bytes: int  # magic + header, before the array data

    @property
    def data_bytes(self) -> int:
        """Bytes of array data the header implies (a Python int: no overflow)."""
        return math.prod(self.shape) * self.dtype.itemsize


class ArchiveReader:
    """The members of a scratch file's zip archive, checked before they are inflated.

    Parameters
    ----------
    stream:
        A seekable binary stream holding the whole file.

    Raises
    ------
    ScratchFormatError
        When the container is not a plain zip archive of ``.npy`` members (see
        the module docstring); the field is the member's key where one is concerned.
    """

    def __init__(self, stream):
        size = stream.seek(0, io.SEEK_END)
        _check_end_record(stream, size)
        try:
            self._zip = zipfile.ZipFile(stream)
        except _ZIP_ERRORS as error:
            raise ScratchFormatError(f"not a scratch file (expected an .npz archive): {error}") from None
        try:
            self.members = _members(self._zip)
            _check_layout(stream, self._zip, self.members)
        except BaseException:
            self._zip.close()
            raise

    def __enter__(self) -> "ArchiveReader":
        return self

    def __exit__(self, *exc) -> None:
        self._zip.close()

    # ------------------------------------------------------------ headers
    def header(self, key: str, max_data_bytes: int) -> MemberHeader:
        """The ``.npy`` header of member ``key``; refuses a member whose declared data exceeds ``max_data_bytes``.

        The zip directory's inflated size is checked first (nothing is
        inflated for a member that declares too much), then the header, which
        must account for that size exactly.
        """
        info = self.members[key]
        if info.file_size > max_data_bytes + _MAX_NPY_HEADER_BYTES:
            raise ScratchFormatError(
                f"member declares {info.file_size:,} bytes inflated; at most {max_data_bytes:,} bytes of "
                "data are possible within the format's limits", key)
        with self._open(key) as member:
            header = _read_npy_header(member, key)
        if header.data_bytes > max_data_bytes:
            raise ScratchFormatError(
                f"declares shape {header.shape} ({header.data_bytes:,} bytes); at most {max_data_bytes:,} "
                "bytes are possible within the format's limits", key)
        if header.header_bytes + header.data_bytes != info.file_size:
            raise ScratchFormatError(
                f"declares shape {header.shape} of {header.dtype} ({header.data_bytes:,} bytes) but the "
                f"member holds {info.file_size - header.header_bytes:,} bytes of data", key)
        return header

    # --------------------------------------------------------------- data
    def array(self, key: str, header: MemberHeader) -> np.ndarray:
        """Inflate member ``key`` (whose checked header is ``header``) into an array of exactly that size."""
        # np.empty, not bytearray: no zero-filling of memory that is overwritten at once.
        buffer = np.empty(header.data_bytes, dtype=np.uint8)
        filled = 0
        with self._open(key) as member:
            try:
                member.read(header.header_bytes)
                while filled < len(buffer):
                    chunk = member.read(min(_CHUNK_BYTES, len(buffer) - filled))
                    if not chunk:
                        break
                    buffer[filled:filled + len(chunk)] = np.frombuffer(chunk, dtype=np.uint8)
                    filled += len(chunk)
                extra = member.read(1)  # also runs the CRC check at the end of the member
            except _ZIP_ERRORS as error:
                raise ScratchFormatError(f"cannot be read (truncated or corrupt file?): {error}", key) from None
        if filled != len(buffer) or extra:
            raise ScratchFormatError(
                f"member data does not match its declared size of {len(buffer):,} bytes", key)
        order = "F" if header.fortran_order else "C"
        return buffer.view(header.dtype).reshape(header.shape, order=order)

    def _open(self, key: str):
        try:
            return _Guarded(self._zip.open(self.members[key]), key)
        except _ZIP_ERRORS as error:
            raise ScratchFormatError(f"cannot be opened (corrupt archive?): {error}", key) from None


class _Guarded:
    """A zip member stream whose read errors become ScratchFormatError (used for header reads)."""

    def __init__(self, member, key: str):
        self._member = member
        self._key = key

    def read(self, size: int = -1) -> bytes:
        if size is None or size < 0:
            raise ValueError("unbounded reads are not allowed on an untrusted member")
        try:
            return self._member.read(size)
        except _ZIP_ERRORS as error:
            raise ScratchFormatError(f"cannot be read (truncated or corrupt file?): {error}", self._key) from None

    def __enter__(self) -> "_Guarded":
        return self

    def __exit__(self, *exc) -> None:
        self._member.close()


# ------------------------------------------------------------ container checks
def _check_end_record(stream, size: int) -> None:
    """The end-of-central-directory record (and its comment) must end the file exactly."""
    if size < _END_RECORD.size:
        raise ScratchFormatError(f"not a scratch file (expected an .npz archive): only {size} bytes")
    search_from = max(0, size - _END_RECORD.size - 0xFFFF)
    stream.seek(search_from)
    tail = stream.read(size - search_from)
    position = tail.rfind(_END_SIGNATURE)
    while position >= 0:
        record = tail[position:position + _END_RECORD.size]
        if len(record) == _END_RECORD.size:
            comment_bytes = _END_RECORD.unpack(record)[-1]
            if position + _END_RECORD.size + comment_bytes == len(tail):
                entries = _END_RECORD.unpack(record)[4]
                if entries > _MAX_MEMBERS and entries != 0xFFFF:  # 0xFFFF: counted in the zip64 record
                    raise ScratchFormatError(f"not a scratch file: the archive lists {entries} members")
                return
        position = tail.rfind(_END_SIGNATURE, 0, position)
    raise ScratchFormatError("not a scratch file (expected an .npz archive): no zip end record at the end of "
                             "the file (truncated, or trailing bytes after the archive)")


def _members(archive: zipfile.ZipFile) -> dict[str, zipfile.ZipInfo]:
    """Member key (name without ``.npy``) -> zip entry, after the per-entry checks."""
    infos = archive.infolist()
    if len(infos) > _MAX_MEMBERS:
        raise ScratchFormatError(f"not a scratch file: the archive holds {len(infos)} members")
    members: dict[str, zipfile.ZipInfo] = {}
    for info in infos:
        key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
        if not info.filename.endswith(".npy") or not key.isidentifier():
            raise ScratchFormatError(f"archive member {info.filename!r} is not an .npy array of a field",
                                     info.filename)
        if key in members:
            raise ScratchFormatError("appears twice in the archive", key)
        if info.compress_type not in ACCEPTED_COMPRESSION:
            raise ScratchFormatError(
                f"compression method {info.compress_type} is not accepted (only "
                + " and ".join(f"{code} {name}" for code, name in ACCEPTED_COMPRESSION.items()) + ")", key)
        if info.flag_bits & 1 or info.flag_bits & (1 << 6) or info.flag_bits & (1 << 13):
            raise ScratchFormatError("is encrypted; scratch files are never encrypted", key)
        if info.flag_bits & ~_ALLOWED_FLAGS:
            raise ScratchFormatError(f"unexpected zip flags 0x{info.flag_bits:04x}", key)
        if info.compress_type == zipfile.ZIP_STORED and info.compress_size != info.file_size:
            raise ScratchFormatError(
                f"stored member of {info.compress_size:,} bytes declares {info.file_size:,} bytes", key)
        members[key] = info
    return members


def _check_layout(stream, archive: zipfile.ZipFile, members: dict[str, zipfile.ZipInfo]) -> None:
    """Members follow each other from offset 0 up to the central directory, without gaps."""
    position, previous = 0, None
    for key, info in sorted(members.items(), key=lambda item: item[1].header_offset):
        if info.header_offset != position:
            gap = info.header_offset - position
            if not (gap in _DESCRIPTOR_SIZES and _has_descriptor(previous)):
                raise ScratchFormatError(
                    f"member starts at byte {info.header_offset}, expected {position} (bytes hidden "
                    "before or between members)", key)
        stream.seek(info.header_offset)
        local = stream.read(_LOCAL_HEADER.size)
        if len(local) != _LOCAL_HEADER.size or local[:4] != _LOCAL_SIGNATURE:
            raise ScratchFormatError("no zip member header where the directory points", key)
        name_bytes, extra_bytes = _LOCAL_HEADER.unpack(local)[-2:]
        position = info.header_offset + _LOCAL_HEADER.size + name_bytes + extra_bytes + info.compress_size
        previous = info
    end_gap = archive.start_dir - position
    if end_gap != 0 and not (end_gap in _DESCRIPTOR_SIZES and _has_descriptor(previous)):
        raise ScratchFormatError(
            f"the central directory starts at byte {archive.start_dir}, expected {position} "
            "(bytes hidden between the members and the directory)")


def _has_descriptor(info: zipfile.ZipInfo | None) -> bool:
    return info is not None and bool(info.flag_bits & (1 << 3))


# ------------------------------------------------------------------ .npy header
def _read_npy_header(member: _Guarded, key: str) -> MemberHeader:
    """Parse an ``.npy`` header with numpy's own parser, turning its errors into ScratchFormatError."""
    magic = member.read(8)
    if len(magic) != 8 or magic[:6] != b"\x93NUMPY":
        raise ScratchFormatError("member is not an .npy array (no NUMPY magic)", key)
    version = (magic[6], magic[7])
    if version not in ((1, 0), (2, 0)):
        raise ScratchFormatError(f".npy format version {version[0]}.{version[1]} is not accepted (1.0 or 2.0)",
                                 key)
    length_bytes = 2 if version == (1, 0) else 4
    raw_length = member.read(length_bytes)
    if len(raw_length) != length_bytes:
        raise ScratchFormatError("truncated .npy header", key)
    length = int.from_bytes(raw_length, "little")
    if length > _MAX_NPY_HEADER_BYTES:
        raise ScratchFormatError(f".npy header of {length:,} bytes; at most {_MAX_NPY_HEADER_BYTES:,}", key)
    text = member.read(length)
    if len(text) != length:
        raise ScratchFormatError("truncated .npy header", key)
    reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    try:
        # A header numpy only accepts with a deprecation warning ("(type, 1)") was not written by numpy.
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            shape, fortran_order, dtype = reader(io.BytesIO(raw_length + text),
                                                 max_header_size=_MAX_NPY_HEADER_BYTES)
    except _NPY_HEADER_ERRORS as error:
        raise ScratchFormatError(f"damaged .npy header: {error}", key) from None
    if any(dimension < 0 for dimension in shape):
        raise ScratchFormatError(f"declares a negative dimension {shape}", key)
    if dtype.hasobject:
        raise ScratchFormatError("holds Python objects; scratch files hold numbers and one string only", key)
    return MemberHeader(dtype=dtype, shape=tuple(int(d) for d in shape), fortran_order=bool(fortran_order),
                        header_bytes=8 + length_bytes + length)
