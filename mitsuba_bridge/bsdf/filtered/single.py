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

import drjit as dr

from ..maths.segment import SegmentGeometry, cross_section, frequencies
from .along import along_expectation
from .footprint import Footprint, projected
from .nodes import envelope_nodes

__all__ = ["segment_intensity", "ACROSS_NODES"]

#: Nodes across a groove: within 0.3 % of quadrature for widths up to 2σ (docs/model.md §11.3).
ACROSS_NODES = 3


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
    nodes = []
    for u, weight in envelope_nodes(segment.a_perp, 0.0, var_u, sigma * sigma, across_nodes):
        shifted = segment._replace(a_perp=segment.a_perp - u)
        nodes.append((slope * u, weight * cross_section(shifted, nu_perp, kappa, sigma, coherent).abs2()))
    before, after = (None, None) if runs is None else runs
    return along_expectation(segment.c, segment.c + segment.length, before, after, nu_par, sigma, nodes, conditional)
