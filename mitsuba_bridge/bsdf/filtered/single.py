"""One segment's intensity averaged over the footprint (docs/model.md §11.3).

A segment's amplitude is a product ``S = Φ(along) A(across)`` (docs/model.md §3), the along factor
depending on the window's position along the segment, τ, the across factor on its position
across, u.  Over a Gaussian footprint whose covariance in the segment's frame is
``[[Σ_tt, Σ_tu], [Σ_tu, Σ_uu]]``, ``E|S|² = E_u[ |A(u)|² E_{τ|u} |Φ(τ)|² ]``: the across factor at
the nodes of :func:`.nodes.envelope_nodes` (it falls off like ``e^{-(u - a⊥)²/σ²}``), each with the
along factor of the conditional footprint ``τ | u ~ N(u Σ_tu/Σ_uu, Σ_tt - Σ_tu²/Σ_uu)``
(:mod:`.along`).  Pieces of one straight run take their share ``Re E[S_k S_run*]`` with their own
cross-section (as the incoherent model does, docs/model.md §4.2).  Units: µm, 1/µm.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from ..maths.segment import SegmentGeometry, cross_section, flat_bottomed, frequencies
from .along import _pick, along_expectation
from .footprint import Footprint, projected
from .nodes import envelope_nodes

__all__ = ["segment_intensity", "ACROSS_NODES"]

#: Nodes across a groove: within 0.3 % of quadrature for widths up to 2σ (docs/model.md §11.3) ...
ACROSS_NODES = 3
#: ... two within 0.4 % for widths up to this many σ.
NARROW_ACROSS_SIGMAS = 1.2
#: Flat-bottomed grooves under footprints at least this many σ (and BROAD_WIDTHS groove widths) wide across
#: take the broad form: within 0.8 % (docs/model.md §11.3).
BROAD_SIGMAS = 2.0
BROAD_WIDTHS = 2.5
#: Gauss–Hermite nodes and weights (summing to 1) of the broad form's average over the squared window's
#: transform, e^{-4π²σ²η²} (as the periodic families' incoherent closed form, periodic.field)
_BROAD_NODES = tuple(float(z) for z in np.polynomial.hermite.hermgauss(4)[0])
_BROAD_WEIGHTS = tuple(float(w) / math.sqrt(math.pi) for w in np.polynomial.hermite.hermgauss(4)[1])


def segment_intensity(segment: SegmentGeometry, footprint: Footprint, xi_x, xi_y, k_z, sigma, coherent: bool,
                      runs=None, across_nodes: int = ACROSS_NODES):
    """``E|S|²`` (``coherent``) or ``E|S'|²`` of the segment over the footprint, per wavelength.

    ``runs``: ``(before, after)``, how far (µm) the piece's groove runs straight on past its ends
    (the piece's share of its run, :func:`.along.along_expectation`), or None (the piece alone).
    """
    nu_par, nu_perp = frequencies(segment, xi_x, xi_y)
    kappa = k_z * segment.depth
    var_t, var_u, cov_tu = projected(footprint, segment.dx, segment.dy)
    has_u = var_u > 1e-12
    slope = dr.select(has_u, cov_tu * dr.rcp(dr.select(has_u, var_u, 1.0)), 0.0)
    conditional = dr.maximum(var_t - slope * cov_tu, 0.0)
    centre = slope * 2.0 * var_u * segment.a_perp * dr.rcp(sigma * sigma + 2.0 * var_u)  # the nodes' mean
    kind = type(nu_perp)
    broad = flat_bottomed(segment.triangular) & (var_u >= dr.square(dr.maximum(BROAD_SIGMAS * sigma,
                                                                              BROAD_WIDTHS * segment.width)))

    def by_nodes(nu_perp, kappa, var_u, slope):
        return tuple(kind(a) for _, a in across_values(segment, nu_perp, kappa, sigma, var_u, slope, coherent,
                                                       across_nodes))

    def by_broad_form(nu_perp, kappa, var_u, slope):
        return (kind(broad_across(segment, nu_perp, kappa, sigma, var_u, coherent)),) \
            + tuple(dr.zeros(kind) for _ in range(across_nodes - 1))

    amounts = dr.if_stmt((nu_perp, kappa, var_u, slope), broad, by_broad_form, by_nodes,
                         label="scratch_filtered_across_form")
    positions = [u for u, _ in envelope_nodes(segment.a_perp, 0.0, var_u, sigma * sigma, across_nodes)]
    nodes = [(dr.select(broad, centre, slope * u) if k == 0 else slope * u, a)
             for k, (u, a) in enumerate(zip(positions, amounts))]
    before, after = (None, None) if runs is None else runs
    return along_expectation(segment.c, segment.c + segment.length, before, after, nu_par, sigma, nodes, conditional,
                             centre)


def broad_across(segment: SegmentGeometry, nu_perp, kappa, sigma, var_u, coherent: bool):
    """``E_u |A(ν⊥; a⊥ - u)|²`` of a flat-bottomed groove under a footprint wide against σ and the groove:

        N(a⊥; 0, Σ_uu + σ²/2 + W²/12) ∫ |A(ν⊥; a)|² da,   ∫ |A|² da = σ√π E[|Ĝ(ν⊥ - η)|²],  η ~ N(0, 1/8π²σ²)

    (Parseval over the offset a; ``Ĝ(μ) = (e^{iκ} - 1) W sinc(πWμ)``, incoherent without the -1), the last
    expectation by four Gauss–Hermite nodes: elementary functions only (docs/model.md §11.3)."""
    width = segment.width
    spread = var_u + 0.5 * sigma * sigma + width * width * (1.0 / 12.0)
    density = dr.rsqrt((2.0 * math.pi) * spread) * dr.exp(-0.5 * segment.a_perp * segment.a_perp * dr.rcp(spread))
    if coherent:
        depth_factor = 4.0 * dr.square(dr.sin(0.5 * kappa))  # |e^{iκ} - 1|²
    else:
        depth_factor = 1.0
    scale = 1.0 / (2.0 * math.pi * sigma)
    total = 0.0
    for z, w in zip(_BROAD_NODES, _BROAD_WEIGHTS):
        x = math.pi * width * (nu_perp - z * scale)
        sinc = dr.select(dr.abs(x) < 1e-4, 1.0 - x * x * (1.0 / 6.0), dr.sin(x) * dr.rcp(x))
        total = total + w * sinc * sinc
    return depth_factor * total * (width * width * math.sqrt(math.pi) * sigma) * density


def across_values(segment: SegmentGeometry, nu_perp, kappa, sigma, var_u, slope, coherent: bool, count: int):
    """``[(mean_j, a_j)]``: the across factor ``w_j |A(ν⊥; a⊥ - u_j)|²`` at the envelope's nodes u_j (a
    symbolic loop: the cross section is traced once) and the along footprint's mean there, ``slope·u_j``."""
    kind = type(nu_perp)
    pairs = envelope_nodes(segment.a_perp, 0.0, var_u, sigma * sigma, count)
    positions = tuple(u for u, _ in pairs)
    weights = tuple(w for _, w in pairs)

    def step(j, *values):
        u = _pick(j, positions)
        value = _pick(j, weights) * cross_section(segment._replace(a_perp=segment.a_perp - u), nu_perp, kappa, sigma,
                                                  coherent).abs2()
        return (j + 1,) + tuple(kind(dr.select(j == k, value, v)) for k, v in enumerate(values))

    values = dr.while_loop((dr.zeros(mi.UInt32),) + tuple(dr.zeros(kind) for _ in range(count)),
                           lambda j, *values: j < count, step, label="scratch_filtered_across")[1:]
    return [(slope * u, v) for u, v in zip(positions, values)]
