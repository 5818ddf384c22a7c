"""Directional-albedo estimate for ``depth_phase="bounded"`` (docs/model.md §4.1).

The Kirchhoff depth phase 2π(γ_i + γ_o)D/λ is not a fixed phase screen, so nothing bounds its
directional albedo A(ω) (deep grooves reach 1.4).  ``"bounded"`` divides the Kirchhoff BRDF by
``max(1, Â(ω_i), Â(ω_o))``: reciprocal by construction, unchanged wherever Â ≤ 1 (shallow
scratches), and ∫ f' cos θ_o dω_o ≤ A(ω_i) / max(1, Â(ω_i)) ≤ 1 as far as Â estimates A.

Â(ω) = 1 + Σ_k e_k(ω) with one term per segment in the window (docs/model.md §4.1):

    e_k(ω) = ε∥ / (πσ²) · ∫_band [2 U0⊥(ν) Re A_k(ν) + |A_k(ν)|²] dν,     ε∥ = ∫_c^{c+L} e^{-t²/σ²} dt

the energy the segment adds to the bare window along its diffraction line, with A_k the exact
windowed cross-section transform (:mod:`.profiles`) at the Kirchhoff phase of each outgoing direction
on the line (ν∥ = 0), U0⊥(ν) = σ√(2π) e^{-2π²σ²ν²} the mirror lobe's cross factor and the band the
visible outgoing directions.  The ν integral is a deterministic quadrature: stratified quantiles of a
Gaussian of the lobe's width (the cross term) and of the scratch sampler's truncated Cauchy mixture
(:func:`.sampling.sample_across`, the sinc tails and V-groove facets), combined by the balance heuristic.
Units: µm and 1/µm.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from . import sampling
from .maths.segment import SegmentGeometry, cross_section

__all__ = ["albedo_excess", "GAUSSIAN_NODES", "CAUCHY_NODES"]

#: Quadrature nodes per segment and direction: quantiles of the lobe-wide Gaussian (the cross term
#: with the mirror lobe) and of the sampler's Cauchy mixture across the scratch (the diffraction line).
GAUSSIAN_NODES = 16
CAUCHY_NODES = 48


def along_energy(segment: SegmentGeometry, sigma):
    """``ε∥ = ∫_c^{c+L} e^{-t²/σ²} dt = (σ√π/2)[erf((c + L)/σ) - erf(c/σ)]`` (µm)."""
    inv = dr.rcp(sigma)
    return (0.5 * math.sqrt(math.pi)) * sigma * (dr.erf((segment.c + segment.length) * inv) - dr.erf(segment.c * inv))


def albedo_excess(segment: SegmentGeometry, wi, wo, wavelength, sigma):
    """``(e_k(ω_i), e_k(ω_o))``, each an ``mi.Spectrum`` (one value per wavelength, dimensionless).

    Both directions run through one symbolic loop of ``2 (GAUSSIAN_NODES + CAUCHY_NODES)`` steps
    with identical arithmetic, so ``e_k(ω)`` is the same number whichever role ω plays: the
    normalisation stays exactly reciprocal.
    """
    spectrum = mi.Spectrum
    per_direction = GAUSSIAN_NODES + CAUCHY_NODES
    s = 1.0 / (2.0 * math.pi * sigma)  # standard deviation of U0⊥ in ν (1/µm)
    depth = segment.depth

    def cond(j, e_i, e_o):
        return j < 2 * per_direction

    def body(j, e_i, e_o):
        second = j >= per_direction
        k = dr.select(second, j - per_direction, j)
        wx = dr.select(second, wo.x, wi.x)
        wy = dr.select(second, wo.y, wi.y)
        wz = dr.select(second, wo.z, wi.z)
        w_n = wy * segment.dx - wx * segment.dy  # ω·n: across the scratch
        w_d = wx * segment.dx + wy * segment.dy  # ω·d: along it
        r2 = dr.maximum(1.0 - w_d * w_d, 0.0)  # the line ν∥ = 0 has ω_o·d = -ω·d
        r = dr.sqrt(r2)
        lo, hi = spectrum((w_n - r) / wavelength), spectrum((w_n + r) / wavelength)
        kappa_mirror = spectrum((4.0 * math.pi) * depth * wz / wavelength)  # facet positions of the sampler

        gaussian = k < GAUSSIAN_NODES
        index = mi.Float(k) + 0.5  # stratified quantiles (k + 1/2)/N of each family
        u = dr.select(gaussian, index * (1.0 / GAUSSIAN_NODES), (index - GAUSSIAN_NODES) * (1.0 / CAUCHY_NODES))
        nu_gauss = spectrum((s * math.sqrt(2.0)) * dr.erfinv(2.0 * u - 1.0))
        nu_cauchy = sampling.sample_across(u, segment, kappa_mirror, lo, hi)
        nu = dr.select(gaussian, nu_gauss, nu_cauchy)
        density = (GAUSSIAN_NODES * dr.exp(-0.5 * dr.square(nu / s)) * (1.0 / (s * math.sqrt(2.0 * math.pi)))
                   + CAUCHY_NODES * sampling.pdf_across(nu, segment, kappa_mirror, lo, hi))

        t = wavelength * nu - w_n  # ω_o·n on the line
        gamma_o = dr.safe_sqrt(r2 - t * t)
        kappa = (2.0 * math.pi) * depth * (wz + gamma_o) / wavelength  # the Kirchhoff phase (docs/model.md §2)
        a = cross_section(segment, nu, kappa, sigma, True)
        lobe = (sigma * math.sqrt(2.0 * math.pi)) * dr.exp((-2.0 * math.pi ** 2) * sigma * sigma * nu * nu)
        g = 2.0 * lobe * a.re + a.abs2()
        inside = (nu > lo) & (nu < hi) & (density > 0.0)
        term = spectrum(dr.select(inside, g / dr.maximum(density, 1e-30), 0.0))
        # (never in place: loop state)
        e_i = e_i + dr.select(second, 0.0, term)
        e_o = e_o + dr.select(second, term, 0.0)
        return j + 1, e_i, e_o

    zero = dr.zeros(spectrum)
    _, e_i, e_o = dr.while_loop((mi.UInt32(0), zero, zero), cond, body, label="scratch_albedo_excess")
    scale = along_energy(segment, sigma) / (math.pi * sigma * sigma)
    return e_i * scale, e_o * scale
