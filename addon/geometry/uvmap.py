"""UV → surface: which triangle a UV point lies in, for many points at once (no ``bpy``).

Scratches are stored in UV space; to draw or erase them the editor needs their
place on the mesh.  :class:`UVLocator` bins the triangles' UV bounding boxes
into a uniform grid once, then answers each query by testing the few
triangles of its cell with barycentric coordinates, all queries of a round in
one numpy step.

Where UV islands overlap (mirrored or stacked UVs) a point lies in several
triangles; the first found wins.  The renderer, which looks scratches up by UV,
puts them on every overlapping copy.
"""
from __future__ import annotations

import numpy as np

__all__ = ["UVLocator"]

_MAX_CELLS_PER_AXIS = 2048
_MAX_CELL_ENTRIES = 8_000_000
# Tolerance on barycentric coordinates: points on a shared edge belong to either side.
_INSIDE_TOLERANCE = 1e-7
_BOX_MARGIN = 1e-7


class UVLocator:
    """Find the triangle containing each of many UV points.

    Parameters
    ----------
    triangle_uv : (T, 3, 2) float
        UV of each triangle corner.
    usable : (T,) bool, optional
        Triangles to consider (default: those with non-zero UV area).
    """

    def __init__(self, triangle_uv, usable=None):
        uv = np.asarray(triangle_uv, dtype=np.float64).reshape(-1, 3, 2)
        self.triangle_count = len(uv)
        e1 = uv[:, 1] - uv[:, 0]
        e2 = uv[:, 2] - uv[:, 0]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        if usable is None:
            usable = np.abs(det) > 1e-300
        usable = np.asarray(usable, dtype=bool) & (det != 0)
        index = np.flatnonzero(usable)
        self._index = index
        self._origin = uv[index, 0]
        safe = det[index]
        # Inverse of [e1 e2] (columns): maps uv - origin to (b1, b2).
        self._inverse = np.stack([np.stack([e2[index, 1], -e2[index, 0]], 1),
                                  np.stack([-e1[index, 1], e1[index, 0]], 1)], 1) / safe[:, None, None]

        if len(index) == 0:
            self._low = np.zeros(2)
            self._cell_size = np.ones(2)
            self._shape = (1, 1)
            self._cell_start = np.zeros(2, dtype=np.int64)
            self._cell_triangles = np.zeros(0, dtype=np.int64)
            return
        low = uv[index].min(axis=1)
        high = uv[index].max(axis=1)
        extent = np.maximum(high.max(axis=0) - low.min(axis=0), 1e-12)
        # Grow the boxes a little: a point a rounding error outside its triangle
        # (on an island's border) must still find it among its cell's candidates.
        low = low - _BOX_MARGIN * extent
        high = high + _BOX_MARGIN * extent
        self._low = low.min(axis=0)
        extent = high.max(axis=0) - self._low
        # Cells about the size of a typical triangle, within limits.
        typical = np.maximum(np.median(high - low, axis=0), extent / _MAX_CELLS_PER_AXIS)
        shape = np.clip(np.ceil(extent / typical), 1, _MAX_CELLS_PER_AXIS).astype(np.int64)
        while True:
            cell_size = extent / shape
            first = np.clip(((low - self._low) / cell_size).astype(np.int64), 0, shape - 1)
            last = np.clip(((high - self._low) / cell_size).astype(np.int64), 0, shape - 1)
            span = last - first + 1
            per_triangle = span[:, 0] * span[:, 1]
            if per_triangle.sum() <= _MAX_CELL_ENTRIES or shape.max() == 1:
                break
            shape = np.maximum(shape // 2, 1)
        self._cell_size = cell_size
        self._shape = (int(shape[0]), int(shape[1]))

        owner = np.repeat(np.arange(len(index)), per_triangle)
        local = np.arange(per_triangle.sum()) - np.repeat(np.cumsum(per_triangle) - per_triangle, per_triangle)
        ix = first[owner, 0] + local % span[owner, 0]
        iy = first[owner, 1] + local // span[owner, 0]
        cell = iy * shape[0] + ix
        order = np.argsort(cell, kind="stable")
        self._cell_triangles = owner[order]
        self._cell_start = np.searchsorted(cell[order], np.arange(shape[0] * shape[1] + 1))

    @property
    def cell_size(self) -> float:
        """Smaller side of a grid cell (UV units): about one triangle."""
        return float(self._cell_size.min())

    def locate(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Triangle (or -1) and barycentric coordinates of each UV point.

        Parameters
        ----------
        points : (N, 2) float

        Returns
        -------
        triangle : (N,) int64, -1 where the point lies in no triangle
        bary : (N, 3) float64 (zeros where not found)
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        n = len(points)
        triangle = np.full(n, -1, dtype=np.int64)
        bary = np.zeros((n, 3))
        if n == 0 or len(self._index) == 0:
            return triangle, bary
        shape = np.array(self._shape)
        cell_xy = np.floor((points - self._low) / self._cell_size).astype(np.int64)
        # Points on the far border belong to the last cell.
        on_border = (cell_xy == shape) & (points <= self._low + self._cell_size * shape + 1e-12)
        cell_xy[on_border] -= 1
        inside_grid = np.all((cell_xy >= 0) & (cell_xy < shape), axis=1)
        cell = np.where(inside_grid, cell_xy[:, 1] * shape[0] + cell_xy[:, 0], 0)
        start = self._cell_start[cell]
        count = np.where(inside_grid, self._cell_start[cell + 1] - start, 0)

        pending = np.flatnonzero(count > 0)
        k = 0
        while pending.size:
            candidate = self._cell_triangles[start[pending] + k]
            b12 = np.einsum("nij,nj->ni", self._inverse[candidate], points[pending] - self._origin[candidate])
            b0 = 1.0 - b12.sum(axis=1)
            inside = (b0 >= -_INSIDE_TOLERANCE) & np.all(b12 >= -_INSIDE_TOLERANCE, axis=1)
            found = pending[inside]
            triangle[found] = self._index[candidate[inside]]
            bary[found] = np.column_stack([b0[inside], b12[inside]])
            k += 1
            pending = pending[~inside & (count[pending] > k)]
        return triangle, bary
