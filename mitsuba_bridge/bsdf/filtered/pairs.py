"""Coherent pairs of segments averaged over the footprint: ``E[S_k S_l*]`` (docs/model.md §11.5).

Two segments interfere only where one window sees both, so a pair's term lives where they come
within a few σ of each other:

* **Crossing pairs** (``|sin θ| >= PARALLEL_BELOW``): around their crossing point.  For grooves
  narrow against σ and ends away from the crossing, the pair identity (model.md §11.1) leaves a
  Gaussian integral over the two lines' arc lengths, in closed form:

      E[S_k S_l*] = πσ² Ĝ_k(0) Ĝ_l(0)* exp(½ Jᵀ H⁻¹ J - ½ δᵀ Σ_s⁻¹ δ) / √(det H det Σ_s),
      H = BᵀB/2σ² + AᵀΣ_s⁻¹A/4,   J = -2πi Bᵀξ - AᵀΣ_s⁻¹δ/2,

  ``B = [d_k, -d_l]``, ``A = [d_k, d_l]``, ``Σ_s = Σ + σ²I/2``, ``δ`` the crossing point and
  ``Ĝ(0) = ∫ (e^{iκp(u)} - 1) du`` the groove's integrated transfer.  It tends to the exact value
  for footprints wide against σ/sin θ (as ``Σ → ∞``: ``πσ²·4πσ² e^{-4π²σ²|ξ|²} Ĝ_k Ĝ_l*/|sin θ|``
  times the footprint's density at the crossing, a lobe at the mirror direction); footprints
  narrower than ``POINT_PAIRS_BELOW`` σ average the exact point products at 3 × 3 Gauss–Hermite
  nodes instead.
* **Nearly parallel pairs**: the amplitude of each factorises along × across in the first
  segment's frame; ``E[A_k A_l*]`` at the nodes of the two envelopes' product and the along factor
  ``Re E[Φ_k Φ_l*]`` from single intervals (:func:`.along.along_pair`).  The along factor's odd
  part (ends staggered inside the footprint) is dropped.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from ..maths.complexmath import Cx, expi
from ..maths.segment import SegmentGeometry, amplitude, cross_section, frequencies
from .along import _pick, along_pair
from .footprint import Footprint, projected
from .nodes import envelope_nodes, hermite_rule

__all__ = ["crossing_point", "crossing_pair", "point_pair", "parallel_pair", "groove_integral", "PARALLEL_BELOW",
           "POINT_PAIRS_BELOW"]

#: Pairs with |sin θ| below this (in the local frame) are nearly parallel.
PARALLEL_BELOW = 0.1
#: Footprints whose largest standard deviation is below this (in σ) average crossing pairs at nodes.
POINT_PAIRS_BELOW = 1.0
#: κ below which (e^{iκ} - 1)/(iκ) is its series.
_SMALL_KAPPA = 1e-3


def groove_integral(segment: SegmentGeometry, kappa) -> Cx:
    """``Ĝ(0) = ∫ (e^{iκp(u)} - 1) du`` over the groove: ``(e^{iκ} - 1) W`` flat, ``W[(e^{iκ}-1)/(iκ) - 1]`` V."""
    flat = (expi(kappa) - 1.0) * segment.width
    small = dr.abs(kappa) < _SMALL_KAPPA
    safe = dr.select(small, 1.0, kappa)
    s, c = dr.sincos(kappa)
    # (e^{iκ} - 1)/(iκ) = sin κ/κ + i (1 - cos κ)/κ
    ratio = Cx(dr.select(small, 1.0 - kappa * kappa * (1.0 / 6.0), s / safe),
               dr.select(small, 0.5 * kappa, (1.0 - c) / safe))
    v_groove = (ratio - 1.0) * segment.width
    return v_groove.select(segment.triangular, flat) if not isinstance(segment.triangular, bool) \
        else (v_groove if segment.triangular else flat)


def crossing_point(first: SegmentGeometry, second: SegmentGeometry):
    """``(x, y, sin θ)``: where the centre lines cross (local frame, from x0) and their angle's sine."""
    sin_theta = first.dx * second.dy - first.dy * second.dx
    inv = dr.rcp(dr.select(sin_theta == 0.0, 1.0, sin_theta))
    # n·x = a⊥ for both lines, n = (-d_y, d_x)
    x = (first.a_perp * second.dx - second.a_perp * first.dx) * inv
    y = (first.a_perp * second.dy - second.a_perp * first.dy) * inv
    return x, y, sin_theta


def crossing_pair(first: SegmentGeometry, second: SegmentGeometry, footprint: Footprint, xi_x, xi_y, k_z,
                  sigma) -> Cx:
    """``E[S_1 S_2*]`` of two crossing segments, the closed form of the module docstring (per wavelength)."""
    x, y, _ = crossing_point(first, second)
    half = 0.5 * sigma * sigma
    sxx, sxy, syy = footprint.xx + half, footprint.xy, footprint.yy + half
    det_s = sxx * syy - sxy * sxy
    inv_det_s = dr.rcp(det_s)
    mxx, mxy, myy = syy * inv_det_s, -sxy * inv_det_s, sxx * inv_det_s  # Σ_s⁻¹
    d1x, d1y, d2x, d2y = first.dx, first.dy, second.dx, second.dy

    def quad(ax, ay, bx, by):
        return ax * (mxx * bx + mxy * by) + ay * (mxy * bx + myy * by)

    inv_2s2 = 0.5 / (sigma * sigma)
    cos_theta = d1x * d2x + d1y * d2y
    h11 = inv_2s2 + 0.25 * quad(d1x, d1y, d1x, d1y)
    h22 = inv_2s2 + 0.25 * quad(d2x, d2y, d2x, d2y)
    h12 = -cos_theta * inv_2s2 + 0.25 * quad(d1x, d1y, d2x, d2y)
    det_h = h11 * h22 - h12 * h12
    inv_det_h = dr.rcp(det_h)
    g11, g22, g12 = h22 * inv_det_h, h11 * inv_det_h, -h12 * inv_det_h  # H⁻¹
    # J = J_r + i J_i: J_r = -Aᵀ Σ_s⁻¹ δ / 2 (geometry), J_i = -2π (ξ·d_1, -ξ·d_2) (per wavelength)
    r1, r2 = -0.5 * quad(d1x, d1y, x, y), -0.5 * quad(d2x, d2y, x, y)
    i1 = (-2.0 * math.pi) * (xi_x * d1x + xi_y * d1y)
    i2 = (2.0 * math.pi) * (xi_x * d2x + xi_y * d2y)

    def form(a1, a2, b1, b2):
        return a1 * (g11 * b1 + g12 * b2) + a2 * (g12 * b1 + g22 * b2)

    exponent_re = 0.5 * (form(r1, r2, r1, r2) - form(i1, i2, i1, i2)) - 0.5 * quad(x, y, x, y)
    exponent_im = form(r1, r2, i1, i2)
    scale = (math.pi * sigma * sigma) * dr.rsqrt(det_h * det_s) * dr.exp(exponent_re)
    grooves = groove_integral(first, k_z * first.depth) * groove_integral(second, k_z * second.depth).conj()
    return grooves * expi(exponent_im) * scale


def point_pair(first: SegmentGeometry, second: SegmentGeometry, footprint: Footprint, xi_x, xi_y, k_z,
               sigma) -> Cx:
    """``E[S_1 S_2*]`` by 3 × 3 Gauss–Hermite nodes over the footprint of the exact point products."""
    # principal axes of the footprint
    half_trace = 0.5 * (footprint.xx + footprint.yy)
    root = dr.sqrt(dr.square(0.5 * (footprint.xx - footprint.yy)) + footprint.xy * footprint.xy)
    big, small = half_trace + root, dr.maximum(half_trace - root, 0.0)
    angle = 0.5 * dr.atan2(2.0 * footprint.xy, footprint.xx - footprint.yy)
    sa, ca = dr.sincos(angle)
    std_big, std_small = dr.sqrt(big), dr.sqrt(small)
    nodes, weights = hermite_rule(3)
    total = Cx(0.0, 0.0)
    for z1, w1 in zip(nodes, weights):
        for z2, w2 in zip(nodes, weights):
            ox = z1 * std_big * ca - z2 * std_small * sa
            oy = z1 * std_big * sa + z2 * std_small * ca
            a = amplitude(_shifted(first, ox, oy), xi_x, xi_y, k_z, sigma)
            b = amplitude(_shifted(second, ox, oy), xi_x, xi_y, k_z, sigma)
            total = total + a * b.conj() * (w1 * w2)
    return total


def _shifted(segment: SegmentGeometry, ox, oy) -> SegmentGeometry:
    """The segment seen from the window moved by (ox, oy)."""
    return segment._replace(c=segment.c - (ox * segment.dx + oy * segment.dy),
                            a_perp=segment.a_perp - (oy * segment.dx - ox * segment.dy))


def parallel_pair(first: SegmentGeometry, second: SegmentGeometry, footprint: Footprint, xi_x, xi_y, k_z, sigma,
                  across_nodes: int = 3):
    """``Re E[S_1 S_2*]`` of two nearly parallel segments, in the first one's frame (per wavelength)."""
    nu_par, nu_perp = frequencies(first, xi_x, xi_y)
    # the second piece in the first one's frame (t along d_1, u along n_1, from x0): its start is
    # c_2 d_2 + a⊥_2 n_2, its direction has the components (d_2·d_1, d_2·n_1)
    along_2 = first.dx * second.dx + first.dy * second.dy  # d_2·d_1 = n_2·n_1
    across_2 = first.dx * second.dy - first.dy * second.dx  # d_2·n_1 = -(n_2·d_1)
    base_t = second.c * along_2 - second.a_perp * across_2
    base_u = second.c * across_2 + second.a_perp * along_2
    end_t = base_t + second.length * along_2
    t0, t1 = dr.minimum(base_t, end_t), dr.maximum(base_t, end_t)
    # its offset across where the footprint's centre sees it (nearly parallel: it drifts along the piece)
    nearest = dr.clip(0.0, t0, t1)
    offset = base_u + (nearest - base_t) * across_2 * dr.rcp(dr.select(along_2 == 0.0, 1.0, along_2))
    var_t, var_u, cov_tu = projected(footprint, first.dx, first.dy)
    has_u = var_u > 1e-12
    slope = dr.select(has_u, cov_tu * dr.rcp(dr.select(has_u, var_u, 1.0)), 0.0)
    conditional = dr.maximum(var_t - slope * cov_tu, 0.0)
    centre = 0.5 * (first.a_perp + offset)
    moved = second._replace(dx=first.dx, dy=first.dy)
    kind = type(nu_perp)
    found = envelope_nodes(centre, 0.0, var_u, sigma * sigma, across_nodes)
    positions = tuple(u for u, _ in found)
    weights = tuple(w for _, w in found)

    def step(j, *values):  # (a symbolic loop: the two cross sections are traced once)
        u = _pick(j, positions)
        a = cross_section(first._replace(a_perp=first.a_perp - u), nu_perp, k_z * first.depth, sigma, True)
        b = cross_section(moved._replace(a_perp=offset - u), nu_perp, k_z * second.depth, sigma, True)
        value = _pick(j, weights) * (a * b.conj()).re
        return (j + 1,) + tuple(kind(dr.select(j == k, value, v)) for k, v in enumerate(values))

    values = dr.while_loop((dr.zeros(mi.UInt32),) + tuple(dr.zeros(kind) for _ in range(across_nodes)),
                           lambda j, *values: j < across_nodes, step, label="scratch_filtered_parallel_across")[1:]
    nodes = [(slope * u, v) for u, v in zip(positions, values)]
    node_mean = slope * 2.0 * var_u * centre * dr.rcp(sigma * sigma + 2.0 * var_u)
    return along_pair(first.c, first.c + first.length, t0, t1, nu_par, sigma, nodes, conditional, node_mean)
