"""Height-field correction of two crossing rectangular pieces (Dr.Jit side; docs/model.md §3.4).

On the overlap P of two flat-bottomed scratches of depths D_1, D_2 the sum of
transfer functions gives ``e^{iκ_1} + e^{iκ_2} - 1`` where the height field
has ``e^{iκ_max}``; the difference is ``-(e^{iκ_min} - 1)``, so

    C(ξ) = -(e^{iκ_min} - 1) ∫_P w(x) e^{-2πiξ·x} dx,      κ = k_z D.

P is the parallelogram of the two strips ``|n_k·x - a⊥_k| <= W_k/2``: centre
``p = (a⊥_1 d_2 - a⊥_2 d_1)/sin θ`` (sin θ = d_1 × d_2), edges
``E_1 = W_1 d_2/sin θ`` and ``E_2 = W_2 d_1/sin θ``.  The window is expanded
about p: its value and slope exactly (a complex frequency
``ζ = ξ - i p/(2πσ²)``), its curvature by its mean over P, so

    ∫_P w e^{-2πiξ·x} ≈ w(p) e^{-2πiξ·p} e^{-(|E_1|² + |E_2|²)/(24σ²)} |E_1 × E_2| sinc(ζ·E_1) sinc(ζ·E_2)

with the normalised sinc of a complex argument.  Lengths in µm.
"""
from __future__ import annotations

import math

import drjit as dr

from .complexmath import Cx, expi
from .segment import SegmentGeometry

__all__ = ["crossing_correction"]

#: Below this |πz|² the complex sinc is its series 1 - (πz)²/6 (next term < 1e-9).
_SERIES_BELOW = 1e-4


def _sinc(re, im) -> Cx:
    """``sin(πz)/(πz)`` for ``z = re + i im`` (normalised sinc, complex argument)."""
    x, y = math.pi * re, math.pi * im
    s, c = dr.sincos(x)
    e = dr.exp(y)
    inv_e = dr.rcp(e)
    cosh, sinh = 0.5 * (e + inv_e), 0.5 * (e - inv_e)
    numerator = Cx(s * cosh, c * sinh)  # sin(x + iy)
    z = Cx(x, y)
    z2 = z * z
    small = z2.abs2() < _SERIES_BELOW * _SERIES_BELOW
    series = 1.0 - z2 * (1.0 / 6.0)
    return (numerator / Cx(dr.select(small, 1.0, x), dr.select(small, 0.0, y))).select(~small, series)


def crossing_correction(first: SegmentGeometry, second: SegmentGeometry, xi_x, xi_y, k_z, sigma) -> Cx:
    """``C(ξ)`` of a crossing pair of rectangular pieces, per wavelength (see the module docstring)."""
    sine = first.dx * second.dy - first.dy * second.dx
    sine = dr.select(dr.abs(sine) > 1e-6, sine, 1e-6)
    inv_sine = dr.rcp(sine)
    # centre of the overlap (relative to x0) and its edges
    px = (first.a_perp * second.dx - second.a_perp * first.dx) * inv_sine
    py = (first.a_perp * second.dy - second.a_perp * first.dy) * inv_sine
    e1 = first.width * inv_sine
    e2 = second.width * inv_sine
    e1x, e1y = e1 * second.dx, e1 * second.dy
    e2x, e2y = e2 * first.dx, e2 * first.dy
    area = dr.abs(first.width * second.width * inv_sine)
    sigma2 = sigma * sigma
    p2 = px * px + py * py
    spread2 = e1 * e1 + e2 * e2  # |E_1|² + |E_2|²
    window = dr.exp(-(0.5 * p2 + spread2 * (1.0 / 24.0)) / sigma2)
    # ζ = ξ - i p/(2πσ²): the imaginary parts of ζ·E are the window's slope along the edges
    slope = -1.0 / ((2.0 * math.pi) * sigma2)
    sinc1 = _sinc(xi_x * e1x + xi_y * e1y, slope * (px * e1x + py * e1y))
    sinc2 = _sinc(xi_x * e2x + xi_y * e2y, slope * (px * e2x + py * e2y))
    shallow = k_z * dr.minimum(first.depth, second.depth)
    step = expi(shallow) - 1.0
    centre = expi((-2.0 * math.pi) * (xi_x * px + xi_y * py))
    return -(step * centre * sinc1 * sinc2 * (window * area))
