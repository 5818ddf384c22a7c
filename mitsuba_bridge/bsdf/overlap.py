"""Height-field correction of two crossing rectangular pieces (Dr.Jit side; docs/model.md §3.4).

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

with the normalised sinc of a complex argument.  Lengths in µm.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from .complexmath import Cx, expi
from .segment import SegmentGeometry

__all__ = ["Parallelogram", "cell_centre", "crossing_correction", "parallelogram", "scaled_sinc"]

#: Below this |πz|² the complex sinc is its series 1 - (πz)²/6 (next term < 1e-9).
_SERIES_BELOW = 1e-4
#: The overlap is cut into n_1 × n_2 sub-parallelograms with edges at most this many σ long, each with
#: its own window expansion: the neglected curvature then stays below ~1 % (docs/model.md §3.4).
SUB_EDGE_SIGMAS = 0.5
#: ... and at most this many along each edge (longer edges get longer cells: at |sin θ| = 0.1, from W = 0.4σ).
MAX_SPLIT = 8


def scaled_sinc(re, im) -> Cx:
    """``e^{-π|im|} sin(πz)/(πz)`` for ``z = re + i im``: the normalised sinc without its growth e^{π|im|}.

    The growth is returned to the caller's exponent, where the window's decay cancels it (a sinc of
    |πz| ≈ 100 would overflow float32 on its own).
    """
    x, y = math.pi * re, math.pi * im
    s, c = dr.sincos(x)
    decay = dr.exp(-2.0 * dr.abs(y))
    half_cosh, half_sinh = 0.5 * (1.0 + decay), dr.copysign(0.5 * (1.0 - decay), y)
    numerator = Cx(s * half_cosh, c * half_sinh)  # sin(x + iy) e^{-|y|}
    z = Cx(x, y)
    z2 = z * z
    small = z2.abs2() < _SERIES_BELOW * _SERIES_BELOW
    series = (1.0 - z2 * (1.0 / 6.0)) * dr.exp(-dr.abs(y))
    return (numerator / Cx(dr.select(small, 1.0, x), dr.select(small, 0.0, y))).select(~small, series)


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
    ``sub_edge_sigmas`` σ (and at most MAX_SPLIT per edge; module docstring)."""
    sine = first.dx * second.dy - first.dy * second.dx
    sine = dr.select(dr.abs(sine) > 1e-6, sine, 1e-6)
    inv_sine = dr.rcp(sine)
    # centre of the overlap (relative to x0) and its edge lengths along d_2 and d_1
    px = (first.a_perp * second.dx - second.a_perp * first.dx) * inv_sine
    py = (first.a_perp * second.dy - second.a_perp * first.dy) * inv_sine
    edge1 = first.width * dr.abs(inv_sine)
    edge2 = second.width * dr.abs(inv_sine)
    sub_edge = sub_edge_sigmas * sigma
    # (at least 1: lanes without a partner divide by the column count too)
    n1 = dr.clip(dr.ceil(edge1 / sub_edge), 1.0, MAX_SPLIT)
    n2 = dr.clip(dr.ceil(edge2 / sub_edge), 1.0, MAX_SPLIT)
    e1, e2 = edge1 / n1, edge2 / n2  # the sub-parallelogram's edges: E_1 = e1 d_2, E_2 = e2 d_1
    return Parallelogram(px, py, e1 * second.dx, e1 * second.dy, e2 * first.dx, e2 * first.dy, n1, n2, sine)


def cell_centre(shape: Parallelogram, index, columns):
    """Centre of cell ``index`` (row-major over ``columns`` = n_1) of the parallelogram."""
    j, k = index % columns, index // columns
    f1 = mi.Float(j) + 0.5 - 0.5 * shape.n1
    f2 = mi.Float(k) + 0.5 - 0.5 * shape.n2
    return shape.px + f1 * shape.e1x + f2 * shape.e2x, shape.py + f1 * shape.e1y + f2 * shape.e2y


def crossing_correction(first: SegmentGeometry, second: SegmentGeometry, xi_x, xi_y, k_z, sigma) -> Cx:
    """``C(ξ)`` of a crossing pair of rectangular pieces, per wavelength (see the module docstring)."""
    shape = parallelogram(first, second, sigma)
    e1x, e1y, e2x, e2y, n1, n2 = shape.e1x, shape.e1y, shape.e2x, shape.e2y, shape.n1, shape.n2
    area = dr.abs(e1x * e2y - e1y * e2x)  # |E_1 × E_2| of a cell
    inv_sigma2 = dr.rcp(sigma * sigma)
    # mean of |x - centre|²/2 over a sub-parallelogram
    curvature = (e1x * e1x + e1y * e1y + e2x * e2x + e2y * e2y) * (1.0 / 24.0)
    slope = (-1.0 / (2.0 * math.pi)) * inv_sigma2
    xi_e1 = xi_x * e1x + xi_y * e1y
    xi_e2 = xi_x * e2x + xi_y * e2y
    cells = mi.UInt32(n1 * n2)
    columns = dr.maximum(mi.UInt32(n1), 1)

    def step(index, re, im):
        cx, cy = cell_centre(shape, index, columns)
        # ζ = ξ - i c/(2πσ²): the imaginary parts of ζ·E are the window's slope along the edges
        im1 = slope * (cx * e1x + cy * e1y)
        im2 = slope * (cx * e2x + cy * e2y)
        exponent = -(0.5 * (cx * cx + cy * cy) + curvature) * inv_sigma2 + math.pi * (dr.abs(im1) + dr.abs(im2))
        term = (expi((-2.0 * math.pi) * (xi_x * cx + xi_y * cy)) * scaled_sinc(xi_e1, im1)
                * scaled_sinc(xi_e2, im2) * dr.exp(exponent))
        return index + 1, type(xi_x)(re + term.re), type(xi_x)(im + term.im)

    zero = dr.zeros(type(xi_x))
    _, re, im = dr.while_loop((mi.UInt32(0), zero, zero), lambda index, re, im: index < cells, step,
                              label="scratch_overlap")
    shallow = k_z * dr.minimum(first.depth, second.depth)
    return -((expi(shallow) - 1.0) * Cx(re, im) * area)
