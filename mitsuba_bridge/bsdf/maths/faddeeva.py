"""The Faddeeva function ``w(z) = exp(-z²) erfc(-i z)`` in the upper half plane.

Finite scratch segments need a complex error function (docs/model.md §3.2); Dr.Jit
only has a real ``erf``, and ``erf`` of a complex argument overflows for large
frequencies.  ``w`` stays bounded (|w| <= 1 for Im z >= 0) and Weideman's
rational approximation (SIAM J. Numer. Anal. 31(5), 1994) evaluates it without
branches, which suits vectorised code::

    Z = (L + i z) / (L - i z),    w(z) ≈ 2 p(Z) / (L - i z)² + (1/√π) / (L - i z)

with ``p`` a polynomial of degree N - 1 whose coefficients come from an FFT of
``exp(-t²)(L² + t²)`` at ``t = L tan(θ/2)``.  :func:`weideman_coefficients`
regenerates them with numpy for any N; the BSDF uses N = 13 (max. relative
error 6.9e-6 over Re z in [-600, 600], Im z in [0, 8] in float32, below what float32
arithmetic adds to the scratch amplitudes); docs/model.md §3.2 lists N = 16 (1.1e-6).
``p`` has real coefficients, so it is evaluated by a real recurrence (:func:`real_polynomial_at`,
docs/model.md §3.2): half the arithmetic of complex Horner steps.
"""
from __future__ import annotations

import math
from functools import lru_cache

import drjit as dr
import numpy as np

from .complexmath import Cx

__all__ = ["faddeeva", "real_polynomial_at", "weideman_coefficients", "DEFAULT_TERMS"]

DEFAULT_TERMS = 13
_INV_SQRT_PI = 1.0 / math.sqrt(math.pi)


@lru_cache(maxsize=None)
def weideman_coefficients(terms: int = DEFAULT_TERMS) -> tuple[float, tuple[float, ...]]:
    """``(L, coefficients)`` of Weideman's approximation with ``terms`` terms.

    The coefficients are in Horner order (highest power first).  For
    ``terms = 16`` they are the ones printed in docs/model.md §3.2.
    """
    m = 2 * terms
    k = np.arange(-m + 1, m)
    scale = math.sqrt(terms / math.sqrt(2.0))  # L = sqrt(N / sqrt(2))
    t = scale * np.tan(k * math.pi / m / 2.0)
    samples = np.concatenate([[0.0], np.exp(-t * t) * (scale * scale + t * t)])
    spectrum = np.real(np.fft.fft(np.fft.fftshift(samples))) / (2 * m)
    coefficients = spectrum[1:terms + 1][::-1]
    return scale, tuple(float(c) for c in coefficients)


def faddeeva(z: Cx, terms: int = DEFAULT_TERMS) -> Cx:
    """``w(z)`` for ``Im z >= 0`` (complex pair of Dr.Jit arrays).

    Branch-free; the only division is by ``|L - i z|² >= L²``, so no input with
    ``Im z >= 0`` produces a NaN or an infinity.
    """
    scale, coefficients = weideman_coefficients(terms)
    # r = 1 / (L - i z), with L - i z = (L + y) - i x.
    denominator_re = scale + z.im
    inverse = dr.rcp(dr.fma(denominator_re, denominator_re, z.re * z.re))
    r = Cx(denominator_re * inverse, z.re * inverse)
    # Z = (L + i z) / (L - i z), with L + i z = (L - y) + i x.
    big_z = Cx(scale - z.im, z.re) * r
    return (real_polynomial_at(coefficients, big_z) * 2.0 * r + _INV_SQRT_PI) * r


def real_polynomial_at(coefficients, z: Cx) -> Cx:
    """``p(z)`` for real ``coefficients`` (Horner order, highest power first, at least three) at complex ``z``.

    p is divided by the real quadratic ``x² - 2Re(z) x + |z|²``, which vanishes at z (docs/model.md
    §3.2): the remainder ``b_1 x + a_0 + s b_2`` comes from the real
    recurrence ``b_k = a_k + r b_{k+1} + s b_{k+2}`` (r = 2 Re z, s = -|z|²), two multiply-adds per
    coefficient against four for a complex Horner step.  Accurate here: |z| <= 1 and the degree is
    small (``tests/bridge/bsdf/maths/test_maths.py`` test02 compares the Faddeeva function with scipy's).
    """
    r = 2.0 * z.re
    s = -z.abs2()
    b2, b1 = coefficients[0], dr.fma(r, coefficients[0], coefficients[1])  # b_{k+2}, b_{k+1}
    for c in coefficients[2:-1]:
        b2, b1 = b1, dr.fma(r, b1, dr.fma(s, b2, c))
    return Cx(dr.fma(b1, z.re, dr.fma(s, b2, coefficients[-1])), b1 * z.im)
