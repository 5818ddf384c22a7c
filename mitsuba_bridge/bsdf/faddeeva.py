"""The Faddeeva function ``w(z) = exp(-z²) erfc(-i z)`` in the upper half plane.

Finite scratch segments need a complex error function (docs/model.md §3.2); Dr.Jit
only has a real ``erf``, and ``erf`` of a complex argument overflows for large
frequencies.  ``w`` stays bounded (|w| <= 1 for Im z >= 0) and Weideman's
rational approximation (SIAM J. Numer. Anal. 31(5), 1994) evaluates it without
branches, which suits vectorised code::

    Z = (L + i z) / (L - i z),    w(z) ≈ 2 p(Z) / (L - i z)² + (1/√π) / (L - i z)

with ``p`` a polynomial of degree N - 1 whose coefficients come from an FFT of
``exp(-t²)(L² + t²)`` at ``t = L tan(θ/2)``.  :func:`weideman_coefficients`
regenerates them with numpy for any N; the BSDF uses N = 12 (max. relative
error 1.2e-5 over Re z in [-500, 500], Im z in [0, 8], below what float32
arithmetic adds to the scratch amplitudes); docs/model.md §3.2 lists N = 16 (5e-7).
"""
from __future__ import annotations

import math
from functools import lru_cache

import drjit as dr
import numpy as np

from .complexmath import Cx

__all__ = ["faddeeva", "weideman_coefficients", "DEFAULT_TERMS"]

DEFAULT_TERMS = 12
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
    p = big_z * coefficients[0] + coefficients[1]
    for c in coefficients[2:]:
        p = p * big_z + c
    return (p * 2.0 * r + _INV_SQRT_PI) * r
