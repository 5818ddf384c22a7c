"""Along a segment: the footprint's expectation of ``|Φ|²`` (docs/model.md §11.3).

Seen from a window shifted by ``τ`` along it, a segment's window integral is
``Φ(t0 - τ, t1 - τ; ν) = ∫_{t0}^{t1} e^{-(t-τ)²/2σ²} e^{-2πiν(t-τ)} dt`` (docs/model.md §3.2).
Over a Gaussian footprint ``τ ~ N(μ, v)`` its squared modulus has the expectation

    Λ = 2σ√π ∫_0^L e^{-d²/4σ²} cos(2πνd) ΔF(d) dd,    ΔF(d) = F(t1 - d/2) - F(t0 + d/2)

(``F`` the normal CDF of mean μ and variance ``s² = v + σ²/2``; the pair identity of model.md §11.1
for one segment).  It is evaluated per lane in one of four ways:

* **Moments** (footprints at least ``2σ`` wide, ``|b| <= TAIL_ABOVE`` with ``b = 4πσν``): ΔF in
  its Taylor series in ``d`` (the coefficients are the normal density's derivatives at the two
  ends), the integral a sum of ``m_k = ∫_0^{L/2σ} y^k e^{-y²} e^{-iby} dy``: one window integral and
  a recursion.  Exact as ``s/σ → ∞``; 7 terms keep it within 2·10⁻⁴ of the line's peak from 2σ on.
* **Half-range Gauss–Hermite in d** (narrower footprints on segments longer than ``3σ``): twelve
  nodes of the weight ``e^{-d²/4σ²}`` on ``[0, ∞)``, each a difference of two real error functions;
  within 0.1 % at any footprint down to the point itself, any position and ``|b| <= TAIL_ABOVE``.
* **Envelope nodes** (segments at most ``3σ`` long, any footprint and frequency): the point value
  falls off like ``e^{-(τ - t_mid)²/σ²}`` around the segment's middle, and Gauss–Hermite nodes of its
  product with the footprint (:func:`.nodes.envelope_nodes`) average the exact point values.
* **Tails** (``|b| > TAIL_ABOVE``, long segments, far off the diffraction line, where only the ends'
  star tails remain): their leading asymptotic ``|g(t1 - τ) - g(t0 - τ)|² / (4π²ν²)`` with
  ``g(t) = e^{-t²/2σ²} e^{-2πiνt}``, averaged exactly (error about ``(2/b)²`` of the tails).

Lengths in µm, frequencies in 1/µm; ``nu`` per wavelength (``mi.Spectrum``), geometry ``mi.Float``.
"""
from __future__ import annotations

import math

import drjit as dr
import numpy as np

from ..maths.complexmath import Cx
from ..maths.window import window_integral
from .nodes import envelope_nodes

__all__ = ["along_intensity", "along_expectation", "along_pair", "moments", "half_range_hermite", "TAYLOR_TERMS", "MOMENTS_FROM_SIGMAS",
           "SHORT_SIGMAS", "TAIL_ABOVE"]

#: Terms of the Taylor series of the footprint's CDF difference (c_0 .. c_6).
TAYLOR_TERMS = 7
#: Footprints at least this wide (standard deviation along, in σ) take the moments.
MOMENTS_FROM_SIGMAS = 2.0
#: Segments at most this long (in σ) are averaged by the nodes of their envelope.
SHORT_SIGMAS = 3.0
#: ``b = 4πσ|ν|`` above which long segments keep only their ends' asymptotic tails (the line's own
#: intensity is e^{-b²/4} < e^{-16} of its peak there).
TAIL_ABOVE = 8.0
#: Nodes of the half-range rule in d and of the short segments' envelopes.
HALF_RANGE_NODES = 12
ENVELOPE_NODES = 4
_SQRT_PI = math.sqrt(math.pi)
_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)
_INV_SQRT_2 = 1.0 / math.sqrt(2.0)


def half_range_hermite(count: int):
    """Gauss nodes and weights of the weight ``e^{-y²}`` on ``[0, ∞)`` (Python floats).

    Golub–Welsch from the three-term recurrence, its coefficients by the Stieltjes procedure on a
    fine trapezoidal grid (float64; the nodes integrate ``y^k``, k < 24, to 1e-14 relative).
    """
    y = np.linspace(0.0, 11.0, 400001)
    w = np.exp(-y * y) * (y[1] - y[0])
    w[0] *= 0.5
    a, b = np.zeros(count), np.zeros(count)
    p_prev, p, norm_prev = np.zeros_like(y), np.ones_like(y), 1.0
    for k in range(count):
        norm = float((w * p * p).sum())
        a[k] = float((w * y * p * p).sum()) / norm
        if k:
            b[k] = norm / norm_prev
        p_prev, p, norm_prev = p, (y - a[k]) * p - (b[k] if k else 0.0) * p_prev, norm
    jacobi = np.diag(a) + np.diag(np.sqrt(b[1:]), 1) + np.diag(np.sqrt(b[1:]), -1)
    nodes, vectors = np.linalg.eigh(jacobi)
    weights = 0.5 * math.sqrt(math.pi) * vectors[0] ** 2
    return [float(v) for v in nodes], [float(v) for v in weights]


_HALF_NODES, _HALF_WEIGHTS = half_range_hermite(HALF_RANGE_NODES)


def moments(length, nu, sigma):
    """``[m_0 .. m_6]`` (complex) of a segment ``length`` µm long: ``m_k = ∫_0^Y y^k e^{-y²-iby} dy``.

    ``Y = L/2σ``, ``b = 4πσν``; ``m_0`` is the window integral of standard deviation √2σ over
    [0, L] divided by 2σ, the others follow from
    ``m_{k+1} = (k m_{k-1} - i b m_k + δ_k0 - Y^k e^{-Y²-ibY}) / 2`` (integration by parts), which
    multiplies m_0's error by about ``(b/2)^k``: used for ``|b| <= TAIL_ABOVE`` only.
    """
    two_sigma = 2.0 * sigma
    m0 = window_integral(dr.zeros(type(length)), length, nu, math.sqrt(2.0) * sigma) * dr.rcp(two_sigma)
    y = dr.minimum(length * dr.rcp(two_sigma), 6.0)  # (e^{-36} beyond: the window integral's own clamp)
    b = (4.0 * math.pi) * sigma * nu
    s, c = dr.sincos(-b * y)
    edge = Cx(c, s) * dr.exp(-y * y)  # e^{-Y²} e^{-ibY}
    result = [m0]
    previous, current, power = None, m0, 1.0
    for k in range(TAYLOR_TERMS - 1):
        step = current.mul_i() * (-b) - edge * power
        step = step + 1.0 if k == 0 else step + previous * float(k)
        previous, current = current, step * 0.5
        result.append(current)
        power = power * y
    return result


def _taylor_terms(t0, t1, mean, variance, sigma):
    """``c_k (2σ)^{k+1}``, k = 0 .. 6: ΔF's Taylor coefficients with the moments' scale (mi.Float).

    ``c_0 = F(t1) - F(t0)``, ``c_k = [(-½)^k F^{(k)}(t1) - (½)^k F^{(k)}(t0)] / k!`` with the
    derivatives of the CDF through the probabilists' Hermite polynomials of the density.
    """
    inv_s = dr.rsqrt(variance + 0.5 * sigma * sigma)
    q = sigma * inv_s
    x0, x1 = (t0 - mean) * inv_s, (t1 - mean) * inv_s
    two_sigma = 2.0 * sigma
    terms = [sigma * (dr.erf(x1 * _INV_SQRT_2) - dr.erf(x0 * _INV_SQRT_2))]
    phi0 = dr.exp(-0.5 * x0 * x0) * _INV_SQRT_2PI
    phi1 = dr.exp(-0.5 * x1 * x1) * _INV_SQRT_2PI
    he0_prev, he0, he1_prev, he1 = 0.0, 1.0, 0.0, 1.0  # He_{k-1}(x0), He_{k-1}(x1) and the ones before
    scale = two_sigma
    for k in range(1, TAYLOR_TERMS):
        scale = scale * q * (1.0 / k)
        sign = 1.0 if k % 2 == 0 else -1.0
        terms.append(scale * (sign * he0 * phi0 - he1 * phi1))
        he0_prev, he0 = he0, x0 * he0 - (k - 1) * he0_prev
        he1_prev, he1 = he1, x1 * he1 - (k - 1) * he1_prev
    return terms


def _by_moments(t0, t1, mean, variance, sigma, m):
    terms = _taylor_terms(t0, t1, mean, variance, sigma)
    total = terms[0] * m[0].re
    for term, moment in zip(terms[1:], m[1:]):
        total = dr.fma(term, moment.re, total)
    return (2.0 * _SQRT_PI * sigma) * total


def _by_half_range(t0, t1, mean, variance, nu, sigma):
    """``2σ√π ∫_0^∞ e^{-d²/4σ²} cos(2πνd) max(ΔF(d), 0) dd`` by the half-range rule (ΔF < 0 past d = L)."""
    inv_scale = dr.rsqrt(2.0 * variance + sigma * sigma)  # 1/(√2 s)
    a0, a1 = (t0 - mean) * inv_scale, (t1 - mean) * inv_scale
    total = 0.0
    for y, w in zip(_HALF_NODES, _HALF_WEIGHTS):
        d = (2.0 * y) * sigma
        half = (0.5 * d) * inv_scale
        difference = dr.maximum(dr.erf(a1 - half) - dr.erf(a0 + half), 0.0)  # 2 ΔF
        total = total + (w * difference) * dr.cos((2.0 * math.pi) * nu * d)
    return (2.0 * _SQRT_PI * sigma * sigma) * total


def _gaussian_overlap(t, mean, variance, sigma):
    """``E[e^{-(t-τ)²/σ²}]`` for ``τ ~ N(mean, variance)``."""
    spread = sigma * sigma + 2.0 * variance
    return sigma * dr.rsqrt(spread) * dr.exp(-dr.square(t - mean) * dr.rcp(spread))


def _by_tails(t0, t1, mean, variance, nu, sigma):
    """The ends' leading asymptotic, ``E|g(t1 - τ) - g(t0 - τ)|² / (4π²ν²)``."""
    length = t1 - t0
    ends = _gaussian_overlap(t0, mean, variance, sigma) + _gaussian_overlap(t1, mean, variance, sigma)
    cross = (2.0 * dr.exp(-length * length * (0.25 / (sigma * sigma)))
             * _gaussian_overlap(0.5 * (t0 + t1), mean, variance, sigma)) * dr.cos((2.0 * math.pi) * nu * length)
    return (ends - cross) * dr.rcp(dr.maximum((4.0 * math.pi ** 2) * nu * nu, 1e-30))


def _by_envelope(t0, t1, mean, variance, nu, sigma):
    """Point values at the nodes of the footprint times the envelope ``e^{-(τ - t_mid)²/σ²}``."""
    total = 0.0
    for tau, weight in envelope_nodes(0.5 * (t0 + t1), mean, variance, sigma * sigma, ENVELOPE_NODES):
        total = total + weight * window_integral(t0 - tau, t1 - tau, nu, sigma).abs2()
    return total


def _interval(t0, t1, nu, sigma, nodes, variance):
    """``Σ_j a_j E_τ|Φ(t0 - τ, t1 - τ; ν)|²``, ``τ ~ N(mean_j, variance)``, over ``nodes = [(mean_j, a_j)]``.

    The regime is chosen per lane (module docstring); the moments, which depend on the length and
    the frequency only, are shared by the nodes.
    """
    spectrum = type(nu)
    short = t1 - t0 <= SHORT_SIGMAS * sigma
    wide = variance >= (MOMENTS_FROM_SIGMAS * sigma) ** 2
    tails = ((4.0 * math.pi) * sigma) * dr.abs(nu) > TAIL_ABOVE
    means = tuple(mean for mean, _ in nodes)
    amounts = tuple(spectrum(amount) for _, amount in nodes)
    state = (t0, t1, variance, nu, means, amounts)

    def envelope(t0, t1, variance, nu, means, amounts):
        return spectrum(sum(a * _by_envelope(t0, t1, mean, variance, nu, sigma) for mean, a in zip(means, amounts)))

    def long_segment(t0, t1, variance, nu, means, amounts):
        # (each expectation clamped at 0, where float32 and the truncated series may leave it below)
        def by_moments(t0, t1, variance, nu, means, amounts):
            m = moments(t1 - t0, nu, sigma)
            return spectrum(sum(a * dr.maximum(_by_moments(t0, t1, mean, variance, sigma, m), 0.0)
                                for mean, a in zip(means, amounts)))

        def by_half_range(t0, t1, variance, nu, means, amounts):
            return spectrum(sum(a * dr.maximum(_by_half_range(t0, t1, mean, variance, nu, sigma), 0.0)
                                for mean, a in zip(means, amounts)))

        core = dr.if_stmt((t0, t1, variance, nu, means, amounts), wide, by_moments, by_half_range,
                          label="scratch_filtered_along_core")
        tail = sum(a * _by_tails(t0, t1, mean, variance, nu, sigma) for mean, a in zip(means, amounts))
        return spectrum(dr.select(tails, tail, core))

    return dr.if_stmt(state, short, envelope, long_segment, label="scratch_filtered_along")


def along_intensity(t0, t1, nu, sigma, mean, variance):
    """``E_τ |Φ(t0 - τ, t1 - τ; ν)|²`` for ``τ ~ N(mean, variance)`` (µm, µm²), per wavelength.

    ``variance = 0`` gives the point value to float precision.
    """
    return _interval(t0, t1, nu, sigma, [(mean, 1.0)], variance)


def along_pair(a, b, c, d, nu, sigma, nodes, variance):
    """``Σ_j a_j E_τ Re[Φ_I Φ_J*]`` for two intervals I = [a, b], J = [c, d] on one line, over
    ``nodes = [(mean_j, a_j)]``, ``τ ~ N(mean_j, variance)``.

    ``Re E[Φ_I Φ_J*] = ½ (Λ[a, d] + Λ[c, b] - Λ[a, c] - Λ[b, d])``, ``Λ[x, y]`` the expectation of
    the interval between x and y (inclusion–exclusion over the four intervals the two ends cut;
    exact for overlapping, nested and disjoint intervals alike).
    """
    def between(x, y):
        return _interval(dr.minimum(x, y), dr.maximum(x, y), nu, sigma, nodes, variance)

    return 0.5 * (between(a, d) + between(c, b) - between(a, c) - between(b, d))


def along_expectation(t0, t1, before, after, nu, sigma, nodes, variance):
    """``Σ_j a_j E_τ Re[Φ_piece Φ_run*]`` over ``nodes = [(mean_j, a_j)]``, ``τ ~ N(mean_j, variance)``.

    The piece [t0, t1] belongs to a straight run that goes on ``before`` its start and ``after`` its
    end (µm; 0 where it ends, ``None`` for both: a piece on its own, ``E|Φ_piece|²``); the shares of
    a run's pieces add up to the run's value (docs/model.md §11.3).  By bilinearity, with the piece
    G = [t0, t1] between B = [t0 - before, t0] and A = [t1, t1 + after],

        Re E[Φ_G Φ_R*] = ½ (Λ(B ∪ G) + Λ(G ∪ A) - Λ(B) - Λ(A)),

    four expectations of single intervals (exact for any lengths).
    """
    if before is None:
        return _interval(t0, t1, nu, sigma, nodes, variance)
    r0, r1 = t0 - before, t1 + after
    value = _interval(r0, t1, nu, sigma, nodes, variance) + _interval(t0, r1, nu, sigma, nodes, variance) \
        - _interval(r0, t0, nu, sigma, nodes, variance) - _interval(t1, r1, nu, sigma, nodes, variance)
    return 0.5 * value  # (along_pair with J = the run, its ends ordered)
