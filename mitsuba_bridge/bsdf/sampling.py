"""Importance-sampling pieces in ξ-space (docs/model.md §5).  Units: µm and 1/µm.

Every sampler here comes with its density; :mod:`.model` combines them with
one-sample MIS (balance heuristic) and maps ξ to a direction.
"""
from __future__ import annotations

import math

import drjit as dr

from .maths import profiles
from .maths.segment import SegmentGeometry

__all__ = [
    "lobe_std", "sample_mirror", "pdf_mirror", "window_energy", "selection_weight", "groove_energy",
    "sample_along", "pdf_along", "sample_across", "pdf_across", "ALONG_CAUCHY_WEIGHT",
]

#: Share of the heavy-tailed (Cauchy) part of the ν∥ mixture: segment ends inside
#: the window spread light as 1/ν∥² away from the diffraction line.
ALONG_CAUCHY_WEIGHT = 0.25
#: Shares of the (centre, +facet, -facet) Cauchy components across a V-groove.
V_GROOVE_WEIGHTS = (0.2, 0.4, 0.4)
#: Selection weight floor relative to κ² (keeps grooves sampled where 4 sin²(κ/2) vanishes at γ_o = γ_i).
ENERGY_FLOOR = 0.1


def lobe_std(sigma):
    """Standard deviation of the mirror lobe ``|U0|²`` per ξ axis: ``1/(2√2 π σ)``."""
    return 1.0 / (2.0 * math.sqrt(2.0) * math.pi * sigma)


# ------------------------------------------------------------- mirror lobe
def sample_mirror(u, sigma):
    """ξ ~ N(0, s² I) by the Box–Muller transform of ``u`` (a 2-D uniform sample)."""
    s = lobe_std(sigma)
    radius = s * dr.sqrt(-2.0 * dr.log(dr.maximum(1.0 - u.x, 1e-30)))
    sin_phi, cos_phi = dr.sincos((2.0 * math.pi) * u.y)
    return radius * cos_phi, radius * sin_phi


def pdf_mirror(xi2, sigma):
    """``4πσ² exp(-4π²σ²|ξ|²)``, exactly ``|U0|² / A_s``."""
    sigma2 = sigma * sigma
    return (4.0 * math.pi) * sigma2 * dr.exp((-4.0 * math.pi ** 2) * sigma2 * xi2)


# ---------------------------------------------------------- segment choice
def window_energy(segment: SegmentGeometry, sigma):
    """``ε_k = ∫ w² χ_k``: the segment's footprint weighted by the squared window.

    ``W e^{-a⊥²/σ²} (σ√π/2) [erf((c + L)/σ) - erf(c/σ)]`` (also the scratch area
    inside the window that the incoherent mode removes from the mirror lobe).
    """
    inv = dr.rcp(sigma)
    along = dr.erf((segment.c + segment.length) * inv) - dr.erf(segment.c * inv)
    return segment.width * dr.exp(-dr.square(segment.a_perp * inv)) * (0.5 * math.sqrt(math.pi)) * sigma * along


def selection_weight(segment: SegmentGeometry, kappa, sigma, coherent: bool):
    """Energy the segment diffracts at depth phase ``kappa`` (hero wavelength, γ_o = γ_i)."""
    return window_energy(segment, sigma) * groove_energy(segment.triangular, kappa, coherent)


def groove_energy(triangular, kappa, coherent: bool):
    """The selection weight per unit of :func:`window_energy`: the profile's diffracted energy, floored."""
    if not coherent:
        return 1.0
    energy = dr.select(triangular, profiles.energy_triangular(kappa), profiles.energy_rectangular(kappa))
    return energy + ENERGY_FLOOR * dr.minimum(kappa * kappa, 1.0)


# ------------------------------------------------------ along the segment
def sample_along(u, sigma):
    """ν∥ from the mixture Gaussian N(0, s²) + Cauchy(scale s); ``u`` uniform in [0, 1)."""
    s = lobe_std(sigma)
    beta = ALONG_CAUCHY_WEIGHT
    cauchy = u < beta
    v = dr.select(cauchy, u / beta, (u - beta) / (1.0 - beta))
    v = dr.clip(v, 1e-7, 1.0 - 1e-7)
    gaussian = (s * math.sqrt(2.0)) * dr.erfinv(2.0 * v - 1.0)
    return dr.select(cauchy, s * dr.tan(math.pi * (v - 0.5)), gaussian)


def pdf_along(nu, sigma):
    s = lobe_std(sigma)
    beta = ALONG_CAUCHY_WEIGHT
    gaussian = dr.exp(-0.5 * dr.square(nu / s)) / (s * math.sqrt(2.0 * math.pi))
    cauchy = s / (math.pi * (nu * nu + s * s))
    return (1.0 - beta) * gaussian + beta * cauchy


# ----------------------------------------------------- across the segment
def _across_components(segment: SegmentGeometry, kappa):
    """(centre, scale, weight) of the Cauchy components: the central lobe and, for V-grooves, the facets."""
    scale = 1.0 / (math.pi * dr.maximum(segment.width, 1e-3))
    facet = kappa * scale
    w0, w1, w2 = V_GROOVE_WEIGHTS
    tri = segment.triangular
    return ((0.0, scale, dr.select(tri, w0, 1.0)),
            (facet, scale, dr.select(tri, w1, 0.0)),
            (-facet, scale, dr.select(tri, w2, 0.0)))


def _truncated_cauchy_bounds(centre, scale, lo, hi):
    return dr.atan((lo - centre) / scale), dr.atan((hi - centre) / scale)


def sample_across(u, segment: SegmentGeometry, kappa, lo, hi):
    """ν⊥ in the visible band [lo, hi] from the Cauchy mixture; ``u`` uniform in [0, 1)."""
    (c0, s0, w0), (c1, s1, w1), (c2, s2, w2) = _across_components(segment, kappa)
    first = u < w0
    second = ~first & (u < w0 + w1)
    v = dr.select(first, u / w0, dr.select(second, (u - w0) / dr.maximum(w1, 1e-6),
                                           (u - w0 - w1) / dr.maximum(w2, 1e-6)))
    v = dr.clip(v, 0.0, 1.0)
    centre = dr.select(first, c0, dr.select(second, c1, c2))
    scale = s0  # all components share the scale 1/(πW)
    a, b = _truncated_cauchy_bounds(centre, scale, lo, hi)
    return dr.clip(centre + scale * dr.tan(dr.fma(v, b - a, a)), lo, hi)


def pdf_across(nu, segment: SegmentGeometry, kappa, lo, hi):
    """Density of :func:`sample_across`; the facet components cost only in SIMD packets holding a V-groove."""
    def mixture(nu, kappa, lo, hi):
        result = 0.0
        for centre, scale, weight in _across_components(segment, kappa):
            result = result + weight * _truncated_cauchy(nu, centre, scale, lo, hi)
        return result

    def central(nu, kappa, lo, hi):
        return _truncated_cauchy(nu, 0.0, 1.0 / (math.pi * dr.maximum(segment.width, 1e-3)), lo, hi)

    result = dr.if_stmt((nu, kappa, lo, hi), segment.triangular, mixture, central, label="scratch_pdf_across")
    return dr.select((nu >= lo) & (nu <= hi), result, 0.0)


def _truncated_cauchy(nu, centre, scale, lo, hi):
    a, b = _truncated_cauchy_bounds(centre, scale, lo, hi)
    return scale / (dr.maximum(b - a, 1e-12) * (dr.square(nu - centre) + scale * scale))
