"""Gather an object's evaluated mesh into numpy arrays, and keep what is costly to rebuild.

Scratches refer to the UV map the renderer uses: the mesh's *active render*
UV map (the camera icon in the UV Maps list), else its active one.  Everything
is read from the evaluated mesh (modifiers applied), as the renderer sees it.

Caches (one entry per object) are keyed by the object, a counter bumped by
every geometry change Blender reports (``depsgraph_update_post``, undo, file
load) and cheap fingerprints, so a stale mesh is never used.
"""
from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np
from bpy.app.handlers import persistent

from ..mitsuba_bridge.errors import ScratchUserError
from .geometry.surface import Surface, SurfaceError

__all__ = ["MeshError", "MeshArrays", "scratch_uv_layer", "mesh_arrays", "world_surface", "Picker",
           "picker_for", "matrix_key", "geometry_generation", "cached", "peek", "clear_caches", "check_object",
           "register", "unregister"]


class MeshError(ScratchUserError, ValueError):
    """The object cannot carry scratches; the message says why and what to do."""


@dataclass(frozen=True, eq=False)
class MeshArrays:
    """Triangles of an evaluated mesh in object space, with the scratch UV map."""

    positions: np.ndarray  # (V, 3) float64
    triangles: np.ndarray  # (T, 3) int64 vertex indices
    triangle_uv: np.ndarray  # (T, 3, 2) float64
    uv_name: str

    @property
    def corners(self) -> np.ndarray:
        return self.positions[self.triangles]


def scratch_uv_layer(mesh):
    """The UV map scratches live in: the active render UV map, else the active one (or None)."""
    layers = mesh.uv_layers
    for layer in layers:
        if layer.active_render:
            return layer
    return layers.active


def check_object(obj) -> None:
    """Raise :class:`MeshError` unless ``obj`` is a mesh object."""
    if obj is None:
        raise MeshError("No active object: select a mesh object")
    if obj.type != "MESH":
        raise MeshError(f"'{obj.name}' is a {obj.type.lower().replace('_', ' ')} object; "
                        "scratches can only be put on mesh objects")


def mesh_arrays(obj, depsgraph) -> MeshArrays:
    """Triangles and UVs of ``obj``'s evaluated mesh (object space)."""
    check_object(obj)
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        layer = scratch_uv_layer(mesh)
        if layer is None:
            raise MeshError(f"'{obj.name}' has no UV map; scratches are stored in UV space: "
                            "unwrap the mesh first (UV > Unwrap)")
        mesh.calc_loop_triangles()
        count = len(mesh.loop_triangles)
        if count == 0:
            raise MeshError(f"'{obj.name}' has no faces to scratch")
        positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", positions)
        triangles = np.empty(count * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", triangles)
        loops = np.empty(count * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("loops", loops)
        uv = np.empty(len(mesh.loops) * 2, dtype=np.float32)
        layer.data.foreach_get("uv", uv)
        name = layer.name
    finally:
        evaluated.to_mesh_clear()
    return MeshArrays(positions=positions.reshape(-1, 3).astype(np.float64),
                      triangles=triangles.reshape(-1, 3).astype(np.int64),
                      triangle_uv=uv.reshape(-1, 2)[loops].reshape(-1, 3, 2).astype(np.float64),
                      uv_name=name)


def world_surface(obj, depsgraph) -> Surface:
    """The world-space :class:`Surface` of ``obj`` (lengths in scene units)."""
    arrays = mesh_arrays(obj, depsgraph)
    try:
        surface = Surface.from_arrays(arrays.positions, arrays.triangles, arrays.triangle_uv,
                                      matrix=np.array(obj.matrix_world))
    except SurfaceError as error:
        raise MeshError(f"'{obj.name}': {error}") from None
    if not surface.usable.any():
        raise MeshError(f"every face of '{obj.name}' has zero area in UV map '{arrays.uv_name}' "
                        "(or in 3D): unwrap the mesh so its faces cover some UV area")
    return surface


class Picker:
    """Nearest points and ray hits on a world-space surface (a BVH over its triangles)."""

    def __init__(self, surface: Surface):
        from mathutils.bvhtree import BVHTree

        self.surface = surface
        vertices = surface.corners.reshape(-1, 3)
        polygons = np.arange(len(vertices)).reshape(-1, 3)
        self._bvh = BVHTree.FromPolygons(vertices.tolist(), polygons.tolist(), all_triangles=True)

    def nearest(self, points, max_distance: float):
        """Snap points to the surface.

        Returns (triangle (N,), bary (N, 3), point (N, 3), hit (N,) bool); a
        point farther than ``max_distance`` or on an unusable face misses.
        """
        from mathutils import Vector

        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = len(points)
        triangle = np.full(n, -1, dtype=np.int64)
        location = np.zeros((n, 3))
        for i, p in enumerate(points):
            found, _, index, _ = self._bvh.find_nearest(Vector(p), max_distance)
            if found is not None:
                triangle[i] = index
                location[i] = found
        return self._finish(triangle, location)

    def ray_cast(self, origin, direction):
        """First hit of a ray: (triangle, bary (3,), point (3,)) or None."""
        from mathutils import Vector

        location, _, index, _ = self._bvh.ray_cast(Vector(origin), Vector(direction))
        if location is None:
            return None
        triangle, bary, point, hit = self._finish(np.array([index]), np.array([location]))
        return (int(triangle[0]), bary[0], point[0]) if hit[0] else None

    def _finish(self, triangle, location):
        hit = triangle >= 0
        hit[hit] = self.surface.usable[triangle[hit]]
        bary = np.zeros((len(triangle), 3))
        if hit.any():
            b = self.surface.barycentric(triangle[hit], location[hit])
            np.maximum(b, 0.0, out=b)
            bary[hit] = b / b.sum(axis=1, keepdims=True)
            location = location.copy()
            location[hit] = self.surface.point(triangle[hit], bary[hit])
        triangle = np.where(hit, triangle, -1)
        return triangle, bary, location, hit


def picker_for(obj, depsgraph) -> Picker:
    """The (cached) :class:`Picker` of ``obj``'s world-space surface."""
    check_object(obj)
    return cached("picker", obj, matrix_key(obj), lambda: Picker(world_surface(obj, depsgraph)))


def matrix_key(obj) -> tuple:
    return tuple(value for row in obj.matrix_world for value in row)


# --------------------------------------------------------------------- caches
_generation = [0]
_caches: dict[str, dict] = {}


def geometry_generation() -> int:
    """A counter that changes whenever Blender reports changed geometry (or undo, or a file load)."""
    return _generation[0]


@persistent
def _bump(*_args):
    _generation[0] += 1


@persistent
def _on_depsgraph_update(_scene, depsgraph):
    for update in depsgraph.updates:
        if update.is_updated_geometry:
            _bump()
            return


def cached(kind: str, obj, key, build):
    """``build()`` cached per (``kind``, object) while ``key`` (plus the geometry generation) holds."""
    store = _caches.setdefault(kind, {})
    full_key = (key, geometry_generation(), obj.name_full, len(obj.data.vertices), len(obj.data.polygons))
    entry = store.get(obj.name_full)
    if entry is not None and entry[0] == full_key:
        return entry[1]
    value = build()
    store[obj.name_full] = (full_key, value)
    return value


def peek(kind: str, obj):
    """The last value cached for (``kind``, object), whether or not still current (None if none)."""
    entry = _caches.get(kind, {}).get(obj.name_full)
    return None if entry is None else entry[1]


def clear_caches() -> None:
    _caches.clear()


_HANDLERS = (
    (bpy.app.handlers.depsgraph_update_post, _on_depsgraph_update),
    (bpy.app.handlers.undo_post, _bump),
    (bpy.app.handlers.redo_post, _bump),
    (bpy.app.handlers.load_post, _bump),
)


def register():
    for handlers, function in _HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister():
    for handlers, function in _HANDLERS:
        if function in handlers:
            handlers.remove(function)
    clear_caches()
