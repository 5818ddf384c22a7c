"""Volumes of the neutral description → Mitsuba media (``homogeneous`` with a ``hg`` phase function).

A closed mesh whose material carries a :class:`~..scene.Volume` gets it as its *interior* medium; the
world's volume is the *exterior* of every other surface, the medium of the camera and of the light
shapes. Rays only learn which medium they are in by crossing surfaces, so every surface in a world
volume has it on both sides (an open sheet, a light's rectangle) unless it bounds a volume of its own.
Media need Mitsuba's ``volpath`` integrator (:func:`.camera.integrator_dict`).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from ..scene import Material, SceneDescription, Volume, Volumetric
from .materials import rgb

__all__ = ["medium_dict", "material_volume", "has_media", "WORLD_MEDIUM"]

#: The key of the world's medium among a scene's media (materials use their own keys).
WORLD_MEDIUM = "world-volume"


def medium_dict(volume: Volume) -> dict:
    """A ``homogeneous`` medium with the coefficients of ``volume`` (1/scene unit).

    Mitsuba's spectral variants take RGB coefficients only within [0, 1] (they are upsampled like
    reflectances): the extinction is stored divided by its largest channel, which becomes ``scale``.
    The single-scattering albedo σ_s/σ_t is a ratio within [0, 1] by construction.
    """
    extinction = np.asarray(volume.extinction, dtype=np.float64)
    scale = float(extinction.max())
    if scale <= 0.0:
        raise ValueError("an empty volume has no medium (nothing scatters or absorbs)")
    albedo = np.divide(np.asarray(volume.scattering, dtype=np.float64), extinction,
                       out=np.zeros(3), where=extinction > 0)
    return {"type": "homogeneous", "sigma_t": rgb(np.clip(extinction / scale, 0.0, 1.0)), "scale": scale,
            "albedo": rgb(np.clip(albedo, 0.0, 1.0)), "phase": {"type": "hg", "g": float(volume.anisotropy)}}


def material_volume(material: Material) -> Optional[Volume]:
    """The volume a material fills its mesh with, or None (also for a volume that changes nothing)."""
    if isinstance(material, Volumetric) and not material.volume.empty:
        return material.volume
    return None


def has_media(description: SceneDescription) -> bool:
    """Whether anything in ``description`` scatters or absorbs between surfaces."""
    if description.world_volume is not None and not description.world_volume.empty:
        return True
    used = {shape.material for shape in description.shapes}
    return any(material_volume(description.materials[key]) is not None for key in used)
