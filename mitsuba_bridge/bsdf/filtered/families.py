"""Periodic families averaged over the footprint (docs/model.md §11.6).

Inside a family (a CD's tracks, a ruled grating, docs/model.md §3.5) the field of the window at x0
depends on x0 only through the lattice's offset ``a0`` (infinite tracks: nothing changes along them):

    F(x0) = (1/P) Φ∞(ν∥) Σ_m c_m e^{2πi m a0/P},   c_m = ŵ(ν⊥ + m/P) G(m/P)

(the orders nearest the window's peak, :func:`..periodic.field._run_field`).  A footprint moves x0
across the tracks by ``u ~ N(0, Σ_uu)``, ``a0 → a0 - u``, so

    E[F]   = (1/P) Φ∞ Σ_m c_m e^{2πi m a0/P} e^{-2π² m² Σ_uu/P²}
    E|F|²  = (1/P)² Φ∞² Σ_{m,m'} c_m c_m'* e^{2πi (m - m') a0/P} e^{-2π² (m - m')² Σ_uu/P²}

exactly: the orders keep their width (set by σ), and a footprint wider than the pitch makes them
incoherent with each other.  Only runs that fill the footprint's reach (no edge, no kink) are summed
so; the rest is scanned piece by piece.
"""
from __future__ import annotations

import math

import drjit as dr

from ..maths.complexmath import Cx, expi
from ..periodic.field import ONE_ORDER_SIGMA_PER_PITCH, groove_transform
from ..periodic.find import Family
from .footprint import Footprint, projected

__all__ = ["family_terms", "family_energy"]


def _orders(family: Family, xi_x, xi_y, kappa, sigma):
    """``(Φ∞/P, [(m, c_m e^{2πi m a0/P})])`` of the nearest order and its two neighbours."""
    nu_par = xi_x * family.dx + xi_y * family.dy
    nu_perp = xi_y * family.dx - xi_x * family.dy
    sigma2 = sigma * sigma
    gauss = math.sqrt(2.0 * math.pi) * sigma
    inv_pitch = dr.rcp(family.pitch)
    along = gauss * dr.exp((-2.0 * math.pi ** 2) * sigma2 * nu_par * nu_par) * inv_pitch
    nearest = dr.round(-nu_perp * family.pitch)
    # (where σ >= 1.8 P the neighbours lie beyond e^-16 of the window's peak: they weigh nothing)
    wide = sigma < ONE_ORDER_SIGMA_PER_PITCH * family.pitch
    orders = []
    for shift in (-1.0, 0.0, 1.0):
        order = nearest + shift
        mu = order * inv_pitch
        eta = nu_perp + mu
        weight = gauss * dr.exp((-2.0 * math.pi ** 2) * sigma2 * eta * eta)
        if shift != 0.0:
            weight = dr.select(wide, weight, 0.0)
        term = groove_transform(family, mu, kappa) * expi((2.0 * math.pi) * order * family.a0 * inv_pitch) * weight
        orders.append((order, term))
    return along, orders


def family_terms(family: Family, footprint: Footprint, xi_x, xi_y, k_z, sigma):
    """``(Re E[F], E|F|²)`` of the family's run over the footprint (module docstring), per wavelength."""
    kind = type(xi_x)
    along, orders = _orders(family, xi_x, xi_y, k_z * family.depth, sigma)
    _, var_u, _ = projected(footprint, family.dx, family.dy)
    damping = (-2.0 * math.pi ** 2) * var_u * dr.rcp(family.pitch * family.pitch)
    mean = Cx(dr.zeros(kind), dr.zeros(kind))
    intensity = dr.zeros(kind)
    for i, (m, c_m) in enumerate(orders):
        mean = mean + c_m * dr.exp(damping * m * m)
        intensity = intensity + c_m.abs2()
        for m2, c_m2 in orders[i + 1:]:
            intensity = intensity + 2.0 * (c_m * c_m2.conj()).re * dr.exp(damping * (m - m2) * (m - m2))
    return kind(mean.re * along), kind(intensity * along * along)


def family_energy(family: Family, footprint: Footprint, sigma):
    """``E Σ_n ε_n``: the footprint's mean of the run's share of the squared window (its sampling weight).

    ``Σ_n e^{-a_n²/σ²} = (σ√π/P)(1 + 2 e^{-π²σ²/P²} cos(2πa0/P))`` up to e^{-4π²σ²/P²}; the footprint
    damps the cosine by ``e^{-2π² Σ_uu/P²}``."""
    _, var_u, _ = projected(footprint, family.dx, family.dy)
    inv_pitch = dr.rcp(family.pitch)
    ratio = sigma * inv_pitch
    damping = dr.exp((-2.0 * math.pi ** 2) * var_u * inv_pitch * inv_pitch - (math.pi ** 2) * ratio * ratio)
    tracks = math.sqrt(math.pi) * ratio * (1.0 + 2.0 * damping * dr.cos((2.0 * math.pi) * family.a0 * inv_pitch))
    return family.width * math.sqrt(math.pi) * sigma * tracks
