"""The Gaussian coherence window: mirror lobe and partial window integrals (docs/model.md §2, §3.2).

All lengths in micrometres, frequencies in 1/µm.  ``σ`` is the window's
standard deviation (σ = δ_c / 6); the window is ``w(x) = exp(-|x - x0|² / 2σ²)``.
In a scratch's own frame the window is a product of a Gaussian along and a
Gaussian across the scratch, so every scratch transform is built from the one
function :func:`window_integral` (along: between the segment's ends; across:
between the edges of each linear piece of the profile).
"""
from __future__ import annotations

import math

import drjit as dr

from .complexmath import Cx, expi
from .faddeeva import faddeeva

__all__ = ["mirror_lobe", "window_integral", "piece_and_run_integrals", "unphased_end_term", "end_term", "line_term",
           "clamp_to_window", "END_CLAMP_SIGMAS", "END_NEGLIGIBLE_SIGMAS"]

#: Segment end positions are clamped to ±8σ (the window is e^-32 there).
END_CLAMP_SIGMAS = 8.0
#: An end farther than 6σ from the foot point contributes at most e^-18 of the
#: window's amplitude: its complex-erf term is skipped (docs/model.md §3.2).
END_NEGLIGIBLE_SIGMAS = 6.0

_SQRT_HALF_PI = math.sqrt(0.5 * math.pi)


def mirror_lobe(xi2, sigma):
    """``U0(ξ) = 2πσ² exp(-2π²σ²|ξ|²)`` of the unscratched window; ``xi2 = |ξ|²``."""
    sigma2 = sigma * sigma
    return (2.0 * math.pi) * sigma2 * dr.exp((-2.0 * math.pi ** 2) * sigma2 * xi2)


def _end_faddeeva(t, nu, sigma):
    """``(s, w(s b/(√2σ) + i|t|/(√2σ)))`` of an end at ``t``, ``s = -1`` for t >= 0, else +1."""
    sign = dr.select(t >= 0.0, -1.0, 1.0)
    inv_scale = dr.rcp(math.sqrt(2.0) * sigma)
    b = (2.0 * math.pi) * nu * (sigma * sigma)
    return sign, faddeeva(Cx(sign * b * inv_scale, dr.abs(t) * inv_scale))


def _end_term(t, nu, sigma):
    """``s g(t) w(s b/(√2σ) + i|t|/(√2σ))`` with ``s = -1`` for t >= 0, else +1.

    With it ``Φ(t) = σ√(π/2) [end_term(t) + 2 e^{-2π²σ²ν²} H(t)]`` for both signs
    of ``t`` (H: unit step), which is the pair of Faddeeva forms of docs/model.md §3.2.
    """
    sign, w = _end_faddeeva(t, nu, sigma)
    g = expi((-2.0 * math.pi) * nu * t) * dr.exp(-0.5 * dr.square(t / sigma))
    return g * w * sign


def unphased_end_term(t, nu, sigma):
    """The end term of :func:`window_integral` at ``t`` without its phase ``e^{-2πiνt}``, in units of
    ``σ√(π/2)``: ``s e^{-t²/2σ²} w(...)``.  For callers that share one phase between the ends at one
    position at several frequencies (:func:`.profiles.triangular`); ``t`` already clamped
    (:func:`clamp_to_window`)."""
    sign, w = _end_faddeeva(t, nu, sigma)
    return w * (sign * dr.exp(-0.5 * dr.square(t / sigma)))


def line_term(nu, sigma):
    """``(Φ(∞; ν) - Φ(-∞; ν)) / (σ√(π/2)) = 2 e^{-2π²σ²ν²}``: the step of Φ at the foot point."""
    return 2.0 * dr.exp((-2.0 * math.pi ** 2) * (sigma * sigma) * nu * nu)


def clamp_to_window(t, sigma):
    """``t`` clamped to ±8σ, where the window is e^-32 (as :func:`window_integral` clamps its ends)."""
    limit = END_CLAMP_SIGMAS * sigma
    return dr.clip(t, -limit, limit)


def _skippable_end_term(t, nu, sigma, wanted=True):
    """:func:`_end_term`, skipped (zero) for whole SIMD packets of far (or not ``wanted``) ends."""
    zero = dr.zeros(type(nu))
    near = (dr.abs(t) < END_NEGLIGIBLE_SIGMAS * sigma) & wanted

    def compute(t, nu):
        term = _end_term(t, nu, sigma)
        return term.re, term.im

    re, im = dr.if_stmt((t, nu), near, compute, lambda t, nu: (zero, zero), label="scratch_end")
    return Cx(re, im)


def end_term(t, nu, sigma):
    """``Φ(t; ν) / (σ√(π/2)) - 2 e^{-2π²σ²ν²} H(t)``: the end term of :func:`window_integral` at ``t`` (clamped
    to the window), zero for whole SIMD packets of ends beyond 6σ (for callers that share an end between
    several integrals: ``window_integral(t0, t1) = σ√(π/2) (end_term(t1) - end_term(t0) + steps)``)."""
    return _skippable_end_term(clamp_to_window(t, sigma), nu, sigma)


def window_integral(t0, t1, nu, sigma, skip_far_ends: bool = True):
    """``Φ(t1; ν) - Φ(t0; ν) = ∫_{t0}^{t1} exp(-τ²/2σ²) exp(-2πiντ) dτ`` (complex).

    ``Φ(t; ν) = ∫_{-∞}^{t} exp(-τ²/2σ²) exp(-2πiντ) dτ`` (docs/model.md §3.2), for
    ``t0 <= t1`` measured from the foot point of the shading point on the line
    of integration.  The full-line terms of both ends cancel analytically, so
    there is no cancellation when both ends lie on the same side.  With
    ``skip_far_ends`` the complex-erf term of an end beyond 6σ is skipped for
    whole SIMD packets (worth its branch for segment ends, not for the edges of
    a scratch's cross-section, which are always near).
    """
    t0, t1 = clamp_to_window(t0, sigma), clamp_to_window(t1, sigma)
    steps = dr.select(t1 >= 0.0, 1.0, 0.0) - dr.select(t0 >= 0.0, 1.0, 0.0)
    line = line_term(nu, sigma) * steps
    end_term = _skippable_end_term if skip_far_ends else _end_term
    result = end_term(t1, nu, sigma) - end_term(t0, nu, sigma) + line
    return result * (_SQRT_HALF_PI * sigma)


def piece_and_run_integrals(t0, t1, before, after, nu, sigma):
    """``(Φ(t1) - Φ(t0), Φ(t1 + after) - Φ(t0 - before))``: :func:`window_integral` along a piece and
    along the straight run it belongs to, which goes on ``before`` its start and ``after`` its end
    (``>= 0``; 0: the piece ends there).  The run shares the piece's end terms where it ends with it,
    and far ends are skipped as there, so a run costs little more than its piece."""
    r0, r1 = clamp_to_window(t0 - before, sigma), clamp_to_window(t1 + after, sigma)
    t0, t1 = clamp_to_window(t0, sigma), clamp_to_window(t1, sigma)
    e0, e1 = _skippable_end_term(t0, nu, sigma), _skippable_end_term(t1, nu, sigma)
    moved0, moved1 = r0 != t0, r1 != t1
    f0 = _skippable_end_term(r0, nu, sigma, moved0)
    f1 = _skippable_end_term(r1, nu, sigma, moved1)
    f0, f1 = f0.select(moved0, e0), f1.select(moved1, e1)
    full = line_term(nu, sigma)
    step = lambda t: dr.select(t >= 0.0, 1.0, 0.0)
    piece = e1 - e0 + full * (step(t1) - step(t0))
    run = f1 - f0 + full * (step(r1) - step(r0))
    return piece * (_SQRT_HALF_PI * sigma), run * (_SQRT_HALF_PI * sigma)
