"""Triple overlaps of crossing rectangular pieces: the third term of the height field (docs/model.md §3.4).

The pair corrections of :mod:`.overlap` are the first two orders of an
inclusion–exclusion over the scratches covering a point; where three strips
overlap (region T) the third order adds back

    C_3(ξ) = +(e^{iκ_min} - 1) ∫_T w(x) e^{-2πiξ·x} dx,      κ_min = k_z min(D_1, D_2, D_3).

**Finding the triples (in the kernel).**  Whether three strips overlap depends
on their widths in µm, which the CPU cannot relate to UV (the Jacobian is the
mesh's, per shading point), and listing every mutually crossing triple of
pieces would cost far more than the pairs.  So, for each crossing pair (A, B)
the kernel visits (:func:`.lookup.for_each_crossing`), a small query of the
lookup grid around the crossing point (:func:`.lookup.for_each_segment`,
radius: P's half diagonal plus half the widest scratch) finds the pieces C
whose strip meets the parallelogram P_AB.  Each triple is counted once:

* C's piece is the one holding the foot point of the crossing on C's centre
  line (a scratch cut into pieces counts once);
* the triple belongs to the pair of its two lines of lowest direction angle
  (mod π, in the local frame): C's angle exceeds A's and B's;
* (A, C) and (B, C) must be pairs the tables correct: C rectangular,
  |sin| >= ``crossings.MIN_SINE`` in UV against both.

T ⊂ P_AB is integrated over the cells of P_AB (:func:`.overlap.parallelogram`,
edges ≤ σ/2) that strip C touches, each cell ∩ strip C by
:func:`.polygon.clipped_cell`.  Lengths in µm.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from .complexmath import Cx, expi
from .crossings import MIN_SINE
from .lookup import Grid, LocalJacobian, for_each_segment, segment_at
from .overlap import Parallelogram, cell_centre, parallelogram
from .polygon import Strip, clipped_cell
from .segment import SegmentGeometry

__all__ = ["add_triples", "MAX_ORDER"]

#: Highest overlap order corrected: pairs (overlap.py), triples and quadruples (here).  Fivefold
#: overlaps stay uncorrected (docs/model.md §3.4 bounds them).
MAX_ORDER = 5


def _angle(segment: SegmentGeometry):
    """Direction angle of a piece, mod π, in [0, π)."""
    angle = dr.atan2(segment.dy, segment.dx)
    angle = dr.select(angle < 0.0, angle + math.pi, angle)
    return dr.select(angle >= math.pi, angle - math.pi, angle)


def _uv_direction(grid: Grid, piece, active):
    tail = dr.gather(mi.Vector4f, grid.segments, 2 * piece + 1, active)
    inv = dr.rsqrt(dr.maximum(tail.x * tail.x + tail.y * tail.y, 1e-30))
    return tail.x * inv, tail.y * inv


def add_triples(grid: Grid, jac: LocalJacobian, first: SegmentGeometry, second: SegmentGeometry, first_piece,
                second_piece, crossing_uv, xi_x, xi_y, k_z, sigma, field: tuple) -> tuple:
    """``field`` plus the triple and quadruple terms of the crossing pair (``first``, ``second``).

    ``field`` is a pair (re, im) of spectra; ``crossing_uv`` the crossing point of the pair's centre lines
    (UV).  See the module docstring.
    """
    shape = parallelogram(first, second, sigma)
    half_diagonal = 0.5 * (dr.norm(mi.Vector2f(shape.e1x, shape.e1y)) * shape.n1
                           + dr.norm(mi.Vector2f(shape.e2x, shape.e2y)) * shape.n2)
    # every strip meeting P passes within this of the crossing point (1 % and 10 nm for float32 UV)
    radius = 1.01 * (half_diagonal + 0.5 * grid.max_width) + 0.01
    around = LocalJacobian(uv=crossing_uv, j00=jac.j00, j01=jac.j01, j10=jac.j10, j11=jac.j11)
    spectrum = type(xi_x)

    def extend(lines, directions, floor, active, field):
        """Add the terms of every overlap of ``lines`` and one more line of angle above ``floor``."""
        order = len(lines) + 1

        def visit(near: SegmentGeometry, piece, field):
            # the piece holding the foot point of the crossing on its centre line, rectangular
            foot = -near.c
            usable = (foot >= 0.0) & (foot < near.length) & ~near.triangular
            other = segment_at(grid, jac, piece, usable)
            angle = _angle(other)
            usable &= angle > floor
            u, v = _uv_direction(grid, piece, usable)
            for du, dv in directions:  # every pair of the overlap is one the tables correct
                usable &= dr.abs(du * v - dv * u) >= MIN_SINE
            usable &= _meets(shape, other)
            overlap = lines + [other]
            integral = _overlap_integral(shape, overlap, usable, xi_x, xi_y, sigma)
            shallow = overlap[0].depth
            for line in overlap[1:]:
                shallow = dr.minimum(shallow, line.depth)
            # Möbius inversion: (-1)^{order+1} (e^{iκ_min} - 1) ∫ over the order-fold overlap
            term = (expi(k_z * shallow) - 1.0) * integral * (1.0 if order % 2 else -1.0)
            field = spectrum(field[0] + term.re), spectrum(field[1] + term.im)
            if order < MAX_ORDER:
                field = extend(overlap, directions + [(u, v)], angle, usable, field)
            return field

        return for_each_segment(grid, around, radius, field, visit, active)

    first_direction = _uv_direction(grid, first_piece, True)
    second_direction = _uv_direction(grid, second_piece, True)
    return extend([first, second], [first_direction, second_direction],
                  dr.maximum(_angle(first), _angle(second)), mi.Bool(True), field)


def _meets(shape: Parallelogram, other: SegmentGeometry):
    """Whether the strip of ``other`` meets the whole parallelogram."""
    nx, ny = -other.dy, other.dx
    distance = dr.abs(nx * shape.px + ny * shape.py - other.a_perp)
    reach = (dr.abs(nx * shape.e1x + ny * shape.e1y) * shape.n1 + dr.abs(nx * shape.e2x + ny * shape.e2y) * shape.n2)
    return distance <= 0.5 * (reach + other.width)


def _overlap_integral(shape: Parallelogram, lines, usable, xi_x, xi_y, sigma) -> Cx:
    """``∫ w e^{-2πiξ·x}`` over the overlap of ``lines``' strips, the first two those of ``shape``.

    Only the cells of ``shape`` that every further strip reaches are integrated (:func:`.polygon.clipped_cell`).
    """
    first, second, extra = lines[0], lines[1], lines[2:]
    normals = [(-line.dy, line.dx) for line in extra]
    reaches = [0.5 * (dr.abs(nx * shape.e1x + ny * shape.e1y) + dr.abs(nx * shape.e2x + ny * shape.e2y)
                      + line.width) for (nx, ny), line in zip(normals, extra)]
    cells = dr.select(usable, mi.UInt32(shape.n1 * shape.n2), 0)
    columns = dr.maximum(mi.UInt32(shape.n1), 1)
    half1 = 0.5 * first.width / shape.n1
    half2 = 0.5 * second.width / shape.n2

    def misses(index):
        cx, cy = cell_centre(shape, index, columns)
        missed = dr.zeros(mi.Bool)
        for (nx, ny), line, reach in zip(normals, extra, reaches):
            missed |= dr.abs(nx * cx + ny * cy - line.a_perp) > reach
        return (index < cells) & missed

    def skip(index):  # cheap: only the cell test, so lanes wait for each other on touched cells alone
        return dr.while_loop((index,), misses, lambda index: (index + 1,), label="scratch_overlap_skip")[0]

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
