"""Overlaps of three to five crossing pieces: the higher orders of the height field (docs/model.md §3.4).

The pair corrections of :mod:`.overlap` are the first two orders of an
inclusion–exclusion over the scratches covering a point; where three strips
overlap (region T) the third order adds back

    C_3(ξ) = +(e^{iκ_min} - 1) ∫_T w(x) e^{-2πiξ·x} dx,      κ_min = k_z min(D_1, D_2, D_3),

the fourth subtracts the same over fourfold overlaps, the fifth adds again.
Where a V-groove takes part the depth varies over T and the third order is
``+∫_T (e^{ik_z min(h_1, h_2, h_3)} - 1) w e^{-2πiξ·x}`` (:func:`_sloped_triple`);
overlaps of four and five with a V-groove are left out (order 3 is kept).

**Finding the overlaps (in the kernel).**  Whether three strips overlap depends
on their widths in µm, which the CPU cannot relate to UV (the Jacobian is the
mesh's, per shading point), and listing every mutually crossing triple of
pieces would cost far more than the pairs.  So, for each crossing pair (A, B)
the kernel visits (:func:`.lookup.for_each_crossing`), one small query of the
lookup grid around the crossing point (:func:`.lookup.for_each_segment`,
radius: P's half diagonal plus half the widest scratch) keeps up to ``SLOTS``
pieces C whose strip meets the parallelogram P_AB and that

* hold the foot point of the crossing on their centre line (a scratch cut
  into pieces counts once);
* are not visited from another pair: an overlap belongs to one of its
  crossing pairs (|sin| >= ``crossings.MIN_SINE`` in UV, the pairs the
  tables list), the lowest in the order of keys (direction angle mod π in
  the local frame, then piece index) that compares a pair's higher key
  first, then its lower.  With A's key below B's a third line C is kept if
  it crosses both and its key is above B's; if it crosses B only (nearly
  parallel to A, whose pair parallel.py corrects) and its key is above A's;
  if it crosses A only and its key is above B's; if it crosses neither,
  always (A and B are its only crossing pair).

Every subset of the kept lines is one overlap of order 2 + its size, up to
``MAX_ORDER``, unless two of its lines make a crossing pair lower than
(A, B) (both keys below B's).  With ``with_parallel`` off (the model
without parallel.py's term) only lines crossing A and B and each other
are kept, the key above both, as the overlaps with a nearly parallel pair
would be corrected only in part.  Its
region lies in P_AB: it is integrated over the cells of P_AB (edges ≤ σ/2)
that every further strip reaches, each cell ∩ strips by
:func:`.polygon.clipped_cell`.  Lengths in µm.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from ..maths.complexmath import Cx, expi
from ..tables.crossings import MIN_SINE
from ..lookup import Grid, LocalJacobian, for_each_segment, segment_at
from .overlap import Parallelogram, below, cell_centre, depth_plane, parallelogram
from .parallel import consecutive, piece_ends
from ..maths.polygon import Strip, clipped_cell
from ..maths.segment import SegmentGeometry, flat_bottomed

__all__ = ["add_triples", "MAX_ORDER", "SLOTS"]

#: Highest overlap order corrected: pairs (overlap.py), then orders 3 .. MAX_ORDER here; higher
#: orders stay uncorrected (docs/model.md §3.4 bounds them).
MAX_ORDER = 5
#: Third lines kept per crossing pair (more meeting one pair's parallelogram are left out).
SLOTS = 6
#: Cells of the overlaps of order 3 and more: edges of at most this many σ, as the pairs' (σ instead saved
#: 15 % of a plate query but took stars of 3-5 scratches from 0.6 % to 3.5 % error; docs/bsdf.md, Cost).
HIGHER_SUB_EDGE_SIGMAS = 0.5


def _angle(segment: SegmentGeometry):
    """Direction angle of a piece, mod π, in [0, π)."""
    angle = dr.atan2(segment.dy, segment.dx)
    angle = dr.select(angle < 0.0, angle + math.pi, angle)
    return dr.select(angle >= math.pi, angle - math.pi, angle)


def _after(angle, piece, than_angle, than_piece):
    """Whether key (``angle``, ``piece``) comes after (``than_angle``, ``than_piece``)."""
    return (angle > than_angle) | ((angle == than_angle) & (piece > than_piece))


def _uv_direction(grid: Grid, piece, active):
    tail = dr.gather(mi.Vector4f, grid.segments, 2 * piece + 1, active)
    inv = dr.rsqrt(dr.maximum(tail.x * tail.x + tail.y * tail.y, 1e-30))
    return tail.x * inv, tail.y * inv


def add_triples(grid: Grid, jac: LocalJacobian, first: SegmentGeometry, second: SegmentGeometry, first_piece,
                second_piece, crossing_uv, xi_x, xi_y, k_z, sigma, field: tuple, with_parallel: bool = True) -> tuple:
    """``field`` plus the terms of order 3 to MAX_ORDER of the crossing pair (``first``, ``second``).

    ``field`` is a pair (re, im) of spectra; ``crossing_uv`` the crossing point of the pair's centre lines
    (UV).  One grid query keeps up to ``SLOTS`` third lines; every subset of them of at most
    ``MAX_ORDER - 2`` lines that is not another crossing pair's is one overlap.  ``with_parallel``: the
    overlaps with a nearly parallel pair too (the model corrects those pairs).  See the module docstring.
    """
    shape = parallelogram(first, second, sigma, HIGHER_SUB_EDGE_SIGMAS)
    half_diagonal = 0.5 * (dr.norm(mi.Vector2f(shape.e1x, shape.e1y)) * shape.n1
                           + dr.norm(mi.Vector2f(shape.e2x, shape.e2y)) * shape.n2)
    # every strip meeting P passes within this of the crossing point (1 % and 10 nm for float32 UV)
    radius = 1.01 * (half_diagonal + 0.5 * grid.max_width) + 0.01
    around = LocalJacobian(uv=crossing_uv, j00=jac.j00, j01=jac.j01, j10=jac.j10, j11=jac.j11)
    first_angle, second_angle = _angle(first), _angle(second)
    # the pair's keys in order: (low_angle, low_piece) before (high_angle, high_piece)
    swap = _after(first_angle, first_piece, second_angle, second_piece)
    high_angle, high_piece = dr.select(swap, first_angle, second_angle), dr.select(swap, first_piece, second_piece)
    first_u, first_v = _uv_direction(grid, first_piece, True)
    second_u, second_v = _uv_direction(grid, second_piece, True)
    first_ends, second_ends = piece_ends(first), piece_ends(second)

    def keep(near: SegmentGeometry, piece, state):
        count, grooved, above, *slots = state
        # the piece holding the foot point of the crossing on its centre line
        foot = -near.c
        usable = (foot >= 0.0) & (foot < near.length)
        other = segment_at(grid, jac, piece, usable)
        angle = _angle(other)
        u, v = _uv_direction(grid, piece, usable)
        crosses_first = dr.abs(first_u * v - first_v * u) >= MIN_SINE
        crosses_second = dr.abs(second_u * v - second_v * u) >= MIN_SINE
        after_first = _after(angle, piece, first_angle, first_piece)
        after_second = _after(angle, piece, second_angle, second_piece)
        if with_parallel:  # not (other, second) nor (first, other) the overlap's pair (module docstring)
            usable &= (~crosses_second | after_first) & (~crosses_first | after_second)
        else:
            usable &= crosses_first & crosses_second & after_first & after_second
        usable &= _meets(shape, other) & (count < SLOTS) & (piece != first_piece) & (piece != second_piece)
        if with_parallel:  # a piece consecutive to the pair's (a cut run's next piece): one line with it
            other_ends = piece_ends(other)
            usable &= ~consecutive(other_ends, first_ends) & ~consecutive(other_ends, second_ends)
        slots = [dr.select(usable & (count == k), piece, slot) for k, slot in enumerate(slots)]
        bit = mi.UInt32(1) << count
        grooved = dr.select(usable & near.triangular, grooved | bit, grooved)
        above = dr.select(usable & _after(angle, piece, high_angle, high_piece), above | bit, above)
        return (dr.select(usable, count + 1, count), grooved, above, *slots)

    empty = tuple(dr.zeros(mi.UInt32) for _ in range(SLOTS + 3))
    count, grooved, above, *slots = for_each_segment(grid, around, radius, empty, keep, mi.Bool(True))
    # triples (the common case) with three strips per cell, V-grooves included; then the higher orders with
    # all of theirs, flat bottoms only: a pile with a V-groove stops at order 3 (docs/model.md §3.4 bounds the rest)
    field = _add_subsets(grid, jac, shape, first, second, count, slots, above, 1, 1, xi_x, xi_y, k_z, sigma, field,
                         with_parallel=with_parallel)
    banned = dr.select(first.triangular | second.triangular, mi.UInt32((1 << SLOTS) - 1), grooved)
    return _add_subsets(grid, jac, shape, first, second, count, slots, above, 2, MAX_ORDER - 2, xi_x, xi_y, k_z,
                        sigma, field, banned, with_parallel)


def _add_subsets(grid, jac, shape, first, second, count, slots, above, smallest, largest, xi_x, xi_y, k_z, sigma,
                 field, banned=None, with_parallel=True):
    """Add ``±(e^{iκ_min} - 1) ∫`` over the overlap of (first, second) with each valid subset of ``slots``
    of ``smallest`` to ``largest`` lines (none of the slots in the bit mask ``banned``); for single lines
    where a V-groove takes part, ``∫ (e^{ik_z min h} - 1)`` (:func:`_sloped_triple`).

    A subset is valid unless two of its lines cross (the tables' pair) with both keys below the pair's
    higher one (no bit of ``above``): that pair, lower than (first, second), owns the overlap.  Without
    ``with_parallel`` its lines must cross each other too.
    """
    spectrum = type(xi_x)
    subsets = mi.UInt32(1) << count  # masks 1 .. 2^count - 1

    def chosen(mask):
        """The pieces of ``mask`` (at most ``largest``; the rest repeat the first), whether each is above the
        pair's higher key, and how many."""
        picked = [dr.zeros(mi.UInt32) for _ in range(largest)]
        high = [dr.zeros(mi.Bool) for _ in range(largest)]
        size = dr.zeros(mi.UInt32)
        for k, slot in enumerate(slots):
            bit = (mask & (1 << k)) != 0
            is_above = (above & (1 << k)) != 0
            high = [dr.select(bit & (size == j), is_above, h) for j, h in enumerate(high)]
            picked = [dr.select(bit & (size == j), slot, p) for j, p in enumerate(picked)]
            size = dr.select(bit, size + 1, size)
        return picked, high, size

    def valid(mask):
        picked, high, size = chosen(mask)
        ok = (size >= smallest) & (size <= largest)
        if banned is not None:
            ok &= (mask & banned) == 0
        directions = [_uv_direction(grid, piece, True) for piece in picked]
        for j in range(largest):
            for k in range(j + 1, largest):
                (uj, vj), (uk, vk) = directions[j], directions[k]
                crossing = dr.abs(uj * vk - vj * uk) >= MIN_SINE
                ok &= (k >= size) | ((~crossing | high[j] | high[k]) if with_parallel else crossing)
        return ok

    def advance(mask):  # the single lines one by one (1, 2, 4, ...), else every mask
        return mask << 1 if largest == 1 else mask + 1

    def skip(mask):  # cheap: lanes wait for each other on valid subsets only
        return dr.while_loop((mask,), lambda mask: (mask < subsets) & ~valid(mask), lambda mask: (advance(mask),),
                             label="scratch_overlap_subsets")[0]

    def step(mask, re, im):
        mask = skip(mask)
        active = mask < subsets
        picked, _, size = chosen(mask)
        lines = [first, second]
        shallow = dr.minimum(first.depth, second.depth)
        for j, piece in enumerate(picked):
            line = segment_at(grid, jac, piece, active & (size > j))
            used = size > j
            shallow = dr.select(used, dr.minimum(shallow, line.depth), shallow)
            # an unused place: a strip a million µm wide along the first, which cuts nothing
            lines.append(SegmentGeometry(*(dr.select(used, a, b) for a, b in zip(line, first._replace(width=2e6)))))
        sloped = None
        if largest == 1:  # a triple: with a V-groove the depths vary over the overlap
            third = lines[2]
            grooved = first.triangular | second.triangular | third.triangular
            sloped = _sloped_triple(shape, first, second, third, active & grooved, xi_x, xi_y, k_z, sigma)
            active_flat = active & flat_bottomed(grooved)
        else:
            active_flat = active
        integral = _overlap_integral(shape, lines, active_flat, xi_x, xi_y, sigma)
        # Möbius inversion: (-1)^{order+1} (e^{iκ_min} - 1) ∫ over the overlap of order = size + 2
        sign = dr.select((size & 1) == 1, 1.0, -1.0)
        term = (expi(k_z * shallow) - 1.0) * integral
        if sloped is not None:
            term = term + sloped
        term = term * sign
        return (advance(mask), spectrum(dr.select(active, re + term.re, re)),
                spectrum(dr.select(active, im + term.im, im)))

    first_mask = mi.UInt32(1 if smallest == 1 else 3)
    _, re, im = dr.while_loop((skip(first_mask), field[0], field[1]), lambda mask, re, im: mask < subsets, step,
                              label="scratch_overlaps")
    return re, im


def _meets(shape: Parallelogram, other: SegmentGeometry):
    """Whether the strip of ``other`` meets the whole parallelogram."""
    nx, ny = -other.dy, other.dx
    distance = dr.abs(nx * shape.px + ny * shape.py - other.a_perp)
    reach = (dr.abs(nx * shape.e1x + ny * shape.e1y) * shape.n1 + dr.abs(nx * shape.e2x + ny * shape.e2y) * shape.n2)
    return distance <= 0.5 * (reach + other.width)


def _cell_skipper(shape: Parallelogram, extra, cells, columns, label):
    """``skip(index)``: the first cell from ``index`` on (below ``cells``) that every strip of ``extra`` reaches.

    Cheap (only the cell test), so SIMD lanes wait for each other on touched cells alone.
    """
    normals = [(-line.dy, line.dx) for line in extra]
    reaches = [0.5 * (dr.abs(nx * shape.e1x + ny * shape.e1y) + dr.abs(nx * shape.e2x + ny * shape.e2y)
                      + line.width) for (nx, ny), line in zip(normals, extra)]

    def misses(index):
        cx, cy = cell_centre(shape, index, columns)
        missed = dr.zeros(mi.Bool)
        for (nx, ny), line, reach in zip(normals, extra, reaches):
            missed |= dr.abs(nx * cx + ny * cy - line.a_perp) > reach
        return (index < cells) & missed

    return lambda index: dr.while_loop((index,), misses, lambda index: (index + 1,), label=label)[0]


def _overlap_integral(shape: Parallelogram, lines, usable, xi_x, xi_y, sigma) -> Cx:
    """``∫ w e^{-2πiξ·x}`` over the overlap of ``lines``' strips, the first two those of ``shape``.

    Only the cells of ``shape`` that every further strip reaches are integrated (:func:`.polygon.clipped_cell`).
    """
    first, second, extra = lines[0], lines[1], lines[2:]
    normals = [(-line.dy, line.dx) for line in extra]
    cells = dr.select(usable, mi.UInt32(shape.n1 * shape.n2), 0)
    columns = dr.maximum(mi.UInt32(shape.n1), 1)
    half1 = 0.5 * first.width / shape.n1
    half2 = 0.5 * second.width / shape.n2
    skip = _cell_skipper(shape, extra, cells, columns, "scratch_overlap_skip")

    def step(index, re, im):
        index = skip(index)
        cx, cy = cell_centre(shape, index, columns)
        strips = [Strip(-first.dy, first.dx, 0.0, half1), Strip(-second.dy, second.dx, 0.0, half2)]
        strips += [Strip(nx, ny, line.a_perp - (nx * cx + ny * cy), 0.5 * line.width)
                   for (nx, ny), line in zip(normals, extra)]
        term = clipped_cell(strips, cx, cy, xi_x, xi_y, sigma)
        inside = index < cells
        return (index + 1, type(xi_x)(dr.select(inside, re + term.re, re)),
                type(xi_x)(dr.select(inside, im + term.im, im)))

    zero = dr.zeros(type(xi_x))
    _, re, im = dr.while_loop((skip(mi.UInt32(0)), zero, zero), lambda index, re, im: index < cells, step,
                              label="scratch_overlap_cells")
    return Cx(re, im)


def _sloped_triple(shape: Parallelogram, first, second, third, usable, xi_x, xi_y, k_z, sigma) -> Cx:
    """``∫_T (e^{ik_z min(h_1, h_2, h_3)} - 1) w e^{-2πiξ·x}`` over the triple overlap T where a V-groove takes
    part (docs/model.md §3.4).

    On each cell of ``shape`` (where a V-groove, split at its centre line) the pair's depths are planes
    (:func:`.overlap.depth_plane`); the third strip is taken half by half (each side of its centre line,
    where its depth is a plane too), and each half splits into the three regions where one depth is the
    smallest (two half-planes each), every one a clipped polygon at its depth's shifted frequency, as in
    :func:`.overlap._sloped_correction`.  The -1 is the cell ∩ third strip at ξ.
    """
    spectrum = type(xi_x)
    nx, ny = -third.dy, third.dx
    cells = dr.select(usable, mi.UInt32(shape.n1 * shape.n2), 0)
    columns = dr.maximum(mi.UInt32(shape.n1), 1)
    half1 = 0.5 * first.width / shape.n1
    half2 = 0.5 * second.width / shape.n2
    reach = dr.norm(mi.Vector2f(shape.e1x, shape.e1y)) + dr.norm(mi.Vector2f(shape.e2x, shape.e2y))
    scale = k_z * (1.0 / (2.0 * math.pi))
    skip = _cell_skipper(shape, [third], cells, columns, "scratch_overlap_sloped_skip")

    def region(cell, planes, k, cx, cy):
        """∫ e^{ik_z h_k} w e^{-2πiξ·x} over the part of ``cell`` where depth ``k`` is the smallest."""
        h, gx, gy = planes[k]
        halves = [below(planes[k], planes[j], reach) for j in range(3) if j != k]
        part = clipped_cell(cell + halves, cx, cy, spectrum(xi_x - scale * gx), spectrum(xi_y - scale * gy), sigma)
        return expi(k_z * (h - gx * cx - gy * cy)) * part

    def step(index, re, im):
        index = skip(index)
        cx, cy = cell_centre(shape, index, columns)
        pair = [Strip(-first.dy, first.dx, 0.0, half1), Strip(-second.dy, second.dx, 0.0, half2)]
        centre = third.a_perp - (nx * cx + ny * cy)  # the third centre line, relative to c
        total = -clipped_cell(pair + [Strip(nx, ny, centre, 0.5 * third.width)], cx, cy, xi_x, xi_y, sigma)
        first_plane, second_plane = depth_plane(first, cx, cy), depth_plane(second, cx, cy)
        for side in (1.0, -1.0):
            cell = pair + [Strip(nx, ny, centre + side * 0.25 * third.width, 0.25 * third.width)]
            planes = (first_plane, second_plane, depth_plane(third, cx, cy, side))
            for k in range(3):
                total = total + region(cell, planes, k, cx, cy)
        inside = index < cells
        return (index + 1, spectrum(dr.select(inside, re + total.re, re)),
                spectrum(dr.select(inside, im + total.im, im)))

    zero = dr.zeros(spectrum)
    _, re, im = dr.while_loop((skip(mi.UInt32(0)), zero, zero), lambda index, re, im: index < cells, step,
                              label="scratch_overlap_sloped_triple")
    return Cx(re, im)
