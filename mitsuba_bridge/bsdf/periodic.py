"""Periodic families: runs of identical, parallel, equally spaced scratches summed in closed form.

A CD's tracks and a ruled grating are, inside a coherence window, one
infinite periodic set of straight grooves.  Their sum over the tracks is a
Fourier series (Poisson summation, docs/model.md §3.5): with the window's
along factor ``σ√(2π) e^{-2π²σ²ν∥²}`` common to all of them,

    Σ_n S_n(ξ) = σ√(2π) e^{-2π²σ²ν∥²} · (1/P) Σ_m ŵ(ν⊥ + m/P) G(m/P) e^{2πi m a0/P}

(``P`` the pitch, ``a0`` the offset of a track from the shading point, ``ŵ``
the window's transform across, ``G`` the transform of one groove's
``e^{iκp(u)} - 1``), and only the three orders ``m`` nearest to ``-ν⊥P``
matter where σ ≥ P.  A query that qualifies costs one closed form instead of
a scan of the ~20 tracks in its window and their transforms.

**Tables** (:func:`periodic_families`, numpy, built when dense tables are
uploaded): per grid cell up to two *families*, each a maximal set of the
cell's references that are parallel (|sin| < ``PARALLEL_SIN``), of one width
and depth, whose lines are equally spaced (``PITCH_TOLERANCE``) and whose
pieces tile each track without gap or overlap, together with the rectangle
(in the family's own frame, cell units) where every track runs through and
no other piece of the cell lies.  A cell with pieces of a third direction, a
missing or an extra track, or pieces that end irregularly gets no family
there, and its queries scan as before.

**Kernel** (:func:`find_family`, :func:`family_field`): a query uses a family
when its window's box (4σ, the scan's window radius, through the UV
Jacobian) reaches no lattice position beyond the first or last track of the
family in any cell it touches — at most 2 × 2 cells, each holding the same
run (direction, pitch, groove, offsets a whole number of pitches apart) —
when no track ends within 7.2σ of x0 (so every end lies beyond the 6σ
where the scan skips its term), and when σ ≥ P.  Otherwise the
lane scans (:func:`.lookup.for_each_segment`) and gets the scan's values bit
for bit.  The closed form is the exact sum over the infinite run; the scan
drops tracks beyond 4σ (e^-8 of the window), so the two differ by that
truncation, ~1e-4 (tests/bsdf/test_periodic.py).

**Kinks** (:func:`_end_lines`, and the same functions): where two families meet on a line on which
every track of one ends and every track of the other begins (a CD's polygonal tracks turn there), a
window across the line (its box in up to 2 × 2 cells) sums each run cut by its side's half-plane (one
Faddeeva evaluation per order, docs/model.md §3.5), and ``sample`` draws either run's line in
proportion to its cut weight; a window near the line but wholly on one side sums that run cut alone.
Sets without kinks compile none of this.

**Incoherent mode** (:func:`family_intensity`): the tracks' intensities sum by the same Poisson formula
to the order 0 alone, the squared along factor times (σ/P) the squared groove transform averaged over
the squared window's transform (4-point Gauss–Hermite; docs/model.md §3.5); at a kink each run's cut
along factor is averaged over the tracks' offsets the same way.
Units as everywhere in the kernels: µm, 1/µm.
"""
from __future__ import annotations

import functools
import math
import operator
from dataclasses import dataclass
from typing import NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from . import profiles
from .complexmath import Cx, expi
from .faddeeva import faddeeva
from .references import aligned, ordered_map
from .segment import SegmentGeometry, cross_section
from .window import window_integral

__all__ = ["PeriodicTables", "periodic_families", "Family", "find_family", "family_field", "family_intensity",
           "run_energies", "MIN_TRACKS", "ACROSS_SIGMAS", "ALONG_SIGMAS"]

#: Fewest tracks in a family (fewer: the scan is as cheap).
MIN_TRACKS = 8
#: Largest |sin| between the pieces of a family (float32 directions are ~1e-7 accurate).
PARALLEL_SIN = 1e-6
#: Largest deviation of a track's offset from the equally spaced one, relative to the pitch.
PITCH_TOLERANCE = 1e-2
#: The same checks in the kernel, between the float32 families of neighbouring cells: directions, and
#: offsets a whole number of pitches apart up to both families' deviations (and pitches as close).
PARALLEL_SIN_KERNEL = 1e-5
PITCH_TOLERANCE_KERNEL = 2 * PITCH_TOLERANCE
#: Relative tolerance of "the pieces of a track tile it" (gaps and overlaps).
TILING_TOLERANCE = 1e-6
#: Offsets closer than this (cells) are the same track: pieces of one measure it along their own float32
#: directions (~1e-7 per cell of distance), while n tracks across a cell lie ~1/n cell apart (n: hundreds).
SAME_TRACK = 1e-5
#: Window reach (σ) across the tracks that must lie among the family's tracks: the
#: scan's window radius (model.WINDOW_RADIUS_SIGMAS); what lies beyond, the scan drops too (e^-8).
ACROSS_SIGMAS = 4.0
#: ... and along the tracks inside its rectangle: every end lying outside the ball of this radius around
#: x0, it lies more than 6σ from x0's foot point on any track within 4σ (√(6² + 4²) = 7.21), where the
#: scan skips the end's term (window.END_NEGLIGIBLE_SIGMAS).
ALONG_SIGMAS = math.sqrt(6.0 ** 2 + 4.0 ** 2) * 1.001
#: Smallest σ/P for the three-order sum (the fourth order is then below e^-44 of the nearest) ...
MIN_SIGMA_PER_PITCH = 1.0
#: ... and from which the nearest order alone does (the next lies 0.5/P > 0.9/σ away: below e^-16).
ONE_ORDER_SIGMA_PER_PITCH = 1.8
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
#: differ by wedges that grow with the angle (~5e-4 relative L2 at 9°, ~1e-3 at 30°, tests/bsdf/test_periodic.py).
KINK_MIN_COS = 0.98
#: The sign of the transform's exponent in a run's frame: ``S(ξ) = ∫ w T e^{-2πiK·y}`` with an order's
#: frequency K = ν∥ t + (ν⊥ + m/P) n as :func:`_run_field` builds it (n = (-t_y, t_x))
HALF_PLANE_SIGN = -1.0
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


# ------------------------------------------------------------------ kernel
@dataclass
class Family:
    """The family a shading point's window lies in (``eligible``), seen from x0 (local frame, µm)."""

    eligible: object  #: mi.Bool
    dx: object  #: mi.Float: unit direction of the tracks
    dy: object
    pitch: object  #: mi.Float: P (µm)
    a0: object  #: mi.Float: signed distance a·n of the nearest track's centre line from x0, |a0| <= P/2
    width: object  #: mi.Float: W (µm)
    depth: object  #: mi.Float: D (µm)
    triangular: object  #: mi.Bool
    #: mi.Bool: the window straddles a kink line: the run above (A) holds the half-plane y·l >= h (y = x - x0)
    #: only, and a second run B of the same groove (direction b_dx, b_dy, pitch b_pitch, offset b_a0) the rest
    kink: object = None
    lone: object = None  #: mi.Bool: at a kink, run A alone (the whole box on its side of its end line; no B)
    b_pitch: object = None
    b_dx: object = None
    b_dy: object = None
    b_a0: object = None
    l_x: object = None  #: mi.Float: unit normal of the kink line into A's side (local frame)
    l_y: object = None
    h: object = None  #: mi.Float: signed distance of the kink line from x0 along l (µm)
    #: mi.Bool: the window reaches past the first or last track (an *edge*): its closed form is
    #: ``base`` (0, or the infinite run where fewer tracks are missing than present) plus ``edge_sign``
    #: (±1) times the sum over ``edge_tracks`` tracks at offsets ``edge_a + j · edge_step`` (µm)
    edge: object = None
    edge_base: object = None  #: mi.Bool: the infinite run's closed form is the base (else 0)
    edge_a: object = None
    edge_step: object = None
    edge_tracks: object = None  #: mi.UInt32 (0 on lanes without an edge)


class _Slot(NamedTuple):
    """One family slot of one cell, tested against one window."""

    holds: object  #: mi.Bool: a family whose rectangle holds the window's part in the cell
    cut: object  #: mi.Bool: a family cut by a kink line, among whose tracks the window lies up to that line
    n_u: object
    n_v: object
    pitch: object  #: µm
    offset: object  #: µm: signed distance a·n of its first track from x0 (n of the tracks' local frame)
    width: object
    depth: object  #: ±D
    l_u: object  #: its end line (cells): unit normal into the family's side, offset (zero: none)
    l_v: object
    l_offset: object
    pitch_cells: object
    #: (own cell only) the window reaches past its first or last track, no other piece within reach:
    #: its tracks in reach, by index from the first: lowest, highest, and the index of the last track
    edge: object = None
    j_lo: object = None
    j_hi: object = None
    last: object = None


def find_family(grid, jac, sigma, active) -> Family:
    """The family whose tracks fill x0's window, if any (module docstring).

    The window's box may reach into the neighbouring cells (at most 2 × 2 cells): each cell it touches
    must hold the same run (same direction, pitch and groove, offsets a whole number of pitches apart)
    with a rectangle holding the window's part in that cell (the box clipped to it)."""
    gu = (jac.uv.x - grid.origin_u) * grid.inverse_cell_size
    gv = (jac.uv.y - grid.origin_v) * grid.inverse_cell_size
    det = jac.j00 * jac.j11 - jac.j01 * jac.j10
    norm2 = jac.j00 * jac.j00 + jac.j01 * jac.j01 + jac.j10 * jac.j10 + jac.j11 * jac.j11
    usable = mi.Bool(active) & (dr.abs(det) > 1e-12 * norm2)
    inv_det = dr.rcp(dr.select(usable, dr.abs(det), 1.0))
    scale = inv_det * grid.inverse_cell_size  # cells per µm, times |adj(J)ᵀ·| below
    reach_um = ACROSS_SIGMAS * sigma
    reach = reach_um * scale
    extent_u = reach * dr.sqrt(jac.j11 * jac.j11 + jac.j01 * jac.j01) + grid.margin
    extent_v = reach * dr.sqrt(jac.j10 * jac.j10 + jac.j00 * jac.j00) + grid.margin
    u0, u1 = dr.floor(gu - extent_u), dr.floor(gu + extent_u)
    v0, v1 = dr.floor(gv - extent_v), dr.floor(gv + extent_v)
    usable &= dr.isfinite(extent_u) & dr.isfinite(extent_v)
    last_u, last_v = mi.Float(grid.cells_u - 1), mi.Float(grid.cells_v - 1)
    in_grid = ((u0 >= 0.0) & (v0 >= 0.0) & (u1 <= last_u) & (v1 <= last_v) & (u1 - u0 <= 1.0) & (v1 - v0 <= 1.0))
    # an edge's box may reach past the grid, where no centre line lies: clamped to the grid, it must lie in
    # one cell (x0's own, the nearest cell where x0 lies outside)
    own_box = (dr.maximum(u0, 0.0) == dr.minimum(u1, last_u)) & (dr.maximum(v0, 0.0) == dr.minimum(v1, last_v))
    usable &= in_grid | own_box
    signed = dr.select(det >= 0.0, 1.0, -1.0)
    kinks = grid.kink_count > 0  # (a Python choice: sets without kinks compile no kink code)

    def box_range(cu, cv, n_u, n_v):
        """``(min, max)`` of n·x over the window's box clipped to cell (cu, cv) (that cell's coordinates)."""
        du, dv = gu - cu, gv - cv  # x0 in this cell's coordinates
        box_u0, box_u1 = dr.maximum(du - extent_u, 0.0), dr.minimum(du + extent_u, 1.0)
        box_v0, box_v1 = dr.maximum(dv - extent_v, 0.0), dr.minimum(dv + extent_v, 1.0)
        positive_u, positive_v = n_u >= 0.0, n_v >= 0.0
        return (n_u * dr.select(positive_u, box_u0, box_u1) + n_v * dr.select(positive_v, box_v0, box_v1),
                n_u * dr.select(positive_u, box_u1, box_u0) + n_v * dr.select(positive_v, box_v1, box_v0))

    def slot(cu, cv, k, wanted, edges=False) -> _Slot:
        """Slot k of cell (cu, cv) against the window's box clipped to that cell (``edges``: x0's own cell,
        whether the window lies at an edge of the family instead)."""
        cell = mi.UInt32(mi.Int32(cv) * grid.cells_u + mi.Int32(cu))
        base = (cell * SLOTS + k) * VECTORS
        f0 = dr.gather(mi.Vector4f, grid.family_frames, base, wanted)  # n_u, n_v, o_first, pitch
        f1 = dr.gather(mi.Vector4f, grid.family_frames, base + 1, wanted)  # o_last, s_lo, s_hi, W
        f2 = dr.gather(mi.Vector4f, grid.family_frames, base + 2, wanted)  # ±D, l_u, l_v, l_offset
        du, dv = gu - cu, gv - cv  # x0 in this cell's coordinates
        box_lo, box_hi = box_range(cu, cv, f0.x, f0.y)
        s = f0.y * du - f0.x * dv  # along t = (n_v, -n_u)
        adj_n = dr.sqrt(dr.square(jac.j11 * f0.x - jac.j10 * f0.y) + dr.square(jac.j00 * f0.y - jac.j01 * f0.x))
        adj_t = dr.sqrt(dr.square(jac.j11 * f0.y + jac.j10 * f0.x) + dr.square(jac.j00 * f0.x + jac.j01 * f0.y))
        along = (ALONG_SIGMAS * sigma) * scale * adj_t + grid.margin
        micrometres_per_cell = dr.abs(det) * dr.rcp(dr.maximum(adj_n, 1e-30)) * grid.cell_size
        # no lattice position of the part lies beyond the first or the last track (those beyond the cell's
        # part belong to its neighbours, checked there), and every track runs past the window's reach
        gap = (1.0 - 2.0 * PITCH_TOLERANCE) * f0.w
        across = wanted & (f0.w > 0.0) & (box_lo >= f0.z - gap) & (box_hi <= f1.x + gap)
        below, above = s - along >= f1.y, s + along <= f1.z
        # cut by its end line: only the far end (away from the line, along t) must lie beyond the reach
        into = f0.y * f2.y - f0.x * f2.z  # t·l
        cut = across & ((f2.y != 0.0) | (f2.z != 0.0)) & dr.select(into > 0.0, above, below)
        offset = signed * (f0.z - (f0.x * du + f0.y * dv)) * micrometres_per_cell
        found = _Slot(across & below & above, cut, f0.x, f0.y, f0.w * micrometres_per_cell, offset, f1.w, f2.x,
                      f2.y, f2.z, f2.w, f0.w)
        if not edges:
            return found
        # at an edge: the whole box in this cell, along the tracks as above, and across them clear of any
        # other piece; the tracks in reach: |offset + signed·j·P| <= the window radius (as the scan's)
        f3 = dr.gather(mi.Vector4f, grid.family_frames, base + 3, wanted)  # clear_before, clear_after
        edge = (wanted & (f0.w > 0.0) & ~(across & in_grid) & below & above & own_box
                & (box_lo >= f0.z - f3.x) & (box_hi <= f1.x + f3.y))
        pitch = found.pitch
        step = signed * dr.maximum(pitch, 1e-30)
        j0, j1 = (-reach_um - offset) / step, (reach_um - offset) / step
        last = dr.round((f1.x - f0.z) * dr.rcp(dr.maximum(f0.w, 1e-30)))
        j_lo = dr.maximum(dr.ceil(dr.minimum(j0, j1)), 0.0)
        j_hi = dr.minimum(dr.floor(dr.maximum(j0, j1)), last)
        return found._replace(edge=edge, j_lo=j_lo, j_hi=j_hi, last=last)

    # ---- only lanes whose own cell holds a family go on (whole SIMD packets elsewhere skip the rest)
    u = dr.floor(dr.clip(gu, 0.0, mi.Float(grid.cells_u - 1)))
    v = dr.floor(dr.clip(gv, 0.0, mi.Float(grid.cells_v - 1)))
    own_cell = mi.UInt32(mi.Int32(v) * grid.cells_u + mi.Int32(u))
    pitch_floats = [4 * ((own_cell * SLOTS + k) * VECTORS) + 3 for k in range(SLOTS)]
    candidate = usable & ((dr.gather(mi.Float, grid.family_frames, pitch_floats[0], usable) > 0.0)
                          | (dr.gather(mi.Float, grid.family_frames, pitch_floats[1], usable) > 0.0))

    def same_run(other: _Slot, run: _Slot):
        """``other`` (a slot of any cell, seen from x0) continues ``run``: same direction, pitch and groove,
        offsets a whole number of pitches apart."""
        same_way = dr.abs(other.n_u * run.n_v - other.n_v * run.n_u) < PARALLEL_SIN_KERNEL
        flip = dr.select(other.n_u * run.n_u + other.n_v * run.n_v >= 0.0, 1.0, -1.0)
        shift = (flip * other.offset - run.offset) * dr.rcp(dr.maximum(run.pitch, 1e-30))
        return (same_way & (dr.abs(shift - dr.round(shift)) < PITCH_TOLERANCE_KERNEL)
                & (dr.abs(other.pitch - run.pitch) < PITCH_TOLERANCE_KERNEL * run.pitch)
                & (other.width == run.width) & (other.depth == run.depth))

    def local_run(run: _Slot):
        """The run's direction J t (t = (n_v, -n_u)) in the local frame and its nearest track's offset."""
        ex, ey = jac.j00 * run.n_v - jac.j01 * run.n_u, jac.j10 * run.n_v - jac.j11 * run.n_u
        inv = dr.rsqrt(dr.maximum(ex * ex + ey * ey, 1e-30))
        return ex * inv, ey * inv, run.offset - run.pitch * dr.round(run.offset * dr.rcp(run.pitch))

    corners = ((u0, v0), (u1, v0), (u0, v1), (u1, v1))
    #: whether each corner is a cell not listed before it (a box within one cell column or row repeats them)
    new_corner = (u0 == u0, u1 != u0, v1 != v0, (u1 != u0) & (v1 != v0))

    def search(candidate):
        first = slot(u, v, 0, candidate, edges=True)
        second = slot(u, v, 1, candidate & ~first.holds, edges=True)
        own = _pick(first.holds, first, second)
        eligible = own.holds & in_grid & (sigma >= MIN_SIGMA_PER_PITCH * own.pitch)
        # an edge: fewer tracks missing (lattice positions in reach beyond the first or last) than present
        # are summed as the infinite run's closed form less those (where it applies), else the present ones
        at_edge = ~eligible & (first.edge | second.edge)
        edge = _pick(first.edge, first, second)
        step = dr.select(det >= 0.0, 1.0, -1.0) * edge.pitch
        j0, j1 = (-reach_um - edge.offset) / step, (reach_um - edge.offset) / step
        j_min, j_max = dr.ceil(dr.minimum(j0, j1)), dr.floor(dr.maximum(j0, j1))
        present = dr.maximum(edge.j_hi - edge.j_lo + 1.0, 0.0)
        before, after = dr.maximum(-j_min, 0.0), dr.maximum(j_max - edge.last, 0.0)
        subtract = (at_edge & (sigma >= MIN_SIGMA_PER_PITCH * edge.pitch) & ((before == 0.0) | (after == 0.0))
                    & (before + after < present))
        edge_start = dr.select(subtract, dr.select(before > 0.0, j_min, edge.last + 1.0), edge.j_lo)
        edge_tracks = mi.UInt32(dr.select(at_edge, dr.select(subtract, before + after, present), 0.0))
        edge_fields = (at_edge, subtract, edge.offset + edge_start * step, step, edge_tracks)
        own = _pick(at_edge, edge, own)

        def neighbours(eligible):
            """Every cell of the window's box continues the run (x0's own cell matches itself)."""
            for cu, cv in corners:
                wanted = eligible & ((cu != u) | (cv != v))
                a = slot(cu, cv, 0, wanted)
                matched = a.holds & same_run(a, own)
                b = slot(cu, cv, 1, wanted & ~matched)
                eligible = eligible & (~wanted | matched | (b.holds & same_run(b, own)))
            return (eligible,)

        # (whole SIMD packets whose boxes stay in their own cells skip this)
        leaves = eligible & ((u0 != u1) | (v0 != v1))
        eligible = dr.if_stmt((eligible,), leaves, neighbours, lambda eligible: (eligible,),
                              label="scratch_family_neighbours")[0]
        dx, dy, offset = local_run(own)
        found = (eligible | at_edge, dx, dy, own.pitch, offset, own.width, own.depth) + edge_fields
        if not kinks:
            return found
        # lanes without a run of their own may lie at a kink (found in any cell of the box)
        wanted = candidate & in_grid & ~eligible & ~at_edge
        kink = dr.if_stmt((wanted,), wanted, at_kink, no_kink, label="scratch_kink")
        return tuple(dr.select(kink[0], k, f) for k, f in zip(kink[:7], found[:7])) + found[7:] + kink[7:]

    def at_kink(active):
        """A kink holding the window (:func:`_end_lines`).  Some cell of the box holds two runs A and B that
        share their end line (or one run A cut by its end line, with the whole box on its side: *lone*),
        and in every cell of the box the part of the box on A's side of the line lies among A's tracks up
        to the line (A continuing, cut by the same line, or running through with the part wholly on its
        side), the same for B, and no other piece lies there (other runs end on the line from beyond)."""
        found = lone = dr.zeros(mi.Bool)
        run_a = run_b = None
        ru, rv = u, v
        for (cu, cv), new in zip(corners, new_corner):
            wanted = active & ~found & new
            a = slot(cu, cv, 0, wanted)
            b = slot(cu, cv, 1, wanted)
            pair = (wanted & _on_line(b, a, 0.0, 0.0, -1.0) & (a.width == b.width) & (a.depth == b.depth)
                    & (sigma >= MIN_SIGMA_PER_PITCH * dr.maximum(a.pitch, b.pitch)))
            part_lo, _ = box_range(cu, cv, a.l_u, a.l_v)
            single = (wanted & ~pair & a.cut & ~(b.pitch_cells > 0.0) & ((a.l_u != 0.0) | (a.l_v != 0.0))
                      & (part_lo >= a.l_offset) & (sigma >= MIN_SIGMA_PER_PITCH * a.pitch))
            here = pair | single
            run_a = a if run_a is None else _pick(here, a, run_a)
            b = _pick(single, a, b)  # (a lone run's B: valid numbers, no weight)
            run_b = b if run_b is None else _pick(here, b, run_b)
            ru, rv = dr.select(here, cu, ru), dr.select(here, cv, rv)
            lone = dr.select(here, single, lone)
            found = found | here
        kink = found
        for (cu, cv), new in zip(corners, new_corner):
            shift_u, shift_v = cu - ru, cv - rv
            a = slot(cu, cv, 0, kink & new)
            b = slot(cu, cv, 1, kink & new)
            part_lo, part_hi = box_range(cu, cv, run_a.l_u, run_a.l_v)
            line = run_a.l_offset - (run_a.l_u * shift_u + run_a.l_v * shift_v)
            a_side, b_side = part_lo >= line, part_hi <= line  # the part wholly on A's / B's side

            def beyond(x, sign):  # x's tracks end on the line from the other side than ``sign``'s run's
                return _on_line(x, run_a, shift_u, shift_v, -sign)

            def covers(x, run, sign, side):  # x continues the run, cut by the line or wholly on its side
                return same_run(x, run) & ((x.cut & _on_line(x, run_a, shift_u, shift_v, sign)) | (x.holds & side))

            alone = ~(b.pitch_cells > 0.0)
            a_covers_a, b_covers_a = covers(a, run_a, 1.0, a_side), covers(b, run_a, 1.0, a_side)
            a_covers_b, b_covers_b = covers(a, run_b, -1.0, b_side), covers(b, run_b, -1.0, b_side)
            on_a = a_side & ((a_covers_a & (alone | beyond(b, 1.0))) | (b_covers_a & beyond(a, 1.0)))
            on_b = b_side & ((a_covers_b & (alone | beyond(b, -1.0))) | (b_covers_b & beyond(a, -1.0)))
            ok = dr.select(lone, on_a, (a_covers_a & b_covers_b) | (a_covers_b & b_covers_a) | on_a | on_b)
            kink = kink & (ok | ~new)

        dx, dy, offset = local_run(run_a)
        b_dx, b_dy, b_a0 = local_run(run_b)
        # the kink line in the local frame: normal ⟂ J t_L (t_L = (l_v, -l_u)), turned towards J l; its
        # distance from x0 through the UV Jacobian as for the tracks' offsets
        lu, lv = run_a.l_u, run_a.l_v
        tx, ty = jac.j00 * lv - jac.j01 * lu, jac.j10 * lv - jac.j11 * lu
        towards = (jac.j00 * lu + jac.j01 * lv) * -ty + (jac.j10 * lu + jac.j11 * lv) * tx
        inv = dr.select(towards >= 0.0, 1.0, -1.0) * dr.rsqrt(dr.maximum(tx * tx + ty * ty, 1e-30))
        adj_l = dr.sqrt(dr.square(jac.j11 * lu - jac.j10 * lv) + dr.square(jac.j00 * lv - jac.j01 * lu))
        h = ((run_a.l_offset - (lu * (gu - ru) + lv * (gv - rv))) * dr.abs(det)
             * dr.rcp(dr.maximum(adj_l, 1e-30)) * grid.cell_size)
        l_x, l_y = -ty * inv, tx * inv
        # nearly across both runs where the lane sees them (a shear of the UV map turns the line obliquely)
        kink = kink & ((dr.abs(l_x * dx + l_y * dy) >= KINK_MIN_COS) & (dr.abs(l_x * b_dx + l_y * b_dy) >= KINK_MIN_COS))
        return (kink, dx, dy, run_a.pitch, offset, run_a.width, run_a.depth,
                kink, lone, run_b.pitch, b_dx, b_dy, b_a0, l_x, l_y, h)

    def no_kink(active):
        zero = dr.zeros(mi.Float)
        return (dr.zeros(mi.Bool),) + (zero,) * 6 + (dr.zeros(mi.Bool),) * 2 + (zero,) * 7

    def nothing(candidate):
        zero = dr.zeros(mi.Float)
        kink = (dr.zeros(mi.Bool), dr.zeros(mi.Bool), zero, zero, zero, zero, zero, zero, zero) if kinks else ()
        edge = (dr.zeros(mi.Bool), dr.zeros(mi.Bool), zero, zero, dr.zeros(mi.UInt32))
        return (dr.zeros(mi.Bool), zero, zero, zero, zero, zero, zero) + edge + kink

    found = dr.if_stmt((candidate,), candidate, search, nothing, label="scratch_family")
    eligible, dx, dy, pitch, offset, width, depth = found[:7]
    family = Family(eligible=eligible, dx=dx, dy=dy, pitch=pitch, a0=offset,
                    width=dr.maximum(width, profiles.MIN_WIDTH_UM), depth=dr.abs(depth),
                    triangular=depth < 0.0 if grid.triangular is None else grid.triangular)
    family.edge, family.edge_base, family.edge_a, family.edge_step, family.edge_tracks = found[7:12]
    if kinks:
        (family.kink, family.lone, family.b_pitch, family.b_dx, family.b_dy, family.b_a0, family.l_x, family.l_y,
         family.h) = found[12:]
    return family


def _pick(mask, a: _Slot, b: _Slot) -> _Slot:
    """``a``'s fields where ``mask``, else ``b``'s (fields that neither has stay None)."""
    return _Slot(*(x if x is None else dr.select(mask, x, y) for x, y in zip(a, b)))


def _on_line(other: _Slot, run: _Slot, shift_u, shift_v, sign):
    """``other``'s end line is ``sign`` × ``run``'s, ``run`` being stored in the cell (shift_u, shift_v)
    cells before ``other``'s (a line n·x = c there is n·x = c - n·shift here)."""
    offset = run.l_offset - (run.l_u * shift_u + run.l_v * shift_v)
    return ((dr.abs(other.l_u - sign * run.l_u) < LINE_NORMAL_TOLERANCE)
            & (dr.abs(other.l_v - sign * run.l_v) < LINE_NORMAL_TOLERANCE)
            & (dr.abs(other.l_offset - sign * offset) < LINE_OFFSET_TOLERANCE * run.pitch_cells)
            & ((run.l_u != 0.0) | (run.l_v != 0.0)))


def _sinc(x):
    return dr.select(dr.abs(x) < 1e-4, 1.0 - x * x * (1.0 / 6.0), dr.sin(x) / x)


def groove_transform(family: Family, mu, kappa, coherent: bool = True) -> Cx:
    """``G(μ) = ∫ (e^{iκp(v)} - 1) e^{2πiμv} dv`` over one groove (µm), per wavelength; ``coherent=False``:
    the transform of ``e^{iκp(v)}`` over the groove instead (the incoherent mode's, docs/model.md §4.2).
    The V-groove's facets cost only in SIMD packets that hold one."""
    width = family.width
    kind = type(mu)  # (the branches' arithmetic may widen the type; both must return the same one)
    box = 1.0 if coherent else 0.0

    def flat(mu, kappa):
        g = (expi(kappa) - box) * (width * _sinc(math.pi * mu * width))
        return kind(g.re), kind(g.im)

    def v_groove(mu, kappa):  # two facets of phase κ ± (2κ/W) v, less the box
        quarter = 0.25 * width
        plus = (2.0 * math.pi) * mu + 2.0 * kappa / width
        minus = (2.0 * math.pi) * mu - 2.0 * kappa / width
        facets = (expi(kappa - plus * quarter) * _sinc(plus * quarter)
                  + expi(kappa + minus * quarter) * _sinc(minus * quarter))
        g = facets * (0.5 * width)
        if coherent:
            g = g - width * _sinc(math.pi * mu * width)
        return kind(g.re), kind(g.im)

    re, im = dr.if_stmt((mu, kappa), family.triangular, v_groove, flat, label="scratch_family_groove")
    return Cx(re, im)


def _groove_intensity(family: Family, mu, kappa):
    """``|G'(μ)|²`` of :func:`groove_transform` (``coherent=False``): for a flat bottom ``(W sinc(πμW))²``,
    the phase e^{iκ} drops out."""
    kind = type(mu)

    def v_groove(mu, kappa):
        return (kind(groove_transform(family, mu, kappa, coherent=False).abs2()),)

    def flat(mu, kappa):
        return (kind(dr.square(family.width * _sinc(math.pi * mu * family.width))),)

    return dr.if_stmt((mu, kappa), family.triangular, v_groove, flat, label="scratch_family_groove_intensity")[0]


def family_field(family: Family, xi_x, xi_y, k_z, sigma) -> Cx:
    """``Σ_n S_n(ξ)`` over the family's infinite run (module docstring), per wavelength; at a kink, the
    sum of its two runs, each cut by the kink line's half-plane (docs/model.md §3.5)."""
    kappa = k_z * family.depth
    kind = type(xi_x)
    full = _run_field(family, family.pitch, family.dx, family.dy, family.a0, xi_x, xi_y, kappa, sigma)
    full = _at_edges(family, full, xi_x, xi_y, kappa, sigma, coherent=True)
    if family.kink is None:
        return full

    def cut_run(i, re, im):
        """Run A (i = 0) or B (i = 1), cut by its side of the kink line."""
        second = i == 1
        pick = lambda a, b: dr.select(second, b, a)
        side = dr.select(second, -1.0, 1.0)
        s = _run_field(family, pick(family.pitch, family.b_pitch), pick(family.dx, family.b_dx),
                       pick(family.dy, family.b_dy), pick(family.a0, family.b_a0), xi_x, xi_y, kappa, sigma,
                       cut=(side * family.l_x, side * family.l_y, side * family.h))
        return i + 1, kind(re + s.re), kind(im + s.im)

    # A loop of two turns on the kink lanes, none elsewhere: SIMD packets without a kink leave it at once.
    # A body this heavy still costs the kernel where it never runs (on the grating, had it kinks: +30 % per
    # query as a symbolic branch, +12 % as this loop, measured), hence no kink code for sets without kinks
    # (find_family); the loop also traces the body once for both runs
    turns = dr.select(family.kink, dr.select(family.lone, 1, 2), 0)
    _, re, im = dr.while_loop((dr.zeros(mi.UInt32), dr.zeros(kind), dr.zeros(kind)),
                              lambda i, re, im: i < turns, cut_run, label="scratch_family_kink")
    return Cx(dr.select(family.kink, re, full.re), dr.select(family.kink, im, full.im))


#: Gauss–Hermite nodes and weights (4 points) of the incoherent closed form's average over the squared
#: window's transform (:func:`family_intensity`) ...
HERMITE_NODES = (-1.6506801238857845, -0.5246476232752904, 0.5246476232752904, 1.6506801238857845)
HERMITE_WEIGHTS = (0.08131283544724518, 0.8049140900055128, 0.8049140900055128, 0.08131283544724518)
#: ... exact to 3e-4 (relative L2 over ν⊥) for grooves up to this many σ wide, to 1e-6 up to one σ;
#: wider grooves scan (incoherent mode only).
MAX_INCOHERENT_WIDTH_SIGMAS = 2.0
#: The 2-point rule (nodes ±1/√2) for grooves up to this many σ wide: exact to 6e-6 there (relative L2 over
#: ν⊥, flat and V-grooves; docs/model.md §3.5), as the 4-point one is to 1e-6 at one σ.
HERMITE_NODES_2 = (-0.7071067811865476, 0.7071067811865476)
HERMITE_WEIGHTS_2 = (0.8862269254527580, 0.8862269254527580)
NARROW_GROOVE_SIGMAS = 0.25


def family_intensity(family: Family, xi_x, xi_y, k_z, sigma):
    """``Σ_n |S'_n(ξ)|²`` over the family's infinite run: the incoherent mode's closed form (docs/model.md
    §3.5), per wavelength; at a kink the sum of its two runs, each cut by its side of the line.

    Poisson summation over the tracks' offsets leaves the order m = 0 alone (the others carry
    e^{-π²σ²m²/P²}, below 5e-5 where σ >= P): the along factor's square times
    (1/P) ∫ |A'(ν⊥; a)|² da = (σ√π/P) E[|G'(ν⊥ + η)|²] over η ~ N(0, 1/(8π²σ²)), the squared window's
    transform, which a 4-point Gauss–Hermite rule averages (``MAX_INCOHERENT_WIDTH_SIGMAS``)."""
    kappa = k_z * family.depth
    kind = type(xi_x)
    full = _run_intensity(family, family.pitch, family.dx, family.dy, xi_x, xi_y, kappa, sigma)
    full = _at_edges(family, full, xi_x, xi_y, kappa, sigma, coherent=False)
    if family.kink is None:
        return full

    def cut_run(i, total):
        """Run A (i = 0) or B (i = 1), cut by its side of the kink line."""
        second = i == 1
        pick = lambda a, b: dr.select(second, b, a)
        side = dr.select(second, -1.0, 1.0)
        run = _run_intensity(family, pick(family.pitch, family.b_pitch), pick(family.dx, family.b_dx),
                             pick(family.dy, family.b_dy), xi_x, xi_y, kappa, sigma,
                             cut=(side * family.l_x, side * family.l_y, side * family.h))
        return i + 1, kind(total + run)

    # (a loop on the kink lanes only, as in family_field)
    turns = dr.select(family.kink, dr.select(family.lone, 1, 2), 0)
    _, total = dr.while_loop((dr.zeros(mi.UInt32), dr.zeros(kind)), lambda i, total: i < turns, cut_run,
                             label="scratch_family_kink_intensity")
    return dr.select(family.kink, total, full)


def _edge_sum(family: Family, term, initial):
    """``edge_sign × Σ term(a)`` over an edge lane's tracks, offsets ``a = edge_a + j · edge_step`` (µm), added
    to ``initial`` (a tuple); the loop runs no turn on other lanes (SIMD packets without an edge skip it)."""
    def body(j, *total):
        terms = term(family.edge_a + mi.Float(j) * family.edge_step)
        return (j + 1,) + tuple(type(t)(t + x) for t, x in zip(total, terms))

    zeros = tuple(dr.zeros(type(x)) for x in initial)
    sums = dr.while_loop((dr.zeros(mi.UInt32),) + zeros, lambda j, *total: j < family.edge_tracks, body,
                         label="scratch_family_edge")[1:]
    return tuple(type(x)(dr.select(family.edge_base, x - t, t)) for x, t in zip(initial, sums))


def _at_edges(family: Family, full, xi_x, xi_y, kappa, sigma, coherent: bool):
    """The run's sum ``full`` (field or intensity), at an edge the sum over its tracks in reach instead
    (:func:`_edge_sum`; docs/model.md §3.5, Edges): each track a whole line across the window, its windowed
    groove transform (:func:`.segment.cross_section`, as the scan's) times the Gaussian along."""
    nu_par = xi_x * family.dx + xi_y * family.dy
    nu_perp = xi_y * family.dx - xi_x * family.dy
    kind = type(xi_x)
    zero = dr.zeros(mi.Float)

    def track(a):  # (c and length: not read across)
        return SegmentGeometry(c=zero, length=zero, a_perp=a, dx=family.dx, dy=family.dy, width=family.width,
                               depth=family.depth, triangular=family.triangular)

    if coherent:
        along = math.sqrt(2.0 * math.pi) * sigma * dr.exp((-2.0 * math.pi ** 2) * sigma * sigma * nu_par * nu_par)

        def term(a):
            s = cross_section(track(a), nu_perp, kappa, sigma, True)
            return kind(s.re * along), kind(s.im * along)

        re, im = _edge_sum(family, term, (full.re, full.im))
        return Cx(dr.select(family.edge, re, full.re), dr.select(family.edge, im, full.im))
    along2 = (2.0 * math.pi) * sigma * sigma * dr.exp((-4.0 * math.pi ** 2) * sigma * sigma * nu_par * nu_par)

    def term(a):
        return (kind(cross_section(track(a), nu_perp, kappa, sigma, False).abs2() * along2),)

    return dr.select(family.edge, _edge_sum(family, term, (full,))[0], full)


def _run_intensity(family: Family, pitch, dx, dy, xi_x, xi_y, kappa, sigma, cut=None):
    """One run's ``Σ_n |S'_n(ξ)|²`` (:func:`family_intensity`).  ``cut = (l_x, l_y, h)``: only the half-plane
    y·l >= h of each track (y = x - x0).  Track n then ends where it meets the line, at a point that
    moves along it with the track's offset a: its along factor |Φ|² is averaged over a with the
    weight e^{-a²/σ²} of the tracks' squared window across (Gauss–Hermite again).  That leaves out
    |A'(ν⊥; a)|²'s own shape in a: its spread, of order (W/σ)² tan²θ (θ the line's angle to the tracks'
    normal), and its odd part (V-grooves), of order tan θ (docs/model.md §3.5)."""
    nu_par = xi_x * dx + xi_y * dy
    nu_perp = xi_y * dx - xi_x * dy
    spread = 1.0 / (2.0 * math.pi) * dr.rcp(sigma)  # √2 × the std of η
    kind = type(xi_x)

    def average(nodes, weights):
        def rule(nu_perp, kappa):
            total = dr.zeros(kind)
            for node, weight in zip(nodes, weights):
                total += weight * _groove_intensity(family, nu_perp + node * spread, kappa)
            return (kind(total),)
        return rule

    def across_tracks(nu_perp, kappa):
        # (the 2-point rule where it is as exact as the scan's own sums: half the groove transforms; whole
        # SIMD packets of narrow grooves skip the 4-point one)
        narrow = family.width <= NARROW_GROOVE_SIGMAS * sigma
        across = dr.if_stmt((nu_perp, kappa), narrow, average(HERMITE_NODES_2, HERMITE_WEIGHTS_2),
                            average(HERMITE_NODES, HERMITE_WEIGHTS), label="scratch_family_across")[0]
        return across * (sigma * dr.rcp(pitch))

    if cut is None:
        along = (2.0 * math.pi) * sigma * sigma * dr.exp((-4.0 * math.pi ** 2) * sigma * sigma * nu_par * nu_par)
        # off the tracks' diffraction line (ν∥ beyond ~1.6/σ: most light samples of a world emitter) the along
        # factor is 0 in float32 at every wavelength: whole SIMD packets there skip the groove transforms
        positive = along > 0.0
        lit = positive if dr.depth_v(positive) == 1 else functools.reduce(operator.or_, positive)
        return dr.if_stmt((nu_perp, kappa, along), lit,
                          lambda nu_perp, kappa, along: (kind(across_tracks(nu_perp, kappa) * along),),
                          lambda nu_perp, kappa, along: (dr.zeros(kind),), label="scratch_family_lit")[0]
    across = across_tracks(nu_perp, kappa)
    l_x, l_y, h = cut
    l_t = l_x * dx + l_y * dy  # |l·t| >= KINK_MIN_COS
    l_n = l_y * dx - l_x * dy  # l·n, n = (-dy, dx)
    forward = l_t > 0.0  # the kept part of a track: s >= its end (forward) or s <= it
    inv_l_t = dr.rcp(l_t)
    along = dr.zeros(type(xi_x))
    for node, weight in zip(HERMITE_NODES, HERMITE_WEIGHTS):
        end = (h - (node * sigma) * l_n) * inv_l_t  # where the track at offset a = σ·node meets the line
        phi = window_integral(dr.select(forward, end, -_FAR), dr.select(forward, _FAR, end), nu_par, sigma)
        along += weight * phi.abs2()
    return across * along * (1.0 / math.sqrt(math.pi))


#: Beyond any window (µm): an open end of an integral along a track (window_integral clamps it to 8σ).
_FAR = 1e30


def _run_field(family: Family, pitch, dx, dy, a0, xi_x, xi_y, kappa, sigma, cut=None) -> Cx:
    """One run's ``Σ_n S_n(ξ)``: the order nearest to the window's peak, and its two neighbours where
    σ < ``ONE_ORDER_SIGMA_PER_PITCH`` P (beyond, they lie more than 0.9/σ away: below e^-16 of the
    window's peak).  ``cut = (l_x, l_y, h)``: only the half-plane y·l >= h of the run (y = x - x0)."""
    nu_par = xi_x * dx + xi_y * dy
    nu_perp = xi_y * dx - xi_x * dy
    sigma2 = sigma * sigma
    gauss = math.sqrt(2.0 * math.pi) * sigma
    inv_pitch = dr.rcp(pitch)
    if cut is None:
        along = gauss * dr.exp((-2.0 * math.pi ** 2) * sigma2 * nu_par * nu_par)
        nearest = dr.round(-nu_perp * pitch)
        spacing = 1.0
    else:
        # an order's frequency K = ν∥ t + (ν⊥ + m/P) n has the components k_l along l (cut: the half-plane
        # integral) and k_c along the line (whole: a Gaussian); the orders lie |l·t|/P apart in k_c
        l_x, l_y, h = cut
        l_t = l_x * dx + l_y * dy  # = l⊥·n, l⊥ = (-l_y, l_x), n = (-dy, dx); |l·t| >= KINK_MIN_COS
        l_n = l_y * dx - l_x * dy  # l·n = -(l⊥·t)
        nearest = dr.round(-(nu_perp - nu_par * l_n * dr.rcp(l_t)) * pitch)
        spacing = dr.abs(l_t)

    def order_term(order):
        mu = order * inv_pitch
        eta = nu_perp + mu
        phase = expi((2.0 * math.pi) * order * a0 * inv_pitch)
        if cut is None:  # (the along factor is common to all orders: applied once, below)
            window = gauss * dr.exp((-2.0 * math.pi ** 2) * sigma2 * eta * eta)
            return groove_transform(family, mu, kappa) * phase * window
        k_l = nu_par * l_t + eta * l_n
        k_c = eta * l_t - nu_par * l_n
        window = _half_plane(k_l, h, sigma) * (gauss * dr.exp((-2.0 * math.pi ** 2) * sigma2 * k_c * k_c))
        return groove_transform(family, mu, kappa) * phase * window

    def neighbours(nearest):
        both = order_term(nearest - 1.0) + order_term(nearest + 1.0)
        return type(nearest)(both.re), type(nearest)(both.im)

    def none(nearest):
        return dr.zeros(type(nearest)), dr.zeros(type(nearest))

    wide = sigma * spacing < ONE_ORDER_SIGMA_PER_PITCH * pitch
    total = order_term(nearest) + Cx(*dr.if_stmt((nearest,), wide, neighbours, none, label="scratch_family_orders"))
    return total * (inv_pitch if cut is not None else along * inv_pitch)


def _half_plane(k, h, sigma) -> Cx:
    """``∫_{α >= h} e^{-α²/2σ²} e^{HALF_PLANE_SIGN 2πikα} dα``: the window across a kink line, cut at h.

    ``σ√(π/2) e^{-h²/2σ²} e^{2πikh} w((2πσ²k + ih)/(√2σ))`` for h >= 0 (Faddeeva's w, bounded in the
    upper half plane), and the whole integral ``σ√(2π) e^{-2π²σ²k²}`` less the mirrored one for h < 0
    (docs/model.md §3.5)."""
    k = k * HALF_PLANE_SIGN
    positive = h >= 0.0
    distance = dr.abs(h)
    flipped = dr.select(positive, k, -k)
    inv = dr.rcp(math.sqrt(2.0) * sigma)
    w = faddeeva(Cx((2.0 * math.pi) * sigma * sigma * flipped * inv, distance * inv))
    part = w * expi((2.0 * math.pi) * k * h) * (math.sqrt(0.5 * math.pi) * sigma
                                                 * dr.exp(-0.5 * dr.square(distance / sigma)))
    whole = math.sqrt(2.0 * math.pi) * sigma * dr.exp((-2.0 * math.pi ** 2) * sigma * sigma * k * k)
    return Cx(dr.select(positive, part.re, whole - part.re), dr.select(positive, part.im, -part.im))


def run_energies(family: Family, sigma):
    """``(A, B)``: ``Σ_n ε_n`` of :func:`.sampling.window_energy` over each run (Poisson summation of
    e^{-a_n²/σ²}); at a kink each is cut to its side of the line (the
    squared window's share there, ½ erfc(±h/σ)), elsewhere B is 0."""
    a = _run_energy(family, family.pitch, family.a0, sigma)
    # at an edge: each track in reach a whole line, ε = W σ√π e^{-a²/σ²} (sampling.window_energy)
    inv = dr.rcp(sigma)
    edge = _edge_sum(family, lambda t: (family.width * math.sqrt(math.pi) * sigma * dr.exp(-dr.square(t * inv)),),
                     (a,))[0]
    a = dr.select(family.edge, edge, a)
    if family.kink is None:
        return a, dr.zeros(mi.Float)
    side = 0.5 - 0.5 * dr.erf(family.h * dr.rcp(sigma))  # share of w² on A's side, y·l >= h
    b = _run_energy(family, family.b_pitch, family.b_a0, sigma)
    return dr.select(family.kink, a * side, a), dr.select(family.kink & ~family.lone, b * (1.0 - side), 0.0)


def _run_energy(family: Family, pitch, a0, sigma):
    ratio = sigma * dr.rcp(pitch)
    tracks = math.sqrt(math.pi) * ratio * (1.0 + 2.0 * dr.exp(-(math.pi ** 2) * ratio * ratio)
                                           * dr.cos((2.0 * math.pi) * a0 * dr.rcp(pitch)))
    return family.width * math.sqrt(math.pi) * sigma * tracks
