"""Scratch set → segment table and a UV grid of references to it (numpy only).

What the BSDF kernel reads (uploaded once per scratch set):

``segments`` (N, 8) float32, one row per straight piece, sorted by the grid cell
  of its midpoint (neighbours in UV are neighbours in memory)::

    a_hi.u, a_hi.v, a_lo.u, a_lo.v, e.u, e.v, W [µm], ±D [µm]

  ``a = a_hi + a_lo`` is the start point in UV as a float32 pair: the kernel
  forms ``(a_hi - uv) + a_lo`` and so gets ``a - x0`` to the float32 accuracy
  of the *difference*, not of the absolute coordinate (docs/model.md §1).
  ``e = b - a``.  A negative depth marks a V-groove (depth 0 never reaches the
  table).
``references`` (R,) uint32: piece indices, grouped by cell; a piece is listed
  in **every** cell its centre line passes through (dilated by ``margin``
  cells, so float32 rounding in the kernel never finds a point of a piece in a
  cell that does not list it).
``cell_start`` (nu·nv + 1,) uint32: the references of cell ``i = v·nu + u`` are
  ``references[cell_start[i]:cell_start[i + 1]]``.

Why references (issue 12): a query must cost about what the pieces inside its
coherence window cost.  A long piece (a CD chord, a grating groove) is listed
in each cell it crosses, 4 bytes per cell, instead of being cut into pieces of
32 bytes; cells can then be about the window's size even for the CD's 3.1
million chords.  A query visits the cells of the window's bounding box and
evaluates a piece only in the cell that holds the piece's point closest to the
shading point (which lies inside the window when the piece counts), so a piece
listed in several visited cells is evaluated once (:mod:`.lookup`).

Cell size (power of two).  The window's size in UV (≈ 4σ in metres through the
UV Jacobian) is only known per shading point, so the automatic size is the
largest whose occupied cells hold at most ``TARGET_PER_CELL`` references on
average, or where halving stops thinning them (parallel tracks closer than the
window: finer cells would only list each track more often).  The search looks
at a crop of the UV box holding about ``SEARCH_PIECES`` pieces.  Bounded below
by a reference budget (``MAX_REFERENCES``: a set's references never need more
than 4 bytes × budget) and ``MAX_CELLS`` cells in all; a ``cell_size`` hint
overrides the density choice.  Pieces are at most ``MAX_PIECE_UV`` long: a
long piece would lose float32 accuracy of its position far from its stored
start (1/64 UV keeps that error below 1 nm for objects up to a metre per UV
unit).  Splitting changes nothing else: the finite-segment model is additive
along a line.

Memory: everything runs in chunks into preallocated arrays, so the transient
memory stays a small multiple of the final tables (the CD's 3.1 million chords
load in well under 2 GB).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ...device.memory import check_memory
from ...scratch import Profile, ScratchSet, subdivide
from ...scratch.polyline import edge_start_vertices
from .crossings import find_crossings
from .references import (CHUNK, aligned, cell_references, doubled_angles, empty_aligned, expand, normals,
                         offsets_in_cell, ordered_map, sorted_references)

__all__ = ["GridTables", "build_tables", "build_constants", "aligned", "cell_references", "TARGET_PER_CELL",
           "MAX_PIECE_UV"]

#: References per occupied cell aimed at by the automatic cell size.
TARGET_PER_CELL = 8.0
#: Tests per cell that the offset spread of nearly parallel pieces may add when cells are coarsened.
SPREAD_TESTS = 4.0
#: Longest piece, in UV units.
MAX_PIECE_UV = 1.0 / 64.0
#: Most cells in all (cell_start: 4 bytes each).
MAX_CELLS = 1 << 22
#: Most references in all (8 bytes each): bounds the cell size below for dense sets.
MAX_REFERENCES = 1 << 26

#: Metres (the scratch file's unit) to micrometres (the kernels' unit, docs/model.md §1.1).
M_TO_UM = 1e6

#: Pieces in the crop the automatic cell size is chosen on.
SEARCH_PIECES = 1 << 16
#: ... and at most this many references in it (the search stops there).
SEARCH_REFERENCES = 1 << 23
#: Columns of the segment table.
SEGMENT_COLUMNS = 8
#: Dilation of every piece's cells, in cells (float32 rounding of the kernel's cell coordinates).
CELL_DILATION = 1e-2


def build_constants() -> tuple:
    """The module constants that shape a set's tables, as they are now: part of the key under which
    tables are shared between scenes (persistent.py), so tables built under other values (a test or a
    study that changes one) are never taken for these."""
    from . import crossings

    return (TARGET_PER_CELL, SPREAD_TESTS, MAX_PIECE_UV, MAX_CELLS, MAX_REFERENCES, SEARCH_PIECES,
            SEARCH_REFERENCES, CELL_DILATION, STRAIGHT_ON_SIN, crossings.MIN_SINE, crossings.MAX_PAIRS)


@dataclass(frozen=True, eq=False)
class GridTables:
    """The kernel's view of one scratch set (see the module docstring)."""

    segments: np.ndarray
    references: np.ndarray
    offsets: np.ndarray  #: float32 per reference: lowest offset of its in-cell part along the cell normal (cells)
    cell_frames: np.ndarray  #: (cells, 4) float32: cell normal n_u, n_v, largest offset spread, 0
    cell_start: np.ndarray
    origin: tuple[float, float]
    cell_size: float
    shape: tuple[int, int]  #: (nu, nv) cells along u and v
    piece_count: int  #: real pieces (the table is padded to at least one row)
    margin: float  #: query padding and piece dilation, in cells
    #: (N + 1,) uint32 CSR starts of each piece's crossing partners (all zero: no crossings listed)
    crossing_start: np.ndarray = None
    crossing_partner: np.ndarray = None  #: uint32 partner pieces, padded to at least two entries
    crossing_along: np.ndarray = None  #: float32 parameter of each crossing along its lower piece
    #: (N, 2) float32: how far (UV) each piece's groove runs on straight, through pieces of the same width
    #: and depth, before its start and after its end (0: it ends or turns there); None: not known
    #: (:func:`continuations`)
    continuation: np.ndarray = None

    @property
    def crossing_count(self) -> int:
        return int(self.crossing_start[-1])

    @property
    def nbytes(self) -> int:
        return sum(x.nbytes for x in (self.segments, self.references, self.offsets, self.cell_frames,
                                      self.cell_start, self.crossing_start, self.crossing_partner,
                                      self.crossing_along))


def build_tables(scratches: ScratchSet, cell_size: float = 0.0, crossings: bool = False) -> GridTables:
    """Segment table, references and grid of ``scratches``.

    Parameters
    ----------
    cell_size:
        Grid cell size in UV units; 0 chooses it from the scratch density
        (rounded up to a power of two either way, and never so small that the
        grid exceeds ``MAX_CELLS`` cells or ``MAX_REFERENCES`` references).
    crossings:
        List the crossing pairs of rectangular pieces (``crossings = "height_field"``).
    """
    return build_sorted(scratches, cell_size, crossings)[0]


def build_sorted(scratches: ScratchSet, cell_size: float = 0.0, crossings: bool = False):
    """:func:`build_tables` and the pieces' float64 ends ``(a, b)`` in the table's row order.

    For :mod:`.incremental`, which extends a build by appended scratches.
    """
    check_piece_memory(scratches)
    a, b, width, depth = _pieces(scratches)
    if len(a) == 0:
        return _empty_tables(), a, b

    lo = np.minimum(a.min(axis=0), b.min(axis=0))
    hi = np.maximum(a.max(axis=0), b.max(axis=0))
    floor = max(_cell_count_limit(lo, hi), _reference_limit(a, b))
    h = _power_of_two(cell_size) if cell_size > 0 else _automatic_cell_size(a, b, lo, hi, floor)
    h = max(h, floor)
    origin = np.floor(lo / h) * h
    shape = np.floor((hi - origin) / h).astype(np.int64) + 1
    # float32 cell coordinates in the kernel: ~1e-7 relative of the UV coordinate, plus rounding
    margin = CELL_DILATION + 1e-6 * float(np.abs(np.concatenate([lo, hi])).max()) / h

    order = np.argsort(_cells(0.5 * (a + b), h, origin, shape), kind="stable")
    a, b, width, depth = a[order], b[order], width[order], depth[order]
    segments = _segment_rows(a, b, width, depth)
    del width, depth, order
    references, offsets, frames, cell_start = sorted_references(a, b, h, origin, shape, margin)
    if crossings:
        crossing_start, crossing_partner, crossing_along = find_crossings(
            a, b, references, cell_start, frames[:, 0:2].astype(np.float64))
    else:
        crossing_start, crossing_partner, crossing_along = _no_crossings(len(segments))
    return GridTables(segments=segments, references=references, offsets=offsets, cell_frames=frames,
                      cell_start=cell_start,
                      origin=(float(origin[0]), float(origin[1])), cell_size=float(h),
                      shape=(int(shape[0]), int(shape[1])), piece_count=len(segments), margin=margin,
                      crossing_start=crossing_start, crossing_partner=crossing_partner,
                      crossing_along=crossing_along, continuation=continuations(a, b, segments)), a, b


#: The least memory one piece takes while the tables are built (bytes): 283 to 1 545 per piece measured with
#: ``tracemalloc`` (build_tables and ScanArrays.of of 5 000 and 20 000 random scratches, 0.5 to 4.8 M pieces).
MIN_BYTES_PER_PIECE = 250


def least_pieces(scratches: ScratchSet) -> int:
    """At least how many pieces the tables cut ``scratches`` into: each polyline edge into pieces of at most
    :data:`MAX_PIECE_UV` along either axis (the noise only adds more)."""
    first = edge_start_vertices(scratches.uv, scratches.offsets)
    spans = np.abs(scratches.uv[first + 1] - scratches.uv[first]).max(axis=1, initial=0.0)
    return int(np.maximum(1.0, np.ceil(spans / MAX_PIECE_UV)).sum())


def check_piece_memory(scratches: ScratchSet) -> None:
    """Refuse (:class:`~mitsuba_bridge.device.memory.NotEnoughMemory`) a set whose tables cannot fit even at the least
    memory per piece: scratches hundreds or thousands of UV units long, as the format allows
    (docs/scratch-format.md)."""
    if scratches.count == 0:
        return
    pieces = least_pieces(scratches)
    check_memory(pieces * MIN_BYTES_PER_PIECE, f"building the tables of {scratches.count:,} scratches",
                 detail=f"at least {pieces:,} pieces of at most 1/{round(1 / MAX_PIECE_UV)} UV unit, "
                        f"{MIN_BYTES_PER_PIECE} bytes or more each",
                 advice="shorten the scratches (their UV length) or split the set")


#: Largest |sin| between a piece and the one continuing it straight on (the split of a long piece: exact).
STRAIGHT_ON_SIN = 1e-6


def end_lattice(a, b) -> tuple[np.ndarray, float]:
    """``(lo, step)`` of the lattice :func:`continuations` matches piece ends on: 2⁻³⁰ of the pieces' extent."""
    return box_lattice(np.minimum(a.min(axis=0), b.min(axis=0)), np.maximum(a.max(axis=0), b.max(axis=0)))


def box_lattice(lo, hi) -> tuple[np.ndarray, float]:
    """:func:`end_lattice` of pieces whose ends span the box ``[lo, hi]`` (both (2,) arrays)."""
    return lo, max(float(np.max(hi - lo)), 1e-30) / float(1 << 30)


def end_keys(points, lattice) -> np.ndarray:
    """int64 key of each point's lattice cell (:func:`end_lattice`): equal keys, meeting ends."""
    lo, step = lattice
    q = np.floor((points - lo) / step).astype(np.int64)
    return (q[:, 0] << 31) | q[:, 1]


def continuations(a, b, segments, lattice=None, same_profile: bool = True) -> np.ndarray:
    """``(N, 2)`` float32: per piece, how far (UV) its groove runs on straight before its start and after
    its end, through pieces of the same width and depth that meet it end to start (0: it ends or turns);
    ``same_profile=False``: through any pieces meeting it end to start on its line (the footprint filter's
    runs, :mod:`.lines`).

    Long pieces are split (``MAX_PIECE_UV``) and polylines may run straight on: a periodic family
    (:mod:`.periodic`) then knows that a track listed in a cell by one piece goes on past that piece's
    end.  Ends meet in float64 to the last bit or so; they are matched on a lattice of 2⁻³⁰ of the
    extent (``lattice``: that of a larger set these pieces belong to, :func:`end_lattice`), and the runs
    summed by pointer doubling."""
    count = len(a)
    result = np.zeros((count, 2), np.float32)
    if count < 2:
        return result
    lattice = end_lattice(a, b) if lattice is None else lattice
    start_keys = end_keys(a, lattice)
    order = np.argsort(start_keys, kind="stable")  # equal starts by piece: an extension keeps the choice
    sorted_keys = start_keys[order]
    del start_keys
    successor = np.full(count, -1, np.int64)

    def joins(first):
        """(piece, the piece its groove runs straight on into) for the ends of one chunk of pieces."""
        mine = np.arange(first, min(first + CHUNK, count))
        ends = end_keys(b[mine], lattice)
        at = np.searchsorted(sorted_keys, ends)
        e = b[mine] - a[mine]
        follower = np.full(len(mine), -1, np.int64)
        # every piece starting where this one ends, in piece order, until one runs straight on (several
        # start there where scratches are cut at one point, e.g. two crossing there)
        for offset in itertools.count():
            place = np.minimum(at + offset, count - 1)
            candidate = (follower < 0) & (at + offset < count) & (sorted_keys[place] == ends)
            if not candidate.any():
                break
            following = order[place]
            e_next = b[following] - a[following]
            size = np.hypot(e[:, 0], e[:, 1]) * np.hypot(e_next[:, 0], e_next[:, 1])
            sine_times_size = np.abs(e[:, 0] * e_next[:, 1] - e[:, 1] * e_next[:, 0])
            forward = np.einsum("ij,ij->i", e, e_next) > 0
            straight = (sine_times_size < STRAIGHT_ON_SIN * np.maximum(size, 1e-300)) & forward
            same = (segments[mine, 6] == segments[following, 6]) & (segments[mine, 7] == segments[following, 7]) \
                if same_profile else True
            joined = candidate & straight & same & (following != mine)
            follower[joined] = following[joined]
        return mine[follower >= 0], follower[follower >= 0]

    # chunks of ends bound the temporaries; each writes its own pieces' successors
    for pieces, followers in ordered_map(joins, range(0, count, CHUNK)):
        successor[pieces] = followers
    del order, sorted_keys
    length = np.hypot(*(b - a).T)
    predecessor = np.full(count, -1, np.int64)
    predecessor[successor[successor >= 0]] = np.flatnonzero(successor >= 0)
    for column, link in ((1, successor), (0, predecessor)):
        run = np.where(link >= 0, length[np.maximum(link, 0)], 0.0)  # the next piece, then doubling
        link = link.copy()
        while np.any(link >= 0):
            ahead = link >= 0
            target = np.maximum(link, 0)
            run = run + np.where(ahead, run[target], 0.0)
            link = np.where(ahead, link[target], -1)
        result[:, column] = run
    return result


def _no_crossings(piece_count):
    return empty_aligned_zeros(piece_count + 1), empty_aligned_zeros(2), empty_aligned_zeros(2).view(np.float32)


def empty_aligned_zeros(count):
    array = empty_aligned(count, np.uint32)
    array[...] = 0
    return array


# --------------------------------------------------------------- internals
def _empty_tables() -> GridTables:
    # One dummy row each: gathers from zero-length arrays raise even when masked.
    return GridTables(segments=np.zeros((1, SEGMENT_COLUMNS), dtype=np.float32),
                      references=np.zeros(1, dtype=np.uint32), offsets=np.zeros(1, dtype=np.float32),
                      cell_frames=np.array([[0.0, 1.0, 0.0, 0.0]], dtype=np.float32),
                      cell_start=np.zeros(2, dtype=np.uint32), origin=(0.0, 0.0), cell_size=1.0,
                      shape=(1, 1), piece_count=0, margin=0.0,
                      crossing_start=empty_aligned_zeros(2), crossing_partner=empty_aligned_zeros(2),
                      crossing_along=empty_aligned_zeros(2).view(np.float32))


def _pieces(scratches: ScratchSet):
    """(a, b, width µm, ±depth µm) of the straight pieces, at most MAX_PIECE_UV long.

    Width and depth come from the noise (``subdivide``); pieces that cannot
    scatter (zero width, depth or length) are dropped; V-grooves carry a
    negative depth.  Chunks of whole scratches (:func:`_scratch_chunks`) bound the temporaries of
    ``subdivide`` and run on a few threads; every scratch's pieces depend on that scratch alone, and
    the chunks are joined in order, so the pieces are those of one pass over the set.
    """
    def pieces_of(rows):
        whole = rows.stop - rows.start == scratches.count
        chunk = scratches if whole else scratches.select(np.arange(rows.start, rows.stop))
        segments = subdivide(chunk)
        keep = (segments.width > 0) & (segments.depth > 0) & np.any(segments.a != segments.b, axis=1)
        signed = np.where(segments.profile == Profile.TRIANGULAR, -segments.depth, segments.depth)
        width_um = (segments.width[keep] * M_TO_UM).astype(np.float32)  # the file's metres -> kernel µm
        signed_depth_um = (signed[keep] * M_TO_UM).astype(np.float32)
        piece = (segments.a[keep], segments.b[keep], width_um, signed_depth_um)
        del segments, keep, signed
        return _split(piece, MAX_PIECE_UV)

    parts = list(ordered_map(pieces_of, _scratch_chunks(scratches)))
    if not parts:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, np.float32), np.zeros(0, np.float32)
    if len(parts) == 1:
        return parts[0]
    return tuple(np.concatenate([p[i] for p in parts]) for i in range(4))


def _scratch_chunks(scratches: ScratchSet) -> list[range]:
    """Runs of whole scratches of about 4 × CHUNK vertices and at most CHUNK scratches each."""
    count = scratches.count
    if count == 0:
        return []
    offsets = np.asarray(scratches.offsets, np.int64)
    vertices = 4 * CHUNK
    by_vertices = np.searchsorted(offsets, np.arange(vertices, int(offsets[-1]), vertices))
    bounds = np.unique(np.r_[0, np.clip(by_vertices, 1, count), np.arange(CHUNK, count, CHUNK), count])
    return [range(int(lo), int(hi)) for lo, hi in zip(bounds[:-1], bounds[1:])]


def _power_of_two(value: float) -> float:
    return 2.0 ** math.ceil(math.log2(max(value, 2.0 ** -60)))


def _cell_count_limit(lo, hi) -> float:
    """Smallest power-of-two cell size with at most MAX_CELLS cells over the box [lo, hi]."""
    extent = np.maximum(hi - lo, 0.0)
    h = _power_of_two(max(math.sqrt(float(extent[0] * extent[1]) / MAX_CELLS), float(extent.max()) / MAX_CELLS))
    while float(np.prod(np.floor(extent / h) + 2)) > MAX_CELLS:
        h *= 2.0
    return h


def _reference_limit(a, b) -> float:
    """Smallest cell size for which the references stay within MAX_REFERENCES.

    A piece crossing ``|Δu|/h + |Δv|/h`` cell boundaries is listed in at most
    that many cells plus one (plus the dilation, a few per cent).
    """
    spans = float(np.abs(b - a).sum())
    room = MAX_REFERENCES / 1.1 - 2.0 * len(a)
    return _power_of_two(spans / room) if room > 0 else 2.0 ** 60


def _automatic_cell_size(a, b, lo, hi, floor) -> float:
    """Largest power of two with at most TARGET_PER_CELL references per occupied cell on average.

    Halving stops early where it no longer thins the cells (by less than a
    quarter) once cells are no longer than the typical piece: the scratches
    are then clustered below that scale (parallel tracks, a grating), and
    smaller cells would only list them more often.  Larger cells keep
    halving: they list several collinear pieces of one scratch, or a few
    crowded coarse cells hold a ring of short pieces.
    """
    a, b, lo, hi = _search_crop(a, b, lo, hi)
    spans = float(np.abs(b - a).sum())
    typical_piece = float(np.median(np.abs(b - a).max(axis=1)))
    # never longer than a typical piece: a cell would list collinear pieces of one scratch, which
    # share their offset and are all scanned
    h = min(_power_of_two(float((hi - lo).max())), 0.5 * _power_of_two(typical_piece))
    h = max(h, floor)  # (a few scratches far apart: no finer grid than MAX_CELLS allows, not even to test it)
    if 2.0 * h > typical_piece and _spread_tests(a, b, lo, hi, h) <= SPREAD_TESTS:
        # Nearly parallel pieces already at the largest size allowed (a grating): the halving below
        # would list them at ever finer cells (seconds for long grooves), and the doubling after it
        # climb back to this size, as the offset spread grows with the cell.
        return h
    density = _references_per_occupied_cell(a, b, lo, hi, h)
    while h > floor and density > TARGET_PER_CELL and spans / (0.5 * h) < SEARCH_REFERENCES:
        finer = _references_per_occupied_cell(a, b, lo, hi, 0.5 * h)
        if finer > 0.75 * density and h <= typical_piece:
            break
        h, density = 0.5 * h, finer
    # Coarser cells cost little where the pieces of a cell are nearly parallel (a query bisects
    # them by offset): double while the offset spread adds at most SPREAD_TESTS tests per cell on
    # average, and no cell grows longer than a typical piece (collinear pieces share their offset).
    while 2.0 * h <= typical_piece and _spread_tests(a, b, lo, hi, 2.0 * h) <= SPREAD_TESTS:
        h *= 2.0
    return h


def _search_crop(a, b, lo, hi):
    """The pieces whose midpoints fall in a square around the median holding ~SEARCH_PIECES of them."""
    if len(a) <= SEARCH_PIECES:
        return a, b, lo, hi
    midpoint = 0.5 * (a + b)
    sample = midpoint[:: max(1, len(a) // 4096)]
    median = np.median(sample, axis=0)  # may lie in a hole (a disc): take the nearest piece
    centre = sample[np.argmin(np.abs(sample - median).sum(axis=1))]
    half = 0.5 * float((hi - lo).max()) * math.sqrt(SEARCH_PIECES / len(a))
    for _ in range(40):  # widen until the crop holds enough pieces (clustered sets)
        inside = np.all(np.abs(midpoint - centre) <= half, axis=1)
        if np.count_nonzero(inside) >= SEARCH_PIECES // 2 or half > float((hi - lo).max()):
            break
        half *= 1.5
    a, b = a[inside], b[inside]
    return a, b, np.minimum(a.min(axis=0), b.min(axis=0)), np.maximum(a.max(axis=0), b.max(axis=0))


def _references_per_occupied_cell(a, b, lo, hi, h) -> float:
    origin = np.floor(lo / h) * h
    shape = np.floor((hi - origin) / h).astype(np.int64) + 1
    cells, _ = cell_references(a, b, h, origin, shape, 0.0)
    return len(cells) / len(np.unique(cells))


def _spread_tests(a, b, lo, hi, h) -> float:
    """Mean over occupied cells of (offset spread × references): what the spread adds to a scan."""
    origin = np.floor(lo / h) * h
    shape = np.floor((hi - origin) / h).astype(np.int64) + 1
    cells, piece = cell_references(a, b, h, origin, shape, 0.0)
    occupied, cells = np.unique(cells, return_inverse=True)
    normal = normals(doubled_angles(a, b, cells, piece, len(occupied)))
    # offsets are measured in cells of the real grid: restore the cell numbers for the clipping
    full = np.zeros((int(shape[0] * shape[1]), 2))
    full[occupied] = normal
    _, extent = offsets_in_cell((a - origin) / h, (b - origin) / h, occupied[cells], piece, full, shape, 0.0)
    spread = np.zeros(len(occupied))
    np.maximum.at(spread, cells, extent)
    return float(np.mean(spread * np.bincount(cells)))


def _split(arrays, max_length):
    """Split pieces ``(a, b, ...)`` whose per-axis span exceeds ``max_length`` into equal collinear pieces."""
    a, b = arrays[0], arrays[1]
    parts = np.maximum(1, np.ceil(np.abs(b - a).max(axis=1) / max_length)).astype(np.int64)
    if np.all(parts == 1):
        return arrays
    source, k = expand(np.zeros(len(a), np.int64), parts)
    step = (b - a)[source] / parts[source, None]
    new_a = a[source] + k[:, None] * step
    # each piece ends exactly where the next one starts (continuations() joins them by equal ends), and
    # the last one at the far end
    new_b = np.where((k + 1 == parts[source])[:, None], b[source], a[source] + (k + 1)[:, None] * step)
    return (new_a, new_b) + tuple(x[source] for x in arrays[2:])


def _cells(points, h, origin, shape):
    """Grid cell (row-major index) of each point."""
    uv = np.clip(np.floor((points - origin) / h).astype(np.int64), 0, shape - 1)
    return uv[:, 1] * shape[0] + uv[:, 0]


def _segment_rows(a, b, width, depth):
    rows = empty_aligned((len(a), SEGMENT_COLUMNS), np.float32)
    for start in range(0, len(a), CHUNK):
        part = slice(start, start + CHUNK)
        a_hi = a[part].astype(np.float32)
        rows[part, 0:2] = a_hi
        rows[part, 2:4] = a[part] - a_hi
        rows[part, 4:6] = b[part] - a[part]
        rows[part, 6] = width[part]
        rows[part, 7] = depth[part]
    return rows
