"""Height-field correction of two crossing pieces (Dr.Jit side; docs/model.md §3.4).

On the overlap P of two flat-bottomed scratches of depths D_1, D_2 the sum of
transfer functions gives ``e^{iκ_1} + e^{iκ_2} - 1`` where the height field
has ``e^{iκ_max}``; the difference is ``-(e^{iκ_min} - 1)``, so

    C(ξ) = -(e^{iκ_min} - 1) ∫_P w(x) e^{-2πiξ·x} dx,      κ = k_z D.

P is the parallelogram of the two strips ``|n_k·x - a⊥_k| <= W_k/2``: centre
``p = (a⊥_1 d_2 - a⊥_2 d_1)/sin θ`` (sin θ = d_1 × d_2), edges
``E_1 = W_1 d_2/sin θ`` and ``E_2 = W_2 d_1/sin θ``.  Its windowed transform
is not separable, so P is cut into n_1 × n_2 sub-parallelograms with edges of
at most σ/2 (at most MAX_SPLIT per edge); over each (centre c, edges E_1/n_1,
E_2/n_2, written E below) the window is expanded: its value and slope exactly
(a complex frequency ``ζ = ξ - i c/(2πσ²)``), its curvature by its mean, so

    ∫ w e^{-2πiξ·x} ≈ w(c) e^{-2πiξ·c} e^{-(|E_1|² + |E_2|²)/(24σ²)} |E_1 × E_2| sinc(ζ·E_1) sinc(ζ·E_2)

with the normalised sinc of a complex argument.

Where a V-groove takes part the depths vary across P and the correction is
``-∫_P (e^{ik_z min(h_1, h_2)} - 1) w e^{-2πiξ·x}`` (the deeper one wins, so
the sum's excess is the shallower one's transfer function): the cells split
the V at its centre line, so both depths are planes over a cell, and the
line h_1 = h_2 cuts it into two convex polygons with a linear phase each
(:func:`_sloped_correction`).

Where a groove ends inside P (a crossing next to a scratch's end) the overlap
ends there too: with the grooves' runs (how far each runs straight on past its
piece, :func:`.tables.continuations`, so that the pieces a long scratch is cut
into do not end it), :func:`run_ends` gives a band along each groove, and where
one cuts P the cells are clipped polygons of the cell strips and both bands.
Lengths in µm.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from ..maths.complexmath import Cx, expi, scaled_sinc
from ..maths.polygon import Strip, clipped_cell
from ..maths.profiles import MIN_WIDTH_UM
from ..maths.segment import SegmentGeometry, flat_bottomed

__all__ = ["Parallelogram", "RunEnd", "below", "cell_centre", "cell_strips", "crossing_correction", "depth_plane",
           "parallelogram", "run_ends"]

#: The overlap is cut into n_1 × n_2 sub-parallelograms with edges at most this many σ long, each with
#: its own window expansion: the neglected curvature then stays below ~1 % (docs/model.md §3.4).
SUB_EDGE_SIGMAS = 0.5
#: ... and at most this many along each edge (longer edges get longer cells: at |sin θ| = 0.1, from W = 0.4σ).
MAX_SPLIT = 8


class Parallelogram(NamedTuple):
    """The overlap P of two crossing strips cut into n_1 × n_2 cells (local frame, µm, relative to x0)."""

    px: object  #: centre
    py: object
    e1x: object  #: a cell's edge E_1/n_1 (along d_2, spanning strip 1)
    e1y: object
    e2x: object  #: a cell's edge E_2/n_2 (along d_1, spanning strip 2)
    e2y: object
    n1: object  #: Float cell counts
    n2: object
    sine: object  #: sin θ = d_1 × d_2 (clamped away from 0)


def parallelogram(first: SegmentGeometry, second: SegmentGeometry, sigma,
                  sub_edge_sigmas: float = SUB_EDGE_SIGMAS) -> Parallelogram:
    """The overlap of the strips of ``first`` and ``second`` and its cells of edges of at most
    ``sub_edge_sigmas`` σ (and at most MAX_SPLIT per edge; module docstring).

    Across a V-groove the cell count is even, so that its centre line is a cell boundary and its depth
    is linear over every cell.
    """
    sine = first.dx * second.dy - first.dy * second.dx
    sine = dr.select(dr.abs(sine) > 1e-6, sine, 1e-6)
    inv_sine = dr.rcp(sine)
    # centre of the overlap (relative to x0) and its edge lengths along d_2 and d_1
    px = (first.a_perp * second.dx - second.a_perp * first.dx) * inv_sine
    py = (first.a_perp * second.dy - second.a_perp * first.dy) * inv_sine
    edge1 = first.width * dr.abs(inv_sine)
    edge2 = second.width * dr.abs(inv_sine)
    sub_edge = sub_edge_sigmas * sigma
    # (at least 1: lanes without a partner divide by the column count too; MAX_SPLIT is even)
    n1 = dr.clip(dr.ceil(edge1 / sub_edge), 1.0, MAX_SPLIT)
    n2 = dr.clip(dr.ceil(edge2 / sub_edge), 1.0, MAX_SPLIT)
    n1 = dr.select(first.triangular, 2.0 * dr.ceil(0.5 * n1), n1)
    n2 = dr.select(second.triangular, 2.0 * dr.ceil(0.5 * n2), n2)
    e1, e2 = edge1 / n1, edge2 / n2  # the sub-parallelogram's edges: E_1 = e1 d_2, E_2 = e2 d_1
    return Parallelogram(px, py, e1 * second.dx, e1 * second.dy, e2 * first.dx, e2 * first.dy, n1, n2, sine)


def cell_centre(shape: Parallelogram, index, columns):
    """Centre of cell ``index`` (row-major over ``columns`` = n_1) of the parallelogram."""
    j, k = index % columns, index // columns
    f1 = mi.Float(j) + 0.5 - 0.5 * shape.n1
    f2 = mi.Float(k) + 0.5 - 0.5 * shape.n2
    return shape.px + f1 * shape.e1x + f2 * shape.e2x, shape.py + f1 * shape.e1y + f2 * shape.e2y


def crossing_correction(first: SegmentGeometry, second: SegmentGeometry, xi_x, xi_y, k_z, sigma,
                        first_run=None, second_run=None) -> Cx:
    """``C(ξ)`` of a crossing pair, per wavelength: flat-bottomed pairs as in the module docstring, pairs
    with a V-groove by :func:`_sloped_correction` (each costs only in SIMD packets that hold one).

    ``first_run``, ``second_run``: how far (µm) each groove runs straight on before its piece's start and
    after its end (:func:`.tables.continuations`); where a groove ends inside P (a crossing next to a
    scratch's end), the pair's cells are clipped to the grooves' rectangles (:func:`run_ends`)."""
    shape = parallelogram(first, second, sigma)
    grooved = first.triangular | second.triangular
    ends = None
    if first_run is not None:
        ends, cut_any = run_ends(shape, first, second, first_run, second_run)
        cut = cut_any & flat_bottomed(grooved)
    else:
        cut = dr.zeros(mi.Bool)
    cells = dr.select(grooved | cut, 0, mi.UInt32(shape.n1 * shape.n2))
    columns = dr.maximum(mi.UInt32(shape.n1), 1)

    def step(index, re, im):
        cx, cy = cell_centre(shape, index, columns)
        term = _cell_integral(shape, cx, cy, xi_x, xi_y, sigma)
        return index + 1, type(xi_x)(re + term.re), type(xi_x)(im + term.im)

    zero = dr.zeros(type(xi_x))
    _, re, im = dr.while_loop((mi.UInt32(0), zero, zero), lambda index, re, im: index < cells, step,
                              label="scratch_overlap")
    if ends is not None:  # cells cut by a groove's end: clipped polygons (only packets holding one pay)
        cut_cells = dr.select(cut, mi.UInt32(shape.n1 * shape.n2), 0)

        def clipped_step(index, re, im):
            cx, cy = cell_centre(shape, index, columns)
            strips = cell_strips(shape, first, second) + [end.at(cx, cy) for end in ends]
            term = clipped_cell(strips, cx, cy, xi_x, xi_y, sigma)
            return index + 1, type(xi_x)(re + term.re), type(xi_x)(im + term.im)

        _, re, im = dr.while_loop((mi.UInt32(0), re, im), lambda index, re, im: index < cut_cells, clipped_step,
                                  label="scratch_overlap_clipped")
    shallow = k_z * dr.minimum(first.depth, second.depth)
    flat = -((expi(shallow) - 1.0) * Cx(re, im))
    return flat + _sloped_correction(first, second, shape, grooved, xi_x, xi_y, k_z, sigma, ends,
                                     None if ends is None else cut_any & grooved)


def cell_strips(shape: Parallelogram, first: SegmentGeometry, second: SegmentGeometry) -> list:
    """A cell of ``shape`` as two :class:`.polygon.Strip` relative to its centre (a 1/n_k slice of each strip)."""
    return [Strip(-first.dy, first.dx, 0.0, 0.5 * first.width / shape.n1),
            Strip(-second.dy, second.dx, 0.0, 0.5 * second.width / shape.n2)]


class RunEnd(NamedTuple):
    """The band of a groove's run along its direction: ``|d·x - middle| <= half`` (local frame, µm)."""

    dx: object
    dy: object
    middle: object
    half: object

    def at(self, cx, cy) -> Strip:
        """The band as a :class:`.polygon.Strip` relative to the cell centre ``c``."""
        return Strip(self.dx, self.dy, self.middle - (self.dx * cx + self.dy * cy), self.half)


def run_ends(shape: Parallelogram, first: SegmentGeometry, second: SegmentGeometry, first_run, second_run):
    """``([RunEnd, RunEnd], cut)``: the bands along each groove between its run's ends (the piece's start
    minus ``run[0]`` µm, its end plus ``run[1]``), and whether one of them cuts the parallelogram (a
    crossing next to a scratch's end: the overlap ends there too)."""
    ends, cut = [], dr.zeros(mi.Bool)
    full1x, full1y = shape.e1x * shape.n1, shape.e1y * shape.n1  # the whole edges E_1, E_2
    full2x, full2y = shape.e2x * shape.n2, shape.e2y * shape.n2
    for line, (before, after) in ((first, first_run), (second, second_run)):
        low, high = line.c - before, line.c + line.length + after
        centre = line.dx * shape.px + line.dy * shape.py
        reach = 0.5 * (dr.abs(line.dx * full1x + line.dy * full1y) + dr.abs(line.dx * full2x + line.dy * full2y))
        cut |= (centre - reach < low) | (centre + reach > high)
        ends.append(RunEnd(line.dx, line.dy, 0.5 * (low + high), 0.5 * (high - low)))
    return ends, cut


def _cell_integral(shape: Parallelogram, cx, cy, xi_x, xi_y, sigma) -> Cx:
    """``∫ w e^{-2πiξ·x}`` over the cell of ``shape`` centred at ``c`` (module docstring)."""
    e1x, e1y, e2x, e2y = shape.e1x, shape.e1y, shape.e2x, shape.e2y
    inv_sigma2 = dr.rcp(sigma * sigma)
    # mean of |x - centre|²/2 over a sub-parallelogram
    curvature = (e1x * e1x + e1y * e1y + e2x * e2x + e2y * e2y) * (1.0 / 24.0)
    slope = (-1.0 / (2.0 * math.pi)) * inv_sigma2
    # ζ = ξ - i c/(2πσ²): the imaginary parts of ζ·E are the window's slope along the edges
    im1 = slope * (cx * e1x + cy * e1y)
    im2 = slope * (cx * e2x + cy * e2y)
    exponent = -(0.5 * (cx * cx + cy * cy) + curvature) * inv_sigma2 + math.pi * (dr.abs(im1) + dr.abs(im2))
    area = dr.abs(e1x * e2y - e1y * e2x)  # |E_1 × E_2|
    return (expi((-2.0 * math.pi) * (xi_x * cx + xi_y * cy)) * scaled_sinc(xi_x * e1x + xi_y * e1y, im1)
            * scaled_sinc(xi_x * e2x + xi_y * e2y, im2) * (dr.exp(exponent) * area))


def depth_plane(segment: SegmentGeometry, cx, cy, side=None):
    """The depth over the cell centred at ``c`` as a plane: ``(h(c), ∇h)`` (µm, per µm).

    Flat bottom: D.  V-groove: D(1 - 2|u|/W) with u = n·x - a⊥, linear on either side of the centre
    line: ``side`` (±1, the sign of u) or, by default, the side of ``c`` (cells of :func:`parallelogram`
    lie on one side)."""
    nx, ny = -segment.dy, segment.dx
    u = nx * cx + ny * cy - segment.a_perp
    if side is None:
        side = dr.select(u >= 0.0, 1.0, -1.0)
    width = dr.maximum(segment.width, MIN_WIDTH_UM)  # (a zero width would make the facet slope infinite)
    rate = dr.select(segment.triangular, -2.0 * segment.depth * side / width, 0.0)
    return segment.depth + rate * u, rate * nx, rate * ny


def below(lower, upper, reach):
    """The half-plane (a :class:`.polygon.Strip`) of the cell where the plane ``lower`` = (h(c), ∇h) is at
    most the plane ``upper``: ``m·y <= t`` (y = x - c), with t clipped to ±``reach`` (the cell lies within
    reach/2 of c); all or nothing where the planes are parallel."""
    gx, gy = lower[1] - upper[1], lower[2] - upper[2]
    level = lower[0] - upper[0]
    norm = dr.sqrt(gx * gx + gy * gy)
    tilted = norm > 1e-6  # else h_1 - h_2 varies by less than a picometre over the cell
    inv = dr.rcp(dr.select(tilted, norm, 1.0))
    mx, my = dr.select(tilted, gx * inv, 1.0), dr.select(tilted, gy * inv, 0.0)
    t = dr.select(tilted, dr.clip(-level * inv, -reach, reach), dr.select(level <= 0.0, reach, -reach))
    return Strip(mx, my, t)


def _sloped_correction(first: SegmentGeometry, second: SegmentGeometry, shape: Parallelogram, active,
                       xi_x, xi_y, k_z, sigma, ends=None, cut=None) -> Cx:
    """``C(ξ) = -∫_P (e^{ik_z min(h_1, h_2)} - 1) w e^{-2πiξ·x}`` where a depth varies across P (docs/model.md §3.4).

    On a cell both depths are planes (:func:`depth_plane`); the line h_1 = h_2 cuts it into Q_1 (h_1 ≤ h_2)
    and Q_2, and over each ``e^{ik_z h}`` with h = h(c) + ∇h·(x - c) is a shift of the frequency by
    k_z ∇h / 2π, so ``∫_Q e^{ik_z h} w e^{-2πiξ·x} = e^{ik_z (h(c) - ∇h·c)} ∫_Q w e^{-2πiξ'·x}``, the clipped
    cell of :mod:`.polygon`.  The -1 is the whole cell's integral.  Where ``cut`` (a groove ends inside P:
    :func:`run_ends`), every cell is clipped to the bands ``ends`` too, the -1 included.
    """
    cells = dr.select(active, mi.UInt32(shape.n1 * shape.n2), 0)
    columns = dr.maximum(mi.UInt32(shape.n1), 1)
    # every point of a cell lies within reach/2 of its centre
    reach = dr.norm(mi.Vector2f(shape.e1x, shape.e1y)) + dr.norm(mi.Vector2f(shape.e2x, shape.e2y))
    spectrum = type(xi_x)
    scale = k_z * (1.0 / (2.0 * math.pi))

    def step(index, re, im):
        cx, cy = cell_centre(shape, index, columns)
        h1, g1x, g1y = depth_plane(first, cx, cy)
        h2, g2x, g2y = depth_plane(second, cx, cy)
        gx, gy = g1x - g2x, g1y - g2y
        level = h1 - h2
        lower_half = below((h1, g1x, g1y), (h2, g2x, g2y), reach)  # h_1 <= h_2
        upper_half = Strip(-lower_half.nx, -lower_half.ny, -lower_half.offset)
        phase1, phase2 = k_z * (h1 - g1x * cx - g1y * cy), k_z * (h2 - g2x * cx - g2y * cy)

        def split(cx, cy):
            """The line h_1 = h_2 crosses the cell (or a groove's end does): two clipped polygons."""
            cell = cell_strips(shape, first, second)
            if ends is not None:
                cell += [end.at(cx, cy) for end in ends]
            lower = clipped_cell(cell + [lower_half], cx, cy,
                                 spectrum(xi_x - scale * g1x), spectrum(xi_y - scale * g1y), sigma)
            upper = clipped_cell(cell + [upper_half], cx, cy,
                                 spectrum(xi_x - scale * g2x), spectrum(xi_y - scale * g2y), sigma)
            term = expi(phase1) * lower + expi(phase2) * upper
            return term.re, term.im

        def whole(cx, cy):
            """One depth is the smaller over the whole cell: the parallelogram at a shifted frequency."""
            first_lower = level <= 0.0
            slope_x = dr.select(first_lower, g1x, g2x)
            slope_y = dr.select(first_lower, g1y, g2y)
            term = expi(dr.select(first_lower, phase1, phase2)) * _cell_integral(
                shape, cx, cy, spectrum(xi_x - scale * slope_x), spectrum(xi_y - scale * slope_y), sigma)
            return term.re, term.im

        # h_1 - h_2 keeps its sign over the cell where its value at the centre exceeds its change to the corners
        crossed = dr.abs(level) < 0.5 * (dr.abs(gx * shape.e1x + gy * shape.e1y)
                                         + dr.abs(gx * shape.e2x + gy * shape.e2y))
        if cut is not None:
            crossed |= cut
        re_cut, im_cut = dr.if_stmt((cx, cy), crossed, split, whole, label="scratch_overlap_split")
        if cut is None:
            term = Cx(re_cut, im_cut) - _cell_integral(shape, cx, cy, xi_x, xi_y, sigma)
        else:
            def clipped(cx, cy):
                strips = cell_strips(shape, first, second) + [end.at(cx, cy) for end in ends]
                whole_cell = clipped_cell(strips, cx, cy, xi_x, xi_y, sigma)
                return whole_cell.re, whole_cell.im

            def unclipped(cx, cy):
                whole_cell = _cell_integral(shape, cx, cy, xi_x, xi_y, sigma)
                return whole_cell.re, whole_cell.im

            minus = dr.if_stmt((cx, cy), cut, clipped, unclipped, label="scratch_overlap_sloped_end")
            term = Cx(re_cut, im_cut) - Cx(*minus)
        return index + 1, spectrum(re - term.re), spectrum(im - term.im)

    zero = dr.zeros(spectrum)
    _, re, im = dr.while_loop((mi.UInt32(0), zero, zero), lambda index, re, im: index < cells, step,
                              label="scratch_overlap_sloped")
    return Cx(re, im)
