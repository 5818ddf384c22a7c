"""Windowed cross-section transforms of the scratch profiles (docs/model.md §3.1, exact form).

``A(ν) = ∫ w⊥(x) (exp(iκ p(x - a⊥)) - 1) exp(-2πiνx) dx`` across a scratch whose
centre line lies at signed distance ``a⊥`` from the shading point, with the
window's cross factor ``w⊥(x) = exp(-x²/2σ²)``, the normalised depth profile
``p`` in [0, 1] on ``|x - a⊥| <= W/2`` and ``κ = k_z D``.

The complex-frequency form (docs/model.md §3.3) approximates the window across
the scratch by its value and slope
at the centre line (``e^{-a⊥²/2σ²} G(ν⊥ - i a⊥/(2πσ²))``); it drops the
window's curvature, which costs ≈ 10 % (relative L2 of f_r) on an offset
2 µm V-groove at σ = 2 µm and up to ≈ 30 % between grating orders
(tests/bridge/bsdf/test_reference.py).  Here each linear piece of the profile has a
linear phase, so its windowed transform is a partial Gaussian integral at a
shifted frequency, :func:`.window.window_integral`: the transform is exact for
any width, at the price of two complex error functions per piece edge.

``coherent=False`` gives the transform of ``exp(iκp)`` over the footprint
instead (the scratch's own reflection, used by the incoherent mode, docs/model.md §4.2).
Lengths in µm, frequencies in 1/µm; ``κ`` is real (one value per wavelength).
"""
from __future__ import annotations

import math

import drjit as dr

from .complexmath import Cx, expi
from .window import clamp_to_window, line_term, unphased_end_term, window_integral

__all__ = ["rectangular", "triangular", "energy_rectangular", "energy_triangular", "MIN_WIDTH_UM"]

_SQRT_HALF_PI = math.sqrt(0.5 * math.pi)
#: Narrower scratches are treated as this wide (guards the facet slope 1/W).
MIN_WIDTH_UM = 1e-4


def rectangular(a_perp, width, nu, kappa, sigma, coherent: bool = True) -> Cx:
    """Flat-bottomed groove: ``(e^{iκ} - 1) ∫_{a⊥-W/2}^{a⊥+W/2} w⊥ e^{-2πiνx} dx``."""
    half = 0.5 * width
    phase = expi(kappa)
    if coherent:
        phase = phase - 1.0
    return window_integral(a_perp - half, a_perp + half, nu, sigma, False) * phase


def triangular(a_perp, width, nu, kappa, sigma, coherent: bool = True) -> Cx:
    """V-groove ``p(u) = 1 - 2|u|/W``: two facets of slope ±2D/W.

    The facet on ``[a⊥ - W/2, a⊥]`` has phase ``κ - τ + (2κ/W) x`` with ``τ = 2κa⊥/W``,
    i.e. frequency ``ν - κ/(πW)``; the other facet mirrors it (docs/model.md §3.1).

    Evaluated as the sum of the facets' partial window integrals, with the phases of their ends
    gathered per edge: at the outer edges the facet's tilt cancels its ``e^{iκ}`` (``2π s W/2 = κ``),
    so an edge's phase is the flat footprint's ``e^{-2πiνt}``, and at the apex both facets share
    ``e^{i(κ - 2πνa⊥)}``; the line term of the facet over the foot point has the depth phase there,
    ``e^{iκ p(-a⊥)}``.  Four complex exponentials per wavelength instead of eight, for the same six
    Faddeeva evaluations (four without the footprint, ``coherent=False``).
    """
    width = dr.maximum(width, MIN_WIDTH_UM)
    half = 0.5 * width
    shift = kappa / (math.pi * width)  # facet frequency offset, 1/µm
    left, apex, right = (clamp_to_window(t, sigma) for t in (a_perp - half, a_perp, a_perp + half))
    # (clamped edges lie beyond 8σ, where their terms are e^-32 of the window: phases taken there alike)
    phase_left = expi((-2.0 * math.pi) * nu * left)
    phase_right = expi((-2.0 * math.pi) * nu * right)
    phase_apex = expi(kappa - (2.0 * math.pi) * nu * apex)
    below, above = nu - shift, nu + shift  # the left and the right facet's frequency
    at_apex = unphased_end_term(apex, below, sigma) - unphased_end_term(apex, above, sigma)
    outer_right, outer_left = unphased_end_term(right, above, sigma), unphased_end_term(left, below, sigma)
    if coherent:  # less the flat footprint's transform (the "- 1" of e^{iκp} - 1), edge by edge
        outer_right = outer_right - unphased_end_term(right, nu, sigma)
        outer_left = outer_left - unphased_end_term(left, nu, sigma)
    result = phase_apex * at_apex + phase_right * outer_right - phase_left * outer_left
    # the step at the foot point x0 (relative offset 0) where x0 lies in the groove: the facet over it
    # (the left one where a⊥ >= 0) at the depth phase there
    inside = (left < 0.0) & (right >= 0.0)
    step = expi(kappa * (1.0 - dr.abs(a_perp) * (2.0 / width))) * line_term(dr.select(apex >= 0.0, below, above), sigma)
    if coherent:
        step = step - line_term(nu, sigma)
    result = result + step.select(inside, Cx(0.0, 0.0))
    return result * (_SQRT_HALF_PI * sigma)


def energy_rectangular(kappa):
    """``(1/W) ∫ |e^{iκp} - 1|² du = 4 sin²(κ/2)`` for the flat bottom."""
    return 4.0 * dr.square(dr.sin(0.5 * kappa))


def energy_triangular(kappa):
    """``(1/W) ∫ |e^{iκp} - 1|² du = 2 (1 - sin κ / κ)`` for the V-groove."""
    kappa2 = kappa * kappa
    # 1 - sin κ / κ without cancellation for small κ (next series term < 1e-7).
    series = kappa2 * (1.0 / 6.0) * (1.0 - kappa2 * (1.0 / 20.0))
    return 2.0 * dr.select(kappa2 < 0.09, series, 1.0 - dr.sin(kappa) / kappa)
