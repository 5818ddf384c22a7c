"""Finding the segments inside a shading point's coherence window (Dr.Jit side).

:func:`for_each_segment` runs nested symbolic ``dr.while_loop`` calls over the
cells of :mod:`.tables` that the window's UV bounding box touches, cell by
cell, and over each cell's references.  A referenced piece is handed to the
caller when its centre line passes within the window radius **and** its point
closest to the shading point lies in the cell being visited: a piece listed in
several visited cells is thus evaluated exactly once (that point lies inside
the window, hence inside the visited box, and the piece is listed in its
cell).  Counts and sizes are array data, never Python literals, so a scratch
set of another size reuses the compiled kernels.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import drjit as dr
import mitsuba as mi

from .segment import SegmentGeometry
from .tables import GridTables, aligned

__all__ = ["Grid", "LocalJacobian", "for_each_segment", "for_each_crossing", "jacobian", "segment_at"]

#: Cells with more references than this are bisected by offset; shorter ones are scanned.
BISECT_ABOVE = 6


@dataclass
class Grid:
    """The tables of :class:`.tables.GridTables` as Dr.Jit arrays of the active variant."""

    segments: object  #: mi.Float, 8 per piece
    references: object  #: mi.UInt32, piece indices grouped by cell, sorted by offset
    offsets: object  #: mi.Float, lowest offset of each reference's in-cell part along the cell normal
    cell_frames: object  #: mi.Float, 4 per cell: normal (u, v), largest offset spread, 0
    cell_start: object  #: mi.UInt32
    origin_u: object  #: opaque mi.Float scalars ...
    origin_v: object
    inverse_cell_size: object
    margin: object  #: query padding (cells): the tables' dilation
    cells_u: object  #: opaque mi.Int32 scalars
    cells_v: object
    crossing_start: object = None  #: mi.UInt32, CSR starts of each piece's crossing partners
    crossing_partner: object = None  #: mi.UInt32
    crossing_along: object = None  #: mi.Float, each crossing's parameter along its lower piece
    max_width: object = None  #: opaque mi.Float: the widest piece's W (µm), the reach of a triple query

    @classmethod
    def upload(cls, tables: GridTables) -> "Grid":
        return cls(
            segments=_owned(mi.Float, tables.segments.ravel()),
            references=_owned(mi.UInt32, tables.references),
            offsets=_owned(mi.Float, tables.offsets),
            cell_frames=_owned(mi.Float, tables.cell_frames.ravel()),
            cell_start=_owned(mi.UInt32, tables.cell_start),
            origin_u=dr.opaque(mi.Float, tables.origin[0]),
            origin_v=dr.opaque(mi.Float, tables.origin[1]),
            inverse_cell_size=dr.opaque(mi.Float, 1.0 / tables.cell_size),
            margin=dr.opaque(mi.Float, tables.margin),
            cells_u=dr.opaque(mi.Int32, tables.shape[0]),
            cells_v=dr.opaque(mi.Int32, tables.shape[1]),
            crossing_start=_owned(mi.UInt32, tables.crossing_start),
            crossing_partner=_owned(mi.UInt32, tables.crossing_partner),
            crossing_along=_owned(mi.Float, tables.crossing_along),
            max_width=dr.opaque(mi.Float, float(tables.segments[:tables.piece_count, 6].max(initial=0.0))))


def _owned(kind, array):
    """A Dr.Jit array of a numpy array, 64-byte aligned.

    On the CPU Dr.Jit maps numpy's memory without copying, and the alignment
    decides whether it emits packet gathers: the kernels would then differ
    (and be compiled again) from one scratch set to the next.  An unaligned
    array is copied into an aligned buffer first (the tables come aligned).
    """
    return kind(aligned(array))


@dataclass
class LocalJacobian:
    """UV → local-frame micrometres at the shading point: ``Δx = J Δuv``."""

    uv: object  #: mi.Point2f, the shading point x0
    j00: object
    j01: object
    j10: object
    j11: object


def jacobian(si, micrometres_per_unit) -> LocalJacobian:
    """From ``si.dp_du``, ``si.dp_dv`` (scene units per UV) projected on ``si.sh_frame``."""
    s, t = si.sh_frame.s, si.sh_frame.t
    scale = micrometres_per_unit
    return LocalJacobian(uv=si.uv,
                         j00=dr.dot(si.dp_du, s) * scale, j01=dr.dot(si.dp_dv, s) * scale,
                         j10=dr.dot(si.dp_du, t) * scale, j11=dr.dot(si.dp_dv, t) * scale)


def _cell_range(grid: Grid, jac: LocalJacobian, radius, active):
    """Cell bounds [u0, u1] x [v0, v1] of the padded window box, and whether there is one."""
    det = jac.j00 * jac.j11 - jac.j01 * jac.j10
    norm2 = jac.j00 * jac.j00 + jac.j01 * jac.j01 + jac.j10 * jac.j10 + jac.j11 * jac.j11
    usable = active & (dr.abs(det) > 1e-12 * norm2)
    inv_det = dr.rcp(dr.select(usable, dr.abs(det), 1.0))
    # Half extents of the ellipse {Δuv : |J Δuv| <= R}: R |row of J⁻¹|, in cells.
    scale = radius * inv_det * grid.inverse_cell_size
    extent_u = scale * dr.sqrt(jac.j11 * jac.j11 + jac.j01 * jac.j01) + grid.margin
    extent_v = scale * dr.sqrt(jac.j10 * jac.j10 + jac.j00 * jac.j00) + grid.margin
    gu = (jac.uv.x - grid.origin_u) * grid.inverse_cell_size
    gv = (jac.uv.y - grid.origin_v) * grid.inverse_cell_size
    usable &= dr.isfinite(extent_u) & dr.isfinite(extent_v) & dr.isfinite(gu) & dr.isfinite(gv)

    def cell(x, cells):  # clamp before the integer conversion: extents may be huge
        return mi.Int32(dr.floor(dr.clip(x, -1.0, mi.Float(cells))))

    u0, u1 = cell(gu - extent_u, grid.cells_u), cell(gu + extent_u, grid.cells_u)
    v0, v1 = cell(gv - extent_v, grid.cells_v), cell(gv + extent_v, grid.cells_v)
    usable &= (u1 >= 0) & (v1 >= 0) & (u0 < grid.cells_u) & (v0 < grid.cells_v)
    u0, v0 = dr.maximum(u0, 0), dr.maximum(v0, 0)
    u1, v1 = dr.minimum(u1, grid.cells_u - 1), dr.minimum(v1, grid.cells_v - 1)
    return u0, u1, v0, v1, gu, gv, scale, usable


def for_each_segment(grid: Grid, jac: LocalJacobian, radius, state: tuple,
                     body: Callable, active) -> tuple:
    """Fold ``body`` over the pieces whose centre line passes within ``radius`` (µm) of x0.

    ``body(segment: SegmentGeometry, piece: mi.UInt32, state) -> state`` is
    called (symbolically) for the lanes that hold such a piece, once per piece.
    ``state`` is a tuple of Dr.Jit arrays; the final state is returned.

    Per visited cell, only the references whose offset along the cell's normal
    can reach the window are tested: a binary search finds the first one at or
    above ``q - R_n - spread`` (q: x0's offset, R_n: the window's half width
    along the normal), the scan stops above ``q + R_n``.  Two nested loops keep
    the SIMD lanes in step: the inner one only searches and scans (a few
    gathers and multiplications per step) until every lane has found its next
    piece or run out of cells, the outer one then calls ``body`` once for all
    of them.  The expensive body thus runs as often as the lane with the most
    pieces in its window needs, not once per reference tested.
    """
    u0, u1, v0, v1, gu, gv, scale, usable = _cell_range(grid, jac, radius, active)
    radius2 = radius * radius
    zero_i = mi.Int32(0)
    u1, v1 = dr.select(usable, u1, zero_i), dr.select(usable, v1, zero_i)
    u_first = dr.select(usable, u0 - 1, zero_i)  # the first step enters cell (u0, v0)
    v_first = dr.select(usable, v0, zero_i)

    def more(u, v, index, end):
        return (index < end) | (u < u1) | (v < v1)

    def scan_step(u, v, index, end, search_end, searching, lo_key, hi_key, found, piece, segment):
        searching = searching & (index < search_end)
        testing = ~searching & (index < end)
        advance = ~searching & ~testing & ((u < u1) | (v < v1))
        # ---- bisection (first reference with offset >= lo_key) and scan share one gather
        middle = (index + search_end) >> 1
        key = dr.gather(mi.Float, grid.offsets, dr.select(searching, middle, index), searching | testing)
        right = searching & (key < lo_key)
        search_end = dr.select(searching & ~right, middle, search_end)
        index = dr.select(right, middle + 1, index)
        # ---- scanning lanes test one reference; past hi_key the cell is done
        testing &= key <= hi_key
        index = dr.select(~searching & ~testing & ~advance & (index < end), end, index)
        piece = dr.gather(mi.UInt32, grid.references, index, testing)
        segment, inside, closest_u, closest_v = _piece_geometry(grid, jac, piece, radius2, testing)
        owner_u = mi.Int32(dr.floor(dr.clip(gu + closest_u * grid.inverse_cell_size, 0.0,
                                             mi.Float(grid.cells_u - 1))))
        owner_v = mi.Int32(dr.floor(dr.clip(gv + closest_v * grid.inverse_cell_size, 0.0,
                                             mi.Float(grid.cells_v - 1))))
        found = testing & inside & (owner_u == u) & (owner_v == v)
        index = dr.select(testing & ~found, index + 1, index)
        # ---- lanes done with their cell enter the next one (the next row after u1)
        new_row = u >= u1
        u = dr.select(advance, dr.select(new_row, u0, u + 1), u)
        v = dr.select(advance & new_row, v + 1, v)
        cell = mi.UInt32(v * grid.cells_u + u)
        first = dr.gather(mi.UInt32, grid.cell_start, cell, advance)
        last = dr.gather(mi.UInt32, grid.cell_start, cell + 1, advance)
        frame = dr.gather(mi.Vector4f, grid.cell_frames, cell, advance)
        q = frame.x * (gu - mi.Float(u)) + frame.y * (gv - mi.Float(v))
        half_width = scale * dr.sqrt(dr.square(jac.j11 * frame.x - jac.j10 * frame.y)
                                     + dr.square(jac.j00 * frame.y - jac.j01 * frame.x)) + grid.margin
        index = dr.select(advance, first, index)
        end = dr.select(advance, last, end)
        search_end = dr.select(advance, last, search_end)
        # bisect only where it saves steps: a short cell is scanned from its start
        searching = searching | (advance & (last - first > BISECT_ABOVE))
        lo_key = dr.select(advance, q - half_width - frame.z, lo_key)
        hi_key = dr.select(advance, q + half_width, hi_key)
        return u, v, index, end, search_end, searching, lo_key, hi_key, found, piece, tuple(segment)

    empty = tuple(dr.zeros(mi.Float) for _ in range(7)) + (dr.zeros(mi.Bool),)

    def visit(u, v, index, end, search_end, searching, lo_key, hi_key, user):
        u, v, index, end, search_end, searching, lo_key, hi_key, found, piece, segment = dr.while_loop(
            (u, v, index, end, search_end, searching, lo_key, hi_key, dr.zeros(mi.Bool),
             dr.zeros(mi.UInt32), empty),
            lambda u, v, index, end, search_end, searching, lo_key, hi_key, found, piece, segment:
                ~found & more(u, v, index, end),
            scan_step, label="scratch_scan")
        segment = SegmentGeometry(*segment)
        user = dr.if_stmt((segment, piece, user), found,
                          lambda segment, piece, user: body(segment, piece, user),
                          lambda segment, piece, user: user, label="scratch_segment")
        return u, v, dr.select(found, index + 1, index), end, search_end, searching, lo_key, hi_key, user

    zero_u, zero_f = dr.zeros(mi.UInt32), dr.zeros(mi.Float)
    return dr.while_loop((u_first, v_first, zero_u, zero_u, zero_u, dr.zeros(mi.Bool), zero_f, zero_f, state),
                         lambda u, v, index, end, search_end, searching, lo_key, hi_key, user:
                             more(u, v, index, end),
                         visit, label="scratch_pieces")[8]


def for_each_crossing(grid: Grid, jac: LocalJacobian, piece, segment: SegmentGeometry, radius, state: tuple,
                      body: Callable) -> tuple:
    """Fold ``body(partner: SegmentGeometry, partner_piece, crossing_uv, state) -> state`` over the crossings
    of ``piece`` within ``radius`` (``crossing_uv``: the mi.Point2f where the centre lines cross).

    The pairs are listed once, under the piece of lower index (:mod:`.crossings`),
    so folding this over every piece found by :func:`for_each_segment` visits
    each crossing pair whose crossing point lies within ``radius`` of x0 once
    (that point lies on the lower piece, which then passes within the radius).
    A piece's crossings are sorted by their parameter t along it, and a crossing
    lies at ``c + t L`` from x0's foot point: a bisection finds the first one
    inside the window, the scan stops after the last.
    """
    first = dr.gather(mi.UInt32, grid.crossing_start, piece)
    last = dr.gather(mi.UInt32, grid.crossing_start, piece + 1)
    half_chord = dr.safe_sqrt(radius * radius - segment.a_perp * segment.a_perp)
    inv_length = dr.rcp(dr.maximum(segment.length, 1e-6))
    t_lo = (-segment.c - half_chord) * inv_length
    t_hi = (-segment.c + half_chord) * inv_length

    def bisect(lo, hi):
        middle = (lo + hi) >> 1
        right = dr.gather(mi.Float, grid.crossing_along, middle) < t_lo
        return dr.select(right, middle + 1, lo), dr.select(right, hi, middle)

    start = dr.while_loop((first, last), lambda lo, hi: lo < hi, bisect, label="scratch_crossing_search")[0]
    head = dr.gather(mi.Vector4f, grid.segments, 2 * piece)
    tail = dr.gather(mi.Vector4f, grid.segments, 2 * piece + 1)

    def inside(index, user):
        return (index < last) & (dr.gather(mi.Float, grid.crossing_along, index, index < last) <= t_hi)

    def step(index, user):
        partner = dr.gather(mi.UInt32, grid.crossing_partner, index)
        t = dr.gather(mi.Float, grid.crossing_along, index)
        crossing_uv = mi.Point2f(dr.fma(t, tail.x, head.x) + head.z, dr.fma(t, tail.y, head.y) + head.w)
        return index + 1, body(segment_at(grid, jac, partner, True), partner, crossing_uv, user)

    return dr.while_loop((start, state), inside, step, label="scratch_crossings")[1]


def segment_at(grid: Grid, jac: LocalJacobian, piece, active) -> SegmentGeometry:
    """Geometry of piece ``piece`` seen from the shading point."""
    return _piece_geometry(grid, jac, piece, 0.0, active)[0]


def _piece_geometry(grid: Grid, jac: LocalJacobian, piece, radius2, active):
    """The piece seen from x0 (local frame, µm), whether it passes within the window radius,
    and its point closest to x0 relative to x0 (UV)."""
    head = dr.gather(mi.Vector4f, grid.segments, 2 * piece, active)  # a_hi, a_lo
    tail = dr.gather(mi.Vector4f, grid.segments, 2 * piece + 1, active)  # e (UV), W (µm), ±D (µm)
    du = (head.x - jac.uv.x) + head.z
    dv = (head.y - jac.uv.y) + head.w
    ax = dr.fma(jac.j00, du, jac.j01 * dv)
    ay = dr.fma(jac.j10, du, jac.j11 * dv)
    ex = dr.fma(jac.j00, tail.x, jac.j01 * tail.y)
    ey = dr.fma(jac.j10, tail.x, jac.j11 * tail.y)
    length = dr.sqrt(dr.fma(ex, ex, ey * ey))
    usable = active & (length > 1e-6)
    inv_length = dr.rcp(dr.select(usable, length, 1.0))
    dx, dy = ex * inv_length, ey * inv_length
    c = dr.fma(ax, dx, ay * dy)
    a_perp = dr.fma(ay, dx, -ax * dy)
    along = dr.clip(-c, 0.0, length)  # closest point of the piece to x0
    distance2 = dr.fma(a_perp, a_perp, dr.square(c + along))
    segment = SegmentGeometry(c=c, length=length, a_perp=a_perp, dx=dx, dy=dy,
                              width=tail.z, depth=dr.abs(tail.w), triangular=tail.w < 0.0)
    t = along * inv_length  # the closest point's parameter: the same in UV as in the local frame
    closest_u = dr.fma(t, tail.x, du)
    closest_v = dr.fma(t, tail.y, dv)
    return segment, usable & (distance2 < radius2), closest_u, closest_v
