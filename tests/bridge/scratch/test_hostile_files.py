"""Hostile scratch files: every one raises ScratchFormatError naming the field, before allocating.

Each test builds its file in code.  They are the defects a hostile-input probe
found (issue 10): exceptions of other types leaking out of zipfile, zlib and
numpy, a format string compared loosely, offsets whose differences wrap around
in int64, and a small file inflating to gigabytes before being rejected.
"""
import io
import struct
import tracemalloc
import zipfile
import zlib

import numpy as np
import pytest
from hostile import (member_bytes, npy_bytes, set_compression_method, set_flag_bits, valid_file,
                     zip_bytes)

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.scratch import ScratchFormatError, ScratchSet
from scratch_iridescence.mitsuba_bridge.scratch.scratchset import MAX_SCRATCHES, MAX_VERTICES, validate_offsets


def refused(data: bytes, tmp_path, field=None, match=None) -> ScratchFormatError:
    """Load ``data`` from a file; it must raise ScratchFormatError naming the file (and ``field``)."""
    path = tmp_path / "hostile.npz"
    path.write_bytes(data)
    with pytest.raises(ScratchFormatError, match=match) as caught:
        scratch.load(path)
    assert caught.value.path == str(path) and str(path) in str(caught.value)
    if field is not None:
        assert caught.value.field == field and f"'{field}'" in str(caught.value)
    return caught.value


# ------------------------------------------------------------- offsets overflow
OVERFLOWING = [0, 2**63 - 1, -2**63 + 1, -1]


def test_offsets_whose_differences_wrap_in_int64_are_refused(two_scratches):
    vertices = two_scratches.vertex_count
    offsets = np.array(OVERFLOWING + [vertices], dtype=np.int64)
    assert np.all(np.diff(offsets) >= 2)  # what fooled the old check
    arrays = two_scratches.as_dict()
    count = len(offsets) - 1
    per_scratch = {name: np.resize(arrays[name], (count,) + arrays[name].shape[1:])
                   for name in ("width", "depth", "profile", "width_variation", "depth_variation", "seed")}
    with pytest.raises(ScratchFormatError, match=r"offsets\[1\] is 9223372036854775807, outside") as caught:
        ScratchSet(uv=arrays["uv"], offsets=offsets, **per_scratch)
    assert caught.value.field == "offsets"


def test_offsets_overflow_in_a_file_is_refused(tmp_path):
    uv = np.zeros((8, 2))
    count = len(OVERFLOWING)
    members = member_bytes(
        ScratchSet.empty(), uv=uv, offsets=np.array(OVERFLOWING + [8], dtype=np.int64),
        width=np.full(count, 1e-6), depth=np.full(count, 1e-7), profile=np.zeros(count, np.uint8),
        width_variation=np.zeros((count, 2)), depth_variation=np.zeros((count, 2)),
        seed=np.zeros(count, np.uint32))
    refused(zip_bytes(members), tmp_path, "offsets", "outside")


def test_offsets_beyond_the_vertices_are_refused_before_uv_is_inflated(tmp_path, two_scratches):
    members = member_bytes(two_scratches, offsets=np.array([0, 2, 7], dtype=np.int64))
    refused(zip_bytes(members), tmp_path, "offsets")


# --------------------------------------------------- zip container and methods
def test_corrupt_deflate_stream_is_a_format_error(tmp_path, plate_scratches):
    data = bytearray(valid_file(plate_scratches, compress=True))
    with zipfile.ZipFile(io.BytesIO(bytes(data))) as archive:
        info = archive.getinfo("uv.npy")
    start = info.header_offset + 30 + len(info.filename) + len(info.extra) + 200
    data[start:start + 64] = bytes(64)  # zeros inside the deflate stream: a zlib.error before
    refused(bytes(data), tmp_path, "uv", "corrupt")


@pytest.mark.parametrize("method", [99, 12, 14], ids=["unknown", "bzip2-declared", "lzma-declared"])
def test_unknown_compression_method_is_refused(tmp_path, two_scratches, method):
    data = set_compression_method(valid_file(two_scratches), method)
    refused(data, tmp_path, "format", f"compression method {method} is not accepted")


@pytest.mark.parametrize("compression", [zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA], ids=["bzip2", "lzma"])
def test_bzip2_and_lzma_members_are_refused(tmp_path, two_scratches, compression):
    data = zip_bytes(member_bytes(two_scratches), compression=compression)
    refused(data, tmp_path, "format", "only 0 stored and 8 deflate")


def test_encrypted_flag_is_refused(tmp_path, two_scratches):
    refused(set_flag_bits(valid_file(two_scratches), 0x1), tmp_path, "format", "encrypted")


def test_member_that_is_not_npy_is_refused(tmp_path, two_scratches):
    members = member_bytes(two_scratches)
    members["readme.txt"] = b"hello"
    refused(zip_bytes(members), tmp_path, "readme.txt", "not an .npy array")


def test_npy_member_without_numpy_magic_is_refused(tmp_path, two_scratches):
    refused(zip_bytes(member_bytes(two_scratches, seed=b"plain text, not numpy")), tmp_path, "seed",
            "no NUMPY magic")


def test_duplicate_member_is_refused(tmp_path, two_scratches):
    members = list(member_bytes(two_scratches).items())
    members.append(("width.npy", npy_bytes(np.array([3e-6, 3e-6]))))
    with pytest.warns(UserWarning, match="Duplicate name"):
        data = zip_bytes(members)
    refused(data, tmp_path, "width", "twice")


@pytest.mark.parametrize("junk", [b"x", b"PK\x05\x06" + bytes(40), bytes(1000)],
                         ids=["one byte", "fake end record", "kilobyte"])
def test_trailing_bytes_are_refused(tmp_path, two_scratches, junk):
    refused(valid_file(two_scratches) + junk, tmp_path, match="trailing bytes|not a scratch file")


def test_leading_bytes_are_refused(tmp_path, two_scratches):
    # zipfile itself accepts a zip appended to other data (self-extracting archives).
    refused(b"#!/bin/sh\n" + valid_file(two_scratches), tmp_path, match="hidden")


UNPICKLED = []


def mark_unpickled(*args):
    UNPICKLED.append(args)
    return 1e-6


class _Payload:
    """Unpickling it calls ``mark_unpickled``: what a malicious pickle would run."""

    def __reduce__(self):
        return mark_unpickled, ("ran",)


def test_object_arrays_are_refused_without_unpickling(tmp_path, two_scratches):
    stream = io.BytesIO()
    np.lib.format.write_array(stream, np.array([_Payload(), _Payload()], dtype=object), allow_pickle=True)
    refused(zip_bytes(member_bytes(two_scratches, width=stream.getvalue())), tmp_path, "width", "Python objects")
    assert UNPICKLED == []


# ------------------------------------------------------------------ format string
@pytest.mark.parametrize("text", ["scratch-iridescence/01", "scratch-iridescence/1 ", " scratch-iridescence/1",
                                  "scratch-iridescence/+1", "Scratch-Iridescence/1", "scratch-iridescence/1.0",
                                  "scratch-iridescence/\u0661", "scratch-iridescence/\uff11",
                                  "scratch-iridescence/" + "9" * 30])
def test_format_string_must_match_exactly(tmp_path, two_scratches, text):
    refused(zip_bytes(member_bytes(two_scratches, format=np.array(text))), tmp_path, "format", "expected exactly")


def test_overlong_format_string_is_refused_from_its_header(tmp_path, two_scratches):
    members = member_bytes(two_scratches, format=np.array("scratch-iridescence/1" + " " * 5000))
    refused(zip_bytes(members), tmp_path, "format", "at most")


def test_newer_format_says_so(tmp_path, two_scratches):
    refused(zip_bytes(member_bytes(two_scratches, format=np.array("scratch-iridescence/2"))), tmp_path,
            "format", "newer version")


# --------------------------------------------------------- sizes before inflation
def _uv_header_declaring(rows: int) -> bytes:
    """An .npy header for a (rows, 2) float64 array, without its data."""
    stream = io.BytesIO()
    np.lib.format.write_array_header_1_0(stream, {"descr": "<f8", "fortran_order": False, "shape": (rows, 2)})
    return stream.getvalue()


def test_huge_declared_shape_is_refused_without_allocating(tmp_path, two_scratches):
    data = zip_bytes(member_bytes(two_scratches, uv=_uv_header_declaring(2**40) + bytes(80)))
    tracemalloc.start()
    try:
        refused(data, tmp_path, "uv", "at most")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4 << 20


def test_declared_shape_must_match_the_member_size(tmp_path, two_scratches):
    data = zip_bytes(member_bytes(two_scratches, uv=_uv_header_declaring(5) + bytes(8)))
    refused(data, tmp_path, "uv", "holds")


def _bomb(inflated_bytes: int, rows: int, declared_bytes: int | None = None) -> bytes:
    """A scratch file whose uv member inflates from ~1/1000 of ``inflated_bytes`` to ``inflated_bytes``.

    Its header declares ``rows`` vertices; the zip directory declares ``declared_bytes``
    (default: the true inflated size).
    """
    header = _uv_header_declaring(rows)
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    # After a full flush the compressor starts afresh, so every block of zeros deflates to the same
    # bytes: deflate one block and repeat it (deflating 1.6 GB would take seconds).
    parts = [compressor.compress(header) + compressor.flush(zlib.Z_FULL_FLUSH)]
    zeros = bytes(1 << 24)
    block = zlib.compressobj(9, zlib.DEFLATED, -15)
    deflated_zeros = block.compress(zeros) + block.flush(zlib.Z_FULL_FLUSH)
    crc = zlib.crc32(header)
    remaining = inflated_bytes - len(header)
    while remaining >= len(zeros):
        parts.append(deflated_zeros)
        crc = zlib.crc32(zeros, crc)
        remaining -= len(zeros)
    parts.append(compressor.compress(zeros[:remaining]) + compressor.flush())
    crc = zlib.crc32(zeros[:remaining], crc)
    deflated = b"".join(parts)
    # Assemble the zip by hand: zipfile would inflate nothing, but building the member with it would
    # hold the 1.6 GB in memory.
    members = member_bytes(ScratchSet.empty(), uv=None, offsets=np.array([0, rows], dtype=np.int64),
                           width=np.ones(1) * 1e-6, depth=np.ones(1) * 1e-7, profile=np.zeros(1, np.uint8),
                           width_variation=np.zeros((1, 2)), depth_variation=np.zeros((1, 2)),
                           seed=np.zeros(1, np.uint32))
    small = zip_bytes(members, compression=zipfile.ZIP_DEFLATED)
    return _append_raw_member(small, "uv.npy", deflated, crc, declared_bytes or inflated_bytes)


def _append_raw_member(archive_bytes: bytes, name: str, deflated: bytes, crc: int, size: int) -> bytes:
    """``archive_bytes`` with one more deflate member whose compressed bytes are given."""
    with zipfile.ZipFile(io.BytesIO(archive_bytes)) as archive:
        infos = archive.infolist()
        directory_start = archive.start_dir
    body = archive_bytes[:directory_start]
    encoded = name.encode()
    zip64 = size >= 0xFFFFFFFF
    extra = struct.pack("<HHQQ", 1, 16, size, len(deflated)) if zip64 else b""
    local = struct.pack("<4s5H3L2H", b"PK\x03\x04", 45, 0, 8, 0, 0x21, crc,
                        0xFFFFFFFF if zip64 else len(deflated), 0xFFFFFFFF if zip64 else size,
                        len(encoded), len(extra)) + encoded + extra
    new_offset = len(body)
    body += local + deflated
    central = b""
    for info in infos:
        central += _central_record(info.filename.encode(), info.compress_type, info.CRC, info.compress_size,
                                   info.file_size, info.header_offset)
    central += _central_record(encoded, 8, crc, len(deflated), size, new_offset)
    end = struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, len(infos) + 1, len(infos) + 1, len(central),
                      len(body), 0)
    return body + central + end


def _central_record(name: bytes, method: int, crc: int, compressed: int, size: int, offset: int) -> bytes:
    zip64 = size >= 0xFFFFFFFF or compressed >= 0xFFFFFFFF
    extra = struct.pack("<HHQQ", 1, 16, size, compressed) if zip64 else b""
    return struct.pack("<4s6H3L5H2L", b"PK\x01\x02", 45, 45, 0, method, 0, 0x21, crc,
                       0xFFFFFFFF if zip64 else compressed, 0xFFFFFFFF if zip64 else size,
                       len(name), len(extra), 0, 0, 0, 0, offset) + name + extra


@pytest.fixture(scope="module")
def bomb() -> bytes:
    """1.6 GB of uv data (100 M vertices, beyond MAX_VERTICES) deflated to about 1.5 MB."""
    rows = 100_000_000
    assert rows > MAX_VERTICES
    return _bomb(16 * rows + 128, rows)


def test_decompression_bomb_is_refused_from_its_headers(tmp_path, bomb):
    assert len(bomb) < 2_000_000
    tracemalloc.start()
    try:
        error = refused(bomb, tmp_path, "uv", "declares 1,600,000,128 bytes inflated")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8 << 20, f"refusing the bomb allocated {peak / 1e6:.0f} MB"
    assert f"{MAX_VERTICES * 16:,}" in str(error)


def test_member_inflating_beyond_its_declared_size_is_cut_at_that_size(tmp_path):
    # A stream of 32 MB whose header and directory declare 2 MB: reading stops at 2 MB, the CRC fails.
    rows, declared_rows = 2_000_000, 125_000
    data = _bomb(16 * rows + 128, declared_rows, declared_bytes=16 * declared_rows + 128)
    tracemalloc.start()
    try:
        refused(data, tmp_path, "uv", "corrupt")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8 << 20, f"reading the member allocated {peak / 1e6:.0f} MB"


def test_limits_are_enforced_on_sets_too():
    offsets = np.zeros(MAX_SCRATCHES + 2, dtype=np.int64)
    with pytest.raises(ScratchFormatError, match="at most") as caught:
        validate_offsets(offsets, 0)
    assert caught.value.field == "offsets"
    with pytest.raises(ScratchFormatError, match="at most") as caught:
        validate_offsets(np.array([0, MAX_VERTICES + 1]), MAX_VERTICES + 1)
    assert caught.value.field == "uv"


# ----------------------------------------------------------- valid variations
def test_fortran_ordered_uv_is_read(two_scratches):
    members = member_bytes(two_scratches, uv=np.asfortranarray(two_scratches.uv))
    assert scratch.loads(zip_bytes(members)) == two_scratches


def test_archive_with_data_descriptors_is_read(two_scratches):
    # zipfile writes sizes after the data (flag bit 3) when the output cannot seek.
    class Unseekable(io.RawIOBase):
        def __init__(self):
            self.data = bytearray()

        def writable(self):
            return True

        def write(self, chunk):
            self.data += chunk
            return len(chunk)

    sink = Unseekable()
    with zipfile.ZipFile(sink, "w") as archive:
        for name, data in member_bytes(two_scratches).items():
            archive.writestr(name, data)
    data = bytes(sink.data)
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        assert all(info.flag_bits & 0x08 for info in archive.infolist())
    assert scratch.loads(data) == two_scratches
