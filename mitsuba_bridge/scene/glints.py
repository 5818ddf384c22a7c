"""Whether a scene's lights can show a scratched surface's glints at all.

A scratch sends light from a direction l towards the eye v only where the half vector h = (l + v)/|l + v|
leans away from the surface normal by no more than the scratch's own slopes and diffraction allow: its
groove's wall slope (atan 2·depth/width for a triangular profile) plus half the angle of its diffraction
orders (sin θ = n λ / width; a segment's diffraction, docs/model.md §3). A point, spot or sun light,
whose light comes from one direction, away from the mirror direction of every visible part of the
surface, shows no glint anywhere: the render is a dark mirror (Blender's startup cube under its point
light: the half vector leans 49° or more from every face's normal). A uniform world shows none either:
the scratches reflect the same radiance as the mirror around them. Environment maps, area lights near
the mirror direction, a sky's sun there and emissive surfaces can.

Geometry only (no occlusion, no field of view): a check that errs towards "can", used to tell the artist
(the object's Scratches panel and the render report) and to place the light that shows them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..scratch import Profile, ScratchSet
from .description import AreaLight, Camera, ConstantWorld, EnvironmentWorld, MeshData, PointLight, SkyWorld, \
    SpotLight, SunLight

__all__ = ["glint_reach", "surface_samples", "GlintCheck", "check_glints", "mirror_light_direction",
           "MAX_SAMPLES"]

#: The longest visible wavelength (metres): diffraction spreads light up to a few λ/width about the mirror.
LONGEST_WAVELENGTH_M = 700e-9
#: Diffraction orders counted in the reach (the envelope of a groove's pattern is dim beyond the second).
DIFFRACTION_ORDERS = 2
#: Triangles looked at per object (every k-th of a denser mesh): enough to find the best-lit facet.
MAX_SAMPLES = 20_000


def glint_reach(scratches: ScratchSet) -> float:
    """How far (radians) the half vector may lean from the normal with the set's scratches still sending light.

    Per scratch: its wall slope atan(2 depth / width) (triangular grooves; rectangular ones have none but
    their diffraction) plus half the deviation of its ``DIFFRACTION_ORDERS``-th order of the longest visible
    wavelength, asin(n λ / width) (a deviation of the outgoing direction tilts the half vector by half of it);
    the 95th percentile over the set, so that a few odd scratches do not decide.
    """
    if scratches.count == 0:
        return 0.0
    width, depth = np.asarray(scratches.width), np.asarray(scratches.depth)
    slope = np.where(np.asarray(scratches.profile) == int(Profile.TRIANGULAR), np.arctan(2 * depth / width), 0.0)
    reach = slope + 0.5 * np.arcsin(np.minimum(DIFFRACTION_ORDERS * LONGEST_WAVELENGTH_M / width, 1.0))
    return float(min(np.percentile(reach, 95), math.pi / 2))


def surface_samples(mesh: MeshData, to_world: np.ndarray, limit: int = MAX_SAMPLES):
    """(centres, unit normals), (N, 3) each, of the triangles of ``mesh`` placed by ``to_world`` (every k-th
    triangle of a mesh with more than ``limit``)."""
    faces = mesh.faces[::max(1, -(-len(mesh.faces) // limit))]
    matrix = np.asarray(to_world, dtype=np.float64)
    corners = mesh.positions.astype(np.float64)[faces] @ matrix[:3, :3].T + matrix[:3, 3]  # (N, 3, 3)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(normals, axis=1)
    keep = length > 0
    return corners[keep].mean(axis=1), normals[keep] / length[keep, None]


@dataclass(frozen=True)
class GlintCheck:
    """The verdict: ``shows`` (some light can show glints), the best half vector's lean from the normal over the
    surface and the lights (``tilt``, radians; None when no light was looked at) against ``reach``."""

    shows: bool
    tilt: Optional[float]
    reach: float

    def describe(self) -> str:
        if self.tilt is None:
            return "no light but a uniform world, which shows no glints"
        return (f"its lights are at best {math.degrees(self.tilt):.0f}° off the mirror direction, "
                f"the scratches reach {math.degrees(self.reach):.0f}°")


def _eye_directions(points, camera: Camera) -> np.ndarray:
    frame = np.asarray(camera.to_world, dtype=np.float64)
    if camera.projection == "orthographic":
        return np.broadcast_to(frame[:3, 2], points.shape)  # towards the camera: its local +Z
    offset = frame[:3, 3] - points
    return offset / np.linalg.norm(offset, axis=1, keepdims=True)


def _light_directions(light, points):
    """(unit directions from the points towards the light, angular radius, which points it reaches) or None."""
    if isinstance(light, SunLight):
        direction = -np.asarray(light.direction, dtype=np.float64)
        return np.broadcast_to(direction / np.linalg.norm(direction), points.shape), 0.0, None
    if isinstance(light, SkyWorld):
        if light.sun_scale <= 0:
            return None
        direction = np.asarray(light.sun_direction, dtype=np.float64)
        return (np.broadcast_to(direction / np.linalg.norm(direction), points.shape),
                math.radians(light.sun_aperture_deg) / 2, None)
    if isinstance(light, PointLight):
        position, radius, reached = np.asarray(light.position, dtype=np.float64), light.radius, None
    else:  # spot and area lights shine along their local −Z
        matrix = np.asarray(light.to_world, dtype=np.float64)
        position, axis = matrix[:3, 3], -matrix[:3, 2] / np.linalg.norm(matrix[:3, 2])
        radius = 0.0
        if isinstance(light, AreaLight):
            radius = 0.5 * max(light.size_x * np.linalg.norm(matrix[:3, 0]),
                               light.size_y * np.linalg.norm(matrix[:3, 1]))
        towards = points - position
        distance = np.linalg.norm(towards, axis=1)
        cosine = towards @ axis / np.maximum(distance, 1e-12)
        reached = cosine > (math.cos(math.radians(light.cutoff_deg)) if isinstance(light, SpotLight) else 0.0)
    offset = position - points
    distance = np.maximum(np.linalg.norm(offset, axis=1), 1e-12)
    angular = np.arcsin(np.clip(radius / distance, 0.0, 1.0))
    return offset / distance[:, None], angular, reached


def check_glints(surfaces, scratches: ScratchSet, camera: Camera, lights, world, *, emissive: bool = False
                 ) -> GlintCheck:
    """Whether any of ``lights`` (and ``world``) can show glints of ``scratches`` on ``surfaces``.

    ``surfaces`` is a (centres, normals) pair (:func:`surface_samples`) in world space; ``emissive``: the scene
    has emissive surfaces (extended lights whose shape is not looked at: they count as able).
    """
    reach = glint_reach(scratches)
    if emissive or isinstance(world, EnvironmentWorld):
        return GlintCheck(True, None, reach)
    points, normals = surfaces
    if len(points) == 0:
        return GlintCheck(True, None, reach)  # nothing to look at: no verdict against the lights
    eye = _eye_directions(points, camera)
    seen = np.einsum("ij,ij->i", normals, eye) > 0
    sources = list(lights) + ([world] if isinstance(world, SkyWorld) else [])
    best = None
    for light in sources:
        found = _light_directions(light, points)
        if found is None:
            continue
        towards, angular, reached = found
        lit = seen & (np.einsum("ij,ij->i", normals, towards) > 0)
        if reached is not None:
            lit &= reached
        if not lit.any():
            continue
        half = towards[lit] + eye[lit]
        half /= np.maximum(np.linalg.norm(half, axis=1, keepdims=True), 1e-12)
        tilt = np.arccos(np.clip(np.einsum("ij,ij->i", half, normals[lit]), -1.0, 1.0))
        # an extended source's light arrives from up to its angular radius away: the half vector moves by half
        tilt = np.maximum(tilt - 0.5 * np.broadcast_to(angular, lit.shape)[lit], 0.0)
        best = float(tilt.min()) if best is None else min(best, float(tilt.min()))
    return GlintCheck(best is not None and best <= reach, best, reach)


def mirror_light_direction(surfaces, camera: Camera, up=(0.0, 0.0, 1.0)):
    """(direction towards a light that the surface mirrors into the camera, the point it is mirrored at).

    The surface point whose triangle faces the camera most squarely is chosen, preferring points whose mirror
    direction rises above the horizon (a light from below the floor would look odd); the direction is the
    camera's, mirrored about that point's normal. None when the camera sees no surface.
    """
    points, normals = surfaces
    if len(points) == 0:
        return None
    eye = _eye_directions(points, camera)
    facing = np.einsum("ij,ij->i", normals, eye)
    mirrored = 2 * facing[:, None] * normals - eye
    score = np.where(facing > 0, facing, -np.inf)
    rising = mirrored @ np.asarray(up, dtype=np.float64) > 0.05
    if (rising & (facing > 0)).any():
        score = np.where(rising, score, -np.inf)
    index = int(np.argmax(score))
    if not np.isfinite(score[index]):
        return None
    return mirrored[index] / np.linalg.norm(mirrored[index]), points[index]
