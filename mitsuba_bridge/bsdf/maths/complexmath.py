"""Complex arithmetic on pairs of Dr.Jit arrays.

Dr.Jit's ``Complex2f`` wraps a single ``Float``; the BSDF needs complex values
for four wavelengths at once, so a complex number here is a pair (re, im) of
arrays of any one Dr.Jit floating-point type (``mi.Float``, ``mi.Spectrum``
...) or Python floats.  :class:`Cx` keeps the formulas readable
(``a * b + c``) and costs nothing at run time: it only exists while tracing.

Put the :class:`Cx` on the left of an operator (``z * x``, not ``x * z``).
"""
from __future__ import annotations

import math

import drjit as dr

__all__ = ["Cx", "expi", "exp", "scaled_sinc"]

#: Below this |πz|² the complex sinc is its series 1 - (πz)²/6 (next term < 1e-9).
_SERIES_BELOW = 1e-4


class Cx:
    """A complex number ``re + i im`` made of two Dr.Jit arrays (or floats)."""

    __slots__ = ("re", "im")

    def __init__(self, re, im=0.0):
        self.re = re
        self.im = im

    # ---------------------------------------------------------- arithmetic
    def __add__(self, other):
        if isinstance(other, Cx):
            return Cx(self.re + other.re, self.im + other.im)
        return Cx(self.re + other, self.im)

    __radd__ = __add__

    def __sub__(self, other):
        if isinstance(other, Cx):
            return Cx(self.re - other.re, self.im - other.im)
        return Cx(self.re - other, self.im)

    def __rsub__(self, other):
        return Cx(other - self.re, -self.im)

    def __neg__(self):
        return Cx(-self.re, -self.im)

    def __mul__(self, other):
        if isinstance(other, Cx):
            return Cx(dr.fma(self.re, other.re, -self.im * other.im),
                      dr.fma(self.re, other.im, self.im * other.re))
        return Cx(self.re * other, self.im * other)

    __rmul__ = __mul__

    def __truediv__(self, other):
        if isinstance(other, Cx):
            scale = dr.rcp(dr.fma(other.re, other.re, other.im * other.im))
            return self * Cx(other.re * scale, -other.im * scale)
        return self * dr.rcp(other)

    def mul_i(self):
        """``i z``."""
        return Cx(-self.im, self.re)

    def conj(self):
        return Cx(self.re, -self.im)

    def abs2(self):
        """``|z|²``."""
        return dr.fma(self.re, self.re, self.im * self.im)

    def select(self, mask, other):
        """``self`` where ``mask``, else ``other`` (both complex)."""
        return Cx(dr.select(mask, self.re, other.re), dr.select(mask, self.im, other.im))

    def __repr__(self):
        return f"Cx({self.re!r}, {self.im!r})"


def expi(theta) -> Cx:
    """``exp(i θ)`` for real θ."""
    s, c = dr.sincos(theta)
    return Cx(c, s)


def exp(z: Cx) -> Cx:
    """``exp(z)`` for complex z."""
    s, c = dr.sincos(z.im)
    magnitude = dr.exp(z.re)
    return Cx(magnitude * c, magnitude * s)


def scaled_sinc(re, im) -> Cx:
    """``e^{-π|im|} sin(πz)/(πz)`` for ``z = re + i im``: the normalised sinc without its growth e^{π|im|}.

    The growth is returned to the caller's exponent, where the window's decay cancels it (a sinc of
    |πz| ≈ 100 would overflow float32 on its own).
    """
    x, y = math.pi * re, math.pi * im
    s, c = dr.sincos(x)
    decay = dr.exp(-2.0 * dr.abs(y))
    half_cosh, half_sinh = 0.5 * (1.0 + decay), dr.copysign(0.5 * (1.0 - decay), y)
    numerator = Cx(s * half_cosh, c * half_sinh)  # sin(x + iy) e^{-|y|}
    z = Cx(x, y)
    z2 = z * z
    small = z2.abs2() < _SERIES_BELOW * _SERIES_BELOW
    series = (1.0 - z2 * (1.0 / 6.0)) * dr.exp(-dr.abs(y))
    return (numerator / Cx(dr.select(small, 1.0, x), dr.select(small, 0.0, y))).select(~small, series)
