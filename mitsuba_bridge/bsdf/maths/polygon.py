"""Windowed Fourier transform of the intersection of three strips (Dr.Jit side; docs/model.md §3.4).

The triple term of the height-field correction integrates over the region
where three rectangular scratches overlap, a convex polygon of at most six
edges.  :mod:`.triples` cuts it into cells of the pair parallelogram (edges
≤ σ/2), each the intersection of three strips ``|n_s·y - m_s| <= h_s``
(``y`` relative to the cell centre ``c``, µm).  Over a cell the window is
expanded as in :mod:`.overlap`: value and slope exactly (the complex
frequency ``ζ = ξ - iη``, ``η = c/(2πσ²)``), its curvature by its mean over
the clipped polygon, so

    ∫ w e^{-2πiξ·x} ≈ w(c) e^{-2πiξ·c} e^{-<|y|²>/(2σ²)} F(ζ),   F(ζ) = ∫_Ω e^{-2πiζ·y} dy.

``F`` by the divergence theorem with the field ``a e^{-2πiζ·y}/(-2πi ζ·a)``
(``a`` a real unit vector, the direction of ξ or of η, whichever is longer, so
that ``|ζ·a| >= |ζ|/√2`` never vanishes unless ζ does):

    F(ζ) = i/(2π ζ·a) Σ_edges (a·N_e) ∫_edge e^{-2πiζ·y} ds

and each edge integral is ``Δ e^{-2πiζ·y_mid} sinc(ζ·d Δ)``.  Every edge lies on
one of the six lines ``n_s·y = m_s ± h_s``; its extent is the interval the
two other strips leave on that line, so no polygon clipping is needed: an
edge outside the polygon has an empty interval.  Area, first and second
moments come from the same edges (Green's theorem); where ``2π|ζ·a|`` times
the polygon's size is below ``SERIES_BELOW`` (float32 cancellation) ``F`` is its
Taylor series ``A - 2πi ζ·∫y``.
"""
from __future__ import annotations

import math

import drjit as dr

from .complexmath import Cx, expi, scaled_sinc

__all__ = ["Strip", "clipped_cell"]

#: Below this 2π|ζ·a|·size the transform is its first-order series (float32 cancellation of the
#: edge sum ~ 6e-8 / (2π|ζ·a| size) < 1e-5 there; series error ~ (2π|ζ| size)²/10 < 2e-5).
SERIES_BELOW = 1e-2
#: Largest exponent formed (float32 overflows above ~88): only degenerate, far-off cells reach it.
MAX_EXPONENT = 60.0


class Strip:
    """``|n·y - offset| <= half_width`` (local frame, µm, relative to the cell centre); with
    ``half_width=None`` the half-plane ``n·y <= offset`` (one edge instead of two)."""

    __slots__ = ("nx", "ny", "offset", "half_width")

    def __init__(self, nx, ny, offset, half_width=None):
        self.nx, self.ny, self.offset, self.half_width = nx, ny, offset, half_width

    def levels(self):
        """``(level, sign)`` of each boundary line ``n·y = level``, ``sign`` n's orientation outwards."""
        if self.half_width is None:
            return [(self.offset, 1.0)]
        return [(self.offset + self.half_width, 1.0), (self.offset - self.half_width, -1.0)]


#: Far end of the interval a half-plane leaves on a line (µm): beyond any polygon here.
_UNBOUNDED = 1e30
#: Parallel boundary lines closer than this (µm) are one line (float32 offsets of a few µm: ~1e-6 µm).
TIE_UM = 1e-5


def _interval_on_line(line: Strip, level, sign, other: Strip, first: bool):
    """Parameter interval ``[lo, hi]`` of ``y = level n + τ d`` (d = (n_y, -n_x)) inside ``other``.

    ``sign``: the orientation of the edge's outward normal (``sign`` n); ``first``: whether ``line``'s strip
    comes before ``other`` in the list.  Where the two are parallel the whole line is inside or outside;
    where it lies on one of ``other``'s boundary lines (the same line within ``TIE_UM``), the edge counts
    once: if both outward normals agree (the same half-plane twice, e.g. two strips sharing an edge), only
    the earlier strip's edge is inside; if they are opposite (a polygon of zero width), neither is."""
    dx, dy = line.ny, -line.nx
    raw = other.nx * dx + other.ny * dy
    parallel = dr.abs(raw) <= 1e-6
    slope = dr.select(parallel, 1.0, raw)
    along = other.nx * line.nx + other.ny * line.ny  # ±1 where parallel
    base = level * along
    inv = dr.rcp(slope)

    def tie(outward):  # the parallel test's margin against other's boundary of outward normal ``outward`` n_o
        if not first:
            return -TIE_UM
        return dr.select(sign * along * outward > 0.0, TIE_UM, -TIE_UM)

    if other.half_width is None:  # base + τ slope <= offset
        bound = (other.offset - base) * inv
        inside = base <= other.offset + tie(1.0)
        lo = dr.select(parallel, dr.select(inside, -_UNBOUNDED, _UNBOUNDED),
                       dr.select(slope > 0.0, -_UNBOUNDED, bound))
        hi = dr.select(parallel, dr.select(inside, _UNBOUNDED, -_UNBOUNDED),
                       dr.select(slope > 0.0, bound, _UNBOUNDED))
        return lo, hi
    t1 = (other.offset - other.half_width - base) * inv
    t2 = (other.offset + other.half_width - base) * inv
    inside = ((base <= other.offset + other.half_width + tie(1.0))
              & (base >= other.offset - other.half_width - tie(-1.0)))
    lo = dr.select(parallel, dr.select(inside, -_UNBOUNDED, _UNBOUNDED), dr.minimum(t1, t2))
    hi = dr.select(parallel, dr.select(inside, _UNBOUNDED, -_UNBOUNDED), dr.maximum(t1, t2))
    return lo, hi


def clipped_cell(strips, cx, cy, xi_x, xi_y, sigma) -> Cx:
    """``∫_Ω w(x) e^{-2πiξ·x} dx`` over the intersection Ω of strips around the cell centre ``c``.

    Parameters
    ----------
    strips:
        Three or more :class:`Strip` (offsets relative to ``c``; half-planes allowed), bounding a polygon.
    cx, cy:
        The cell centre relative to the shading point x0 (µm).
    xi_x, xi_y:
        Spatial frequency (µm⁻¹), one per wavelength.
    sigma:
        Window σ (µm).

    Returns
    -------
    The integral per wavelength (see the module docstring for the expansion and its error).
    """
    inv_sigma2 = dr.rcp(sigma * sigma)
    eta_x = cx * inv_sigma2 * (1.0 / (2.0 * math.pi))
    eta_y = cy * inv_sigma2 * (1.0 / (2.0 * math.pi))
    # a: the longer of ξ̂ and η̂ (|ζ·a| >= max(|ξ|, |η|))
    xi_norm = dr.sqrt(xi_x * xi_x + xi_y * xi_y)
    eta_norm = dr.sqrt(eta_x * eta_x + eta_y * eta_y)
    use_xi = xi_norm >= eta_norm
    inv_xi = dr.rcp(dr.maximum(xi_norm, 1e-30))
    inv_eta = dr.rcp(dr.maximum(eta_norm, 1e-30))
    ax = dr.select(use_xi, xi_x * inv_xi, eta_x * inv_eta)
    ay = dr.select(use_xi, xi_y * inv_xi, eta_y * inv_eta)
    ax = dr.select((xi_norm > 0.0) | (eta_norm > 0.0), ax, 1.0)

    zero = dr.zeros(type(xi_x))
    flux_re, flux_im = zero, zero
    area, first_x, first_y, second, perimeter = 0.0, 0.0, 0.0, 0.0, 0.0
    terms = []
    for s in range(len(strips)):
        line = strips[s]
        others = [(strips[r], s < r) for r in range(len(strips)) if r != s]
        for level, sign in line.levels():
            lo = hi = None
            for other, first in others:
                a, b = _interval_on_line(line, level, sign, other, first)
                lo = a if lo is None else dr.maximum(lo, a)
                hi = b if hi is None else dr.minimum(hi, b)
            length = dr.maximum(hi - lo, 0.0)
            middle = dr.select(length > 0.0, 0.5 * (lo + hi), 0.0)
            dx, dy = line.ny, -line.nx
            # end points, in the polygon's counter-clockwise order (along -sign·d)
            px, py = level * line.nx + middle * dx, level * line.ny + middle * dy
            half = 0.5 * length * sign
            start_x, start_y = px + half * dx, py + half * dy
            end_x, end_y = px - half * dx, py - half * dy
            cross = start_x * end_y - start_y * end_x
            area = area + 0.5 * cross
            first_x = first_x + cross * (start_x + end_x) * (1.0 / 6.0)
            first_y = first_y + cross * (start_y + end_y) * (1.0 / 6.0)
            second = second + cross * (start_x * start_x + start_y * start_y + start_x * end_x
                                       + start_y * end_y + end_x * end_x + end_y * end_y) * (1.0 / 12.0)
            perimeter = perimeter + length
            terms.append((sign * line.nx, sign * line.ny, px, py, dx, dy, length))

    # curvature of the window by its mean over Ω: e^{-<|y|²>/(2σ²)}; w(c) e^{..} joins the exponents
    # (a sliver's moments are rounding noise: a negative mean square would grow the window by up to e^60)
    mean_square = dr.maximum(second * dr.rcp(dr.maximum(area, 1e-30)), 0.0)
    base_exponent = -(0.5 * (cx * cx + cy * cy) + 0.5 * mean_square) * inv_sigma2
    zeta_a = Cx(xi_x * ax + xi_y * ay, -(eta_x * ax + eta_y * ay))
    for normal_x, normal_y, px, py, dx, dy, length in terms:
        # e^{-2πiζ·y_mid} = e^{-2πiξ·y_mid} e^{-2π η·y_mid}; the sinc's growth e^{π|Im|} joins the exponent
        arg_im = -(eta_x * dx + eta_y * dy) * length
        exponent = base_exponent - 2.0 * math.pi * (eta_x * px + eta_y * py) + math.pi * dr.abs(arg_im)
        term = (expi((-2.0 * math.pi) * (xi_x * px + xi_y * py))
                * scaled_sinc((xi_x * dx + xi_y * dy) * length, arg_im)
                * (dr.exp(dr.minimum(exponent, MAX_EXPONENT)) * length * (normal_x * ax + normal_y * ay)))
        flux_re, flux_im = flux_re + term.re, flux_im + term.im
    # F = i/(2π ζ·a) Σ flux, or its series where ζ·a is too small for the edge sum's cancellation
    transform = (Cx(flux_re, flux_im) / zeta_a).mul_i() * (1.0 / (2.0 * math.pi))
    size = 0.25 * perimeter  # about the polygon's diameter
    small = 2.0 * math.pi * dr.sqrt(zeta_a.abs2()) * size < SERIES_BELOW
    weight = dr.exp(dr.minimum(base_exponent, MAX_EXPONENT))
    series = Cx(weight * (area - 2.0 * math.pi * (eta_x * first_x + eta_y * first_y)),
                weight * (-2.0 * math.pi) * (xi_x * first_x + xi_y * first_y))
    result = transform.select(~small, series)
    return expi((-2.0 * math.pi) * (xi_x * cx + xi_y * cy)) * result
