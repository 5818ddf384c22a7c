"""Finding the segments inside a shading point's coherence window (Dr.Jit side).

:func:`for_each_segment` runs nested symbolic ``dr.while_loop`` calls over the
cells of :mod:`.tables` that the window's UV bounding box touches, cell by
cell, and over each cell's references.  Each cell's references are sorted by
their offset along the cell's normal and grouped into **offset buckets** of a
few references each (:func:`.tables.scan.offset_buckets`, built when the tables are
uploaded): a query jumps to the bucket of the lowest offset that can reach its
window and scans until the offsets pass the highest, so dense parallel tracks
cost about the pieces inside the window.  A referenced piece is handed to the
caller when its centre line passes within the window radius **and** its point
closest to the shading point lies in the cell being visited: a piece listed in
several visited cells is thus evaluated exactly once (that point lies inside
the window, hence inside the visited box, and the piece is listed in its
cell).  Counts and sizes are array data, never Python literals, so a scratch
set of another size reuses the compiled kernels.  Lanes whose window lies in a
periodic family (:mod:`.periodic`, found when the tables are uploaded) skip the
search: their tracks are summed in closed form.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import drjit as dr
import mitsuba as mi

from .maths.segment import SegmentGeometry
from .tables.grid import CELL_DILATION, GridTables
from .tables.references import aligned_array
from .tables.scan import BUCKET_REFERENCES, ScanArrays, profiles_of, relative_continuation

__all__ = ["Grid", "LocalJacobian", "for_each_segment", "replay_pieces", "for_each_crossing", "jacobian",
           "segment_at"]

#: Padding (cells) of the offset interval a cell's scan covers, against float32 rounding: the
#: offsets are float32 values of at most ~1.5 cells, x0's offset carries the rounding of its cell
#: coordinate (the tables' margin less their dilation covers that, relative 1e-6 of the UV extent).
OFFSET_PADDING = 1e-3


@dataclass
class Grid:
    """The tables of :class:`.tables.GridTables` as Dr.Jit arrays of the active variant."""

    segments: object  #: mi.Float, 8 per piece
    references: object  #: mi.UInt32, piece indices grouped by cell, sorted by offset
    offsets: object  #: mi.Float, lowest offset of each reference's in-cell part along the cell normal
    #: mi.Float, 4 per cell: normal (u, v), then (bucketed) lowest offset + offset spread, buckets per offset
    scan_frames: object
    cell_start: object  #: mi.UInt32, first reference of each cell (cells + 1, CSR)
    cell_bucket: object  #: mi.UInt32, first offset bucket of each cell
    bucket_start: object  #: mi.UInt32, first reference of each bucket (buckets + 1)
    origin_u: object  #: opaque mi.Float scalars ...
    origin_v: object
    inverse_cell_size: object
    margin: object  #: query padding (cells): the tables' dilation
    offset_padding: object  #: padding (cells) of each cell's offset interval
    cells_u: object  #: opaque mi.Int32 scalars
    cells_v: object
    crossing_start: object = None  #: mi.UInt32, CSR starts of each piece's crossing partners
    crossing_partner: object = None  #: mi.UInt32
    crossing_along: object = None  #: mi.Float, each crossing's parameter along its lower piece
    max_width: object = None  #: opaque mi.Float: the widest piece's W (µm), the reach of a triple query
    #: scan from the offset bucket of the window (dense cells) or from each cell's start (sparse sets, whose
    #: cells hold a bucket or two: the bucket arithmetic would only slow every step down)
    bucketed: bool = True
    #: mi.Float, per cell SLOTS × 3 Vector4f: the periodic families of :mod:`.periodic` (None: the set has none)
    family_frames: object = None
    cell_size: object = None  #: opaque mi.Float: the cell's side in UV units
    family_count: int = 0  #: periodic families in all (to_string)
    #: cells whose families meet on a kink line (a Python choice too: none, and the kernel has no kink code)
    kink_count: int = 0
    #: mi.Float, 2 per piece: how far its groove runs straight on before its start and after its end, in
    #: units of the piece's own length (:func:`.tables.continuations`; None: not uploaded)
    continuation: object = None
    #: True / False: every piece is a V-groove / none is; None: both profiles occur.  A Python choice: a set
    #: of one profile compiles the other's code nowhere (never run, that code still slowed every query:
    #: 16 → 13 ns per evaluation on empty windows of the grating, docs/bsdf.md, Performance)
    triangular: object = None

    @property
    def periodic(self) -> bool:
        """Whether some cell holds a periodic family (a Python choice: the closed form is compiled only then)."""
        return self.family_frames is not None

    @classmethod
    def upload(cls, tables: GridTables, periodic: bool = True, continuation: bool = False) -> "Grid":
        """The tables as Dr.Jit arrays; ``periodic``: also find their periodic families (dense sets only;
        a model that never sums them in closed form saves their build); ``continuation``: also upload
        how far each piece's groove runs straight on (the incoherent model joins such pieces)."""
        return cls.from_arrays(tables, ScanArrays.of(tables, periodic), continuation)

    @classmethod
    def from_arrays(cls, tables: GridTables, scan: "ScanArrays", continuation: bool = False) -> "Grid":
        """:meth:`upload` with the scan's arrays already built (:class:`ScanArrays`, or read from the disk
        cache, :mod:`.disk_cache`)."""
        rounding = max(tables.margin - CELL_DILATION, 0.0)
        return cls(
            segments=aligned_array(mi.Float, tables.segments.ravel()),
            references=aligned_array(mi.UInt32, tables.references),
            offsets=aligned_array(mi.Float, tables.offsets),
            scan_frames=aligned_array(mi.Float, scan.scan_frames.ravel()),
            cell_start=aligned_array(mi.UInt32, tables.cell_start),
            cell_bucket=aligned_array(mi.UInt32, scan.cell_bucket),
            bucket_start=aligned_array(mi.UInt32, scan.bucket_start),
            origin_u=dr.opaque(mi.Float, tables.origin[0]),
            origin_v=dr.opaque(mi.Float, tables.origin[1]),
            inverse_cell_size=dr.opaque(mi.Float, 1.0 / tables.cell_size),
            margin=dr.opaque(mi.Float, tables.margin),
            offset_padding=dr.opaque(mi.Float, OFFSET_PADDING + rounding),
            cells_u=dr.opaque(mi.Int32, tables.shape[0]),
            cells_v=dr.opaque(mi.Int32, tables.shape[1]),
            crossing_start=aligned_array(mi.UInt32, tables.crossing_start),
            crossing_partner=aligned_array(mi.UInt32, tables.crossing_partner),
            crossing_along=aligned_array(mi.Float, tables.crossing_along),
            max_width=dr.opaque(mi.Float, float(tables.segments[:tables.piece_count, 6].max(initial=0.0))),
            bucketed=scan.bucketed,
            family_frames=None if scan.family_frames is None else aligned_array(mi.Float, scan.family_frames.ravel()),
            cell_size=dr.opaque(mi.Float, tables.cell_size),
            family_count=scan.family_count,
            kink_count=scan.kink_count,
            continuation=aligned_array(mi.Float, relative_continuation(tables).ravel()) if continuation else None,
            triangular=profiles_of(tables))


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
    return u0, u1, v0, v1, gu, gv, scale, extent_u, extent_v, usable


def for_each_segment(grid: Grid, jac: LocalJacobian, radius, state: tuple,
                     body: Callable, active) -> tuple:
    """Fold ``body`` over the pieces whose centre line passes within ``radius`` (µm) of x0.

    ``body(segment: SegmentGeometry, piece: mi.UInt32, state) -> state`` is
    called (symbolically) for the lanes that hold such a piece, once per piece.
    ``state`` is a tuple of Dr.Jit arrays; the final state is returned.

    Per visited cell, only the references whose offset along the cell's normal
    can reach the window are tested (:func:`_cell_scan`): the scan starts at the
    offset bucket of the lowest such offset and stops past the highest.  Two
    nested loops keep the SIMD lanes in step: the inner one only scans (a few
    gathers and multiplications per step) until every lane has found its next
    piece or run out of cells, the outer one then calls ``body`` once for all
    of them.  The expensive body thus runs as often as the lane with the most
    pieces in its window needs, not once per reference tested.
    """
    u0, u1, v0, v1, gu, gv, scale, extent_u, extent_v, usable = _cell_range(grid, jac, radius, active)
    radius2 = radius * radius
    zero_i = mi.Int32(0)
    u1, v1 = dr.select(usable, u1, zero_i), dr.select(usable, v1, zero_i)
    u_first = dr.select(usable, u0 - 1, zero_i)  # the first step enters cell (u0, v0)
    v_first = dr.select(usable, v0, zero_i)

    def more(u, v, index, end):
        return (index < end) | (u < u1) | (v < v1)

    def scan_step(u, v, index, end, hi_key, found, piece):
        testing = index < end
        advance = ~testing & ((u < u1) | (v < v1))
        # ---- scanning lanes test one reference; past hi_key the cell is done
        key = dr.gather(mi.Float, grid.offsets, index, testing)
        testing &= key <= hi_key
        index = dr.select(~testing & ~advance & (index < end), end, index)
        piece = dr.gather(mi.UInt32, grid.references, index, testing)
        inside, closest_u, closest_v = _closest_point(grid, jac, piece, radius2, testing)
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
        first, last, hi = _cell_scan(grid, jac, u, v, gu, gv, scale, extent_u, extent_v, advance)
        index = dr.select(advance, first, index)
        end = dr.select(advance, last, end)
        hi_key = dr.select(advance, hi, hi_key)
        return u, v, index, end, hi_key, found, piece

    def visit(u, v, index, end, hi_key, user):
        u, v, index, end, hi_key, found, piece = dr.while_loop(
            (u, v, index, end, hi_key, dr.zeros(mi.Bool), dr.zeros(mi.UInt32)),
            lambda u, v, index, end, hi_key, found, piece: ~found & more(u, v, index, end),
            scan_step, label="scratch_scan")
        user = dr.if_stmt((piece, user), found,
                          lambda piece, user: body(segment_at(grid, jac, piece, True), piece, user),
                          lambda piece, user: user, label="scratch_segment")
        return u, v, dr.select(found, index + 1, index), end, hi_key, user

    zero_u = dr.zeros(mi.UInt32)
    return dr.while_loop((u_first, v_first, zero_u, zero_u, dr.zeros(mi.Float), state),
                         lambda u, v, index, end, hi_key, user: more(u, v, index, end),
                         visit, label="scratch_pieces")[5]


def _cell_scan(grid: Grid, jac: LocalJacobian, u, v, gu, gv, scale, extent_u, extent_v, active):
    """``(first, end, hi_key)``: the references of cell (u, v) that can hold a piece for the window.

    A piece is handed over in the cell that holds its point closest to x0, a
    point inside the window *and* the cell: its offset along the cell normal n
    lies within the projection on n of the window (q ± R_n, R_n = R|J^{-T}n|)
    and of the window's box clipped to the cell; its reference's offset, the
    lowest of its in-cell part, lies at most the cell's offset spread below.
    The scan starts at the offset bucket of the interval's low end and stops
    past its high end (float32 rounding: ``grid.offset_padding``).
    """
    cell = mi.UInt32(v * grid.cells_u + u)
    if grid.bucketed:
        frame = dr.gather(mi.Vector4f, grid.scan_frames, cell, active)  # n_u, n_v, lowest + spread, buckets/offset
    else:  # the sparse scan reads the normal only
        frame = dr.gather(mi.Vector2f, grid.scan_frames, 2 * cell, active)
    begin = dr.gather(mi.UInt32, grid.cell_start, cell, active)
    end = dr.gather(mi.UInt32, grid.cell_start, cell + 1, active)
    du, dv = gu - mi.Float(u), gv - mi.Float(v)  # x0 in the cell's coordinates (cells)
    q = frame.x * du + frame.y * dv
    half_width = scale * dr.sqrt(dr.square(jac.j11 * frame.x - jac.j10 * frame.y)
                                 + dr.square(jac.j00 * frame.y - jac.j01 * frame.x))
    pad = grid.offset_padding
    if not grid.bucketed:
        return begin, end, q + half_width + pad
    # the window's box clipped to the cell (its extents already carry the margin)
    box_u0, box_u1 = dr.maximum(du - extent_u, -pad), dr.minimum(du + extent_u, 1.0 + pad)
    box_v0, box_v1 = dr.maximum(dv - extent_v, -pad), dr.minimum(dv + extent_v, 1.0 + pad)
    positive_u, positive_v = frame.x >= 0.0, frame.y >= 0.0
    box_lo = frame.x * dr.select(positive_u, box_u0, box_u1) + frame.y * dr.select(positive_v, box_v0, box_v1)
    box_hi = frame.x * dr.select(positive_u, box_u1, box_u0) + frame.y * dr.select(positive_v, box_v1, box_v0)
    lowest_pieces = dr.maximum(q - half_width, box_lo) - pad  # the scan's low end is this less the spread
    hi_key = dr.minimum(q + half_width, box_hi) + pad
    last_bucket = dr.maximum(mi.Int32(end - begin) // BUCKET_REFERENCES, 1) - 1
    bucket0 = dr.gather(mi.UInt32, grid.cell_bucket, cell, active)
    k = mi.Int32(dr.floor(dr.clip((lowest_pieces - frame.z) * frame.w, 0.0, mi.Float(last_bucket))))
    first = dr.gather(mi.UInt32, grid.bucket_start, bucket0 + mi.UInt32(k), active)
    return first, end, hi_key


def replay_pieces(grid: Grid, jac: LocalJacobian, count, pieces: tuple, state: tuple, body: Callable,
                  active) -> tuple:
    """Fold ``body`` (as in :func:`for_each_segment`) over ``pieces[:count]`` of each lane, in order.

    For lanes where an earlier :func:`for_each_segment` over the same window found ``count <=
    len(pieces)`` pieces and kept them in the order found: the fold then adds them in the same order,
    so its result equals a new search's bit for bit, without the search."""
    def step(index, user):
        piece = pieces[-1]
        for k in range(len(pieces) - 2, -1, -1):
            piece = dr.select(index == k, pieces[k], piece)
        return index + 1, body(segment_at(grid, jac, piece, True), piece, user)

    return dr.while_loop((dr.zeros(mi.UInt32), state), lambda index, user: active & (index < count), step,
                         label="scratch_replay")[1]


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
    """Geometry of piece ``piece`` seen from the shading point (local frame, µm)."""
    tail, _, _, ax, ay, ex, ey = _piece_from_x0(grid, jac, piece, active)
    length = dr.sqrt(dr.fma(ex, ex, ey * ey))
    inv_length = dr.rcp(dr.select(active & (length > 1e-6), length, 1.0))
    dx, dy = ex * inv_length, ey * inv_length
    return SegmentGeometry(c=dr.fma(ax, dx, ay * dy), length=length, a_perp=dr.fma(ay, dx, -ax * dy), dx=dx, dy=dy,
                           width=tail.z, depth=dr.abs(tail.w),
                           triangular=tail.w < 0.0 if grid.triangular is None else grid.triangular)


def _closest_point(grid: Grid, jac: LocalJacobian, piece, radius2, active):
    """Whether the piece passes within the window radius, and its point closest to x0 relative to x0 (UV).

    The scan's test, without the segment's frame (no square root): the body gets that from
    :func:`segment_at` for the pieces found."""
    tail, du, dv, ax, ay, ex, ey = _piece_from_x0(grid, jac, piece, active)
    length2 = dr.fma(ex, ex, ey * ey)
    usable = active & (length2 > 1e-12)
    t = dr.clip(-dr.fma(ax, ex, ay * ey) / dr.select(usable, length2, 1.0), 0.0, 1.0)  # closest point
    distance2 = dr.square(dr.fma(t, ex, ax)) + dr.square(dr.fma(t, ey, ay))
    return usable & (distance2 < radius2), dr.fma(t, tail.x, du), dr.fma(t, tail.y, dv)


def _piece_from_x0(grid: Grid, jac: LocalJacobian, piece, active):
    """``(tail, du, dv, ax, ay, ex, ey)``: the piece's row tail (e (UV), W, ±D), its start a - x0 in UV
    and in the local frame (µm), and e = b - a in the local frame."""
    head = dr.gather(mi.Vector4f, grid.segments, 2 * piece, active)  # a_hi, a_lo
    tail = dr.gather(mi.Vector4f, grid.segments, 2 * piece + 1, active)  # e (UV), W (µm), ±D (µm)
    du = (head.x - jac.uv.x) + head.z
    dv = (head.y - jac.uv.y) + head.w
    return (tail, du, dv, dr.fma(jac.j00, du, jac.j01 * dv), dr.fma(jac.j10, du, jac.j11 * dv),
            dr.fma(jac.j00, tail.x, jac.j01 * tail.y), dr.fma(jac.j10, tail.x, jac.j11 * tail.y))
