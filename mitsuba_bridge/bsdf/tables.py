"""Scratch set → segment table sorted into a uniform UV grid (numpy only).

What the BSDF kernel reads (uploaded once per scratch set):

``segments`` (N, 8) float32, one row per straight piece, sorted by grid cell::

    a_hi.u, a_hi.v, a_lo.u, a_lo.v, e.u, e.v, W [µm], ±D [µm]

  ``a = a_hi + a_lo`` is the start point in UV as a float32 pair: the kernel
  forms ``(a_hi - uv) + a_lo`` and so gets ``a - x0`` to the float32 accuracy
  of the *difference*, not of the absolute coordinate (docs/model.md §1).
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
and little more than the pieces inside it otherwise.  The search looks at a
crop of the UV box holding about ``SEARCH_PIECES`` pieces (the density, not
the count, decides).  The size is bounded below so that pieces stay within a
budget (four times the segment count, at most ``MAX_PIECES``) and cells within
``MAX_CELLS_PER_AXIS`` per axis; a ``cell_size`` hint overrides it.  Pieces are also at most ``MAX_PIECE_UV`` long: a long piece would lose
float32 accuracy of its position far from its stored start (1/64 UV keeps that
error below 1 nm for objects up to a metre per UV unit).  Splitting changes
nothing else: the finite-segment model is additive along a line.

Memory: everything runs in chunks of ``CHUNK`` scratches or pieces into
preallocated arrays, so the transient memory stays a small multiple of the
final table (3.1 million CD scratches load in well under 2 GB).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scratch import Profile, ScratchSet, subdivide

__all__ = ["GridTables", "build_tables", "aligned", "TARGET_PER_CELL", "MAX_PIECE_UV"]

#: Pieces per occupied cell aimed at by the automatic cell size.
TARGET_PER_CELL = 4.0
#: Longest piece, in UV units.
MAX_PIECE_UV = 1.0 / 64.0
#: Largest number of cells along one axis (keeps cell_start within 16 MB).
MAX_CELLS_PER_AXIS = 2048
#: Splitting may add at most this many pieces per piece (at least 2^20 in all) ...
EXTRA_PIECES_PER_SEGMENT = 3.0
#: ... up to this many pieces in all (32 bytes each in the kernel's table).
MAX_PIECES = 16 * 2 ** 20

#: Metres (the scratch file's unit) to micrometres (the kernels' unit, docs/model.md §1.1).
M_TO_UM = 1e6

#: Pieces in the crop the automatic cell size is chosen on.
SEARCH_PIECES = 1 << 19
#: Scratches (or pieces) processed at a time.
CHUNK = 1 << 18
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
    pieces = _pieces(scratches)
    a, b = pieces[0], pieces[1]
    if len(a) == 0:
        return _empty_tables()

    lo = np.minimum(a.min(axis=0), b.min(axis=0))
    hi = np.maximum(a.max(axis=0), b.max(axis=0))
    extent = float((hi - lo).max())
    floor = _power_of_two(max(extent / MAX_CELLS_PER_AXIS, _splitting_limit(a, b)))
    h = _power_of_two(cell_size) if cell_size > 0 else _automatic_cell_size(a, b, lo, hi, floor)
    h = max(h, floor)
    origin = np.floor(lo / h) * h
    shape = np.floor((hi - origin) / h).astype(np.int64) + 1

    rows, cell_start = _sorted_rows(pieces, h, origin, shape)
    del pieces, a, b
    longest = float(np.abs(rows[:, 4:6]).max())
    # float32 grid coordinates in the kernel are exact to ~2.5e-4 cells at 2048 cells
    margin = 0.5 * longest / h + 2e-3 + 1e-6 * float(np.abs(np.concatenate([lo, hi])).max()) / h
    return GridTables(segments=rows, cell_start=cell_start, origin=(float(origin[0]), float(origin[1])),
                      cell_size=float(h), shape=(int(shape[0]), int(shape[1])), piece_count=len(rows),
                      margin=margin)


# --------------------------------------------------------------- internals
def _empty_tables() -> GridTables:
    # One dummy row: gathers from zero-length arrays raise even when masked.
    return GridTables(segments=np.zeros((1, SEGMENT_COLUMNS), dtype=np.float32),
                      cell_start=np.zeros(2, dtype=np.uint32), origin=(0.0, 0.0), cell_size=1.0,
                      shape=(1, 1), piece_count=0, margin=0.0)


def _pieces(scratches: ScratchSet):
    """(a, b, width µm, ±depth µm) of the straight pieces, at most MAX_PIECE_UV long.

    Width and depth come from the noise (``subdivide``); pieces that cannot
    scatter (zero width, depth or length) are dropped; V-grooves carry a
    negative depth.  Chunks of scratches bound the temporaries of ``subdivide``.
    """
    parts = []
    for start in range(0, scratches.count, CHUNK):
        chunk = scratches if scratches.count <= CHUNK else \
            scratches.select(np.arange(start, min(start + CHUNK, scratches.count)))
        segments = subdivide(chunk)
        keep = (segments.width > 0) & (segments.depth > 0) & np.any(segments.a != segments.b, axis=1)
        signed = np.where(segments.profile == Profile.TRIANGULAR, -segments.depth, segments.depth)
        width_um = (segments.width[keep] * M_TO_UM).astype(np.float32)  # the file's metres -> kernel µm
        signed_depth_um = (signed[keep] * M_TO_UM).astype(np.float32)
        piece = (segments.a[keep], segments.b[keep], width_um, signed_depth_um)
        del segments, keep, signed
        parts.append(_split(piece, MAX_PIECE_UV))
    if not parts:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, np.float32), np.zeros(0, np.float32)
    if len(parts) == 1:
        return parts[0]
    return tuple(np.concatenate([p[i] for p in parts]) for i in range(4))


def _power_of_two(value: float) -> float:
    return 2.0 ** math.ceil(math.log2(max(value, 2.0 ** -60)))


def _spans(a, b) -> np.ndarray:
    """Per-axis extent of each piece: splitting to cell size h makes ceil(span / h) pieces."""
    return np.abs(b - a).max(axis=1)


def _splitting_limit(a, b) -> float:
    """Smallest cell size for which splitting pieces to one cell stays within the piece budget.

    The budget: ``EXTRA_PIECES_PER_SEGMENT`` more pieces per piece, but no more
    than ``MAX_PIECES`` in all (and never less than 2^20 extra pieces).
    """
    count = len(a)
    budget = max(min((1.0 + EXTRA_PIECES_PER_SEGMENT) * count, MAX_PIECES), count + 2.0 ** 20)
    return float(_spans(a, b).sum()) / (budget - count)


def _automatic_cell_size(a, b, lo, hi, floor) -> float:
    """Largest power of two with at most TARGET_PER_CELL pieces per occupied cell on average.

    Halving stops early where it no longer thins the cells (by less than a
    quarter): the scratches are then clustered below that scale (parallel
    tracks, a grating), and smaller cells would only add cells to visit.
    """
    a, b, lo, hi = _search_crop(a, b, lo, hi)
    h = _power_of_two(float((hi - lo).max()))
    density = _pieces_per_occupied_cell(a, b, lo, h)
    while h > floor and density > TARGET_PER_CELL:
        finer = _pieces_per_occupied_cell(a, b, lo, 0.5 * h)
        if finer > 0.75 * density:
            break
        h, density = 0.5 * h, finer
    return h


def _search_crop(a, b, lo, hi):
    """The pieces whose midpoints fall in a square around the median holding ~SEARCH_PIECES of them."""
    if len(a) <= SEARCH_PIECES:
        return a, b, lo, hi
    midpoint = 0.5 * (a + b)
    centre = np.median(midpoint[:: max(1, len(a) // 4096)], axis=0)
    half = 0.5 * float((hi - lo).max()) * math.sqrt(SEARCH_PIECES / len(a))
    for _ in range(40):  # widen until the crop holds enough pieces (clustered sets)
        inside = np.all(np.abs(midpoint - centre) <= half, axis=1)
        if np.count_nonzero(inside) >= SEARCH_PIECES // 2 or half > float((hi - lo).max()):
            break
        half *= 1.5
    return a[inside], b[inside], np.maximum(lo, centre - half), np.minimum(hi, centre + half)


def _pieces_per_occupied_cell(a, b, lo, h) -> float:
    a, b = _split((a, b), h)
    cells = np.floor((0.5 * (a + b) - lo) / h).astype(np.int64)
    cells -= cells.min(axis=0)
    shape = cells.max(axis=0) + 1
    occupied = np.zeros(int(shape[0] * shape[1]), dtype=bool)
    occupied[cells[:, 1] * shape[0] + cells[:, 0]] = True
    return len(a) / np.count_nonzero(occupied)


def _split(arrays, max_length):
    """Split pieces ``(a, b, ...)`` whose per-axis span exceeds ``max_length`` into equal collinear pieces."""
    a, b = arrays[0], arrays[1]
    parts = np.maximum(1, np.ceil(_spans(a, b) / max_length)).astype(np.int64)
    if np.all(parts == 1):
        return arrays
    source = np.repeat(np.arange(len(a)), parts)
    k = np.arange(len(source)) - np.repeat(np.cumsum(parts) - parts, parts)
    step = (b - a)[source] / parts[source, None]
    new_a = a[source] + k[:, None] * step
    new_b = np.where((k + 1 == parts[source])[:, None], b[source], new_a + step)  # exact far ends
    return (new_a, new_b) + tuple(x[source] for x in arrays[2:])


def _cells(a, b, h, origin, shape):
    """Grid cell (row-major index) of each piece's midpoint."""
    uv = np.clip(np.floor((0.5 * (a + b) - origin) / h).astype(np.int64), 0, shape - 1)
    return uv[:, 1] * shape[0] + uv[:, 0]


def _sorted_rows(pieces, h, origin, shape):
    """Kernel rows of the pieces split to one cell, sorted by cell, and ``cell_start``.

    A counting sort in two chunked passes: the first counts the pieces per
    cell, the second splits again and writes every row straight to its place,
    so only the final table is ever held in full.
    """
    cell_count = int(shape[0] * shape[1])
    counts = np.zeros(cell_count, dtype=np.int64)
    for chunk in _split_chunks(pieces, h):
        counts += np.bincount(_cells(chunk[0], chunk[1], h, origin, shape), minlength=cell_count)
    cell_start = _empty_aligned(cell_count + 1, np.uint32)
    cell_start[0] = 0
    np.cumsum(counts, out=cell_start[1:])
    cursor = cell_start[:-1].astype(np.int64)
    rows = _empty_aligned((int(cell_start[-1]), SEGMENT_COLUMNS), np.float32)
    for ca, cb, width, depth in _split_chunks(pieces, h):
        cell = _cells(ca, cb, h, origin, shape)
        order = np.argsort(cell, kind="stable")
        cell = cell[order]
        first = np.searchsorted(cell, cell, side="left")  # start of each piece's run within the chunk
        destination = cursor[cell] + (np.arange(len(cell)) - first)
        cursor += np.bincount(cell, minlength=cell_count)
        ca, cb = ca[order], cb[order]
        a_hi = ca.astype(np.float32)
        rows[destination, 0:2] = a_hi
        rows[destination, 2:4] = ca - a_hi
        rows[destination, 4:6] = cb - ca
        rows[destination, 6] = width[order]
        rows[destination, 7] = depth[order]
    return rows, cell_start


def _split_chunks(pieces, h):
    for start in range(0, len(pieces[0]), CHUNK):
        yield _split(tuple(x[start:start + CHUNK] for x in pieces), h)


ALIGNMENT = 64


def _empty_aligned(shape, dtype) -> np.ndarray:
    """``np.empty`` starting on a 64-byte boundary (see :func:`aligned`)."""
    dtype = np.dtype(dtype)
    size = int(np.prod(shape)) * dtype.itemsize
    raw = np.empty(size + ALIGNMENT, dtype=np.uint8)
    offset = (-raw.ctypes.data) % ALIGNMENT
    return raw[offset:offset + size].view(dtype).reshape(shape)


def aligned(array: np.ndarray) -> np.ndarray:
    """``array`` as a contiguous array on a 64-byte boundary (the array itself when it already is).

    Dr.Jit's CPU backend maps numpy memory without copying, and emits different
    (packet or element) gathers depending on its alignment.
    """
    array = np.ascontiguousarray(array)
    if array.ctypes.data % ALIGNMENT == 0:
        return array
    result = _empty_aligned(array.shape, array.dtype)
    result[...] = array
    return result
