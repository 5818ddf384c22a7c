"""The footprint's mean of one segment's amplitude, ``E[S_k]`` (docs/model.md §11.4).

``S_k`` is linear in the window, and the footprint's mean of the window times the phase reference,
``E[w(x - x0) e^{2πiξ·x0}]`` over ``x0 ~ N(0, Σ)``, is again a Gaussian window:

    E[S_k](ξ) = 2πσ² e^{-2π²σ²(|ξ|² - ξ·ξ')} ∫ g_k(x) N(x; 0, C) e^{-2πiξ'·x} dx,
    C = Σ + σ²I,   ξ' = σ² C⁻¹ ξ.

Only the cross term ``2 Re(U0* Σ E[S_k])`` with the mirror lobe needs it: it is what the scratches
take from the lobe.  In the segment's frame the window ``N(x; 0, C)`` is the across marginal
``N(u; 0, C_uu)`` times the along conditional ``N(t; u C_tu/C_uu, C_tt - C_tu²/C_uu)``, taken at the
groove's centre line ``u = a⊥`` (exact for an isotropic footprint, the groove's width times
``C_tu/C_uu`` off otherwise): the point model's along and across factors with their own σ.
"""
from __future__ import annotations

import math

import drjit as dr

from ..maths.complexmath import Cx, expi
from ..maths.segment import SegmentGeometry, cross_section, frequencies
from ..maths.window import window_integral
from .footprint import Footprint, projected

__all__ = ["mean_amplitude"]


def mean_amplitude(segment: SegmentGeometry, footprint: Footprint, xi_x, xi_y, k_z, sigma) -> Cx:
    """``E[S_k](ξ)`` over the footprint (x0 as the phase reference), per wavelength."""
    nu_par, nu_perp = frequencies(segment, xi_x, xi_y)
    var_t, var_u, cov_tu = projected(footprint, segment.dx, segment.dy)
    sigma2 = sigma * sigma
    c_tt, c_uu = var_t + sigma2, var_u + sigma2
    inv_det = dr.rcp(c_tt * c_uu - cov_tu * cov_tu)
    # ξ' = σ² C⁻¹ ξ in the segment's frame
    par = sigma2 * inv_det * (c_uu * nu_par - cov_tu * nu_perp)
    perp = sigma2 * inv_det * (c_tt * nu_perp - cov_tu * nu_par)
    sigma_u = dr.sqrt(c_uu)
    sigma_t = dr.sqrt(dr.maximum(c_tt - cov_tu * cov_tu * dr.rcp(c_uu), 1e-12))
    shift = segment.a_perp * cov_tu * dr.rcp(c_uu)  # the along window's mean at u = a⊥
    along = window_integral(segment.c - shift, segment.c + segment.length - shift, par, sigma_t) \
        * expi((-2.0 * math.pi) * par * shift)
    across = cross_section(segment, perp, k_z * segment.depth, sigma_u, True)
    decay = (sigma2 * dr.rsqrt(c_tt * c_uu - cov_tu * cov_tu)) * dr.exp(
        (-2.0 * math.pi ** 2) * sigma2 * (nu_par * (nu_par - par) + nu_perp * (nu_perp - perp)))
    return along * across * decay
