"""Materials of the neutral description → Mitsuba BSDF (and area emitter) dicts.

Shader trees map one node to one plugin: Mix → ``blendbsdf``, alpha → ``mask``,
normal and bump maps → ``normalmap`` / ``bumpmap`` around their BSDF. Reflective
leaves are wrapped in ``twosided`` (Blender shades both sides alike); transmissive
ones (glass, translucent, transmissive Principled) handle both sides themselves.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Optional

import numpy as np

from ..scene import (Add, Bump, Checker, Dielectric, Diffuse, Emission, Glossy, Interface, Mask, Mix, NormalMap,
                     Principled, ScratchedMetal, Texture, Translucent, Transparent, Volumetric)
from ..scene.albedo import add_scale, albedo_bound
from .transform import scale, to_mitsuba

__all__ = ["bsdf_dict", "emitter_dict", "value_dict", "rgb", "BLACK", "add_weights", "scaled"]

#: A BSDF that reflects nothing (emitters' own surfaces).
BLACK = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}

# Below this GGX alpha a rough conductor or dielectric is numerically smooth: use the smooth plugin.
_SMOOTH_ALPHA = 1e-4


def rgb(value) -> dict:
    """An ``rgb`` spectrum dict (reflectances are upsampled, emitters get a D65 white point)."""
    return {"type": "rgb", "value": [float(c) for c in value]}


def value_dict(value, resources, *, colour: bool):
    """A float, an RGB triple or a texture as something a Mitsuba parameter accepts.

    Textures in Generated coordinates read them from the mesh (the project's ``generated`` texture).
    """
    if isinstance(value, Texture):
        lookup = resources.texture(value, colour=colour)
        if value.coordinates == "generated":
            return {"type": "generated", "mode": "flat", "texture": lookup}
        return lookup
    if isinstance(value, Checker):
        color0 = value_dict(value.color2, resources, colour=colour)
        color1 = value_dict(value.color1, resources, colour=colour)
        if value.coordinates == "generated":
            return {"type": "generated", "mode": "checker", "scale": float(value.scale), "color0": color0,
                    "color1": color1}
        # Mitsuba's squares are half a UV unit wide, with color0 in the one at the origin.
        return {"type": "checkerboard", "color0": color0, "color1": color1,
                "to_uv": to_mitsuba(scale(value.scale / 2, value.scale / 2, 1.0))}
    if isinstance(value, (int, float)):
        return rgb((value,) * 3) if colour else float(value)
    return rgb(value)


def _two_sided(bsdf: dict) -> dict:
    # Blender shades both sides of a surface alike; Mitsuba's reflective BSDFs are one-sided.
    return {"type": "twosided", "bsdf": bsdf}


def bsdf_dict(material, resources, *, key: str) -> dict:
    """The BSDF of ``material``; ``key`` names it for resources that write files."""
    colour = lambda value: value_dict(value, resources, colour=True)  # noqa: E731
    nested = lambda inner: bsdf_dict(inner, resources, key=key)  # noqa: E731
    if isinstance(material, Diffuse):
        return _two_sided({"type": "diffuse", "reflectance": colour(material.reflectance)})
    if isinstance(material, Principled):
        return _principled(material, resources)
    if isinstance(material, Glossy):
        if material.alpha < _SMOOTH_ALPHA:
            return _two_sided({"type": "conductor", "material": "none", "specular_reflectance": colour(material.color)})
        return _two_sided({"type": "roughconductor", "material": "none", "distribution": "ggx",
                           "alpha": float(material.alpha), "specular_reflectance": colour(material.color)})
    if isinstance(material, Dielectric):
        return _dielectric(material, colour)
    if isinstance(material, Translucent):
        return {"type": "translucent", "transmittance": colour(material.color)}
    if isinstance(material, Transparent):
        # mask's opacity is a scalar: a tinted Transparent BSDF passes its mean grey level.
        return {"type": "mask", "opacity": float(1.0 - np.clip(np.mean(material.color), 0.0, 1.0)), "bsdf": BLACK}
    if isinstance(material, Mask):
        return {"type": "mask", "opacity": value_dict(material.opacity, resources, colour=False),
                "bsdf": nested(material.bsdf)}
    if isinstance(material, Mix):
        return {"type": "blendbsdf", "weight": value_dict(material.factor, resources, colour=False),
                "bsdf_0": nested(material.first), "bsdf_1": nested(material.second)}
    if isinstance(material, Add):
        second_share, first_scale, second_scale = _add_as_blend(material)
        return {"type": "blendbsdf", "weight": second_share,
                "bsdf_0": nested(scaled(material.first, first_scale)),
                "bsdf_1": nested(scaled(material.second, second_scale))}
    if isinstance(material, NormalMap):
        return {"type": "normalmap", "normalmap": resources.texture(material.texture, colour=False),
                "bsdf": nested(material.bsdf)}
    if isinstance(material, Bump):
        return {"type": "bumpmap", "height": resources.texture(material.height, colour=False),
                "scale": float(material.scale), "bsdf": nested(material.bsdf)}
    if isinstance(material, Emission):
        return BLACK if material.bsdf is None else nested(material.bsdf)
    if isinstance(material, ScratchedMetal):
        return resources.scratch_bsdf(material, key=key)
    if isinstance(material, Interface):
        return {"type": "null"}
    if isinstance(material, Volumetric):  # the volume is the shape's medium (builder.volumes)
        return nested(material.surface)
    raise TypeError(f"unknown material type {type(material).__name__}")


def emitter_dict(material) -> Optional[dict]:
    """The area emitter of an emissive material, or None."""
    if isinstance(material, Volumetric):
        material = material.surface
    if isinstance(material, Emission) and any(c > 0 for c in material.radiance):
        return {"type": "area", "radiance": rgb(material.radiance)}
    return None


def _dielectric(material: Dielectric, colour) -> dict:
    # Mitsuba needs a relative index different from 1; Cycles' glass colour tints both lobes.
    ior = float(material.ior) if abs(material.ior - 1.0) > 1e-3 else 1.001
    result = {"int_ior": ior, "ext_ior": 1.0, "specular_transmittance": colour(material.color),
              "specular_reflectance": colour(material.color) if material.reflect else rgb((0.0, 0.0, 0.0))}
    if material.alpha < _SMOOTH_ALPHA:
        return {"type": "dielectric", **result}
    return {"type": "roughdielectric", "distribution": "ggx", "alpha": float(material.alpha), **result}


def _principled(material: Principled, resources) -> dict:
    bsdf = {
        "type": "principled",
        "base_color": value_dict(material.base_color, resources, colour=True),
        "metallic": value_dict(material.metallic, resources, colour=False),
        "roughness": value_dict(material.roughness, resources, colour=False),
        "eta": float(max(material.ior, 1.0 + 1e-3)),
        "anisotropic": float(material.anisotropic),
        "spec_trans": float(material.transmission),
        "clearcoat": float(material.coat),
        "clearcoat_gloss": float(1.0 - material.coat_roughness),
        "sheen": float(material.sheen),
    }
    # A transmissive principled BSDF already handles both sides; wrapping it would cut refraction.
    return bsdf if material.transmission > 0 else _two_sided(bsdf)


# ---- the Add Shader ------------------------------------------------------------------------------

def _brightest(texture: Texture) -> np.ndarray:
    return _linear_pixels(texture).reshape(-1, 3).max(axis=0)


def _albedo_bound(material) -> np.ndarray:
    return albedo_bound(material, _brightest)


def add_weights(material: Add) -> tuple[float, float]:
    """The weights the builder gives the two halves of an Add Shader.

    Cycles sums them, which can scatter more light than arrives (white diffuse
    + white glossy reflects 2×). Here the sum is kept (weights 1, 1) while the
    halves' brightest channels add up to at most 1, and both are scaled down
    together to a sum of 1 otherwise (:mod:`...scene.albedo`).
    """
    weight = add_scale(material, _brightest)
    return weight, weight


def _add_as_blend(material: Add) -> tuple[float, float, float]:
    """(blend weight of the second half, colour scale of the first, of the second) giving ``add_weights``.

    ``blendbsdf(t, s₁·A, s₂·B) = (1 − t)·s₁·A + t·s₂·B``; choosing ``t`` in proportion to the
    halves' brightest channels keeps every scaled colour at most 1 (Mitsuba's reflectance range).
    """
    weight, _ = add_weights(material)
    first = float(np.max(_albedo_bound(material.first)))
    second = float(np.max(_albedo_bound(material.second)))
    if first + second <= 0:
        return 0.5, 1.0, 1.0
    share = second / (first + second)
    first_scale = weight / (1 - share) if share < 1 else 1.0
    second_scale = weight / share if share > 0 else 1.0
    return share, first_scale, second_scale


def scaled(material, factor: float):
    """``material`` with its colours multiplied by ``factor`` (textures are scaled pixel by pixel; the
    scratch BSDF is left as it is)."""
    if abs(factor - 1.0) < 1e-9:
        return material

    def times(value):
        if isinstance(value, (int, float)):
            return value * factor
        if isinstance(value, tuple):
            return tuple(c * factor for c in value)
        if isinstance(value, Texture):
            return _scaled_texture(value, factor)
        if isinstance(value, Checker):
            return replace(value, color1=tuple(c * factor for c in value.color1),
                           color2=tuple(c * factor for c in value.color2))
        return value

    if isinstance(material, Diffuse):
        return replace(material, reflectance=times(material.reflectance))
    if isinstance(material, (Glossy, Dielectric, Translucent)):
        return replace(material, color=times(material.color))
    if isinstance(material, Principled):
        return replace(material, base_color=times(material.base_color))
    if isinstance(material, Transparent):
        return replace(material, color=times(material.color))
    if isinstance(material, Mix):
        return Mix(material.factor, scaled(material.first, factor), scaled(material.second, factor))
    if isinstance(material, Add):
        return Add(scaled(material.first, factor), scaled(material.second, factor))
    if isinstance(material, Mask):
        return Mask(material.opacity, scaled(material.bsdf, factor))
    if isinstance(material, NormalMap):
        return NormalMap(material.texture, scaled(material.bsdf, factor))
    if isinstance(material, Bump):
        return Bump(material.height, material.scale, scaled(material.bsdf, factor))
    return material


def _linear_pixels(texture: Texture) -> np.ndarray:
    """The linear RGB pixels of ``texture`` (files are read with Mitsuba's own image loader)."""
    from ..scene.colour import srgb_to_linear

    if texture.pixels is not None:
        pixels = srgb_to_linear(texture.pixels) if texture.srgb else texture.pixels
    else:
        import mitsuba as mi

        pixels = np.array(mi.Bitmap(str(texture.path)).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32,
                                                               srgb_gamma=False))
    return np.asarray(pixels[..., :3], dtype=np.float32)


def _scaled_texture(texture: Texture, factor: float) -> Texture:
    """``texture`` × ``factor`` as linear pixels (Mitsuba's textures have no scale of their own)."""
    return Texture(name=f"{texture.name}*{factor:.6g}", pixels=_linear_pixels(texture) * np.float32(factor),
                   srgb=False, interpolation=texture.interpolation, coordinates=texture.coordinates)
