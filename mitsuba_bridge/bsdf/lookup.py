"""Finding the segments inside a shading point's coherence window (Dr.Jit side).

:func:`for_each_segment` runs nested symbolic ``dr.while_loop`` calls over the grid of
:mod:`.tables`: over the rows of cells that the window's UV bounding box
(padded by half a cell, the pieces' reach beyond their cell) touches, each row
being one contiguous range of the sorted segment table.  Pieces whose centre
line passes within the window radius are handed to the caller.  Counts and
sizes are array data, never Python literals, so a scratch set of another size
reuses the compiled kernels.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import drjit as dr
import mitsuba as mi

from .segment import SegmentGeometry
from .tables import GridTables, aligned

__all__ = ["Grid", "LocalJacobian", "for_each_segment", "jacobian", "segment_at"]


@dataclass
class Grid:
    """The tables of :class:`.tables.GridTables` as Dr.Jit arrays of the active variant."""

    segments: object  #: mi.Float, 8 per piece
    cell_start: object  #: mi.UInt32
    origin_u: object  #: opaque mi.Float scalars ...
    origin_v: object
    inverse_cell_size: object
    margin: object  #: query padding (cells)
    cells_u: object  #: opaque mi.Int32 scalars
    cells_v: object

    @classmethod
    def upload(cls, tables: GridTables) -> "Grid":
        return cls(
            segments=_owned(mi.Float, tables.segments.ravel()),
            cell_start=_owned(mi.UInt32, tables.cell_start),
            origin_u=dr.opaque(mi.Float, tables.origin[0]),
            origin_v=dr.opaque(mi.Float, tables.origin[1]),
            inverse_cell_size=dr.opaque(mi.Float, 1.0 / tables.cell_size),
            margin=dr.opaque(mi.Float, tables.margin),
            cells_u=dr.opaque(mi.Int32, tables.shape[0]),
            cells_v=dr.opaque(mi.Int32, tables.shape[1]))


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
    return u0, u1, v0, v1, usable


def for_each_segment(grid: Grid, jac: LocalJacobian, radius, state: tuple,
                     body: Callable, active) -> tuple:
    """Fold ``body`` over the pieces whose centre line passes within ``radius`` (µm) of x0.

    ``body(segment: SegmentGeometry, piece: mi.UInt32, state) -> state`` is
    called (symbolically) for the lanes that hold such a piece.  ``state`` is a
    tuple of Dr.Jit arrays; the final state is returned.

    Two nested loops keep the SIMD lanes in step: the inner one only scans (a
    few gathers and multiplications per piece) until every lane has found its
    next piece inside the window or run out, the outer one then calls ``body``
    once for all of them.  The expensive body thus runs as often as the lane
    with the most pieces in its window needs, not once per piece tested.
    """
    u0, u1, v0, v1, usable = _cell_range(grid, jac, radius, active)
    radius2 = radius * radius

    def row_range(v, active):
        first = mi.UInt32(v * grid.cells_u + u0)
        last = mi.UInt32(v * grid.cells_u + u1 + 1)
        return (dr.gather(mi.UInt32, grid.cell_start, first, active),
                dr.gather(mi.UInt32, grid.cell_start, last, active))

    start, end = row_range(v0, usable)
    rows_left = dr.select(usable, mi.UInt32(v1 - v0), 0)

    def more(index, end, rows_left):
        return (index < end) | (rows_left > 0)

    def scan_step(v, index, end, rows_left, found, segment):
        in_row = index < end
        # ---- lanes done with their row load the next one
        advance = ~in_row & (rows_left > 0)
        next_start, next_end = row_range(v + 1, advance)
        # ---- lanes inside a row test one piece and stop on a hit
        segment, inside = _piece_geometry(grid, jac, index, radius2, in_row)
        found = in_row & inside
        index = dr.select(advance, next_start, dr.select(in_row & ~found, index + 1, index))
        end = dr.select(advance, next_end, end)
        v = dr.select(advance, v + 1, v)
        rows_left = dr.select(advance, rows_left - 1, rows_left)
        return v, index, end, rows_left, found, tuple(segment)

    empty = tuple(dr.zeros(mi.Float) for _ in range(7)) + (dr.zeros(mi.Bool),)

    def visit(v, index, end, rows_left, user):
        v, index, end, rows_left, found, segment = dr.while_loop(
            (v, index, end, rows_left, dr.zeros(mi.Bool), empty),
            lambda v, index, end, rows_left, found, segment: ~found & more(index, end, rows_left),
            scan_step, label="scratch_scan")
        segment = SegmentGeometry(*segment)
        user = dr.if_stmt((segment, index, user), found,
                          lambda segment, piece, user: body(segment, piece, user),
                          lambda segment, piece, user: user, label="scratch_segment")
        return v, dr.select(found, index + 1, index), end, rows_left, user

    return dr.while_loop((v0, start, end, rows_left, state),
                         lambda v, index, end, rows_left, user: more(index, end, rows_left),
                         visit, label="scratch_pieces")[4]


def segment_at(grid: Grid, jac: LocalJacobian, piece, active) -> SegmentGeometry:
    """Geometry of piece ``piece`` seen from the shading point."""
    return _piece_geometry(grid, jac, piece, 0.0, active)[0]


def _piece_geometry(grid: Grid, jac: LocalJacobian, piece, radius2, active):
    """The piece seen from x0 (local frame, µm), and whether it passes within the window radius."""
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
    return segment, usable & (distance2 < radius2)
