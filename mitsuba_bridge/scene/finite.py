"""Meshes with NaN or infinite values: dropped triangle by triangle, with a warning, instead of a black image.

One non-finite vertex position can poison Mitsuba's acceleration structure and
blacken far more than its own triangles, silently.  Blender produces such
vertices from e.g. a Displace modifier fed with a broken texture, a driver
dividing by zero or a script.  The triangles that touch a non-finite position
or UV are removed (a UV decides where scratches lie); non-finite normals are
replaced by Mitsuba's own face normals (the mesh keeps its triangles).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .description import MeshData, SceneDescription

__all__ = ["finite_mesh", "with_finite_meshes"]


def finite_mesh(mesh: MeshData) -> tuple[MeshData, int, bool]:
    """``(mesh without its non-finite triangles, triangles dropped, normals dropped)``.

    The same ``mesh`` object comes back when everything is finite (no copy).
    """
    bad_vertex = ~np.isfinite(mesh.positions).all(axis=1)
    for coordinates in (mesh.uvs, mesh.generated):
        if coordinates is not None:
            bad_vertex |= ~np.isfinite(coordinates).all(axis=1)
    bad_normals = mesh.normals is not None and not np.isfinite(mesh.normals).all()
    if not bad_vertex.any() and not bad_normals:
        return mesh, 0, False
    keep = ~bad_vertex[mesh.faces].any(axis=1)
    faces = mesh.faces[keep]
    fixed = dataclasses.replace(mesh, faces=np.ascontiguousarray(faces, dtype=np.uint32),
                                normals=None if bad_normals else mesh.normals)
    return fixed, int((~keep).sum()), bool(bad_normals)


def with_finite_meshes(description: SceneDescription) -> SceneDescription:
    """``description`` with :func:`finite_mesh` applied to every mesh, one warning per mesh that changed.

    Shapes left without triangles are removed.  The same object comes back
    when every mesh is finite.
    """
    fixed: dict[int, tuple[MeshData, int, bool]] = {}
    for shape in description.shapes:
        if id(shape.mesh) not in fixed:  # instances share their mesh: check and warn once
            fixed[id(shape.mesh)] = finite_mesh(shape.mesh)
    if all(fixed[id(shape.mesh)][0] is shape.mesh for shape in description.shapes):
        return description
    warnings, shapes = list(description.warnings), []
    for mesh, dropped, normals in fixed.values():
        total = mesh.triangle_count + dropped
        if dropped:
            warnings.append(f"mesh '{mesh.name}': {dropped} of {total} triangles have NaN or infinite vertex "
                            "positions or UVs and are not rendered")
        if normals:
            warnings.append(f"mesh '{mesh.name}': NaN or infinite normals: rendered with flat face normals")
    for shape in description.shapes:
        mesh = fixed[id(shape.mesh)][0]
        if mesh.triangle_count:
            shapes.append(shape if mesh is shape.mesh else dataclasses.replace(shape, mesh=mesh))
    return dataclasses.replace(description, shapes=tuple(shapes), warnings=tuple(warnings))
