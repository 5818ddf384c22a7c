"""The world: a colour, an environment texture (HDRI) or a sky → neutral world.

Blender's four sky models all become Mitsuba's ``sunsky`` (Hosek–Wilkie sky
and sun).  Hosek–Wilkie is the same model in the same units as Blender's (same
radiance, checked against Cycles to 0.5 %).  Blender's scattering skies
(Nishita) are brighter by a roughly constant factor, measured against Cycles
5.0 at sun elevations of 10°, 30° and 60° (spread ±5 %): those factors keep a
scene's exposure; the sky's colour and angular falloff are Hosek–Wilkie's.
Blender 4.x calls the single-scattering sky ``NISHITA`` and its aerosol
density ``dust_density`` (renamed in 5.0): both names are read.
"""
from __future__ import annotations

import math

import numpy as np

from ....mitsuba_bridge.scene import ConstantWorld, EnvironmentWorld, SkyWorld
from .materials import linked_node
from .report import Warnings
from .textures import MISSING, gather_image
from .volumes import gather_volume

__all__ = ["gather_world", "gather_world_volume", "sky_from_node", "SKY_SCALES"]

#: sky type → (sky radiance, sun radiance) of Blender's model relative to Mitsuba's sunsky.
SKY_SCALES = {
    "MULTIPLE_SCATTERING": (57.0, 119.0),
    "SINGLE_SCATTERING": (38.0, 112.0),
    "HOSEK_WILKIE": (1.0, 0.0),   # no sun disc in Blender's Hosek-Wilkie
    "PREETHAM": (7.4, 0.0),       # measured at 30° only
}
#: Blender 4.x's name of the single-scattering sky (5.0 renamed it; `make test-blender` compares it with Cycles 4.x).
SKY_SCALES["NISHITA"] = SKY_SCALES["SINGLE_SCATTERING"]


def sun_direction(elevation: float, rotation: float) -> tuple[float, float, float]:
    """Towards the sun for Blender's elevation and rotation (radians): rotation 0 is +Y, 90° is +X."""
    return (math.sin(rotation) * math.cos(elevation), math.cos(rotation) * math.cos(elevation),
            math.sin(elevation))


def sky_from_node(node, strength: float, warnings: Warnings) -> SkyWorld:
    """A Sky Texture node → :class:`SkyWorld`."""
    sky_scale, sun_scale = SKY_SCALES.get(node.sky_type, (1.0, 0.0))
    if node.sky_type in ("HOSEK_WILKIE", "PREETHAM"):
        direction = np.array(node.sun_direction, dtype=np.float64)
        direction = tuple(direction / max(np.linalg.norm(direction), 1e-12))
        turbidity, albedo, aperture = float(node.turbidity), float(node.ground_albedo), 0.5338
        if node.sky_type == "PREETHAM":
            warnings.warn("the Preetham sky is rendered with the Hosek-Wilkie model, scaled to similar brightness")
    else:
        direction = sun_direction(float(node.sun_elevation), float(node.sun_rotation))
        # Dust density 1 (clear day) ~ turbidity 3, 5 (city) and more ~ 10.  Blender 4.x: dust_density.
        aerosols = node.aerosol_density if hasattr(node, "aerosol_density") else node.dust_density
        turbidity = float(np.clip(1.0 + 2.0 * aerosols, 1.0, 10.0))
        albedo, aperture = 0.3, math.degrees(float(node.sun_size))
        sun_scale *= float(node.sun_intensity) if node.sun_disc else 0.0
        if abs(node.altitude) > 1e3 or abs(node.ozone_density - 1.0) > 1e-3:
            warnings.warn("sky altitude and ozone are not supported: rendered at sea level", key="sky-altitude")
    return SkyWorld(sun_direction=direction, turbidity=turbidity, albedo=float(np.clip(albedo, 0.0, 1.0)),
                    sun_scale=sun_scale * strength, sky_scale=sky_scale * strength,
                    sun_aperture_deg=max(aperture, 0.01))


def _mapping_rotation(node, warnings: Warnings) -> np.ndarray:
    """The rotation a Mapping node applies to the environment lookup direction."""
    import mathutils

    rotation = np.array(mathutils.Euler(node.inputs["Rotation"].default_value).to_matrix())
    if node.vector_type == "TEXTURE":
        rotation = rotation.T
    scale = np.array(node.inputs["Scale"].default_value) if "Scale" in node.inputs else np.ones(3)
    if not np.allclose(scale, 1.0) or (node.vector_type == "POINT"
                                       and not np.allclose(node.inputs["Location"].default_value, 0.0)):
        warnings.warn("world: only the rotation of the environment's Mapping node is used")
    return rotation


def _environment(node, strength: float, warnings: Warnings):
    texture = gather_image(node, warnings, owner="world")
    if texture.name.startswith("missing:"):
        return ConstantWorld(tuple(c * strength for c in MISSING))
    if node.projection != "EQUIRECTANGULAR":
        warnings.warn(f"world: {node.projection.lower()} environment projection is not supported: "
                      "read as equirectangular")
    rotation = np.eye(3)
    vector = linked_node(node.inputs["Vector"])
    if vector is not None and vector.bl_idname == "ShaderNodeMapping":
        rotation = _mapping_rotation(vector, warnings)
    elif vector is not None and vector.bl_idname != "ShaderNodeTexCoord":
        warnings.warn(f"world: environment coordinates from '{vector.name}' are not supported: ignored")
    return EnvironmentWorld(texture=texture, strength=strength, rotation=rotation)


def gather_world(world, warnings: Warnings):
    """The neutral world, or None when the world emits nothing."""
    if world is None:
        return None
    tree = world.node_tree
    if tree is None:
        colour = tuple(float(c) for c in world.color[:3])
        return ConstantWorld(colour) if any(colour) else None
    output = tree.get_output_node("CYCLES")
    background = linked_node(output.inputs["Surface"]) if output is not None else None
    if background is None:
        return None
    if background.bl_idname != "ShaderNodeBackground":
        warnings.warn(f"world: '{background.name}' ({background.bl_label}) is not supported; use a Background "
                      "node: the world is black")
        return None
    strength = float(background.inputs["Strength"].default_value)
    if linked_node(background.inputs["Strength"]) is not None:
        warnings.warn("world: a linked background strength is not supported: its own value is used")
    source = linked_node(background.inputs["Color"])
    if source is None:
        colour = tuple(float(c) * strength for c in background.inputs["Color"].default_value[:3])
        return ConstantWorld(colour) if any(c > 0 for c in colour) else None
    if source.bl_idname == "ShaderNodeTexEnvironment":
        return _environment(source, strength, warnings)
    if source.bl_idname == "ShaderNodeTexSky":
        return sky_from_node(source, strength, warnings)
    warnings.warn(f"world: background colour from '{source.name}' ({source.bl_label}) is not supported: "
                  "its own colour is used")
    colour = tuple(float(c) * strength for c in background.inputs["Color"].default_value[:3])
    return ConstantWorld(colour) if any(c > 0 for c in colour) else None


def gather_world_volume(world, warnings: Warnings):
    """The world's volume (its output's Volume), filling the space around everything, or None."""
    tree = world.node_tree if world is not None else None
    output = tree.get_output_node("CYCLES") if tree is not None else None
    if output is None or "Volume" not in output.inputs:
        return None
    volume = gather_volume(output.inputs["Volume"], warnings, "world")
    return None if volume is None or volume.empty else volume
