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

__all__ = ["add_triples"]


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
    """``field`` plus the triple terms of the crossing pair (``first``, ``second``) (module docstring).

    ``field`` is a pair (re, im) of spectra; ``crossing_uv`` the crossing point of the pair's centre lines (UV).
    """
    shape = parallelogram(first, second, sigma)
    half_diagonal = 0.5 * (dr.norm(mi.Vector2f(shape.e1x, shape.e1y)) * shape.n1
                           + dr.norm(mi.Vector2f(shape.e2x, shape.e2y)) * shape.n2)
    radius = 1.01 * (half_diagonal + 0.5 * grid.max_width) + 0.01
    around = LocalJacobian(uv=crossing_uv, j00=jac.j00, j01=jac.j01, j10=jac.j10, j11=jac.j11)
    lowest = dr.maximum(_angle(first), _angle(second))
    first_u, first_v = _uv_direction(grid, first_piece, True)
    second_u, second_v = _uv_direction(grid, second_piece, True)
    spectrum = type(xi_x)

    def third(near: SegmentGeometry, piece, field):
        # the piece holding the foot point of the crossing on its centre line, rectangular
        foot = -near.c
        usable = (foot >= 0.0) & (foot < near.length) & ~near.triangular
        other = segment_at(grid, jac, piece, usable)
        usable &= _angle(other) > lowest
        u, v = _uv_direction(grid, piece, usable)
        usable &= (dr.abs(first_u * v - first_v * u) >= MIN_SINE) & (dr.abs(second_u * v - second_v * u) >= MIN_SINE)
        usable &= _meets(shape, other)
        integral = _triple_integral(shape, first, second, other, usable, xi_x, xi_y, sigma)
        shallow = k_z * dr.minimum(dr.minimum(first.depth, second.depth), other.depth)
        term = (expi(shallow) - 1.0) * integral
        return spectrum(field[0] + term.re), spectrum(field[1] + term.im)

    return for_each_segment(grid, around, radius, field, third, mi.Bool(True))


def _strip_reach(shape: Parallelogram, nx, ny):
    """Half the spread of ``n·x`` over one cell of the parallelogram."""
    return 0.5 * (dr.abs(nx * shape.e1x + ny * shape.e1y) + dr.abs(nx * shape.e2x + ny * shape.e2y))


def _meets(shape: Parallelogram, other: SegmentGeometry):
    """Whether the strip of ``other`` meets the whole parallelogram."""
    nx, ny = -other.dy, other.dx
    distance = dr.abs(nx * shape.px + ny * shape.py - other.a_perp)
    reach = (dr.abs(nx * shape.e1x + ny * shape.e1y) * shape.n1 + dr.abs(nx * shape.e2x + ny * shape.e2y) * shape.n2)
    return distance <= 0.5 * (reach + other.width)


def _triple_integral(shape: Parallelogram, first, second, other, usable, xi_x, xi_y, sigma) -> Cx:
    """``∫_T w e^{-2πiξ·x}`` over the cells of ``shape`` that the strip of ``other`` touches."""
    nx, ny = -other.dy, other.dx
    reach = _strip_reach(shape, nx, ny) + 0.5 * other.width
    cells = dr.select(usable, mi.UInt32(shape.n1 * shape.n2), 0)
    columns = dr.maximum(mi.UInt32(shape.n1), 1)
    half1 = 0.5 * first.width / shape.n1
    half2 = 0.5 * second.width / shape.n2

    def misses(index):
        cx, cy = cell_centre(shape, index, columns)
        return (index < cells) & (dr.abs(nx * cx + ny * cy - other.a_perp) > reach)

    def skip(index):  # cheap: only the cell test, so lanes wait for each other on touched cells alone
        return dr.while_loop((index,), misses, lambda index: (index + 1,), label="scratch_triple_skip")[0]

    def step(index, re, im):
        index = skip(index)
        cx, cy = cell_centre(shape, index, columns)
        strips = (Strip(-first.dy, first.dx, 0.0, half1), Strip(-second.dy, second.dx, 0.0, half2),
                  Strip(nx, ny, other.a_perp - (nx * cx + ny * cy), 0.5 * other.width))
        term = clipped_cell(strips, cx, cy, xi_x, xi_y, sigma)
        inside = index < cells
        return (index + 1, type(xi_x)(dr.select(inside, re + term.re, re)),
                type(xi_x)(dr.select(inside, im + term.im, im)))

    zero = dr.zeros(type(xi_x))
    start = skip(mi.UInt32(0))
    _, re, im = dr.while_loop((start, zero, zero), lambda index, re, im: index < cells, step,
                              label="scratch_triple_cells")
    return Cx(re, im)
