"""Materials of the neutral description → Mitsuba BSDF (and area emitter) dicts."""
from __future__ import annotations

from typing import Optional

from ..scene import Diffuse, Emission, Glossy, Principled, ScratchedMetal, Texture

__all__ = ["bsdf_dict", "emitter_dict", "value_dict", "rgb", "BLACK"]

#: A BSDF that reflects nothing (emitters' own surfaces).
BLACK = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}

# Below this GGX alpha a rough conductor is numerically a mirror: use the smooth one.
_SMOOTH_ALPHA = 1e-4


def rgb(value) -> dict:
    """An ``rgb`` spectrum dict (reflectances are upsampled, emitters get a D65 white point)."""
    return {"type": "rgb", "value": [float(c) for c in value]}


def value_dict(value, resources, *, colour: bool):
    """A float, an RGB triple or a texture as something a Mitsuba parameter accepts."""
    if isinstance(value, Texture):
        return resources.texture(value, colour=colour)
    if isinstance(value, (int, float)):
        return rgb((value,) * 3) if colour else float(value)
    return rgb(value)


def _two_sided(bsdf: dict) -> dict:
    # Blender shades both sides of a surface alike; Mitsuba's reflective BSDFs are one-sided.
    return {"type": "twosided", "bsdf": bsdf}


def bsdf_dict(material, resources, *, key: str) -> dict:
    """The BSDF of ``material``; ``key`` names it for resources that write files."""
    if isinstance(material, Diffuse):
        return _two_sided({"type": "diffuse", "reflectance": value_dict(material.reflectance, resources, colour=True)})
    if isinstance(material, Principled):
        return _principled(material, resources)
    if isinstance(material, Glossy):
        colour = value_dict(material.color, resources, colour=True)
        if material.alpha < _SMOOTH_ALPHA:
            return _two_sided({"type": "conductor", "material": "none", "specular_reflectance": colour})
        return _two_sided({"type": "roughconductor", "material": "none", "distribution": "ggx",
                           "alpha": float(material.alpha), "specular_reflectance": colour})
    if isinstance(material, Emission):
        return BLACK if material.bsdf is None else bsdf_dict(material.bsdf, resources, key=key)
    if isinstance(material, ScratchedMetal):
        return resources.scratch_bsdf(material, key=key)
    raise TypeError(f"unknown material type {type(material).__name__}")


def emitter_dict(material) -> Optional[dict]:
    """The area emitter of an emissive material, or None."""
    if isinstance(material, Emission) and any(c > 0 for c in material.radiance):
        return {"type": "area", "radiance": rgb(material.radiance)}
    return None


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
