"""Shader-node materials of the neutral description (re-exported by :mod:`mitsuba_bridge.scene`).

Glass and refraction, translucent and transparent surfaces, the Mix and Add
Shader nodes, alpha, normal and bump maps, and the Checker texture: what
``addon.render.gather.materials`` reads from node trees and
``mitsuba_bridge.builder.materials`` turns into Mitsuba plugins. Plain frozen
dataclasses, as the rest of the description (conventions in :mod:`.scene`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: scene.py imports this module
    from .scene import Material, Texture, Value

__all__ = ["Checker", "Dielectric", "Translucent", "Transparent", "Mix", "Add", "Mask", "NormalMap", "Bump"]

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Checker:
    """Blender's Checker Texture in UV space: ``scale`` squares per UV unit, ``color2`` in the square at the origin."""

    color1: RGB = (0.8, 0.8, 0.8)
    color2: RGB = (0.2, 0.2, 0.2)
    scale: float = 5.0


@dataclass(frozen=True)
class Dielectric:
    """Glass (``reflect``) or Refraction BSDF: a smooth (``alpha`` 0) or GGX-rough interface of index ``ior``.

    ``color`` tints what is transmitted and, for glass, what is reflected, as in Cycles.
    """

    color: Value = (1.0, 1.0, 1.0)
    ior: float = 1.5
    alpha: float = 0.0  #: GGX roughness α = Blender roughness²
    reflect: bool = True


@dataclass(frozen=True)
class Translucent:
    """Lambertian transmission to the other side (Blender's Translucent BSDF)."""

    color: Value = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class Transparent:
    """Light passes straight through, attenuated by the grey level of ``color`` (Blender's Transparent BSDF)."""

    color: RGB = (1.0, 1.0, 1.0)


@dataclass(frozen=True, eq=False)
class Mix:
    """``(1 − factor) · first + factor · second`` (Mix Shader); ``factor`` may be a texture."""

    factor: Value
    first: Material
    second: Material


@dataclass(frozen=True, eq=False)
class Add:
    """``first + second`` (Add Shader); the builder keeps the sum energy-conserving (docs/rendering.md)."""

    first: Material
    second: Material


@dataclass(frozen=True, eq=False)
class Mask:
    """Alpha: ``opacity`` of the surface is ``bsdf``, the rest lets light through unchanged."""

    opacity: Value
    bsdf: Material


@dataclass(frozen=True, eq=False)
class NormalMap:
    """``bsdf`` shaded with the tangent-space normals of ``texture`` (non-colour RGB, 0.5 = no tilt)."""

    texture: Texture
    bsdf: Material


@dataclass(frozen=True, eq=False)
class Bump:
    """``bsdf`` shaded as if the surface were displaced by ``height`` × ``scale`` along its normal."""

    height: Texture
    scale: float
    bsdf: Material
