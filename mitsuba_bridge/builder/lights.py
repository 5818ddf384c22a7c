"""Lights and the world → Mitsuba emitter (and emitting shape) dicts.

Quantities arrive physical (see :mod:`mitsuba_bridge.scene`); only frames
change here: Blender's lights shine along local −Z, Mitsuba's along +Z, and an
equirectangular image is laid around +Z in Blender but around +Y in Mitsuba.
"""
from __future__ import annotations

import math

import numpy as np

from ..scene import AreaLight, ConstantWorld, EnvironmentWorld, PointLight, SkyWorld, SpotLight, SunLight
from .materials import rgb
from .transform import FLIP_YZ, scale, to_mitsuba

__all__ = ["light_dict", "world_dict", "ENVMAP_BASIS", "SEE_THROUGH"]

#: The surface of an emitting light shape: rays pass through it, so that a
#: light's back (or a sphere light's far side) does not show as a black hole.
#: Blender's lights are invisible to camera rays; here their emitting side is seen.
SEE_THROUGH = {"type": "null"}

#: Mitsuba's ``envmap`` local frame expressed in Blender's world: it puts image
#: column u = 0.5 on local +Z and the top row on local +Y; Blender puts u = 0.5
#: on world +X, the top row on +Z, and u grows towards −Y.
ENVMAP_BASIS = np.array([   # columns: images of local X, Y, Z = world +Y, +Z, +X
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
])


def light_dict(light) -> dict:
    """An emitter dict, or a shape dict carrying an area emitter."""
    if isinstance(light, PointLight):
        if light.radius <= 0:
            return {"type": "point", "position": [float(c) for c in light.position],
                    "intensity": rgb(light.intensity)}
        # A Lambertian sphere of radius r with radiance L has intensity π r² L in every direction.
        radiance = np.asarray(light.intensity) / (math.pi * light.radius ** 2)
        return {"type": "sphere", "center": [float(c) for c in light.position], "radius": float(light.radius),
                "bsdf": SEE_THROUGH, "emitter": {"type": "area", "radiance": rgb(radiance)}}
    if isinstance(light, SpotLight):
        cutoff = float(np.clip(light.cutoff_deg, 1e-3, 90.0))
        beam = float(np.clip(light.beam_deg, 0.0, cutoff * (1 - 1e-4)))  # Mitsuba needs beam < cutoff
        return {"type": "spot", "to_world": to_mitsuba(np.asarray(light.to_world) @ FLIP_YZ),
                "intensity": rgb(light.intensity), "cutoff_angle": cutoff, "beam_width": beam}
    if isinstance(light, SunLight):
        return {"type": "directional", "direction": [float(c) for c in light.direction],
                "irradiance": rgb(light.irradiance)}
    if isinstance(light, AreaLight):
        # Mitsuba's rectangle spans [-1, 1]², its disk has radius 1; both face +Z.
        matrix = np.asarray(light.to_world) @ scale(0.5 * light.size_x, 0.5 * light.size_y, 1.0) @ FLIP_YZ
        return {"type": light.shape, "to_world": to_mitsuba(matrix), "bsdf": SEE_THROUGH,
                "emitter": {"type": "area", "radiance": rgb(light.radiance)}}
    raise TypeError(f"unknown light type {type(light).__name__}")


def world_dict(world, resources) -> dict:
    """The environment emitter of ``world``."""
    if isinstance(world, ConstantWorld):
        return {"type": "constant", "radiance": rgb(world.radiance)}
    if isinstance(world, EnvironmentWorld):
        # The image is looked up at R·d (Blender's Mapping node): rotate the map by R⁻¹.
        to_world = np.eye(4)
        to_world[:3, :3] = np.asarray(world.rotation).T @ ENVMAP_BASIS
        return {"type": "envmap", "scale": float(world.strength), "to_world": to_mitsuba(to_world),
                **resources.environment(world.texture)}
    if isinstance(world, SkyWorld):
        # sunsky's frame is Z-up like Blender's world: no rotation needed.
        return {"type": "sunsky", "sun_direction": [float(c) for c in world.sun_direction],
                "turbidity": float(np.clip(world.turbidity, 1.0, 10.0)),
                "albedo": float(np.clip(world.albedo, 0.0, 1.0)),
                "sun_scale": float(world.sun_scale), "sky_scale": float(world.sky_scale),
                "sun_aperture": float(world.sun_aperture_deg)}
    raise TypeError(f"unknown world type {type(world).__name__}")
