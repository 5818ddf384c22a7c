"""The scratch set: every scratch of one object as structure-of-arrays numpy data.

A scratch is a polyline in the object's UV space with a mean width and depth in
metres, a cross-section profile and a noise variation of width and depth along
its length (docs/model.md §7).  Scratch ``i`` owns the vertices
``uv[offsets[i]:offsets[i + 1]]``; there is never a Python object per scratch.
"""
from __future__ import annotations

from ..errors import ScratchUserError

import enum
from dataclasses import dataclass, fields
from typing import Iterable, Sequence

import numpy as np

__all__ = ["Profile", "ScratchFormatError", "ScratchSet", "FIELD_SPECS", "MAX_SCRATCHES", "MAX_VERTICES",
           "MAX_UV_COORDINATE", "MAX_SCRATCH_SIZE_M", "MAX_VARIATION_AMPLITUDE", "MAX_VARIATION_FREQUENCY",
           "validate_arrays", "validate_offsets"]

#: Most scratches a set (and a scratch file) may hold: 56 times the paper's densest scene (300 000).
MAX_SCRATCHES = 2**24
#: Most polyline vertices a set may hold (their ``uv`` array is then 1 GiB).
MAX_VERTICES = 2**26
#: Largest |u| or |v|: UV maps span [0, 1], UDIM tiles and tiled maps tens or hundreds of units; far beyond
#: that the renderer's tables (pieces at most 1/64 UV long, docs/bsdf.md) would need more memory than any machine.
MAX_UV_COORDINATE = 1e4
#: Largest width or depth (metres).  The model is for microscopic scratches, micrometres wide and nanometres
#: deep (docs/model.md §7: the paper's widths are 0.2-6 µm); a millimetre is far beyond any of them and still
#: catches a mistyped unit or an infinity that a user interface clamped to its largest float.
MAX_SCRATCH_SIZE_M = 1e-3
#: Largest relative amplitude of the width and depth noise (the supplement's largest is 1.1).
MAX_VARIATION_AMPLITUDE = 10.0
#: Largest noise frequency: 255 oscillations along a scratch.  The renderer cuts a varying scratch into
#: four pieces per oscillation (``subdivide``), so the frequency bounds the pieces of every scratch.
MAX_VARIATION_FREQUENCY = 1.0


class Profile(enum.IntEnum):
    """Cross-section of a scratch (stored as ``uint8`` in the ``profile`` field)."""

    RECTANGULAR = 0  #: flat bottom, vertical walls
    TRIANGULAR = 1  #: V-groove, deepest on the centre line


class ScratchFormatError(ScratchUserError, ValueError):
    """A scratch set or scratch file breaks format v1.

    Parameters
    ----------
    problem:
        What is wrong, in words.
    field:
        The offending field (``"width"``, ``"offsets"`` ...), or ``None`` when the
        problem concerns the whole file (not a zip archive, truncated ...).
    path:
        The file, when the data came from or was going to a file.
    """

    def __init__(self, problem: str, field: str | None = None, path: str | None = None):
        self.problem = problem
        self.field = field
        self.path = None if path is None else str(path)
        where = self.path if self.path is not None else "scratch set"
        what = f"field '{field}': " if field is not None else ""
        super().__init__(f"{where}: {what}{problem}")

    def with_path(self, path) -> "ScratchFormatError":
        """The same error, naming ``path`` as the file it concerns."""
        return ScratchFormatError(self.problem, self.field, path)


# field -> (dtype, trailing shape); the leading dimension is P (uv), S + 1
# (offsets) or S (everything else).
FIELD_SPECS: dict[str, tuple[np.dtype, tuple[int, ...]]] = {
    "uv": (np.dtype(np.float64), (2,)),
    "offsets": (np.dtype(np.int64), ()),
    "width": (np.dtype(np.float64), ()),
    "depth": (np.dtype(np.float64), ()),
    "profile": (np.dtype(np.uint8), ()),
    "width_variation": (np.dtype(np.float64), (2,)),
    "depth_variation": (np.dtype(np.float64), (2,)),
    "seed": (np.dtype(np.uint32), ()),
}


@dataclass(frozen=True, eq=False)
class ScratchSet:
    """Scratches of one surface, validated on construction.

    Attributes
    ----------
    uv : (P, 2) float64
        Polyline vertices in UV space.
    offsets : (S + 1,) int64
        Scratch ``i`` is ``uv[offsets[i]:offsets[i + 1]]`` (at least two vertices).
    width, depth : (S,) float64
        Mean width and depth in metres, > 0.
    profile : (S,) uint8
        :class:`Profile` values.
    width_variation, depth_variation : (S, 2) float64
        (relative amplitude >= 0, frequency >= 0) of the simplex-noise variation;
        amplitude 0 means constant.  Frequency 1/255 is one oscillation along
        the whole scratch (docs/model.md §7).
    seed : (S,) uint32
        Per-scratch noise seed.

    The set keeps read-only *views* of the arrays it is given, without copying
    (300 000 scratches are tens of megabytes): hand it arrays you no longer
    modify, or copies.
    """

    uv: np.ndarray
    offsets: np.ndarray
    width: np.ndarray
    depth: np.ndarray
    profile: np.ndarray
    width_variation: np.ndarray
    depth_variation: np.ndarray
    seed: np.ndarray

    def __post_init__(self):
        for f in fields(self):
            array = np.asarray(getattr(self, f.name)).view()
            array.setflags(write=False)
            object.__setattr__(self, f.name, array)
        validate_arrays({f.name: getattr(self, f.name) for f in fields(self)})

    # ----------------------------------------------------------------- sizes
    @property
    def count(self) -> int:
        """Number of scratches S."""
        return len(self.offsets) - 1

    def __len__(self) -> int:
        return self.count

    @property
    def vertex_count(self) -> int:
        """Number of polyline vertices P."""
        return len(self.uv)

    @property
    def vertex_counts(self) -> np.ndarray:
        """Vertices per scratch, shape (S,)."""
        return np.diff(self.offsets)

    @property
    def nbytes(self) -> int:
        """Memory held by the arrays, in bytes."""
        return sum(getattr(self, f.name).nbytes for f in fields(self))

    def scratch_index_of_vertices(self) -> np.ndarray:
        """For each vertex, the index of its scratch; shape (P,)."""
        return np.repeat(np.arange(self.count, dtype=np.int64), self.vertex_counts)

    def polyline(self, i: int) -> np.ndarray:
        """Vertices of scratch ``i``, shape (n, 2)."""
        return self.uv[self.offsets[i]:self.offsets[i + 1]]

    def as_dict(self) -> dict[str, np.ndarray]:
        """The eight arrays by field name (the file's keys without ``format``)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def __eq__(self, other) -> bool:
        if not isinstance(other, ScratchSet):
            return NotImplemented
        return all(np.array_equal(a, b) and a.dtype == b.dtype
                   for a, b in zip(self.as_dict().values(), other.as_dict().values()))

    __hash__ = None  # arrays: not hashable

    def __repr__(self) -> str:
        if self.count == 0:
            return "ScratchSet(0 scratches)"
        return (f"ScratchSet({self.count} scratches, {self.vertex_count} vertices, "
                f"mean width {self.width.mean() * 1e6:.3g} um, "
                f"mean depth {self.depth.mean() * 1e9:.3g} nm)")

    # ----------------------------------------------------------- construction
    @classmethod
    def empty(cls) -> "ScratchSet":
        """A set without scratches."""
        return cls.from_polylines([], width=[], depth=[])

    @classmethod
    def from_polylines(cls, polylines: Sequence[np.ndarray], width, depth, *,
                       profile=Profile.RECTANGULAR, width_variation=(0.0, 0.0),
                       depth_variation=(0.0, 0.0), seed=None) -> "ScratchSet":
        """Build a set from a list of (n_i, 2) vertex arrays.

        Per-scratch parameters may be scalars (broadcast) or length-S sequences.
        ``seed`` defaults to the scratch index.  Meant for small hand-made sets
        and tests; bulk producers should build the arrays directly.
        """
        n = len(polylines)
        lengths = np.array([len(p) for p in polylines], dtype=np.int64)
        offsets = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(lengths, out=offsets[1:])
        uv = (np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in polylines])
              if n else np.zeros((0, 2)))

        def per_scratch(value, dtype, trailing=()):
            array = np.asarray(value, dtype=dtype)
            if array.size == 0:  # an empty list of tuples has lost its trailing shape
                array = array.reshape((0,) + trailing)
            return np.broadcast_to(array, (n,) + trailing).copy()

        return cls(
            uv=uv, offsets=offsets,
            width=per_scratch(width, np.float64), depth=per_scratch(depth, np.float64),
            profile=per_scratch(profile, np.uint8),
            width_variation=per_scratch(width_variation, np.float64, (2,)),
            depth_variation=per_scratch(depth_variation, np.float64, (2,)),
            seed=(np.arange(n, dtype=np.uint32) if seed is None else per_scratch(seed, np.uint32)),
        )

    @classmethod
    def concatenate(cls, sets: Iterable["ScratchSet"]) -> "ScratchSet":
        """All scratches of ``sets``, in order."""
        sets = list(sets)
        if not sets:
            return cls.empty()
        vertex_base = np.cumsum([0] + [s.vertex_count for s in sets[:-1]])
        offsets = np.concatenate([[0]] + [s.offsets[1:] + base for s, base in zip(sets, vertex_base)])
        arrays = {name: np.concatenate([getattr(s, name) for s in sets])
                  for name in FIELD_SPECS if name != "offsets"}
        return cls(offsets=offsets.astype(np.int64), **arrays)

    def select(self, keep) -> "ScratchSet":
        """The scratches selected by a boolean mask or an index array, in that order."""
        index = np.arange(self.count)[np.asarray(keep)] if np.asarray(keep).dtype == bool \
            else np.asarray(keep, dtype=np.int64)
        counts = self.vertex_counts[index]
        offsets = np.zeros(len(index) + 1, dtype=np.int64)
        np.cumsum(counts, out=offsets[1:])
        # Vertex indices of the kept scratches, without a Python loop per scratch.
        starts = np.repeat(self.offsets[index] - offsets[:-1], counts)
        vertex = starts + np.arange(offsets[-1])
        return ScratchSet(
            uv=self.uv[vertex], offsets=offsets,
            **{name: getattr(self, name)[index] for name in FIELD_SPECS if name not in ("uv", "offsets")})

    def replace(self, **changes) -> "ScratchSet":
        """A copy with some fields replaced (validated again)."""
        arrays = self.as_dict()
        arrays.update(changes)
        return ScratchSet(**arrays)


# --------------------------------------------------------------- validation
def validate_arrays(arrays: dict[str, np.ndarray]) -> None:
    """Check the eight fields of format v1; raise :class:`ScratchFormatError` naming the field."""
    for name, (dtype, trailing) in FIELD_SPECS.items():
        if name not in arrays:
            raise ScratchFormatError("missing", name)
        array = arrays[name]
        if array.dtype != dtype:
            raise ScratchFormatError(f"dtype is {array.dtype}, expected {dtype}", name)
        if array.ndim != 1 + len(trailing) or array.shape[1:] != trailing:
            expected = "(N" + "".join(f", {t}" for t in trailing) + ")"
            raise ScratchFormatError(f"shape is {array.shape}, expected {expected}", name)

    uv, offsets = arrays["uv"], arrays["offsets"]
    validate_offsets(offsets, len(uv))
    count = len(offsets) - 1
    for name in FIELD_SPECS:
        if name not in ("uv", "offsets") and len(arrays[name]) != count:
            raise ScratchFormatError(
                f"has {len(arrays[name])} entries but offsets describe {count} scratches", name)

    for name in ("width", "depth", "width_variation", "depth_variation"):
        if not np.all(np.isfinite(arrays[name])):
            raise ScratchFormatError("contains NaN or infinity", name)
    largest = float(np.abs(uv).max(initial=0.0))  # (NaN propagates: one pass checks both)
    if not largest <= MAX_UV_COORDINATE:
        raise ScratchFormatError(
            "contains NaN or infinity" if not np.isfinite(largest) else
            f"coordinates must lie within ±{MAX_UV_COORDINATE:g} UV units; largest is {largest:g}", "uv")
    for name in ("width", "depth"):
        if np.any(arrays[name] <= 0):
            raise ScratchFormatError(f"must be > 0 (metres); smallest is {arrays[name].min()!r}", name)
        if np.any(arrays[name] > MAX_SCRATCH_SIZE_M):
            raise ScratchFormatError(f"must be at most {MAX_SCRATCH_SIZE_M:g} m (scratches are microscopic); largest "
                                     f"is {arrays[name].max()!r}", name)
    for name in ("width_variation", "depth_variation"):
        if np.any(arrays[name] < 0):
            raise ScratchFormatError("amplitude and frequency must be >= 0", name)
        if len(arrays[name]) and (arrays[name][:, 0].max() > MAX_VARIATION_AMPLITUDE
                                  or arrays[name][:, 1].max() > MAX_VARIATION_FREQUENCY):
            raise ScratchFormatError(
                f"amplitude must be at most {MAX_VARIATION_AMPLITUDE:g} and frequency at most "
                f"{MAX_VARIATION_FREQUENCY:g} (255 oscillations along a scratch); largest are "
                f"{arrays[name][:, 0].max()!r} and {arrays[name][:, 1].max()!r}", name)
    if np.any(arrays["profile"] > max(Profile)):
        unknown = sorted(set(np.unique(arrays["profile"]).tolist()) - {int(p) for p in Profile})
        raise ScratchFormatError(
            f"unknown profile code(s) {unknown}; known: "
            + ", ".join(f"{int(p)} = {p.name.lower()}" for p in Profile), "profile")


def validate_offsets(offsets: np.ndarray, vertex_count: int) -> None:
    """Check ``offsets`` (int64, shape (S + 1,)) against ``vertex_count`` P and the format's limits.

    Every entry is compared with 0 and P before any difference is taken, so
    entries near the int64 limits cannot wrap around into valid-looking steps.

    Raises
    ------
    ScratchFormatError
        For field ``offsets`` (or ``uv`` when P exceeds :data:`MAX_VERTICES`).
    """
    if vertex_count > MAX_VERTICES:
        raise ScratchFormatError(f"{vertex_count:,} vertices; at most {MAX_VERTICES:,} are allowed", "uv")
    if len(offsets) < 1:
        raise ScratchFormatError("needs at least one entry (offsets[0] = 0)", "offsets")
    if len(offsets) - 1 > MAX_SCRATCHES:
        raise ScratchFormatError(f"describes {len(offsets) - 1:,} scratches; at most {MAX_SCRATCHES:,} are "
                                 "allowed", "offsets")
    if offsets[0] != 0:
        raise ScratchFormatError(f"offsets[0] is {offsets[0]}, expected 0", "offsets")
    if offsets[-1] != vertex_count:
        raise ScratchFormatError(f"offsets[-1] is {offsets[-1]} but uv has {vertex_count} vertices", "offsets")
    outside = (offsets < 0) | (offsets > vertex_count)
    if outside.any():
        bad = int(np.argmax(outside))
        raise ScratchFormatError(f"offsets[{bad}] is {offsets[bad]}, outside [0, {vertex_count}]", "offsets")
    steps = np.diff(offsets)  # entries lie in [0, P]: no overflow
    if len(steps) and np.any(steps < 2):
        bad = int(np.argmax(steps < 2))
        raise ScratchFormatError(
            f"scratch {bad} has {steps[bad]} vertices; each needs at least 2", "offsets")
