"""Periodic families in the tables: runs of identical, parallel, equally spaced pieces per grid cell
(numpy only; the kernel that sums them in closed form is :mod:`..periodic`, docs/model.md §3.5).

Built when dense tables are uploaded (:func:`periodic_families`): per grid cell up to two *families*,
each a maximal set of the cell's references that are parallel (|sin| < ``PARALLEL_SIN``), of one width
and depth, whose lines are equally spaced (``PITCH_TOLERANCE``) and whose pieces tile each track
without gap or overlap, together with the rectangle (in the family's own frame, cell units) where
every track runs through and no other piece of the cell lies.  A cell with pieces of a third
direction, a missing or an extra track, or pieces that end irregularly gets no family there, and
its queries scan as before.

**Kinks** (:func:`_end_lines`): each family stores its end line when all its tracks end on one line
on one side; two families of a cell that share their end line from opposite sides make a kink cell
(a CD's polygonal tracks turn there).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .references import aligned, ordered_map

__all__ = ["PeriodicTables", "periodic_families", "MIN_TRACKS", "FAMILY_FLOATS", "SLOTS", "VECTORS"]

#: Fewest tracks in a family (fewer: the scan is as cheap).
MIN_TRACKS = 8
#: Largest |sin| between the pieces of a family (float32 directions are ~1e-7 accurate).
PARALLEL_SIN = 1e-6
#: Largest deviation of a track's offset from the equally spaced one, relative to the pitch.
PITCH_TOLERANCE = 1e-2
#: Relative tolerance of "the pieces of a track tile it" (gaps and overlaps).
TILING_TOLERANCE = 1e-6
#: Offsets closer than this (cells) are the same track: pieces of one measure it along their own float32
#: directions (~1e-7 per cell of distance), while n tracks across a cell lie ~1/n cell apart (n: hundreds).
SAME_TRACK = 1e-5
#: Cells whose pieces spread more than this across their dominant direction hold no family (a CD's
#: chords turn by 2.5°, spreading 0.02 cells; pieces in all directions spread about a cell).
MAX_SPREAD_CELLS = 0.1
#: Largest distance of a track's end from the kink line, relative to the pitch (a CD's lie on it to float
#: precision: its polygons share their angles).
KINK_TOLERANCE = 1e-2
#: Two families' end lines are one where their normals differ by less than this and their offsets by
#: less than this many pitches (each is fitted to its own tracks' float32 ends)
LINE_NORMAL_TOLERANCE = 1e-4
LINE_OFFSET_TOLERANCE = 2 * KINK_TOLERANCE
#: Smallest |cos| between an end line's normal and the tracks (in the cell and where a lane sees them):
#: the closed form cuts each run along the line where the scan ends each piece square, and the two
#: differ by wedges that grow with the angle (~5e-4 relative L2 at 9°, ~1e-3 at 30°, tests/bridge/bsdf/test_periodic.py).
KINK_MIN_COS = 0.98
#: Families per cell (a CD cell with a chord's kink holds two).
SLOTS = 2
#: Floats per family: n_u, n_v, o_first, pitch | o_last, s_lo, s_hi, W | ±D, l_u, l_v, l_offset (its end
#: line's normal into the family's side and its offset, :func:`_end_lines`; zero where none) | clear_before,
#: clear_after (how far beyond its first and its last track no other piece of the cell lies, :func:`_family`), 0, 0.
FAMILY_FLOATS = 16
VECTORS = FAMILY_FLOATS // 4  #: (the kernel gathers a family as this many Vector4f)
#: The clear distance (cells) stored where no other piece lies beside a family: more than any window box
#: held by one cell needs.
CLEAR_CELLS = 2.0
#: References per chunk of the numpy build (bounds its temporaries, ~150 bytes per reference; the chunks
#: run on the table build's threads, references.ordered_map).
CHUNK_REFERENCES = 1 << 19


@dataclass(frozen=True, eq=False)
class PeriodicTables:
    """``frames`` (cells, SLOTS, FAMILY_FLOATS) float32.

    Per family, in the cell's coordinates (cells, from its corner): the unit normal n of its tracks,
    the offset n·x of its first track and the pitch, the offset of its last track, the interval
    [s_lo, s_hi] along t = (n_v, -n_u) where all of its tracks run and no other piece lies, the
    width (µm) and the depth (µm, negative: V-groove) of its grooves, its end line, and how far
    beyond its first and last tracks (across them) no other piece of the cell lies.  An empty slot has
    pitch 0."""

    frames: np.ndarray
    families: int  #: families in all
    cells: int  #: cells holding one or two
    kinks: int = 0  #: cells whose two families share their end line (:func:`_end_lines`)


def periodic_families(cell_start, references, segments, cell_frames, origin, cell_size, shape,
                      continuation=None) -> PeriodicTables | None:
    """The families of every cell (module docstring); ``None`` when no cell holds one.

    The arguments are the fields of :class:`.tables.GridTables`; ``continuation`` (its field of that
    name) lets a track run on past a listed piece's end into a piece the cell does not list."""
    starts = cell_start.astype(np.int64)
    counts = np.diff(starts)
    cells = len(counts)
    frames = np.zeros((cells, SLOTS, FAMILY_FLOATS), np.float32)
    # cells of nearly parallel pieces only (the tables' largest offset spread of a piece across the cell's
    # dominant direction): a scattered set is passed over at no cost
    candidates = np.flatnonzero((counts >= MIN_TRACKS) & (cell_frames[:, 2] < MAX_SPREAD_CELLS))
    if len(candidates) == 0:
        return None
    nu = int(shape[0])
    if continuation is None:
        continuation = np.zeros((len(segments), 2), np.float32)
    # chunks of whole cells, on a few threads (numpy releases the GIL; each chunk writes its own cells)
    bounds = np.searchsorted(np.cumsum(counts[candidates]), np.arange(1, 1 + counts.sum() // CHUNK_REFERENCES + 1)
                             * CHUNK_REFERENCES)
    chunks = [chunk for chunk in np.split(candidates, np.unique(np.clip(bounds, 0, len(candidates)))) if len(chunk)]
    normals = cell_frames[:, 0:2].astype(np.float64)

    def run(chunk):
        return _chunk_families(chunk, starts, counts, references, segments, np.asarray(origin, np.float64),
                               float(cell_size), nu, frames, normals, continuation)

    kinks = sum(ordered_map(run, chunks))
    filled = frames[:, :, 3] > 0
    if not filled.any():
        return None
    return PeriodicTables(frames=aligned(frames), families=int(filled.sum()),
                          cells=int(filled.any(axis=1).sum()), kinks=kinks)


def _chunk_families(chunk, starts, counts, references, segments, origin, h, nu, frames, cell_normals,
                    continuation):
    """Fill the slots of the cells in ``chunk`` (vectorised over their references, grouped by cell)."""
    n_refs = counts[chunk]
    local = np.repeat(np.arange(len(chunk)), n_refs)  # chunk-local cell of each reference (non-decreasing)
    first = np.zeros(len(chunk), np.int64)
    np.cumsum(n_refs[:-1], out=first[1:])
    index = starts[chunk][local] + (np.arange(len(local)) - first[local])
    piece = references[index].astype(np.int64)
    # rows gathered with np.take: several times faster than fancy indexing (numpy 1.26)
    rows = np.take(segments, piece, axis=0)
    corner = np.stack([chunk % nu, chunk // nu], axis=1).astype(np.float64) * h + origin
    a = (rows[:, 0:2].astype(np.float64) - np.take(corner, local, axis=0) + rows[:, 2:4]) / h  # cells, from the corner
    e = rows[:, 4:6].astype(np.float64) / h
    length = np.hypot(e[:, 0], e[:, 1])
    usable = length > 0
    t = e / np.where(usable, length, 1.0)[:, None]
    width, depth = rows[:, 6], rows[:, 7]
    # cells: straight on before the start, after the end
    runs_on = np.take(continuation, piece, axis=0).astype(np.float64) / h
    del rows, index

    # ---- family A: parallel to the cell's first piece; B: to its first piece not in A; others spoil the cell
    def cross(t_ref):
        t_ref = np.take(t_ref, local, axis=0)
        return np.abs(t[:, 0] * t_ref[:, 1] - t[:, 1] * t_ref[:, 0])

    t_a = np.take(t, first, axis=0)
    in_a = cross(t_a) < PARALLEL_SIN
    not_a = np.where(~in_a, np.arange(len(local)), len(local))
    first_b = np.minimum.reduceat(not_a, first)
    has_b = first_b < len(local)
    t_b = t[np.where(has_b, first_b, 0)]
    in_b = ~in_a & has_b[local] & (cross(t_b) < PARALLEL_SIN)
    spoiled = _any_per_cell(~(in_a | in_b) | ~usable, local, len(chunk))
    normal = cell_normals[chunk]
    runs = []
    for slot, (member, t_f, other) in enumerate(((in_a, t_a, in_b), (in_b, t_b, in_a))):
        # orient each family like the cell's normal: its references then come nearly sorted by offset
        flip = (t_f[:, 1] * normal[:, 0] - t_f[:, 0] * normal[:, 1]) > 0  # n_f = (-t_v, t_u)
        t_f = np.where(flip[:, None], -t_f, t_f)
        ok = ~spoiled & (has_b if slot else True)
        runs.append(_family(slot, member & ok[local], t_f, other & ok[local], local, a, e, t, runs_on, width,
                            depth, chunk, frames))
    return _end_lines(runs, chunk, frames)


def _any_per_cell(flags, cell_of, cells):
    result = np.zeros(cells, bool)
    result[cell_of[flags]] = True  # a scatter of the few flagged entries (a weighted bincount summed them all)
    return result


def _project(vectors, direction_x, direction_y):
    return vectors[:, 0] * direction_x + vectors[:, 1] * direction_y


def _family(slot, member, t_f, other, local, a, e, t, runs_on, width, depth, chunk, frames):
    """One slot of every cell of the chunk: the family of the references ``member`` (direction ``t_f``)."""
    cells = len(chunk)
    idx = np.flatnonzero(member)
    if len(idx) == 0:
        return
    c = local[idx]
    t_c = np.take(t_f, c, axis=0)  # (rows by np.take: see _chunk_families)
    tx, ty = t_c[:, 0], t_c[:, 1]  # normal n_f = (-t_y, t_x)
    # offset of each piece's own line where it passes the cell's centre (pieces of one straight track agree
    # there exactly; their start points would differ by their direction's float32 rounding times the length)
    start, direction = np.take(a, idx, axis=0), np.take(t, idx, axis=0)
    along_to_centre = _project(0.5 - start, direction[:, 0], direction[:, 1])
    offset = _project(start + along_to_centre[:, None] * direction, -ty, tx)
    s0 = _project(start, tx, ty)
    s1 = s0 + _project(np.take(e, idx, axis=0), tx, ty)
    del start, direction, along_to_centre
    lo, hi = np.minimum(s0, s1), np.maximum(s0, s1)
    forward = s1 >= s0
    before, after = np.take(runs_on[:, 0], idx), np.take(runs_on[:, 1], idx)
    lo_on = lo - np.where(forward, before, after)  # how far the track surely runs
    hi_on = hi + np.where(forward, after, before)
    del tx, ty, s0, s1, forward, before, after
    # sort by (cell, offset): references come sorted by cell and, within one, nearly by offset
    key = c * 8.0 + offset  # offsets of lines through a (dilated) cell lie within (-1.5, 1.5) cells
    unsorted = np.flatnonzero(key[1:] < key[:-1])
    if len(unsorted):
        order = np.argsort(key, kind="stable")
        idx, c, offset, lo, hi = idx[order], c[order], offset[order], lo[order], hi[order]
        lo_on, hi_on = lo_on[order], hi_on[order]

    # ---- tracks: consecutive pieces of one cell at (nearly) one offset
    new_track = np.ones(len(idx), bool)
    new_track[1:] = (c[1:] != c[:-1]) | (offset[1:] - offset[:-1] > SAME_TRACK)
    track_start = np.flatnonzero(new_track)
    t_cell = c[track_start]
    t_offset = offset[track_start]
    span = np.maximum.reduceat(hi, track_start) - np.minimum.reduceat(lo, track_start)
    tiled = np.abs(np.add.reduceat(hi - lo, track_start) - span) <= TILING_TOLERANCE * np.maximum(span, 1e-12)
    t_lo = np.minimum.reduceat(lo_on, track_start)
    t_hi = np.maximum.reduceat(hi_on, track_start)
    w, d = width[idx], depth[idx]

    # ---- per cell: enough tracks, equally spaced, tiled, one groove shape
    counts = np.bincount(t_cell, minlength=cells)
    has = counts >= MIN_TRACKS
    cell_first = np.zeros(cells + 1, np.int64)
    np.cumsum(counts, out=cell_first[1:])
    o_first = np.where(has, t_offset[np.minimum(cell_first[:-1], len(t_offset) - 1)], 0.0)
    o_last = np.where(has, t_offset[np.maximum(cell_first[1:] - 1, 0)], 0.0)
    pitch = np.where(has, (o_last - o_first) / np.maximum(counts - 1, 1), 0.0)
    expected = o_first[t_cell] + pitch[t_cell] * (np.arange(len(t_cell)) - cell_first[t_cell])
    bad = _any_per_cell((np.abs(t_offset - expected) > PITCH_TOLERANCE * pitch[t_cell]) | ~tiled, t_cell, cells)
    first_piece = cell_first_piece(c, cells)
    bad |= _any_per_cell((w != w[first_piece[c]]) | (d != d[first_piece[c]]), c, cells)
    occupied = counts > 0
    s_lo = np.full(cells, -np.inf)
    s_hi = np.full(cells, np.inf)
    s_lo[occupied] = np.maximum.reduceat(t_lo, cell_first[:-1][occupied])
    s_hi[occupied] = np.minimum.reduceat(t_hi, cell_first[:-1][occupied])

    # ---- the other family's pieces: beside the tracks, or wholly on one side along them
    jdx = np.flatnonzero(other)  # grouped by cell, as the references
    if len(jdx):
        oc = local[jdx]
        t_o, a_o, e_o = (np.take(x, i, axis=0) for x, i in ((t_f, oc), (a, jdx), (e, jdx)))
        tx, ty = t_o[:, 0], t_o[:, 1]
        q0 = _project(a_o, -ty, tx)
        q1 = q0 + _project(e_o, -ty, tx)
        r0 = _project(a_o, tx, ty)
        r1 = r0 + _project(e_o, tx, ty)
        r_lo, r_hi = np.minimum(r0, r1), np.maximum(r0, r1)
        beside = (np.minimum(q0, q1) > o_last[oc]) | (np.maximum(q0, q1) < o_first[oc])
        middle = 0.5 * (s_lo[oc] + s_hi[oc])
        above = ~beside & (r_lo >= middle)
        below = ~beside & (r_hi <= middle)
        bad |= _any_per_cell(~(beside | above | below), oc, cells)
        s_hi = np.minimum(s_hi, _per_cell_extreme(np.minimum, np.where(above, r_lo, np.inf), oc, cells, np.inf))
        s_lo = np.maximum(s_lo, _per_cell_extreme(np.maximum, np.where(below, r_hi, -np.inf), oc, cells, -np.inf))
        # the nearest centre line beside the tracks on either side (an edge's window must not reach it)
        q_lo, q_hi = np.minimum(q0, q1), np.maximum(q0, q1)
        nearest_before = _per_cell_extreme(np.maximum, np.where(q_hi < o_first[oc], q_hi, -np.inf), oc, cells, -np.inf)
        nearest_after = _per_cell_extreme(np.minimum, np.where(q_lo > o_last[oc], q_lo, np.inf), oc, cells, np.inf)
        clear_before = np.minimum(o_first - nearest_before, CLEAR_CELLS)
        clear_after = np.minimum(nearest_after - o_last, CLEAR_CELLS)
    else:
        clear_before = clear_after = np.full(cells, CLEAR_CELLS)

    keep = has & ~bad & (s_hi > s_lo) & (pitch > 0)
    # the side along the tracks where the other family lies (+1: beyond the tracks' upper ends), 0: none
    # or both sides; a run with the other family on one side only may end on a kink line (_end_lines)
    other_side = np.zeros(cells, np.int8)
    if len(jdx):
        up = _any_per_cell(above, oc, cells)
        down = _any_per_cell(below, oc, cells)
        other_side = np.where(up & ~down, 1, np.where(down & ~up, -1, 0)).astype(np.int8)
    rows = np.flatnonzero(keep)
    target = chunk[rows]
    frames[target, slot, 0] = -t_f[rows, 1]
    frames[target, slot, 1] = t_f[rows, 0]
    frames[target, slot, 2] = o_first[rows]
    frames[target, slot, 3] = pitch[rows]
    frames[target, slot, 4] = o_last[rows]
    frames[target, slot, 5] = s_lo[rows]
    frames[target, slot, 6] = s_hi[rows]
    frames[target, slot, 7] = w[first_piece[rows]]
    frames[target, slot, 8] = d[first_piece[rows]]
    frames[target, slot, 12] = clear_before[rows]
    frames[target, slot, 13] = clear_after[rows]
    return _Run(keep=keep, other_side=other_side, t_f=t_f, pitch=pitch, track_cell=t_cell,
                track_offset=t_offset, track_lo=t_lo, track_hi=t_hi)


class _Run(NamedTuple):
    """One slot's family in every cell of a chunk, as the kink detection needs it (cell units)."""

    keep: np.ndarray  #: per cell: the slot holds a family
    other_side: np.ndarray  #: per cell: +1 / -1 the other family lies wholly beyond its tracks' upper / lower ends
    t_f: np.ndarray  #: per cell: the tracks' direction (its normal is (-t_v, t_u))
    pitch: np.ndarray  #: per cell
    track_cell: np.ndarray  #: per track (grouped by cell, by offset): its chunk-local cell
    track_offset: np.ndarray  #: per track
    track_lo: np.ndarray  #: per track: how far it surely runs along t_f, down and up
    track_hi: np.ndarray


def _end_lines(runs, chunk, frames):
    """Store each family's *end line*: a line L on which every one of its tracks ends on one side, crossing
    them nearly square (a CD's chords end on the radial line where its polygons turn), as L's unit normal
    into the family's side and its offset n·x (cells), in the slot's floats 9–11 (zero: none).

    A cell whose two families share their end line, one on each side, is a *kink*: each family is its
    infinite run cut by a half-plane (docs/model.md §3.5).  Where the other family lies along the tracks,
    the line is the ends facing it; a lone family takes the side whose line passes nearer the cell's
    centre (the one a window in the cell can reach).  Returns the number of kink cells."""
    cells = len(chunk)
    found = []
    for k, run in enumerate(runs):
        if run is None:
            found.append(None)
            continue
        best = np.zeros((cells, 3))  # l_u, l_v, offset; zero normal: no line
        distance = np.full(cells, np.inf)
        for side in (1, -1):
            normal, offset, valid = _line_of_ends(run, side, cells)
            valid &= run.keep & ((run.other_side == side) | (run.other_side == 0))
            nearness = np.abs(0.5 * normal[:, 0] + 0.5 * normal[:, 1] - offset)  # from the cell's centre
            take = valid & (nearness < distance)
            best[take, 0:2], best[take, 2], distance[take] = normal[take], offset[take], nearness[take]
        rows = np.flatnonzero(np.isfinite(distance))
        frames[chunk[rows], k, 9:12] = best[rows]
        found.append(best)
    if found[0] is None or found[1] is None:
        return 0
    first, second = found
    grooves = frames[chunk, :, 7:9]
    tolerance = LINE_OFFSET_TOLERANCE * np.maximum(runs[0].pitch, runs[1].pitch)
    kink = ((np.abs(first[:, 0:2] + second[:, 0:2]).max(axis=1) < LINE_NORMAL_TOLERANCE)
            & (np.abs(first[:, 2] + second[:, 2]) < tolerance) & (np.abs(first[:, 0:2]).sum(axis=1) > 0)
            & np.all(grooves[:, 0] == grooves[:, 1], axis=1))
    return int(np.count_nonzero(kink))


def _line_of_ends(run: _Run, side, cells):
    """Per cell: the line through the ends of the run's tracks on ``side`` (+1: their upper ends along
    t_f), its unit normal into the run, its offset, and whether every end lies on it (``KINK_TOLERANCE``)
    and it crosses the tracks at |cos| >= ``KINK_MIN_COS``."""
    cell = run.track_cell
    along = run.track_hi if side > 0 else run.track_lo
    t = np.take(run.t_f, cell, axis=0)  # (rows by np.take: see _chunk_families)
    points = run.track_offset[:, None] * np.stack([-t[:, 1], t[:, 0]], axis=1) + along[:, None] * t
    starts = cell_first_piece(cell, cells)
    counts = np.bincount(cell, minlength=cells)
    lasts = starts + np.maximum(counts, 1) - 1
    first_points = np.take(points, starts, axis=0)
    direction = np.take(points, lasts, axis=0) - first_points
    length = np.hypot(direction[:, 0], direction[:, 1])
    valid = (counts > 1) & (length > 0) & np.isfinite(length)
    normal = np.stack([-direction[:, 1], direction[:, 0]], axis=1) / np.where(valid, length, 1.0)[:, None]
    normal *= np.where(_dot(normal, -side * run.t_f) < 0, -1.0, 1.0)[:, None]  # into the run
    offset = _dot(normal, first_points)
    off_line = ~np.isfinite(along) | (np.abs(_dot(np.take(normal, cell, axis=0), points) - np.take(offset, cell))
                                      > KINK_TOLERANCE * np.take(run.pitch, cell))
    valid &= ~_any_per_cell(off_line, cell, cells) & (np.abs(_dot(normal, run.t_f)) >= KINK_MIN_COS)
    return normal, offset, valid


def _dot(x, y):
    """Row-wise dot products of (N, 2) arrays: ``np.sum(x * y, axis=1)`` to the bit, without numpy's slow
    reduction along a short axis."""
    return x[:, 0] * y[:, 0] + x[:, 1] * y[:, 1]


def _per_cell_extreme(ufunc, values, cell_of, cells, fill):
    """``ufunc.reduce`` of ``values`` per cell (``cell_of`` non-decreasing); ``fill`` for cells without."""
    result = np.full(cells, fill)
    present = np.ones(len(cell_of), bool)
    present[1:] = cell_of[1:] != cell_of[:-1]
    starts = np.flatnonzero(present)
    result[cell_of[starts]] = ufunc.reduceat(values, starts)
    return result


def cell_first_piece(cell_of, cells):
    """Index of the first entry of each cell in the cell-sorted array ``cell_of`` (0 for cells without)."""
    first = np.zeros(cells, np.int64)
    present = np.ones(len(cell_of), bool)
    present[1:] = cell_of[1:] != cell_of[:-1]
    first[cell_of[present]] = np.flatnonzero(present)
    return first
