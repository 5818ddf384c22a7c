"""How much light a material can scatter: the bound that keeps an Add Shader from creating energy.

Cycles sums the two halves of an Add Shader, which can scatter more light than arrives (a white
diffuse plus a white glossy reflects twice the light). Mitsuba can only blend BSDFs, so the builder
keeps the sum while the halves' brightest channels add up to at most 1 and scales both down together
otherwise (docs/rendering.md, "The Add Shader, honestly"); the Blender side warns when that happens.
Both ask these functions, each with its own way of finding a texture's brightest pixel.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .materials import (Add, Bump, Checker, Dielectric, Diffuse, Emission, Glossy, Mask, Mix, NormalMap, Principled,
                        Texture, Translucent, Transparent)

__all__ = ["albedo_bound", "add_sum", "add_scale", "Brightest"]

#: A texture → its brightest linear RGB value per channel, shape (3,).
Brightest = Callable[[Texture], np.ndarray]


def albedo_bound(material, brightest: Brightest) -> np.ndarray:
    """An upper bound per RGB channel of the fraction of light ``material`` scatters (a texture: its brightest
    pixel, from ``brightest``)."""
    def bound(value):
        if isinstance(value, Texture):
            return np.minimum(np.asarray(brightest(value), dtype=float), 1.0)
        if isinstance(value, Checker):
            return np.maximum(np.asarray(value.color1, dtype=float), np.asarray(value.color2, dtype=float))
        return np.broadcast_to(np.asarray(value, dtype=float), (3,))

    if isinstance(material, Diffuse):
        return bound(material.reflectance)
    if isinstance(material, (Glossy, Dielectric, Translucent, Transparent)):
        return bound(material.color)
    if isinstance(material, Principled):
        return np.minimum(bound(material.base_color) + 0.04, 1.0)  # plus the dielectric specular (F0 ≈ 4 %)
    if isinstance(material, Mix):
        factor = material.factor if isinstance(material.factor, (int, float)) else None
        first, second = albedo_bound(material.first, brightest), albedo_bound(material.second, brightest)
        return np.maximum(first, second) if factor is None else (1 - factor) * first + factor * second
    if isinstance(material, Add):
        return add_scale(material, brightest) * (albedo_bound(material.first, brightest)
                                                  + albedo_bound(material.second, brightest))
    if isinstance(material, (Mask, NormalMap, Bump)):
        return albedo_bound(material.bsdf, brightest)
    if isinstance(material, Emission):
        return np.zeros(3) if material.bsdf is None else albedo_bound(material.bsdf, brightest)
    return np.ones(3)


def add_sum(material: Add, brightest: Brightest) -> float:
    """The sum of the two halves' brightest channels: more than 1 means Cycles' sum creates energy."""
    return float(np.max(albedo_bound(material.first, brightest)) + np.max(albedo_bound(material.second, brightest)))


def add_scale(material: Add, brightest: Brightest) -> float:
    """The factor both halves of an Add Shader are rendered at: 1 while :func:`add_sum` ≤ 1, else 1 / the sum."""
    total = add_sum(material, brightest)
    return 1.0 if total <= 1.0 else 1.0 / total
