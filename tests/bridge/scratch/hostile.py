"""Building hostile scratch files byte by byte: zip members, headers and patches of them."""
from __future__ import annotations

import io
import struct
import zipfile

import numpy as np

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.scratch import FORMAT

CENTRAL_SIGNATURE = b"PK\x01\x02"
LOCAL_SIGNATURE = b"PK\x03\x04"


def npy_bytes(array: np.ndarray) -> bytes:
    """The ``.npy`` serialisation of ``array`` (what np.savez puts in each member)."""
    stream = io.BytesIO()
    np.lib.format.write_array(stream, np.asanyarray(array), allow_pickle=False)
    return stream.getvalue()


def member_bytes(scratches, **overrides) -> dict[str, bytes]:
    """Member name -> ``.npy`` bytes of a valid file of ``scratches``, with some members replaced."""
    arrays = {"format": np.array(FORMAT), **scratches.as_dict()}
    members = {f"{key}.npy": npy_bytes(value) for key, value in arrays.items()}
    for key, value in overrides.items():
        name = f"{key}.npy" if not key.endswith(".npy") and "." not in key else key
        if value is None:
            members.pop(name, None)
        else:
            members[name] = value if isinstance(value, bytes) else npy_bytes(value)
    return members


def zip_bytes(members: dict[str, bytes] | list[tuple[str, bytes]], compression=zipfile.ZIP_STORED) -> bytes:
    """A zip archive of ``members`` (a dict, or a list of pairs to allow duplicate names)."""
    stream = io.BytesIO()
    items = members.items() if isinstance(members, dict) else members
    with zipfile.ZipFile(stream, "w", compression=compression) as archive:
        for name, data in items:
            archive.writestr(name, data)
    return stream.getvalue()


def header_offsets(data: bytes, signature: bytes) -> list[int]:
    """Offsets of every zip record with ``signature`` (local or central headers)."""
    found, start = [], 0
    while (position := data.find(signature, start)) >= 0:
        found.append(position)
        start = position + 1
    return found


def patch_u16(data: bytes, where: list[int], field_offset: int, value) -> bytes:
    """Set a little-endian 16-bit field at ``record + field_offset`` of every record in ``where``."""
    patched = bytearray(data)
    for record in where:
        old = struct.unpack_from("<H", patched, record + field_offset)[0]
        struct.pack_into("<H", patched, record + field_offset, value(old) if callable(value) else value)
    return bytes(patched)


def set_compression_method(data: bytes, method: int) -> bytes:
    """Declare compression ``method`` in every local and central header."""
    data = patch_u16(data, header_offsets(data, LOCAL_SIGNATURE), 8, method)
    return patch_u16(data, header_offsets(data, CENTRAL_SIGNATURE), 10, method)


def set_flag_bits(data: bytes, bits: int) -> bytes:
    """OR ``bits`` into the general-purpose flags of every local and central header."""
    data = patch_u16(data, header_offsets(data, LOCAL_SIGNATURE), 6, lambda old: old | bits)
    return patch_u16(data, header_offsets(data, CENTRAL_SIGNATURE), 8, lambda old: old | bits)


def valid_file(scratches, compress: bool = False) -> bytes:
    return scratch.dumps(scratches, compress=compress)
