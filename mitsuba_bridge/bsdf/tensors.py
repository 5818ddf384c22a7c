"""Scratch sets as in-memory plugin parameters (Dr.Jit tensors), and back.

Every format-v1 field travels as one tensor under the key ``scratch_<field>``
with its exact dtype, so a set survives the trip bit for bit and is validated
again on arrival.  Each tensor has a leading axis of length 1 (``uv`` is
(1, P, 2), ``width`` (1, S) ...): Mitsuba's dictionary parser tries to read any
value of length 3 as a 3-vector (a plain array becomes one, a tensor prints
warnings), and a length-1 leading axis avoids that for every scratch count.
Values without the leading axis are accepted as well.
"""
from __future__ import annotations

import numpy as np

from ..scratch import ScratchFormatError, ScratchSet
from ..scratch.scratchset import FIELD_SPECS

__all__ = ["KEY_PREFIX", "KEYS", "to_tensors", "from_values"]

KEY_PREFIX = "scratch_"
#: field -> name of the Mitsuba tensor type carrying it
TENSOR_TYPES = {
    "uv": "TensorXf64", "offsets": "TensorXi64", "width": "TensorXf64", "depth": "TensorXf64",
    "profile": "TensorXu8", "width_variation": "TensorXf64", "depth_variation": "TensorXf64",
    "seed": "TensorXu",
}
#: parameter key -> field, in file order
KEYS = {KEY_PREFIX + field: field for field in FIELD_SPECS}


def to_tensors(scratches: ScratchSet) -> dict:
    """``{"scratch_uv": mi.TensorXf64, ...}`` for the active Mitsuba variant."""
    import mitsuba as mi

    if not isinstance(scratches, ScratchSet):
        raise TypeError(f"expected a ScratchSet, got {type(scratches).__name__}")
    result = {}
    for key, field in KEYS.items():
        array = np.ascontiguousarray(getattr(scratches, field))
        result[key] = getattr(mi, TENSOR_TYPES[field])(array.reshape((1,) + array.shape))
    return result


def from_values(values: dict) -> ScratchSet:
    """The scratch set held by ``values`` (key -> Dr.Jit tensor or array-like).

    Raises :class:`ScratchFormatError` naming the field for a missing key, a
    value of the wrong kind, or anything format v1 forbids.
    """
    arrays = {}
    for key, field in KEYS.items():
        if key not in values:
            raise ScratchFormatError(f"missing (in-memory key '{key}')", field)
        dtype, trailing = FIELD_SPECS[field]
        array = np.asarray(values[key])
        if array.ndim == 2 + len(trailing) and array.shape[0] == 1:
            array = array[0]  # the leading axis of to_tensors
        if array.ndim == 1 and trailing and array.size % trailing[0] == 0:
            array = array.reshape((-1,) + trailing)  # a flat Float64 array is accepted too
        if array.dtype != dtype:
            same_kind = array.dtype.kind in "iu" if dtype.kind in "iu" else array.dtype.kind == "f"
            if not same_kind:
                raise ScratchFormatError(f"has dtype {array.dtype}, expected {dtype}", field)
            array = array.astype(dtype)
        arrays[field] = array
    return ScratchSet(**arrays)
