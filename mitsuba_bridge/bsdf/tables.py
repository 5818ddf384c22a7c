"""Scratch set → segment table sorted into a uniform UV grid (numpy only).

What the BSDF kernel reads (uploaded once per scratch set):

``segments`` (N, 8) float32, one row per straight piece, sorted by grid cell::

    a_hi.u, a_hi.v, a_lo.u, a_lo.v, e.u, e.v, W [µm], ±D [µm]

  ``a = a_hi + a_lo`` is the start point in UV as a float32 pair: the kernel
  forms ``(a_hi - uv) + a_lo`` and so gets ``a - x0`` to the float32 accuracy
  of the *difference*, not of the absolute coordinate (MODEL.md §1).
  ``e = b - a``.  A negative depth marks a V-groove (depth 0 never reaches the
  table).
``cell_start`` (nu·nv + 1,) uint32: the pieces of cell ``i = v·nu + u`` are rows
  ``cell_start[i]:cell_start[i + 1]``, so a row of cells ``u0..u1`` is one
  contiguous range ``cell_start[v·nu + u0]:cell_start[v·nu + u1 + 1]``.

Grid design ("loose" grid).  Every piece lives in exactly one cell, the one of
its midpoint, and is at most one cell long; a shading point visits the cells
within (window radius + half a cell) of it, row by row, each row one range.
There is nothing to deduplicate and empty cells cost nothing.  The BSDF knows
nothing of the mesh, so the window's size in UV (≈ 4σ in metres through the
UV Jacobian) is unknown at load time; the automatic cell size is the largest
power of two whose occupied cells hold at most ``TARGET_PER_CELL`` pieces on
average (or where finer cells stop thinning them: clustered scratches), so a
query tests a few dozen pieces at most when the window is smaller than a cell
and little more than the pieces inside it otherwise.  It is bounded below so that pieces stay within a few times the segment count and
cells within ``MAX_CELLS_PER_AXIS`` per axis; a ``cell_size`` hint overrides
it.  Pieces are also at most ``MAX_PIECE_UV`` long: a long piece would lose
float32 accuracy of its position far from its stored start (1/64 UV keeps that
error below 1 nm for objects up to a metre per UV unit).  Splitting changes
nothing else: the finite-segment model is additive along a line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scratch import Profile, ScratchSet, subdivide

__all__ = ["GridTables", "build_tables", "TARGET_PER_CELL", "MAX_PIECE_UV"]

#: Pieces per occupied cell aimed at by the automatic cell size.
TARGET_PER_CELL = 4.0
#: Longest piece, in UV units.
MAX_PIECE_UV = 1.0 / 64.0
#: Largest number of cells along one axis (keeps cell_start within 16 MB).
MAX_CELLS_PER_AXIS = 2048
#: Splitting may add at most this many pieces per segment (or 2^20 in all).
EXTRA_PIECES_PER_SEGMENT = 3.0
#: Columns of the segment table.
SEGMENT_COLUMNS = 8


@dataclass(frozen=True, eq=False)
class GridTables:
    """The kernel's view of one scratch set (see the module docstring)."""

    segments: np.ndarray
    cell_start: np.ndarray
    origin: tuple[float, float]
    cell_size: float
    shape: tuple[int, int]  #: (nu, nv) cells along u and v
    piece_count: int  #: real pieces (the table is padded to at least one row)
    margin: float  #: query padding in cells: half the longest piece plus rounding

    @property
    def nbytes(self) -> int:
        return self.segments.nbytes + self.cell_start.nbytes


def build_tables(scratches: ScratchSet, cell_size: float = 0.0) -> GridTables:
    """Segment table and grid of ``scratches``.

    Parameters
    ----------
    cell_size:
        Grid cell size in UV units; 0 chooses it from the scratch density
        (rounded up to a power of two either way).
    """
    a, b, width, depth, triangular = _pieces(scratches)
    if len(a) == 0:
        return _empty_tables()
    a, b, width, depth, triangular = _split(a, b, width, depth, triangular, MAX_PIECE_UV)

    lo = np.minimum(a.min(axis=0), b.min(axis=0))
    hi = np.maximum(a.max(axis=0), b.max(axis=0))
    extent = float((hi - lo).max())
    floor = _power_of_two(max(extent / MAX_CELLS_PER_AXIS, _splitting_limit(a, b)))
    h = _power_of_two(cell_size) if cell_size > 0 else _automatic_cell_size(a, b, lo, extent, floor)
    h = max(h, floor)
    a, b, width, depth, triangular = _split(a, b, width, depth, triangular, h)

    origin = np.floor(lo / h) * h
    shape = np.floor((hi - origin) / h).astype(np.int64) + 1
    cell_uv = np.clip(np.floor((0.5 * (a + b) - origin) / h).astype(np.int64), 0, shape - 1)
    cell = cell_uv[:, 1] * shape[0] + cell_uv[:, 0]
    del cell_uv
    order = np.argsort(cell, kind="stable")
    counts = np.bincount(cell, minlength=int(shape[0] * shape[1]))
    cell_start = np.zeros(len(counts) + 1, dtype=np.uint32)
    np.cumsum(counts, out=cell_start[1:])
    del cell, counts

    longest = float(np.max(np.abs(b - a))) if len(a) else 0.0
    # float32 grid coordinates in the kernel are exact to ~2.5e-4 cells at 2048 cells
    margin = 0.5 * longest / h + 2e-3 + 1e-6 * float(np.abs(np.concatenate([lo, hi])).max()) / h
    return GridTables(
        segments=_segment_rows(a[order], b[order], width[order], depth[order], triangular[order]),
        cell_start=cell_start, origin=(float(origin[0]), float(origin[1])), cell_size=float(h),
        shape=(int(shape[0]), int(shape[1])), piece_count=len(a), margin=margin)


# --------------------------------------------------------------- internals
def _empty_tables() -> GridTables:
    # One dummy row: gathers from zero-length arrays raise even when masked.
    return GridTables(segments=np.zeros((1, SEGMENT_COLUMNS), dtype=np.float32),
                      cell_start=np.zeros(2, dtype=np.uint32), origin=(0.0, 0.0), cell_size=1.0,
                      shape=(1, 1), piece_count=0, margin=0.0)


def _pieces(scratches: ScratchSet):
    """Straight pieces with width/depth from the noise; pieces that cannot scatter are dropped."""
    segments = subdivide(scratches)
    keep = (segments.width > 0) & (segments.depth > 0) & np.any(segments.a != segments.b, axis=1)
    return (segments.a[keep], segments.b[keep], segments.width[keep], segments.depth[keep],
            segments.profile[keep] == Profile.TRIANGULAR)


def _power_of_two(value: float) -> float:
    return 2.0 ** math.ceil(math.log2(max(value, 2.0 ** -60)))


def _splitting_limit(a, b) -> float:
    """Smallest cell size for which splitting pieces to one cell adds at most the allowed count."""
    total = float(np.abs(b - a).max(axis=1).sum())
    return total / max(EXTRA_PIECES_PER_SEGMENT * len(a), 2.0 ** 20)


def _automatic_cell_size(a, b, lo, extent, floor) -> float:
    """Largest power of two with at most TARGET_PER_CELL pieces per occupied cell on average.

    Halving stops early where it no longer thins the cells (by less than a
    quarter): the scratches are then clustered below that scale (parallel
    tracks, a grating), and smaller cells would only add cells to visit.
    """
    h = _power_of_two(extent)
    density = _pieces_per_occupied_cell(a, b, lo, h)
    while h > floor and density > TARGET_PER_CELL:
        finer = _pieces_per_occupied_cell(a, b, lo, 0.5 * h)
        if finer > 0.75 * density:
            break
        h, density = 0.5 * h, finer
    return h


def _pieces_per_occupied_cell(a, b, lo, h) -> float:
    a, b = _split(a, b, None, None, None, h)[:2]
    midpoint = 0.5 * (a + b)
    cells = np.floor((midpoint - lo) / h).astype(np.int64)
    shape = cells.max(axis=0) + 1
    occupied = np.zeros(int(shape[0] * shape[1]), dtype=bool)
    occupied[cells[:, 1] * shape[0] + cells[:, 0]] = True
    return len(a) / np.count_nonzero(occupied)


def _split(a, b, width, depth, triangular, max_length):
    """Split pieces longer than ``max_length`` (per axis) into equal collinear pieces."""
    parts = np.maximum(1, np.ceil(np.abs(b - a).max(axis=1) / max_length)).astype(np.int64)
    if np.all(parts == 1):
        return a, b, width, depth, triangular
    source = np.repeat(np.arange(len(a)), parts)
    k = np.arange(len(source)) - np.repeat(np.cumsum(parts) - parts, parts)
    f0 = (k / parts[source])[:, None]
    f1 = ((k + 1) / parts[source])[:, None]
    direction = (b - a)[source]
    new_a = a[source] + f0 * direction
    new_b = np.where(f1 == 1.0, b[source], a[source] + f1 * direction)
    if width is None:
        return new_a, new_b, None, None, None
    return new_a, new_b, width[source], depth[source], triangular[source]


def _segment_rows(a, b, width, depth, triangular) -> np.ndarray:
    rows = np.empty((len(a), SEGMENT_COLUMNS), dtype=np.float32)
    a_hi = a.astype(np.float32)
    rows[:, 0:2] = a_hi
    rows[:, 2:4] = a - a_hi.astype(np.float64)
    rows[:, 4:6] = b - a
    rows[:, 6] = width * 1e6
    rows[:, 7] = np.where(triangular, -depth, depth) * 1e6
    return rows
