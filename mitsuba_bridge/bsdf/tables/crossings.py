"""Crossing pairs of straight pieces, for the height-field correction (numpy only; docs/model.md §3.4).

Where two scratches cross, the paper's sum of transfer functions
counts both depths; the true height field has the deeper one's.  The kernel
(:mod:`.overlap`) adds one correction per crossing pair inside the window, so
the tables list, per piece, the pieces it crosses (CSR: ``crossing_start``,
``crossing_partner``), each pair once, under the piece of lower index.

A pair counts when the two **centre lines intersect inside both pieces**
(parameters in [0, 1): a crossing at a polyline vertex belongs to the piece
starting there, so it is found once).  Intersection parameters are invariant
under the linear UV → tangent-plane map, so this test is exact in UV whatever
the mesh's Jacobian.  Candidates are the pieces listed together in a cell of
the lookup grid (both pieces are listed in the cell of their crossing point).
Left out (docs/model.md §3.4):

* nearly parallel pairs, ``|sin θ| < MIN_SINE`` (measured in UV): their
  overlap is a long sliver whose shape the piece ends and the widths in µm
  decide; the kernel pairs them itself (:mod:`.parallel`);
* consecutive pieces of one polyline (they share an end point);
* cells whose pieces all lie within ``MIN_SINE / 2`` of the cell's dominant
  direction (a CD's tracks, a grating: no pair there can count), so dense
  parallel sets cost nothing.
"""
from __future__ import annotations

import numpy as np

from ...errors import ScratchUserError
from .references import aligned, expand

__all__ = ["find_crossings", "extend_crossings", "crossing_tables", "pairs_of", "MAX_PAIRS", "MIN_SINE", "PAIR_BUDGET",
           "TooManyCrossings"]

#: Smallest |sin θ| between two crossing pieces that gets the correction (about 5.7°).
MIN_SINE = 0.1
#: Candidate pairs examined at a time (bounds the temporaries).
PAIR_BUDGET = 1 << 22
#: Most crossing pairs listed (8 bytes each in the tables, ~40 during the search): a set with more is refused
#: with a clear error rather than exhausting the machine's memory (a plate of 30 000 scratches 2-6 cm long on
#: 4 cm × 4 cm crosses itself ~6·10⁸ times; the Fig. 1 table's 300 000 scratches 10⁷ times).
MAX_PAIRS = 50_000_000


class TooManyCrossings(ScratchUserError, MemoryError):
    """The scratch set crosses itself more often than ``crossings = "height_field"`` can list."""


def find_crossings(a, b, references, cell_start, cell_normals, max_pairs=None):
    """``(crossing_start, crossing_partner, crossing_along)`` of the pieces ``a[i] → b[i]`` (UV, float64).

    Parameters
    ----------
    a, b:
        (N, 2) start and end points of the pieces, in table order.
    references, cell_start:
        The lookup grid's references (piece indices grouped by cell) and CSR starts.
    cell_normals:
        (cells, 2) unit normal of each cell's dominant direction.
    max_pairs:
        Raise :class:`TooManyCrossings` beyond this many pairs (default ``MAX_PAIRS``).

    Returns
    -------
    crossing_start:
        (N + 1,) uint32; the partners of piece ``i`` are
        ``crossing_partner[crossing_start[i]:crossing_start[i + 1]]``.
    crossing_partner:
        (max(M, 2),) uint32, padded with zeros (the kernel gathers from it, see below).
    crossing_along:
        (max(M, 2),) float32: where the crossing lies along the lower piece (parameter in [0, 1)),
        ascending per piece, so that the kernel bisects for the crossings inside the window.
    """
    e = b - a
    direction = _directions(e)
    starts = cell_start.astype(np.int64)
    sizes = np.diff(starts)
    cells = np.flatnonzero(sizes > 1)
    if len(cells):
        # a cell whose pieces all run within MIN_SINE/2 of its direction holds no countable pair
        cells = cells[_largest_deviation(cells, starts, sizes, references, direction, cell_normals)
                      >= 0.5 * MIN_SINE]
    pairs = _pairs_crossing_in(cells, starts, sizes, references, a, e, direction, None, max_pairs)
    return crossing_tables(pairs, a, b, max_pairs)


def extend_crossings(a, b, old_pairs, new_piece, references, cell_start, cells, max_pairs=None):
    """:func:`find_crossings` of a set whose pieces ``~new_piece`` were listed before (a stroke appended the
    others): ``old_pairs`` (M, 2), those pieces' pairs renumbered to the new table order (lower first), and
    the pairs of the new pieces, candidates in ``cells`` (every cell a new piece is listed in: the cell
    of a crossing point lists both pieces).  The same three arrays as a full :func:`find_crossings` of
    the set, bit for bit: a pair's parameter is computed from the same float64 ends, and the pairs are
    ordered as there.
    """
    e = b - a
    starts = cell_start.astype(np.int64)
    sizes = np.diff(starts)
    cells = cells[sizes[cells] > 1]
    pairs = _pairs_crossing_in(cells, starts, sizes, references, a, e, _directions(e), new_piece, max_pairs)
    return crossing_tables(np.concatenate([old_pairs.astype(np.int64), pairs]), a, b, max_pairs)


def pairs_of(crossing_start, crossing_partner):
    """The listed pairs ``(lower, partner)`` (M, 2) of :func:`find_crossings`' CSR arrays."""
    count = np.diff(crossing_start.astype(np.int64))
    lower = np.repeat(np.arange(len(count)), count)
    return np.stack([lower, crossing_partner[:len(lower)].astype(np.int64)], axis=1)


def crossing_tables(pairs, a, b, max_pairs=None):
    """The CSR arrays of :func:`find_crossings` from its pairs (``(M, 2)``, repeats allowed)."""
    count = len(a)
    pairs = _unique_pairs(pairs, count)
    _check_count(len(pairs), max_pairs)
    along = _parameters(a, b - a, pairs[:, 0], pairs[:, 1]).astype(np.float32) + np.float32(0.0)  # (no -0)
    # by piece, then along it (the kernel bisects), equal parameters by partner: one sort of a uint64 key
    # (a non-negative float32's bits order as its values), the pairs being in (piece, partner) order
    key = (pairs[:, 0].astype(np.uint64) << np.uint64(32)) | along.view(np.uint32).astype(np.uint64)
    order = np.argsort(key, kind="stable")
    pairs, along = pairs[order], along[order]
    crossing_start = np.zeros(count + 1, dtype=np.uint32)
    np.cumsum(np.bincount(pairs[:, 0], minlength=count), out=crossing_start[1:])
    # padded to two entries: Dr.Jit turns a gather from a one-element array into a broadcast, which
    # would compile a different kernel for a set with exactly one pair
    partner = np.zeros(max(len(pairs), 2), dtype=np.uint32)
    partner[:len(pairs)] = pairs[:, 1]
    crossing_along = np.zeros(len(partner), dtype=np.float32)
    crossing_along[:len(pairs)] = along
    return aligned(crossing_start), aligned(partner), aligned(crossing_along)


def _unique_pairs(pairs, count):
    """The distinct rows of ``pairs`` (M, 2), sorted by first then second column: ``np.unique(axis=0)``'s
    result, through one int64 key per pair (several times faster than comparing rows)."""
    key = np.unique(pairs[:, 0].astype(np.int64) * count + pairs[:, 1])
    return np.stack(np.divmod(key, count), axis=1)


def _directions(e):
    length = np.maximum(np.hypot(e[:, 0], e[:, 1]), 1e-300)
    return e / length[:, None]


def _check_count(listed, max_pairs):
    max_pairs = MAX_PAIRS if max_pairs is None else max_pairs
    if listed > max_pairs:
        raise TooManyCrossings(
            f"crossings = 'height_field': the scratches cross each other more than {max_pairs:,} times "
            f"(the list would take over {8 * max_pairs / 1e9:.1f} GB); render this set with crossings = "
            "'additive', or with fewer or shorter scratches")


def _pairs_crossing_in(cells, starts, sizes, references, a, e, direction, new_piece, max_pairs):
    """The crossing pairs ``(lower, higher)`` among the pieces listed together in ``cells`` (repeats where a
    pair shares cells); with ``new_piece`` (a mask over the pieces) only pairs holding a new piece."""
    max_pairs = MAX_PAIRS if max_pairs is None else max_pairs
    pairs, listed = [np.zeros((0, 2), dtype=np.int64)], 0
    for group in _cell_groups(cells, sizes):
        first, second = _pairs_in_cells(group, starts, sizes, references)
        if new_piece is not None:
            keep = new_piece[first] | new_piece[second]
            first, second = first[keep], second[keep]
        found = _crossing(a, e, direction, first, second)
        first, second = first[found], second[found]  # (about a quarter of the candidates on a random plate)
        pairs.append(np.stack([np.minimum(first, second), np.maximum(first, second)], axis=1))
        listed += len(pairs[-1])
        if listed > max_pairs:  # (counted with repeats: compact, then judge)
            pairs = [_unique_pairs(np.concatenate(pairs), len(a))]
            listed = len(pairs[0])
            _check_count(listed, max_pairs)
    return np.concatenate(pairs)


def _largest_deviation(cells, starts, sizes, references, direction, cell_normals, block=1 << 22):
    """Per cell of ``cells``, the largest |sin| between a listed piece and the cell's direction.

    Blocks of cells of about ``block`` references bound the temporaries (the CD lists 20 million).
    """
    result = np.zeros(len(cells))
    first = 0
    while first < len(cells):
        last = int(np.searchsorted(np.cumsum(sizes[cells[first:]]), block, side="right")) + first
        last = min(max(last, first + 1), len(cells))
        group = cells[first:last]
        index, cell = _references_of(group, starts, sizes)
        deviation = np.abs(np.einsum("ij,ij->i", direction[references[index]], cell_normals[group[cell]]))
        result[first:last] = np.maximum.reduceat(deviation, np.r_[0, np.cumsum(sizes[group])[:-1]])
        first = last
    return result


def _references_of(group, starts, sizes):
    """Positions in ``references`` of the cells in ``group``, and which cell of the group each is."""
    k = sizes[group]
    cell = np.repeat(np.arange(len(group)), k)
    return starts[group][cell] + (np.arange(len(cell)) - np.repeat(np.cumsum(k) - k, k)), cell


def _cell_groups(cells, sizes):
    """Split ``cells`` into groups whose candidate pairs fit in PAIR_BUDGET."""
    k = sizes[cells].astype(np.int64)
    total = np.cumsum(k * (k - 1) // 2)
    start = 0
    while start < len(cells):
        base = total[start - 1] if start else 0
        stop = max(int(np.searchsorted(total, base + PAIR_BUDGET, side="right")), start + 1)
        yield cells[start:stop]
        start = stop


def _pairs_in_cells(cells, starts, sizes, references):
    """All pairs (i, j), i listed before j, of the references of each cell in ``cells`` (a cell lists a
    piece at most once, so i ≠ j): row by row, each reference with those after it in its cell."""
    k = sizes[cells]
    # every listed reference of the cells: its position in ``references`` and how many follow it in its cell
    _, position = expand(starts[cells], k)
    after = np.repeat(np.cumsum(k), k) - np.arange(1, len(position) + 1)
    row, step = expand(np.zeros(len(position), dtype=np.int64), after)
    position = position[row]
    return references[position].astype(np.int64), references[position + 1 + step].astype(np.int64)


def _parameters(a, e, first, second):
    """Parameter along ``first`` of the intersection of the centre lines of ``first`` and ``second``."""
    cross = e[first, 0] * e[second, 1] - e[first, 1] * e[second, 0]
    gap = a[second] - a[first]
    safe = np.where(cross != 0.0, cross, 1.0)
    return (gap[:, 0] * e[second, 1] - gap[:, 1] * e[second, 0]) / safe


def _crossing(a, e, direction, first, second):
    """Whether the centre lines of the pieces cross inside both (parameters in [0, 1)), not nearly parallel.

    In two stages: the crossing's parameter along ``first`` rules out most candidates (about 9 in 10 on
    the Fig. 1 table), so the rest of the test gathers and computes for the others only.  Row gathers
    through ``np.take``: 3-4x faster than fancy indexing's ``e[first]`` (numpy 1.26).
    """
    e_first, e_second = np.take(e, first, axis=0), np.take(e, second, axis=0)
    gap = np.take(a, second, axis=0) - np.take(a, first, axis=0)
    cross = e_first[:, 0] * e_second[:, 1] - e_first[:, 1] * e_second[:, 0]
    safe = np.where(cross != 0.0, cross, 1.0)  # (parallel pieces fail the sine test below)
    t_first = (gap[:, 0] * e_second[:, 1] - gap[:, 1] * e_second[:, 0]) / safe
    candidate = np.flatnonzero((t_first >= 0.0) & (t_first < 1.0) & (cross != 0.0))
    e_first, gap, t_first, safe = e_first[candidate], gap[candidate], t_first[candidate], safe[candidate]
    d_first = np.take(direction, first[candidate], axis=0)
    d_second = np.take(direction, second[candidate], axis=0)
    sine = d_first[:, 0] * d_second[:, 1] - d_first[:, 1] * d_second[:, 0]
    t_second = (gap[:, 0] * e_first[:, 1] - gap[:, 1] * e_first[:, 0]) / safe
    # consecutive pieces of a polyline meet at an end of both (up to rounding): not a crossing
    shared_vertex = _near_end(t_first) & _near_end(t_second)
    found = np.zeros(len(first), dtype=bool)
    found[candidate] = (np.abs(sine) >= MIN_SINE) & (t_second >= 0.0) & (t_second < 1.0) & ~shared_vertex
    return found


def _near_end(t, tolerance=1e-9):
    return (t < tolerance) | (t > 1.0 - tolerance)
