"""Scratch tables updated by appended scratches: a pen stroke in the viewport (numpy only).

A full :func:`.tables.build_tables` of the demo plate (3 000 scratches, 115 000
pieces) takes ~0.4–0.7 s on a 2-core CPU, most of it the automatic cell-size
search and the per-cell sort of every reference.  A stroke appends a few
scratches, so :func:`update_tables` keeps the previous build's cell size (no
search) and, when the new pieces stay inside the grid's UV box, merges them
into the previous tables: the new segment rows are inserted at their cells'
places, old piece numbers are shifted, and only the cells the new pieces cross
get their normal, offsets, spread and order recomputed; with ``crossings =
"height_field"`` the previous crossing pairs are renumbered and the new pieces'
pairs are looked for in those cells only.  The result is
**identical** (bit for bit) to ``build_tables(scratches, cell_size)`` at that
cell size: every per-piece quantity is computed elementwise as there, and the
per-cell direction sums are added in the same order and chunks as
:func:`.references.sorted_references` adds them (tested).

Anything else (first build, removed or edited scratches, a new piece outside
the box, another cell-size hint, the crossings option switched) is a full
build: at the previous cell size when scratches were only appended, else with
the automatic search.  The cell
size then stays the one searched for the set before the strokes; it only
changes the acceleration grid, not what the kernel computes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scratch import ScratchSet
from .crossings import extend_crossings, pairs_of
from .references import CHUNK, cell_references, doubled_angles, empty_aligned, normals, offsets_in_cell
from .grid import (GridTables, _cells, _no_crossings, _pieces, _reference_limit, _segment_rows, box_lattice,
                     build_sorted, continuations, end_keys)

__all__ = ["TableCache", "update_tables", "MAX_CACHED_PIECES"]

#: Sets with more pieces keep no float64 ends (32 bytes a piece) and are always built in full: a
#: dense set (the CD's millions of chords) is not painted stroke by stroke, and F12 holds its BSDF.
MAX_CACHED_PIECES = 1 << 20


@dataclass(frozen=True, eq=False)
class TableCache:
    """A build and what extending it needs: the scratches and the pieces' float64 ends in row order."""

    scratches: ScratchSet
    tables: GridTables
    a: np.ndarray | None  #: None above MAX_CACHED_PIECES pieces (no extension then)
    b: np.ndarray | None
    cell_size_hint: float  #: the hint the first full build got (0: automatic)
    crossings: bool = False  #: whether the tables list crossing pairs (``crossings = "height_field"``)
    incremental: bool = False  #: whether this build extended the previous one (for tests and statistics)


def update_tables(previous: TableCache | None, scratches: ScratchSet, cell_size: float = 0.0, *,
                  crossings: bool = False) -> TableCache:
    """Tables of ``scratches``, extending ``previous`` where ``scratches`` only appends to its set.

    Parameters
    ----------
    previous : TableCache or None
        The cache returned for the previous set of the same BSDF.
    scratches : ScratchSet
    cell_size : float
        The BSDF's cell-size hint (0: automatic), as for :func:`.tables.build_tables`.
    crossings : bool
        List crossing pairs (``crossings = "height_field"``): an extension keeps the previous pairs
        (renumbered) and adds those of the appended pieces, found in the cells they are listed in.

    Returns
    -------
    TableCache
        ``.tables`` equals ``build_tables(scratches, c)`` where ``c`` is ``cell_size``, or, after
        appended scratches under an automatic hint, the cell size of ``previous``.
    """
    if (previous is None or previous.a is None or previous.cell_size_hint != cell_size
            or previous.crossings != crossings or not _appends(previous.scratches, scratches)):
        return _full(scratches, cell_size, cell_size, crossings)
    merged = _extend(previous, scratches)
    if merged is not None:
        return merged
    return _full(scratches, previous.tables.cell_size, cell_size, crossings)


def _full(scratches, cell_size, hint, crossings) -> TableCache:
    tables, a, b = build_sorted(scratches, cell_size, crossings)
    if len(a) > MAX_CACHED_PIECES:
        a = b = None
    return TableCache(scratches, tables, a, b, hint, crossings)


def _appends(old: ScratchSet, new: ScratchSet) -> bool:
    """Whether ``new`` is ``old`` followed by more scratches (compared field by field)."""
    n = old.count
    if new.count <= n or n == 0:
        return False
    vertices = int(old.offsets[-1])
    if not np.array_equal(new.offsets[:n + 1], old.offsets) or not np.array_equal(new.uv[:vertices], old.uv):
        return False
    return all(np.array_equal(getattr(new, name)[:n], getattr(old, name))
               for name in ("width", "depth", "profile", "width_variation", "depth_variation", "seed"))


def _extended_continuations(previous: TableCache, a, b, segments, old_index, new_index, lattice) -> np.ndarray:
    """:func:`.tables.continuations` of the merged pieces: the old runs renumbered and the new pieces'
    own, unless an end of a new piece meets an end of an old one (then all of them again).

    Exact: the merged set has the old set's box (the extension's condition), hence its lattice, and
    equal starts are taken in piece order, which the merge keeps."""
    old = previous.tables.continuation
    if old is None:
        return continuations(a, b, segments, lattice)
    na, nb = a[new_index], b[new_index]
    # only old ends within a lattice step of the new pieces' box can share a key with theirs
    points = np.concatenate([na, nb])
    low, high = points.min(axis=0) - 2.0 * lattice[1], points.max(axis=0) + 2.0 * lattice[1]

    def keys_near(ends):
        near = np.all((ends >= low) & (ends <= high), axis=1)
        return end_keys(ends[near], lattice)

    if (np.isin(end_keys(na, lattice), keys_near(previous.b)).any()
            or np.isin(end_keys(nb, lattice), keys_near(previous.a)).any()):
        return continuations(a, b, segments, lattice)
    result = np.empty((len(a), 2), np.float32)
    result[old_index] = old[:len(old_index)]
    result[new_index] = continuations(na, nb, segments[new_index], lattice)
    return result


def _extend(previous: TableCache, scratches: ScratchSet) -> TableCache | None:
    """The merged tables, or None where the new pieces change the grid (box, floor, margin)."""
    old = previous.tables
    added = scratches.select(np.arange(previous.scratches.count, scratches.count))
    na, nb, nw, nd = _pieces(added)
    if len(na) == 0:  # nothing that scatters: the same tables
        return TableCache(scratches, old, previous.a, previous.b, previous.cell_size_hint, previous.crossings, True)
    if old.piece_count == 0:
        return None
    h, margin = old.cell_size, old.margin
    origin, shape = np.array(old.origin), np.array(old.shape, dtype=np.int64)
    lo = np.minimum(previous.a.min(axis=0), previous.b.min(axis=0))
    hi = np.maximum(previous.a.max(axis=0), previous.b.max(axis=0))
    new_lo = np.minimum(na.min(axis=0), nb.min(axis=0))
    new_hi = np.maximum(na.max(axis=0), nb.max(axis=0))
    if np.any(new_lo < lo) or np.any(new_hi > hi):
        return None  # another box: another origin, shape or margin

    # ---- segment rows: the new pieces go after the old ones of their midpoint's cell (stable sort)
    new_cells = _cells(0.5 * (na + nb), h, origin, shape)
    order = np.argsort(new_cells, kind="stable")
    na, nb, nw, nd, new_cells = na[order], nb[order], nw[order], nd[order], new_cells[order]
    old_cells = _cells(0.5 * (previous.a + previous.b), h, origin, shape)
    place = np.searchsorted(old_cells, new_cells, side="right")
    n_old, n_new = len(old_cells), len(na)
    new_index = place + np.arange(n_new)
    old_index = np.arange(n_old) + np.searchsorted(place, np.arange(n_old), side="right")
    a = np.empty((n_old + n_new, 2))
    b = np.empty_like(a)
    a[old_index], a[new_index] = previous.a, na
    b[old_index], b[new_index] = previous.b, nb
    if _reference_limit(a, b) > h:
        return None  # the finer grid would exceed the reference budget: the full build coarsens it
    segments = empty_aligned((n_old + n_new, old.segments.shape[1]), np.float32)
    segments[old_index] = old.segments[:n_old]
    segments[new_index] = _segment_rows(na, nb, nw, nd)

    # ---- the references of the cells the new pieces cross are recomputed, the others renumbered
    cell_count = int(shape[0] * shape[1])
    cells_n, piece_n = cell_references(na, nb, h, origin, shape, margin)
    touched = np.unique(cells_n)
    is_touched = np.zeros(cell_count, dtype=bool)
    is_touched[touched] = True
    ref_cell = np.repeat(np.arange(cell_count), np.diff(old.cell_start.astype(np.int64)))
    real = old.references[:len(ref_cell)]
    inside = is_touched[ref_cell]
    cells_t = np.concatenate([ref_cell[inside], cells_n])
    pieces_t = np.concatenate([old_index[real[inside]], new_index[piece_n]])
    by_piece = np.argsort(pieces_t, kind="stable")
    cells_t, pieces_t = cells_t[by_piece], pieces_t[by_piece]
    local = np.searchsorted(touched, cells_t)

    # direction sums added as sorted_references adds them: bincount per chunk of pieces, then summed
    doubled = np.zeros((2, len(touched)))
    chunk = pieces_t // CHUNK
    for k in np.unique(chunk):
        sel = chunk == k
        doubled += doubled_angles(a[pieces_t[sel]], b[pieces_t[sel]], local[sel], np.arange(np.count_nonzero(sel)),
                                  len(touched))
    frames = empty_aligned(old.cell_frames.shape, np.float32)
    frames[...] = old.cell_frames
    frames[touched, 0:2] = normals(doubled)
    normal = np.zeros((cell_count, 2))
    normal[touched] = frames[touched, 0:2].astype(np.float64)
    ga, gb = (a[pieces_t] - origin) / h, (b[pieces_t] - origin) / h
    low, extent = offsets_in_cell(ga, gb, cells_t, np.arange(len(pieces_t)), normal, shape, margin)
    spread = np.zeros(len(touched))
    np.maximum.at(spread, local, extent)
    frames[touched, 2] = spread * (1.0 + 1e-6) + 1e-6
    frames[touched, 3] = 0.0

    # per cell by offset, ties by piece (the full build's stable sort of piece-ordered references)
    sort = np.lexsort((pieces_t, low, cells_t))
    all_cells = np.concatenate([ref_cell[~inside], cells_t[sort]])
    all_pieces = np.concatenate([old_index[real[~inside]], pieces_t[sort]])
    all_offsets = np.concatenate([old.offsets[:len(ref_cell)][~inside], low[sort]])
    merge = np.argsort(all_cells, kind="stable")  # two sorted runs: a merge
    references = empty_aligned(len(merge), np.uint32)
    offsets = empty_aligned(len(merge), np.float32)
    references[:] = all_pieces[merge]
    offsets[:] = all_offsets[merge]
    cell_start = empty_aligned(cell_count + 1, np.uint32)
    cell_start[0] = 0
    np.cumsum(np.bincount(all_cells, minlength=cell_count), out=cell_start[1:])
    if previous.crossings:  # the old pairs renumbered, and the new pieces' pairs from the cells they touch
        new_piece = np.zeros(n_old + n_new, dtype=bool)
        new_piece[new_index] = True
        crossing_start, crossing_partner, crossing_along = extend_crossings(
            a, b, old_index[pairs_of(old.crossing_start, old.crossing_partner)], new_piece, references,
            cell_start, touched)
    else:
        crossing_start, crossing_partner, crossing_along = _no_crossings(n_old + n_new)
    tables = GridTables(segments=segments, references=references, offsets=offsets, cell_frames=frames,
                        cell_start=cell_start, origin=old.origin, cell_size=h, shape=old.shape,
                        piece_count=n_old + n_new, margin=margin, crossing_start=crossing_start,
                        crossing_partner=crossing_partner, crossing_along=crossing_along,
                        continuation=_extended_continuations(previous, a, b, segments, old_index, new_index,
                                                             box_lattice(lo, hi)))
    if len(a) > MAX_CACHED_PIECES:
        a = b = None
    return TableCache(scratches, tables, a, b, previous.cell_size_hint, previous.crossings, True)
