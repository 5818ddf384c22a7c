"""Light objects → physical lights, with Blender's power conventions.

Measured against Cycles in Blender 5.0 (``tests/addon/test_render_lights.py``
keeps checking it) and matching Blender's manual:

* point and spot: power P [W] → radiant intensity I = P / (4π) [W/sr]; a spot
  is *not* renormalised to its cone (its axis is as bright as a point light);
* sun: strength [W/m²] is the irradiance on a surface facing the sun;
* area: power P is emitted by a one-sided Lambertian surface of area A
  (object scale included, disk and ellipse π/4 of their box):
  L = P / (π A) [W/(m²·sr)]; with "Normalize" off, L = P / π (A ignored).

All of these are scaled by the light colour (or its blackbody temperature
colour) and by 2^exposure.  A spot's soft edge is Blender's smoothstep in the
cosine; Mitsuba's spot falls linearly in angle, so its ramp is placed to cross
one half where Blender's does.
"""
from __future__ import annotations

import math

import numpy as np

from ....mitsuba_bridge.scene import AreaLight, PointLight, SpotLight, SunLight
from .report import Warnings

__all__ = ["gather_light", "light_colour", "spot_angles", "area_radiance"]


def light_colour(light) -> np.ndarray:
    """Colour × power × 2^exposure (RGB)."""
    colour = np.array(light.color[:3], dtype=np.float64)
    if getattr(light, "use_temperature", False):
        colour = colour * np.array(light.temperature_color[:3], dtype=np.float64)
    return colour * float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))


def spot_angles(spot_size: float, spot_blend: float) -> tuple[float, float]:
    """(cutoff, beam) in degrees for Blender's cone angle (full, radians) and blend.

    Blender's mask is smoothstep((cos θ − cos θ_c) / ((1 − cos θ_c)·blend)),
    one half where cos θ = cos θ_c + (1 − cos θ_c)·blend / 2.
    """
    cutoff = 0.5 * spot_size
    if spot_blend <= 0:
        return math.degrees(cutoff), math.degrees(cutoff)
    cos_cutoff = math.cos(cutoff)
    half = math.acos(min(1.0, cos_cutoff + 0.5 * (1.0 - cos_cutoff) * spot_blend))
    beam = max(0.0, 2.0 * half - cutoff)
    return math.degrees(cutoff), math.degrees(beam)


def area_radiance(light, matrix: np.ndarray) -> tuple[str, float, float, np.ndarray]:
    """(shape, size_x, size_y, radiance) of an area light placed by ``matrix``."""
    square = light.shape in ("SQUARE", "DISK")
    size_x = float(light.size)
    size_y = size_x if square else float(light.size_y)
    round_shape = light.shape in ("DISK", "ELLIPSE")
    scale_x, scale_y = np.linalg.norm(matrix[:3, 0]), np.linalg.norm(matrix[:3, 1])
    area = size_x * size_y * scale_x * scale_y * (math.pi / 4 if round_shape else 1.0)
    colour = light_colour(light)
    normalize = getattr(light, "normalize", True)
    radiance = colour / (math.pi * area) if normalize and area > 0 else colour / math.pi
    return ("disk" if round_shape else "rectangle"), size_x, size_y, radiance


def gather_light(light_object, matrix, warnings: Warnings):
    """The light of an evaluated light object instance placed by ``matrix`` (4×4)."""
    light = light_object.data
    matrix = np.asarray(matrix, dtype=np.float64)
    owner = f"light '{light_object.name}'"
    if light.type in ("POINT", "SPOT"):
        intensity = tuple(light_colour(light) / (4.0 * math.pi))
        if light.type == "POINT":
            return PointLight(position=tuple(matrix[:3, 3]), intensity=intensity,
                              radius=float(light.shadow_soft_size))
        cutoff, beam = spot_angles(float(light.spot_size), float(light.spot_blend))
        if light.shadow_soft_size > 0:
            warnings.warn(f"{owner}: spot lights render with a point source (radius ignored)",
                          key="spot-radius")
        return SpotLight(to_world=matrix, intensity=intensity, cutoff_deg=cutoff, beam_deg=beam)
    if light.type == "SUN":
        direction = -matrix[:3, 2] / np.linalg.norm(matrix[:3, 2])
        return SunLight(direction=tuple(direction), irradiance=tuple(light_colour(light)))
    if light.type == "AREA":
        if getattr(light, "spread", math.pi) < math.pi - 1e-4:
            warnings.warn(f"{owner}: area light spread is not supported: emits over the whole hemisphere")
        shape, size_x, size_y, radiance = area_radiance(light, matrix)
        return AreaLight(to_world=matrix, shape=shape, size_x=size_x, size_y=size_y, radiance=tuple(radiance))
    warnings.warn(f"{owner}: light type {light.type} is not supported and is ignored")
    return None
