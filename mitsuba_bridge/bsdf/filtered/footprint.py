"""The footprint of one camera sample on the scratch plane (docs/model.md §11.2).

A camera ray that hits at distance ``t`` stands for a cone of ``angle`` radians (the pixel's
angle divided among the render's samples, set by the renderer) plus ``width`` scene units (an
orthographic camera's share of a pixel).  Its cross-section, a disc of radius
``ρ = angle·t + width``, lies on the surface as an ellipse stretched by ``1/cos θ_i`` along the
incident direction's projection; the footprint is the Gaussian of that covariance,

    Σ = ρ² (I + ω_t ω_tᵀ / ω_z²),     ω = ω_i in the local shading frame, ω_t = (ω_x, ω_y),

in µm² of the local frame (scene units times ``micrometres_per_unit``).  Lengths in µm.
"""
from __future__ import annotations

from typing import NamedTuple

import drjit as dr

__all__ = ["Footprint", "footprint_of", "projected", "MAX_STRETCH", "zero_footprint"]

#: The footprint is stretched at most this much along ω_i (grazing views: cost and the flat-surface
#: assumption both fail long before the ellipse would reach infinity).
MAX_STRETCH = 8.0


class Footprint(NamedTuple):
    """A Gaussian footprint's covariance in the local shading frame (µm²)."""

    xx: object
    xy: object
    yy: object

    @property
    def largest_variance(self):
        """The larger eigenvalue of the covariance (µm²)."""
        half_trace = 0.5 * (self.xx + self.yy)
        return half_trace + dr.sqrt(dr.square(0.5 * (self.xx - self.yy)) + self.xy * self.xy)

    @property
    def smallest_variance(self):
        """The smaller eigenvalue of the covariance (µm²): r² for a camera sample's footprint."""
        half_trace = 0.5 * (self.xx + self.yy)
        return dr.maximum(half_trace - dr.sqrt(dr.square(0.5 * (self.xx - self.yy)) + self.xy * self.xy), 0.0)


def zero_footprint(value_type):
    zero = dr.zeros(value_type)
    return Footprint(zero, zero, zero)


def footprint_of(si, angle, width, micrometres_per_unit, max_radius_um=None) -> Footprint:
    """The footprint of the sample that reached ``si`` (``si.t``: scene units from the ray's origin).

    ``angle`` (radians) and ``width`` (scene units) per sample; 0 and 0 give the point (no filtering).
    ``max_radius_um``: the radius is capped there (a smaller footprint only filters less: the image
    converges to the same one; it bounds the pieces one evaluation visits, docs/model.md §11.8).
    """
    # (an interaction built by hand may carry t = ∞: the cone then plays no part, the width still does)
    cone = dr.select(angle > 0.0, angle * dr.maximum(si.t, 0.0), 0.0)
    radius = (cone + width) * micrometres_per_unit
    radius = dr.select(dr.isfinite(radius), radius, 0.0)
    if max_radius_um is not None:
        radius = dr.minimum(radius, max_radius_um)
    wi = si.wi
    cos_i = dr.maximum(dr.abs(wi.z), 1.0 / MAX_STRETCH)
    r2 = radius * radius
    scale = r2 * dr.rcp(cos_i * cos_i)
    return Footprint(dr.fma(scale, wi.x * wi.x, r2), scale * wi.x * wi.y, dr.fma(scale, wi.y * wi.y, r2))


def projected(footprint: Footprint, dx, dy):
    """``(Σ_tt, Σ_uu, Σ_tu)``: the covariance along the unit direction (dx, dy), across it (its normal
    n = (-dy, dx)) and between the two."""
    along = footprint.xx * dx * dx + 2.0 * footprint.xy * dx * dy + footprint.yy * dy * dy
    across = footprint.xx * dy * dy - 2.0 * footprint.xy * dx * dy + footprint.yy * dx * dx
    cross = (footprint.yy - footprint.xx) * dx * dy + footprint.xy * (dx * dx - dy * dy)
    return along, across, cross
