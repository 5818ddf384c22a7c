"""The triangulated surface scratches live on, as numpy arrays (no ``bpy``).

A :class:`Surface` is built from a triangle mesh with one UV coordinate per
triangle corner (Blender's loop triangles of the evaluated mesh).  It knows

* each triangle's 3D corners, normal, area and UV area,
* which triangle lies across each edge, and whether crossing that edge is a
  **UV seam** (the two triangles give the shared corners different UVs), so a
  path crossing it must become two scratches,
* the UV **islands** (triangles connected without crossing a seam),
* a **tangent frame** per triangle (``tangent`` along dp/du, ``bitangent``
  towards dp/dv), in which scratch directions are given,
* the linear map from a 3D offset to barycentric coordinates, which the path
  tracer (:mod:`.trace`) steps with.

Triangles with (almost) no 3D area or no UV area are *unusable*: nothing is
placed on them and paths stop at their edges.

Corner ``k`` of a triangle faces *edge* ``k``, the edge between corners
``k + 1`` and ``k + 2`` (mod 3).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...mitsuba_bridge.errors import ScratchUserError

__all__ = ["Surface", "SurfaceError", "EDGE_CORNERS"]

#: Corners (a, b) of edge k, the edge opposite corner k.
EDGE_CORNERS = np.array([[1, 2], [2, 0], [0, 1]])

# A UV difference above this (in UV units) between the two sides of an edge makes it a seam.
SEAM_TOLERANCE_UV = 1e-6
# Triangles below these fractions of the mesh's largest area (3D, UV) are degenerate.
DEGENERATE_AREA_FRACTION = 1e-12


class SurfaceError(ScratchUserError, ValueError):
    """The mesh cannot carry scratches (no faces, no usable UV area ...)."""


@dataclass(frozen=True, eq=False)
class Surface:
    """A triangle mesh with UVs, prepared for placing and tracing scratches.

    Attributes
    ----------
    corners : (T, 3, 3) float64
        Triangle corners (world units when built from world positions).
    uv : (T, 3, 2) float64
        UV of each corner.
    normal : (T, 3) float64
        Unit normals (corner order, right hand).
    area, uv_area : (T,) float64
        Triangle area in 3D (units²) and in UV space (unsigned).
    usable : (T,) bool
        Non-degenerate in 3D and in UV.
    neighbour : (T, 3) int64
        Triangle across edge k, or -1 (mesh boundary, non-manifold edge, or an
        unusable neighbour).
    neighbour_edge : (T, 3) int64
        Which edge of the neighbour is the shared one.
    seam : (T, 3) bool
        Crossing edge k changes UV island (UV seam).
    flat : (T, 3) bool
        Crossing edge k keeps the same plane and the same UV map (a straight
        UV line stays straight in 3D across it).
    island : (T,) int64
        UV island label (connected through non-seam edges), -1 for unusable.
    tangent, bitangent : (T, 3) float64
        Orthonormal tangent frame in the triangle plane; ``tangent`` follows
        the U direction, ``bitangent`` the side of V (MikkTSpace convention).
    to_bary : (T, 2, 3) float64
        ``(b1, b2) = to_bary @ (p - corner0)`` for a point p in the plane.
    edge_out : (T, 3, 3) float64
        Unit in-plane normal of edge k, pointing out of the triangle.
    """

    corners: np.ndarray
    uv: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    uv_area: np.ndarray
    usable: np.ndarray
    neighbour: np.ndarray
    neighbour_edge: np.ndarray
    seam: np.ndarray
    flat: np.ndarray
    island: np.ndarray
    tangent: np.ndarray
    bitangent: np.ndarray
    to_bary: np.ndarray
    edge_out: np.ndarray

    @property
    def triangle_count(self) -> int:
        return len(self.area)

    @property
    def total_area(self) -> float:
        """Area of the usable triangles (units²)."""
        return float(self.area[self.usable].sum())

    @property
    def size(self) -> float:
        """Diagonal of the bounding box (units)."""
        if not len(self.corners):
            return 0.0
        flat = self.corners.reshape(-1, 3)
        return float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))

    # ----------------------------------------------------------- construction
    @classmethod
    def from_arrays(cls, positions, triangles, triangle_uv, *, matrix=None, weld: bool = True) -> "Surface":
        """Build a surface.

        Parameters
        ----------
        positions : (V, 3) float
            Vertex positions.
        triangles : (T, 3) int
            Vertex indices of each triangle.
        triangle_uv : (T, 3, 2) float
            UV of each triangle corner.
        matrix : (4, 4) float, optional
            Applied to the positions first (an object's world matrix).
        weld : bool
            Treat vertices at exactly the same position as one vertex, so that
            meshes whose UV seams were split into separate vertices (OBJ, glTF
            imports) are still connected across them.
        """
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        triangle_uv = np.asarray(triangle_uv, dtype=np.float64).reshape(-1, 3, 2)
        if len(triangles) == 0:
            raise SurfaceError("the mesh has no faces")
        if len(triangle_uv) != len(triangles):
            raise ValueError(f"{len(triangle_uv)} UV triangles for {len(triangles)} triangles")
        if matrix is not None:
            matrix = np.asarray(matrix, dtype=np.float64)
            positions = positions @ matrix[:3, :3].T + matrix[:3, 3]
        if weld:
            positions, inverse = np.unique(positions, axis=0, return_inverse=True)
            triangles = inverse.reshape(-1)[triangles]

        corners = positions[triangles]
        e1 = corners[:, 1] - corners[:, 0]
        e2 = corners[:, 2] - corners[:, 0]
        cross = np.cross(e1, e2)
        double_area = np.linalg.norm(cross, axis=1)
        area = 0.5 * double_area
        duv1 = triangle_uv[:, 1] - triangle_uv[:, 0]
        duv2 = triangle_uv[:, 2] - triangle_uv[:, 0]
        uv_det = duv1[:, 0] * duv2[:, 1] - duv1[:, 1] * duv2[:, 0]
        uv_area = 0.5 * np.abs(uv_det)
        usable = ((area > DEGENERATE_AREA_FRACTION * max(area.max(), 1e-300))
                  & (uv_area > DEGENERATE_AREA_FRACTION * max(uv_area.max(), 1e-300)))

        with np.errstate(invalid="ignore", divide="ignore"):
            normal = cross / np.where(double_area > 0, double_area, 1.0)[:, None]

            # Barycentric map: least-squares inverse of [e1 e2].
            edges = np.stack([e1, e2], axis=2)  # (T, 3, 2)
            gram = np.einsum("tki,tkj->tij", edges, edges)
            det = gram[:, 0, 0] * gram[:, 1, 1] - gram[:, 0, 1] * gram[:, 1, 0]
            inverse_gram = np.stack([np.stack([gram[:, 1, 1], -gram[:, 0, 1]], 1),
                                     np.stack([-gram[:, 1, 0], gram[:, 0, 0]], 1)], 1)
            inverse_gram /= np.where(det != 0, det, 1.0)[:, None, None]
            to_bary = np.einsum("tij,tkj->tik", inverse_gram, edges)  # (T, 2, 3)

            # dp/du and dp/dv: [e1 e2] = [dpdu dpdv] [duv1 duv2].
            inverse_duv = np.stack([np.stack([duv2[:, 1], -duv2[:, 0]], 1),
                                    np.stack([-duv1[:, 1], duv1[:, 0]], 1)], 1)
            inverse_duv /= np.where(uv_det != 0, uv_det, 1.0)[:, None, None]
            jacobian = np.einsum("tki,tij->tkj", edges, inverse_duv)  # (T, 3, 2): columns dpdu, dpdv
        dpdu, dpdv = jacobian[:, :, 0], jacobian[:, :, 1]
        tangent = _unit(dpdu - np.einsum("ti,ti->t", dpdu, normal)[:, None] * normal, fallback=e1)
        bitangent = np.cross(normal, tangent)
        flip = np.einsum("ti,ti->t", bitangent, dpdv) < 0
        bitangent[flip] *= -1.0

        edge_out = np.empty((len(triangles), 3, 3))
        for k, (a, b) in enumerate(EDGE_CORNERS):
            along = corners[:, b] - corners[:, a]
            out = _unit(np.cross(along, normal), fallback=np.cross(along, [0.0, 0.0, 1.0]))
            inward = np.einsum("ti,ti->t", out, corners[:, k] - corners[:, a]) > 0
            out[inward] *= -1.0
            edge_out[:, k] = out

        neighbour, neighbour_edge, seam = _adjacency(triangles, triangle_uv)
        neighbour[neighbour >= 0] = np.where(usable[neighbour[neighbour >= 0]], neighbour[neighbour >= 0], -1)
        neighbour[~usable] = -1
        flat = _flat_edges(neighbour, seam, normal, jacobian)
        island = _islands(neighbour, seam, usable)
        return cls(corners=corners, uv=triangle_uv, normal=normal, area=area, uv_area=uv_area,
                   usable=usable, neighbour=neighbour, neighbour_edge=neighbour_edge, seam=seam,
                   flat=flat, island=island, tangent=tangent, bitangent=bitangent, to_bary=to_bary,
                   edge_out=edge_out)

    # ------------------------------------------------------------- evaluation
    def point(self, triangle, bary) -> np.ndarray:
        """3D points at barycentric coordinates ``bary`` (N, 3) of ``triangle`` (N,)."""
        return np.einsum("nk,nki->ni", bary, self.corners[triangle])

    def uv_at(self, triangle, bary) -> np.ndarray:
        """UV at barycentric coordinates ``bary`` (N, 3) of ``triangle`` (N,)."""
        return np.einsum("nk,nki->ni", bary, self.uv[triangle])

    def barycentric(self, triangle, points) -> np.ndarray:
        """Barycentric coordinates (N, 3) of ``points`` projected into the planes of ``triangle``."""
        b12 = np.einsum("nij,nj->ni", self.to_bary[triangle], points - self.corners[triangle, 0])
        return np.column_stack([1.0 - b12.sum(axis=1), b12])

    def direction(self, triangle, angle) -> np.ndarray:
        """Unit 3D directions at ``angle`` (radians) from the tangent towards the bitangent."""
        angle = np.asarray(angle, dtype=np.float64)[:, None]
        return np.cos(angle) * self.tangent[triangle] + np.sin(angle) * self.bitangent[triangle]

    def tangent_angle(self, triangle, direction) -> np.ndarray:
        """Angle (radians) of 3D ``direction`` in the tangent frame of ``triangle``."""
        return np.arctan2(np.einsum("ni,ni->n", direction, self.bitangent[triangle]),
                          np.einsum("ni,ni->n", direction, self.tangent[triangle]))

    def sample_points(self, rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray]:
        """``count`` points uniformly distributed over the usable area (3D, not UV).

        Returns (triangle (count,), barycentric (count, 3)).
        """
        weight = np.where(self.usable, self.area, 0.0)
        cumulative = np.cumsum(weight)
        if cumulative[-1] <= 0:
            raise SurfaceError("the mesh has no usable faces (zero area in 3D or in UV)")
        triangle = np.searchsorted(cumulative, rng.uniform(0.0, cumulative[-1], count), side="right")
        np.minimum(triangle, len(weight) - 1, out=triangle)
        r1 = np.sqrt(rng.uniform(0.0, 1.0, count))
        r2 = rng.uniform(0.0, 1.0, count)
        bary = np.column_stack([1.0 - r1, r1 * (1.0 - r2), r1 * r2])
        return triangle, bary


# ------------------------------------------------------------------ helpers
def _unit(vectors, fallback) -> np.ndarray:
    vectors = np.asarray(vectors, dtype=np.float64)
    norm = np.linalg.norm(vectors, axis=1)
    fallback = np.broadcast_to(np.asarray(fallback, dtype=np.float64), vectors.shape)
    fallback_norm = np.linalg.norm(fallback, axis=1)
    good = norm > 1e-300
    out = np.where(good[:, None], vectors / np.where(good, norm, 1.0)[:, None],
                   fallback / np.where(fallback_norm > 0, fallback_norm, 1.0)[:, None])
    return out


def _adjacency(triangles: np.ndarray, triangle_uv: np.ndarray):
    """Neighbours across edges shared by exactly two triangles, and which of them are seams."""
    count = len(triangles)
    a = triangles[:, EDGE_CORNERS[:, 0]].reshape(-1)  # (3T,) half-edge k of triangle t at 3t + k
    b = triangles[:, EDGE_CORNERS[:, 1]].reshape(-1)
    low, high = np.minimum(a, b), np.maximum(a, b)
    key = low * (int(triangles.max()) + 1) + high
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    run_start = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    run_length = np.diff(np.r_[run_start, len(key)])
    pairs = run_start[run_length == 2]  # manifold edges only
    first, second = order[pairs], order[pairs + 1]

    neighbour = np.full(3 * count, -1, dtype=np.int64)
    neighbour_edge = np.full(3 * count, -1, dtype=np.int64)
    neighbour[first], neighbour[second] = second // 3, first // 3
    neighbour_edge[first], neighbour_edge[second] = second % 3, first % 3

    # Seam: compare the UV of each shared vertex on both sides.
    seam = np.zeros(3 * count, dtype=bool)
    uv_flat = triangle_uv.reshape(-1, 2)  # corner c of triangle t at 3t + c
    tri_first, edge_first = first // 3, first % 3
    tri_second, edge_second = second // 3, second % 3
    for side in (0, 1):
        corner_first = EDGE_CORNERS[edge_first, side]
        vertex = triangles[tri_first, corner_first]
        candidates = EDGE_CORNERS[edge_second]  # (n, 2)
        match = np.where(triangles[tri_second, candidates[:, 0]] == vertex, candidates[:, 0], candidates[:, 1])
        difference = uv_flat[3 * tri_first + corner_first] - uv_flat[3 * tri_second + match]
        jump = np.abs(difference).max(axis=1) > SEAM_TOLERANCE_UV
        seam[first[jump]] = True
        seam[second[jump]] = True
    return neighbour.reshape(count, 3), neighbour_edge.reshape(count, 3), seam.reshape(count, 3)


def _flat_edges(neighbour, seam, normal, jacobian) -> np.ndarray:
    """Edges across which the plane and the UV map do not change."""
    flat = np.zeros(neighbour.shape, dtype=bool)
    has = (neighbour >= 0) & ~seam
    t, k = np.nonzero(has)
    other = neighbour[t, k]
    same_plane = np.einsum("ni,ni->n", normal[t], normal[other]) > 1.0 - 1e-12
    scale = np.maximum(np.abs(jacobian[t]).max(axis=(1, 2)), 1e-300)
    same_map = np.abs(jacobian[t] - jacobian[other]).max(axis=(1, 2)) <= 1e-9 * scale
    flat[t, k] = same_plane & same_map
    return flat


def _islands(neighbour, seam, usable) -> np.ndarray:
    """Connected components through non-seam edges (label = smallest triangle index)."""
    count = len(neighbour)
    t, k = np.nonzero((neighbour >= 0) & ~seam)
    a, b = t, neighbour[t, k]
    label = np.arange(count, dtype=np.int64)
    while True:  # hook and jump; converges in O(log diameter) rounds
        la, lb = label[a], label[b]
        if np.array_equal(la, lb):
            break
        np.minimum.at(label, np.maximum(la, lb), np.minimum(la, lb))
        while True:
            jumped = label[label]
            if np.array_equal(jumped, label):
                break
            label = jumped
    label[~usable] = -1
    return label
