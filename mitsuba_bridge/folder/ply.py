"""Binary PLY meshes for export folders (what Mitsuba's ``ply`` plugin reads)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_ply"]


def write_ply(path, positions: np.ndarray, faces: np.ndarray, normals: np.ndarray | None = None,
              uvs: np.ndarray | None = None, generated: np.ndarray | None = None) -> Path:
    """Write a little-endian binary PLY with vertex normals, UVs and Generated coordinates when given.

    Written in bulk from numpy (one structured array per element type), so a
    million triangles take a fraction of a second.  UVs are stored as ``u, v``
    exactly as given (Mitsuba's PLY loader does not flip them); Generated coordinates
    as ``generated_x, _y, _z``, which Mitsuba's loader makes the mesh attribute
    ``vertex_generated``.
    """
    path = Path(path)
    positions = np.asarray(positions, dtype="<f4")
    faces = np.asarray(faces)
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if normals is not None:
        fields += [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
    if uvs is not None:
        fields += [("u", "<f4"), ("v", "<f4")]
    if generated is not None:
        fields += [("generated_x", "<f4"), ("generated_y", "<f4"), ("generated_z", "<f4")]
    vertices = np.empty(len(positions), dtype=fields)
    vertices["x"], vertices["y"], vertices["z"] = positions.T
    if normals is not None:
        vertices["nx"], vertices["ny"], vertices["nz"] = np.asarray(normals, dtype="<f4").T
    if uvs is not None:
        vertices["u"], vertices["v"] = np.asarray(uvs, dtype="<f4").T
    if generated is not None:
        vertices["generated_x"], vertices["generated_y"], vertices["generated_z"] = \
            np.asarray(generated, dtype="<f4").T
    triangles = np.empty(len(faces), dtype=[("n", "u1"), ("i", "<u4", (3,))])
    triangles["n"] = 3
    triangles["i"] = faces
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(vertices)}"]
    header += [f"property float {name}" for name, _ in fields]
    header += [f"element face {len(triangles)}", "property list uchar uint vertex_indices", "end_header"]
    with open(path, "wb") as stream:
        stream.write(("\n".join(header) + "\n").encode("ascii"))
        stream.write(vertices.tobytes())
        stream.write(triangles.tobytes())
    return path
