"""Evaluated geometry → :class:`MeshData` with bulk ``foreach_get`` (no per-element Python).

Every triangle corner becomes a vertex (positions, the corner's normal and UV),
which keeps UV seams and sharp edges exact without any search.  A mesh with
several materials is split into one MeshData per used slot; instances share
the MeshData of their source object (gathered once per depsgraph).

Generated texture coordinates are computed as Cycles does (``mesh_texture_space`` in its Blender
sync): the vertex's undeformed position (``undeformed_co``: before deforming modifiers) mapped by the
evaluated mesh's texture space, ``(co − location) / (2 size) + 0.5``; with Auto Texture Space (the
default) that space is the mesh's bounding box, so the coordinates span [0, 1]³ over it.
"""
from __future__ import annotations

import numpy as np

from ....mitsuba_bridge.scene import MeshData
from ...mesh import scratch_uv_layer

__all__ = ["mesh_parts", "generated_coordinates"]


def _read(collection, attribute: str, count: int, width: int, dtype) -> np.ndarray:
    values = np.empty(count * width, dtype=dtype)
    collection.foreach_get(attribute, values)
    return values.reshape(count, width) if width > 1 else values


def generated_coordinates(mesh) -> np.ndarray:
    """Blender's Generated texture coordinates of the vertices of an evaluated mesh, (N, 3) float32."""
    count = len(mesh.vertices)
    undeformed = _read(mesh.vertices, "undeformed_co", count, 3, np.float32).astype(np.float64)
    location = np.array(mesh.texspace_location, dtype=np.float64)
    size = np.array(mesh.texspace_size, dtype=np.float64)
    # Cycles' mesh_texture_space: a zero size leaves that axis unscaled (0.5 / 0 is skipped)
    half_inverse = np.divide(0.5, size, out=np.ones(3), where=size != 0)
    return ((undeformed - location) * half_inverse + 0.5).astype(np.float32)


def mesh_parts(mesh, name: str, *, generated: bool = False) -> list[tuple[int, MeshData]]:
    """``[(material slot index, MeshData), ...]`` of an evaluated mesh, in object space.

    Triangles come from ``loop_triangles``; normals from ``corner_normals``
    (smooth, flat, auto-smooth and custom normals alike) unless every face is
    flat, in which case Mitsuba's own face normals are used. ``generated``: also the
    Generated texture coordinates (:func:`generated_coordinates`), for materials that use them.
    """
    triangle_count = len(mesh.loop_triangles)
    if triangle_count == 0:
        return []
    corners = _read(mesh.loop_triangles, "loops", triangle_count, 3, np.int32)
    slots = _read(mesh.loop_triangles, "material_index", triangle_count, 1, np.int32)
    loop_count = len(mesh.loops)
    corner_vertex = _read(mesh.loops, "vertex_index", loop_count, 1, np.int32)
    positions = _read(mesh.vertices, "co", len(mesh.vertices), 3, np.float32)[corner_vertex]
    normals = None
    if mesh.normals_domain != "FACE":
        normals = _read(mesh.corner_normals, "vector", loop_count, 3, np.float32)
    uv_layer = scratch_uv_layer(mesh)  # the UV map the editor paints scratches in (render UV, else active)
    uvs = _read(uv_layer.uv, "vector", loop_count, 2, np.float32) if uv_layer is not None else None
    orco = generated_coordinates(mesh)[corner_vertex] if generated else None

    used = np.unique(slots)
    if len(used) == 1:
        return [(int(used[0]), MeshData(name, positions, corners.astype(np.uint32), normals, uvs, orco))]
    parts = []
    for slot in used:
        faces = corners[slots == slot]
        keep, faces = np.unique(faces, return_inverse=True)
        parts.append((int(slot), MeshData(
            f"{name}.{slot}", positions[keep], faces.reshape(-1, 3).astype(np.uint32),
            None if normals is None else normals[keep], None if uvs is None else uvs[keep],
            None if orco is None else orco[keep])))
    return parts
