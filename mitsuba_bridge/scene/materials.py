"""Materials of the neutral scene description: textures, the shader nodes the Blender side reads, and
the scratched surface.

What ``addon.render.gather.materials`` reads from node trees and ``mitsuba_bridge.builder.materials``
turns into Mitsuba plugins: plain frozen dataclasses, as the rest of the description (conventions in
:mod:`.description`).  Principled, Diffuse, Glossy, Emission; glass and refraction, translucent and
transparent surfaces, the Mix and Add Shader nodes, alpha, normal and bump maps; image and checker
textures; :class:`ScratchedMetal`, the ``scratch_diffraction`` BSDF's surface; and the volume inside a
closed mesh (:class:`Volume`, carried by :class:`Volumetric` beside the surface, which may be an
:class:`Interface`: a boundary that does not scatter).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

from ..bsdf.parameters import CROSSINGS, DEFAULT_CROSSINGS, DEFAULT_DEPTH_PHASE, DEPTH_PHASES
from ..scratch import ScratchSet

__all__ = ["RGB", "Texture", "Checker", "Value", "Diffuse", "Principled", "Glossy", "Emission", "ScratchedMetal",
           "Dielectric", "Translucent", "Transparent", "Mix", "Add", "Mask", "NormalMap", "Bump", "Interface",
           "Volume", "Volumetric", "Material", "walk_materials", "TEXTURE_COORDINATES"]

RGB = tuple[float, float, float]

#: Where a texture is looked up: the mesh's UV map, or Blender's Generated coordinates (the object's
#: texture space, the bounding box of its evaluated mesh mapped to [0, 1]³; :class:`MeshData.generated`).
TEXTURE_COORDINATES = ("uv", "generated")


@dataclass(frozen=True)
class Checker:
    """Blender's Checker Texture: ``scale`` squares per coordinate unit, ``color2`` in the square at the origin.

    In ``"uv"`` coordinates the squares tile the UV plane; in ``"generated"`` coordinates they are
    Cycles' 3D checker (cubes of side 1/``scale`` in the object's texture space).
    """

    color1: RGB = (0.8, 0.8, 0.8)
    color2: RGB = (0.2, 0.2, 0.2)
    scale: float = 5.0
    coordinates: str = "uv"

    def __post_init__(self):
        if self.coordinates not in TEXTURE_COORDINATES:
            raise ValueError(f"unknown texture coordinates {self.coordinates!r}")


@dataclass(frozen=True)
class Texture:
    """An image texture, from a file or from pixels (packed or generated images).

    ``pixels`` are float32 (H, W, C) with row 0 at the *top*; ``srgb`` says
    whether the values are sRGB-encoded colours (False: linear or non-colour data).
    """

    name: str
    path: Optional[str] = None
    pixels: Optional[np.ndarray] = None
    srgb: bool = True
    interpolation: str = "bilinear"  #: or "nearest" (Blender's Closest)
    #: ``"generated"``: looked up at the (x, y) of the Generated coordinates (Blender's Flat projection)
    coordinates: str = "uv"

    def __post_init__(self):
        if (self.path is None) == (self.pixels is None):
            raise ValueError(f"texture {self.name!r}: give exactly one of path and pixels")
        if self.coordinates not in TEXTURE_COORDINATES:
            raise ValueError(f"texture {self.name!r}: unknown texture coordinates {self.coordinates!r}")


Value = Union[float, RGB, Texture, Checker]


@dataclass(frozen=True)
class Diffuse:
    """Lambertian reflection (Blender's Diffuse BSDF; also the fallback)."""

    reflectance: Value = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class Principled:
    """The subset of Blender's Principled BSDF that Mitsuba's ``principled`` has."""

    base_color: Value = (0.8, 0.8, 0.8)
    metallic: Value = 0.0
    roughness: Value = 0.5
    ior: float = 1.5
    anisotropic: float = 0.0
    transmission: float = 0.0
    coat: float = 0.0
    coat_roughness: float = 0.03
    sheen: float = 0.0


@dataclass(frozen=True)
class Glossy:
    """A tinted mirror-like metal (Blender's Glossy BSDF); ``alpha`` = roughness²."""

    color: Value = (0.8, 0.8, 0.8)
    alpha: float = 0.25


@dataclass(frozen=True)
class Emission:
    """A surface that emits ``radiance`` (W/(m²·sr)) and, with ``bsdf``, also reflects."""

    radiance: RGB = (1.0, 1.0, 1.0)
    bsdf: Optional["Material"] = None


@dataclass(frozen=True, eq=False)
class ScratchedMetal:
    """A scratched surface rendered with the ``scratch_diffraction`` BSDF.

    ``coherence_diameter_m`` is in metres; ``metres_per_unit`` is metres per
    scene unit (maps the mesh's UV Jacobian to metres; the plugin's ``unit_scale``); ``material`` is a Mitsuba
    conductor name or ``"none"`` (perfect mirror). ``crossings`` and ``depth_phase``
    are the plugin's options of those names (docs/bsdf.md).
    """

    scratches: ScratchSet
    coherence_diameter_m: float
    metres_per_unit: float = 1.0
    material: str = "Al"
    coherent: bool = True
    diffuse_reflectance: Optional[RGB] = None
    crossings: str = DEFAULT_CROSSINGS
    depth_phase: str = DEFAULT_DEPTH_PHASE

    def __post_init__(self):
        if self.crossings not in CROSSINGS:
            raise ValueError(f"crossings must be one of {', '.join(CROSSINGS)}, got {self.crossings!r}")
        if self.depth_phase not in DEPTH_PHASES:
            raise ValueError(f"depth_phase must be one of {', '.join(DEPTH_PHASES)}, got {self.depth_phase!r}")


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


@dataclass(frozen=True)
class Interface:
    """A surface that does not scatter: light passes straight through (the boundary of a volume whose
    material has nothing on its Surface; Mitsuba's ``null``)."""


@dataclass(frozen=True)
class Volume:
    """A homogeneous participating medium (Blender's volume shaders on a closed mesh or the world).

    ``scattering`` and ``absorption`` are the coefficients σ_s and σ_a per RGB channel in 1/scene unit
    (Blender's densities are per scene unit); ``anisotropy`` is the Henyey–Greenstein mean cosine g.
    """

    scattering: RGB = (0.0, 0.0, 0.0)
    absorption: RGB = (0.0, 0.0, 0.0)
    anisotropy: float = 0.0

    def __post_init__(self):
        if min(self.scattering) < 0 or min(self.absorption) < 0:
            raise ValueError(f"volume coefficients must not be negative, got {self.scattering}, {self.absorption}")
        if not -1.0 < self.anisotropy < 1.0:
            raise ValueError(f"volume anisotropy must lie in (-1, 1), got {self.anisotropy}")

    @property
    def extinction(self) -> RGB:
        """σ_t = σ_s + σ_a per channel (1/scene unit)."""
        return tuple(s + a for s, a in zip(self.scattering, self.absorption))

    @property
    def empty(self) -> bool:
        """Nothing scatters or absorbs: the medium changes no ray."""
        return max(self.extinction) <= 0.0


@dataclass(frozen=True, eq=False)
class Volumetric:
    """A material with a volume: ``surface`` on the mesh (an :class:`Interface` when the material has nothing
    on its Surface), ``volume`` filling the closed mesh."""

    surface: Material
    volume: Volume


Material = Union[Diffuse, Principled, Glossy, Emission, ScratchedMetal, Dielectric, Translucent, Transparent, Mix,
                 Add, Mask, NormalMap, Bump, Interface, Volumetric]
#: Materials holding other materials, and the fields that hold them.
_NESTED = {Mix: ("first", "second"), Add: ("first", "second"), Mask: ("bsdf",), NormalMap: ("bsdf",),
           Bump: ("bsdf",), Emission: ("bsdf",), Volumetric: ("surface",)}


def walk_materials(material):
    """``material`` and every material nested in it (depth first)."""
    yield material
    for name in _NESTED.get(type(material), ()):
        inner = getattr(material, name)
        if inner is not None:
            yield from walk_materials(inner)
