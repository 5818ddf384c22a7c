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
import mitsuba as mi
import numpy as np

from ..maths.complexmath import Cx
from ..maths.window import end_term, window_integral
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


def moments_start(nu, sigma):
    """The end term at d = 0 of every interval's :func:`moments` (one Faddeeva evaluation, shared)."""
    return end_term(dr.zeros(mi.Float), nu, math.sqrt(2.0) * sigma)


def moments(length, nu, sigma, start=None):
    """``[m_0 .. m_6]`` (complex) of a segment ``length`` µm long: ``m_k = ∫_0^Y y^k e^{-y²-iby} dy``.

    ``Y = L/2σ``, ``b = 4πσν``; ``m_0`` is the window integral of standard deviation √2σ over
    [0, L] divided by 2σ (``start``: :func:`moments_start`, its end term at 0, when the caller shares it;
    the end at L is skipped for whole SIMD packets of long intervals), the others follow from
    ``m_{k+1} = (k m_{k-1} - i b m_k + δ_k0 - Y^k e^{-Y²-ibY}) / 2`` (integration by parts), which
    multiplies m_0's error by about ``(b/2)^k``: used for ``|b| <= TAIL_ABOVE`` only.
    """
    two_sigma = 2.0 * sigma
    root2_sigma = math.sqrt(2.0) * sigma
    if start is None:
        start = moments_start(nu, sigma)
    m0 = (end_term(length, nu, root2_sigma) - start) * (math.sqrt(0.5 * math.pi) * root2_sigma / two_sigma)
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


def _any_wavelength(mask):
    """Per lane: whether any wavelength's entry of ``mask`` (a spectrum's mask) holds."""
    result = mask[0]
    for k in range(1, len(mask)):
        result = result | mask[k]
    return result


def _pick(index, values):
    """``values[index]`` for a per-lane (or loop) index over a Python tuple of arrays."""
    result = values[-1]
    for k in range(len(values) - 2, -1, -1):
        result = dr.select(index == k, values[k], result)
    return result


def _loop_over_nodes(nodes, body, initial, label):
    """``Σ_j body(mean_j, a_j)`` over ``nodes = [(mean_j, a_j)]`` as a symbolic loop (its body traced once)."""
    means = tuple(mean for mean, _ in nodes)
    amounts = tuple(amount for _, amount in nodes)
    kind = type(initial)

    def step(j, total):
        return j + 1, kind(total + body(_pick(j, means), _pick(j, amounts)))

    return dr.while_loop((dr.zeros(mi.UInt32), initial), lambda j, total: j < len(nodes), step, label=label)[1]


def _by_envelope(t0, t1, mean, variance, nu, sigma):
    """Point values at the nodes of the footprint times the envelope ``e^{-(τ - t_mid)²/σ²}`` (a loop)."""
    pairs = envelope_nodes(0.5 * (t0 + t1), mean, variance, sigma * sigma, ENVELOPE_NODES)
    positions = tuple(p for p, _ in pairs)
    weights = tuple(w for _, w in pairs)
    kind = type(nu)

    def step(e, total):
        tau = _pick(e, positions)
        return e + 1, kind(total + _pick(e, weights) * window_integral(t0 - tau, t1 - tau, nu, sigma).abs2())

    return dr.while_loop((dr.zeros(mi.UInt32), dr.zeros(kind)), lambda e, total: e < ENVELOPE_NODES, step,
                         label="scratch_filtered_envelope")[1]


def _interval(t0, t1, nu, sigma, nodes, variance, wide_mean, start=None):
    """``Σ_j a_j E_τ|Φ(t0 - τ, t1 - τ; ν)|²``, ``τ ~ N(mean_j, variance)``, over ``nodes = [(mean_j, a_j)]``;
    footprints at least MOMENTS_FROM_SIGMAS σ wide take all nodes at ``wide_mean`` (the along factor barely
    changes over the nodes' spread, of order σ, there: one evaluation instead of one per node).

    The regime is chosen per lane (module docstring); every regime's body is traced once (symbolic loops
    over the nodes), and whole SIMD packets skip the regimes none of their lanes needs.
    """
    spectrum = type(nu)
    short = t1 - t0 <= SHORT_SIGMAS * sigma
    wide = variance >= (MOMENTS_FROM_SIGMAS * sigma) ** 2
    tails = ((4.0 * math.pi) * sigma) * dr.abs(nu) > TAIL_ABOVE
    total_amount = spectrum(sum(amount for _, amount in nodes))
    state = (t0, t1, variance, nu, wide_mean, total_amount)

    def envelope(t0, t1, variance, nu, wide_mean, total_amount):
        return _loop_over_nodes(nodes, lambda mean, a: a * _by_envelope(t0, t1, mean, variance, nu, sigma),
                                dr.zeros(spectrum), "scratch_filtered_envelope_nodes")

    def long_segment(t0, t1, variance, nu, wide_mean, total_amount):
        def by_moments(t0, t1, variance, nu, wide_mean, total_amount):
            value = _by_moments(t0, t1, wide_mean, variance, sigma, moments(t1 - t0, nu, sigma, start))
            return spectrum(total_amount * dr.maximum(value, 0.0))

        def by_half_range(t0, t1, variance, nu, wide_mean, total_amount):
            # (each expectation clamped at 0, where float32 may leave it a little below)
            return _loop_over_nodes(
                nodes, lambda mean, a: a * dr.maximum(_by_half_range(t0, t1, mean, variance, nu, sigma), 0.0),
                dr.zeros(spectrum), "scratch_filtered_half_range_nodes")

        def by_tails(t0, t1, variance, nu, wide_mean, total_amount):
            return _loop_over_nodes(nodes, lambda mean, a: a * _by_tails(t0, t1, mean, variance, nu, sigma),
                                    dr.zeros(spectrum), "scratch_filtered_tail_nodes")

        def core(t0, t1, variance, nu, wide_mean, total_amount):
            return dr.if_stmt((t0, t1, variance, nu, wide_mean, total_amount), wide, by_moments, by_half_range,
                              label="scratch_filtered_along_core")

        # (per wavelength: the tails where |b| is large; the core's regimes only in SIMD packets with a lane
        # near some wavelength's diffraction line)
        tail = by_tails(t0, t1, variance, nu, wide_mean, total_amount)
        inner = dr.if_stmt((t0, t1, variance, nu, wide_mean, total_amount), _any_wavelength(~tails), core,
                           lambda *_: dr.zeros(spectrum), label="scratch_filtered_along_lit")
        return spectrum(dr.select(tails, tail, inner))

    return dr.if_stmt(state, short, envelope, long_segment, label="scratch_filtered_along")


def along_intensity(t0, t1, nu, sigma, mean, variance):
    """``E_τ |Φ(t0 - τ, t1 - τ; ν)|²`` for ``τ ~ N(mean, variance)`` (µm, µm²), per wavelength.

    ``variance = 0`` gives the point value (within 0.3 % of the segment's peak: the nodes' quadrature).
    """
    return _interval(t0, t1, nu, sigma, [(mean, 1.0)], variance, mean)


def along_pair(a, b, c, d, nu, sigma, nodes, variance, wide_mean):
    """``Σ_j a_j E_τ Re[Φ_I Φ_J*]`` for two intervals I = [a, b], J = [c, d] on one line, over
    ``nodes = [(mean_j, a_j)]``, ``τ ~ N(mean_j, variance)`` (``wide_mean``: :func:`_interval`).

    ``Re E[Φ_I Φ_J*] = ½ (Λ[a, d] + Λ[c, b] - Λ[a, c] - Λ[b, d])``, ``Λ[x, y]`` the expectation of
    the interval between x and y (inclusion–exclusion over the four intervals the two ends cut;
    exact for overlapping, nested and disjoint intervals alike).  The four are one symbolic loop.
    """
    spectrum = type(nu)
    ends = ((a, d, 0.5), (c, b, 0.5), (a, c, -0.5), (b, d, -0.5))
    lows = tuple(dr.minimum(x, y) for x, y, _ in ends)
    highs = tuple(dr.maximum(x, y) for x, y, _ in ends)

    start = moments_start(nu, sigma)  # (the four intervals' moments share their end term at d = 0)

    def step(i, total):
        sign = dr.select(i < 2, 0.5, -0.5)
        value = _interval(_pick(i, lows), _pick(i, highs), nu, sigma, nodes, variance, wide_mean, start)
        return i + 1, spectrum(total + sign * value)

    return dr.while_loop((dr.zeros(mi.UInt32), dr.zeros(spectrum)), lambda i, total: i < 4, step,
                         label="scratch_filtered_intervals")[1]


#: Intervals at least this long (in σ) have the moments of an infinite one (the window integral of
#: standard deviation √2σ is clamped at 8√2σ; e^{-32} beyond).
LONG_SIGMAS = 8.0 * math.sqrt(2.0)


def _endpoint_terms(t, mean, variance, sigma):
    """Per endpoint: ``(σ erf(x/√2), [2σ q^k He_{k-1}(x) φ(x) / k!], k = 1 .. 6)``, x its standardised position."""
    inv_s = dr.rsqrt(variance + 0.5 * sigma * sigma)
    q = sigma * inv_s
    x = (t - mean) * inv_s
    phi = dr.exp(-0.5 * x * x) * _INV_SQRT_2PI
    he_prev, he, scale = 0.0, 1.0, 2.0 * sigma
    values = []
    for k in range(1, TAYLOR_TERMS):
        scale = scale * q * (1.0 / k)
        values.append(scale * he * phi)
        he_prev, he = he, x * he - (k - 1) * he_prev
    return sigma * dr.erf(x * _INV_SQRT_2), values


def _wide_run_share(t0, t1, before, after, nu, sigma, mean, variance):
    """:func:`along_pair` of a piece and its run for a wide footprint where every one of the four intervals
    is empty or at least LONG_SIGMAS σ long: they share the moments of an infinite interval (one window
    integral), and each of the four endpoints' Taylor terms is computed once.  (Where the run goes on past
    both ends, the odd terms of its cut points cancel: a cut is no end, docs/model.md §11.3.)"""
    m = moments(dr.zeros(mi.Float) + 1e30, nu, sigma)  # (clamped: the infinite interval's)
    r0, r1 = t0 - before, t1 + after
    e_r0, e_t0, e_t1, e_r1 = (_endpoint_terms(t, mean, variance, sigma) for t in (r0, t0, t1, r1))
    has_before, has_after = before > 0.0, after > 0.0
    # ½ (Λ[r0, t1] + Λ[t0, r1] - Λ[r0, t0] - Λ[t1, r1]), each Λ[lo, hi] = 2σ√π Σ_k c_k(lo, hi) Re m_k with
    # c_0 = σ (erf_hi - erf_lo), c_k = (-1)^k E_k(lo) - E_k(hi)
    intervals = ((e_r0, e_t1, 0.5, True), (e_t0, e_r1, 0.5, True), (e_r0, e_t0, -0.5, has_before),
                 (e_t1, e_r1, -0.5, has_after))
    total = 0.0
    for lo, hi, sign, present in intervals:
        weight = sign if present is True else dr.select(present, sign, 0.0)
        value = (hi[0] - lo[0]) * m[0].re
        for k in range(1, TAYLOR_TERMS):
            parity = 1.0 if k % 2 == 0 else -1.0
            value = dr.fma(parity * lo[1][k - 1] - hi[1][k - 1], m[k].re, value)
        total = total + weight * value
    return (2.0 * _SQRT_PI * sigma) * total


def along_expectation(t0, t1, before, after, nu, sigma, nodes, variance, wide_mean):
    """``Σ_j a_j E_τ Re[Φ_piece Φ_run*]`` over ``nodes = [(mean_j, a_j)]``, ``τ ~ N(mean_j, variance)``.

    The piece [t0, t1] belongs to a straight run that goes on ``before`` its start and ``after`` its
    end (µm; 0 where it ends, ``None`` for both: a piece on its own, ``E|Φ_piece|²``); the shares of
    a run's pieces add up to the run's value (docs/model.md §11.3): :func:`along_pair` with J the run.
    """
    if before is None:
        return _interval(t0, t1, nu, sigma, nodes, variance, wide_mean)
    spectrum = type(nu)
    long_enough = LONG_SIGMAS * sigma
    fast = ((variance >= (MOMENTS_FROM_SIGMAS * sigma) ** 2) & (t1 - t0 >= long_enough)
            & ((before == 0.0) | (before >= long_enough)) & ((after == 0.0) | (after >= long_enough))
            & ~_any_wavelength(((4.0 * math.pi) * sigma) * dr.abs(nu) > TAIL_ABOVE))
    total_amount = spectrum(sum(amount for _, amount in nodes))

    def quick(t0, t1, before, after, nu, variance, wide_mean):
        value = _wide_run_share(t0, t1, before, after, nu, sigma, wide_mean, variance)
        return spectrum(total_amount * dr.maximum(value, 0.0))

    def general(t0, t1, before, after, nu, variance, wide_mean):
        return along_pair(t0, t1, t0 - before, t1 + after, nu, sigma, nodes, variance, wide_mean)

    return dr.if_stmt((t0, t1, before, after, nu, variance, wide_mean), fast, quick, general,
                      label="scratch_filtered_run_share")
