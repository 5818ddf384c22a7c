"""Distributions of per-scratch parameters, in the paper's notation (docs/model.md §7).

``U[lower, upper]`` is :class:`Uniform`, ``G[mean, std]`` is :class:`Gaussian`,
a fixed value is :class:`Constant`.  Widths and depths must be positive, so a
drawn value <= 0 is drawn again (the supplement's convention); a distribution
that almost never yields a positive value is refused instead of looping.

Every ``sample`` takes a ``numpy.random.Generator``: the same seed gives the
same values on every machine.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from typing import Union

import numpy as np

from ..errors import ParameterError

__all__ = ["Uniform", "Gaussian", "Constant", "Distribution", "parse_distribution"]

# Refuse distributions whose probability of a positive draw is below this.
_MIN_ACCEPTANCE = 1e-3


@dataclass(frozen=True)
class Uniform:
    """U[lower, upper]; draws <= 0 are redrawn."""

    lower: float
    upper: float

    def __post_init__(self):
        if not (math.isfinite(self.lower) and math.isfinite(self.upper)):
            raise ParameterError(f"U[{self.lower}, {self.upper}]: bounds must be finite")
        if self.upper < self.lower:
            raise ParameterError(f"U[{self.lower}, {self.upper}]: upper bound below lower bound")
        if self.upper <= 0 or (self.upper - max(self.lower, 0.0)) < _MIN_ACCEPTANCE * (self.upper - self.lower):
            raise ParameterError(f"U[{self.lower}, {self.upper}]: (almost) no positive values to draw")

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """``size`` positive float64 draws."""
        if self.lower == self.upper:
            return np.full(size, float(self.lower))
        return _redraw_nonpositive(lambda n: rng.uniform(self.lower, self.upper, n), size)

    def mean(self) -> float:
        """Mean of the positive part (what the drawn values average to)."""
        low = max(self.lower, 0.0)
        return 0.5 * (low + self.upper)

    def __str__(self) -> str:
        return f"U[{self.lower:g}, {self.upper:g}]"


@dataclass(frozen=True)
class Gaussian:
    """G[mean, std]; draws <= 0 are redrawn (a truncated normal)."""

    mean: float
    std: float

    def __post_init__(self):
        if not (math.isfinite(self.mean) and math.isfinite(self.std)) or self.std < 0:
            raise ParameterError(f"G[{self.mean}, {self.std}]: needs a finite mean and std >= 0")
        if self.std == 0 and self.mean <= 0:
            raise ParameterError(f"G[{self.mean}, {self.std}]: never positive")
        if self.std > 0 and 0.5 * math.erfc(-self.mean / (self.std * math.sqrt(2))) < _MIN_ACCEPTANCE:
            raise ParameterError(f"G[{self.mean}, {self.std}]: (almost) no positive values to draw")

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """``size`` positive float64 draws."""
        if self.std == 0:
            return np.full(size, float(self.mean))
        return _redraw_nonpositive(lambda n: rng.normal(self.mean, self.std, n), size)

    def __str__(self) -> str:
        return f"G[{self.mean:g}, {self.std:g}]"


@dataclass(frozen=True)
class Constant:
    """A fixed positive value (the supplement writes ``D = 120nm``)."""

    value: float

    def __post_init__(self):
        if not (math.isfinite(self.value) and self.value > 0):
            raise ParameterError(f"constant {self.value}: must be finite and > 0")

    def sample(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """``size`` copies of the value (consumes no random numbers)."""
        return np.full(size, float(self.value))

    def __str__(self) -> str:
        return f"{self.value:g}"


Distribution = Union[Uniform, Gaussian, Constant]


_UNIT_EXPONENTS = {"m": 0, "mm": -3, "um": -6, "µm": -6, "nm": -9}


def parse_distribution(text: str, unit: str = "m") -> Distribution:
    """Parse the paper's notation: ``"U[0, 6]"``, ``"G[250, 80]"`` or ``"120"``.

    ``unit`` (``"m"``, ``"mm"``, ``"um"``, ``"nm"``) is the unit of the numbers;
    the result is in metres, e.g. ``parse_distribution("G[250, 80]", "nm")``.
    Numbers are scaled by decimal exponent, so ``"250"`` nm is exactly ``250e-9``.
    """
    if unit not in _UNIT_EXPONENTS:
        raise ParameterError(f"unknown unit {unit!r}; use one of {sorted(_UNIT_EXPONENTS)}")
    exponent = _UNIT_EXPONENTS[unit]

    def metres(number: str) -> float:
        try:  # scaled by decimal exponent: "1e30" µm is exactly 1e24 m
            return float(Decimal(number.strip()).scaleb(exponent))
        except InvalidOperation:
            raise ValueError(f"not a number: {number.strip()!r}") from None

    text = text.strip()
    try:
        if text[:2].upper() in ("U[", "G[") and text.endswith("]"):
            a, b = (metres(x) for x in text[2:-1].split(","))
            return Uniform(a, b) if text[0].upper() == "U" else Gaussian(a, b)
        return Constant(metres(text))
    except ValueError as error:
        raise ParameterError(f"cannot read distribution {text!r}: {error}") from None


def _redraw_nonpositive(draw, size: int) -> np.ndarray:
    values = draw(size)
    bad = np.flatnonzero(values <= 0)
    while bad.size:  # terminates: the constructors refuse acceptance < 1e-3
        values[bad] = draw(bad.size)
        bad = bad[values[bad] <= 0]
    return values
