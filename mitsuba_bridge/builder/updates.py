"""Changes of a description → new values of a loaded scene's parameters (``mi.traverse`` keys).

:func:`..scene_dict` names every plugin of a scene (``sensor``, ``shape-<name>``, ``light-<index>``,
``world``); this module is the only other place that knows those names, so that whoever builds a
scene also says how an edit of its description reaches the loaded scene (the live viewport's
:class:`...render.session.Session` applies what these functions return).  A function returns the
values to write, or None where the change has no in-place form (another plugin type): the caller
then rebuilds the scene.  Values are written opaque by the caller, so no kernel sees them as literals.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene import Camera, Film, RenderSettings, ScratchedMetal, Shape, Volumetric
from .camera import sensor_dict
from .lights import light_dict, world_dict
from .materials import bsdf_dict
from .resources import InMemory, load_dict, mesh_buffer, scratch_plugin_settings, world_geometry

__all__ = ["SENSOR", "PREVIEW_SENSOR", "STRIP_SENSOR", "WORLD", "SceneKeys", "sensor_values", "shape_values",
           "material_values", "light_values", "world_values"]

#: The main sensor's key in the scene dict (:func:`..camera.sensor_dict`), and those of the extra
#: sensors an interactive session adds beside it: the enlarged first pass and the CPU's strips.
SENSOR = "sensor"
PREVIEW_SENSOR = "sensor-preview"
STRIP_SENSOR = "sensor-strip"
#: The world emitter's key.
WORLD = "world"
_SHAPE_PREFIX = "shape-"
_LIGHT_PREFIX = "light-"


@dataclass(frozen=True)
class SceneKeys:
    """The keys of a scene dict built by :func:`..scene_dict` with ``instancing=False`` (one Mitsuba shape
    per described shape), in the description's order."""

    sensors: tuple[str, ...]  #: in Mitsuba's order (the dict's): a sensor's index for ``mi.render``
    shapes: tuple[str, ...]  #: one per ``description.shapes``

    @classmethod
    def of(cls, scene_dict: dict) -> "SceneKeys":
        sensors = tuple(key for key in scene_dict if key in (SENSOR, PREVIEW_SENSOR, STRIP_SENSOR))
        # scene_dict adds the "shape-…" entries in the order of description.shapes and nothing else so named
        return cls(sensors, tuple(key for key in scene_dict if key.startswith(_SHAPE_PREFIX)))

    def sensor_index(self, key: str) -> int:
        return self.sensors.index(key)

    @staticmethod
    def light(index: int) -> str:
        """The traversal prefix of light ``index`` of the description."""
        return f"{_LIGHT_PREFIX}{index}."

    def bsdf(self, shapes: tuple[Shape, ...], material_key: str) -> str | None:
        """The traversal prefix of the BSDF shared by the shapes of ``material_key`` (None: no shape uses it)."""
        for shape, key in zip(shapes, self.shapes):
            if shape.material == material_key:
                return key + ".bsdf."
        return None


def sensor_values(params, prefix: str, camera: Camera, film: Film, settings: RenderSettings, *,
                  clip: bool = True) -> dict:
    """The new parameters of the sensor ``prefix`` (``"sensor."``) seeing through ``camera`` onto ``film``.

    Clipping distances are scalars of the sensor, compiled into the kernels as literals: they are
    returned only where they differ from ``params``' (and only with ``clip``).
    """
    import mitsuba as mi

    values = {}
    sensor = sensor_dict(camera, film, settings)
    values[prefix + "to_world"] = mi.AffineTransform4f(sensor["to_world"].matrix)
    for name in ("near_clip", "far_clip") if clip else ():
        if np.float32(params[prefix + name]) != np.float32(sensor[name]):  # stored as float32
            values[prefix + name] = sensor[name]
    if camera.projection == "perspective":
        values[prefix + "x_fov"] = mi.Float(sensor["fov"])
        values[prefix + "principal_point_offset_x"] = mi.Float(sensor["principal_point_offset_x"])
        values[prefix + "principal_point_offset_y"] = mi.Float(sensor["principal_point_offset_y"])
    return values


def shape_values(prefix: str, old: Shape, new: Shape) -> dict:
    """The vertices (and, where the winding flips, the faces) of the shape ``prefix`` moved from ``old``'s
    placement to ``new``'s (shapes are stored in world space)."""
    import mitsuba as mi

    positions, faces, normals = world_geometry(new)
    values = {prefix + "vertex_positions": mesh_buffer(mi.Float, positions)}
    if (np.linalg.det(old.to_world[:3, :3]) < 0) != (np.linalg.det(new.to_world[:3, :3]) < 0):
        values[prefix + "faces"] = mesh_buffer(mi.UInt32, faces, np.uint32)
    if normals is not None:
        values[prefix + "vertex_normals"] = mesh_buffer(mi.Float, normals)
    return values


def material_values(params, prefix: str, old, new, key: str) -> dict | None:
    """The parameters of the BSDF ``prefix`` (built from ``old``) that make it ``new``; None: another kind of
    BSDF (a rebuild).  A scratched material's scratches are not among them: the caller hands a new set to
    the BSDF (:func:`...bsdf.update_scratches`)."""
    from ..bsdf import plugin_dict, tensors

    if isinstance(new, Volumetric) or isinstance(old, Volumetric):
        # A medium is the shapes' interior, not a BSDF parameter: only the surface changes in place.
        if not (isinstance(new, Volumetric) and isinstance(old, Volumetric)) or new.volume != old.volume:
            return None
        return material_values(params, prefix, old.surface, new.surface, key)
    if isinstance(new, ScratchedMetal) and isinstance(old, ScratchedMetal):
        same_kind = (new.coherent == old.coherent
                     and (new.crossings, new.depth_phase) == (old.crossings, old.depth_phase)
                     and (new.diffuse_reflectance is None) == (old.diffuse_reflectance is None)
                     and (new.material.lower() == "none") == (old.material.lower() == "none"))
        if not same_kind:
            return None
        source = load_dict(plugin_dict(None, **scratch_plugin_settings(new)))
        return _traversed_values(params, prefix, source, skip=tensors.KEYS)
    if type(new) is type(old):
        return _traversed_values(params, prefix, load_dict(bsdf_dict(new, InMemory(), key=key)))
    return None


def light_values(params, prefix: str, old, new) -> dict | None:
    """The parameters of the emitter ``prefix`` (built from ``old``) that make it ``new``; None: another type."""
    if type(old) is not type(new) or (getattr(old, "radius", 0.0) > 0) != (getattr(new, "radius", 0.0) > 0):
        return None
    return _traversed_values(params, prefix, load_dict(light_dict(new)))


def world_values(params, prefix: str, old, new) -> dict | None:
    """The parameters of the world emitter ``prefix`` (built from ``old``) that make it ``new``; None: another
    type, or no world before or after."""
    if old is None or new is None or type(old) is not type(new):
        return None
    return _traversed_values(params, prefix, load_dict(world_dict(new, InMemory())))


def _traversed_values(params, prefix: str, source, skip=()) -> dict | None:
    """Every traversed parameter of ``source`` (but ``skip``) as the value of ``prefix + key`` in ``params`` (a
    scene's ``mi.traverse``); None when ``params`` lacks one of them (the structures differ: a rebuild)."""
    import mitsuba as mi

    new = mi.traverse(source)
    keys = [key for key in new.keys() if key not in skip]
    if not keys or any(prefix + key not in params for key in keys):
        return None
    return {prefix + key: new[key] for key in keys}
