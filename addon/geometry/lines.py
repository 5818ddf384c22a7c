"""Scratches as 3D line segments on the mesh, with colours: the overlay's data (no ``bpy``).

:func:`scratch_lines` maps every scratch from UV to the surface through a
:class:`~.uvmap.UVLocator`.  Polylines are first cut into straight pieces with
:func:`mitsuba_bridge.scratch.subdivide`, the function the renderer uses, so the
preview shows width and depth where the renderer evaluates them (the noise
variation included), and no piece is longer than about one triangle in UV (a
UV segment crossing triangles bends on the surface).  :func:`line_colours`
colours the pieces by depth or width.  Both are pure functions of numpy
arrays: the viewport only uploads their result.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...mitsuba_bridge.scratch import ScratchSet, subdivide
from .uvmap import UVLocator

__all__ = ["Lines", "scratch_lines", "line_colours", "COLOUR_MAP", "overlay_arrays"]

#: Colour ramp for the overlay (viridis at five stops, sRGB): low values dark blue, high yellow.
COLOUR_MAP = np.array([
    [0.267, 0.005, 0.329],
    [0.229, 0.322, 0.546],
    [0.128, 0.567, 0.551],
    [0.369, 0.789, 0.383],
    [0.993, 0.906, 0.144],
])


@dataclass(frozen=True, eq=False)
class Lines:
    """Straight pieces of scratches on the surface.

    Attributes
    ----------
    a, b : (M, 3) float64
        End points in the mesh's coordinates (lifted off the surface by ``offset``).
    scratch : (M,) int64
        Scratch each piece belongs to.
    width, depth : (M,) float64
        Width and depth in metres at the piece's midpoint (variation applied).
    unplaced : int
        Scratches with at least one piece outside every UV triangle (not drawn).
    """

    a: np.ndarray
    b: np.ndarray
    scratch: np.ndarray
    width: np.ndarray
    depth: np.ndarray
    unplaced: int

    def __len__(self) -> int:
        return len(self.scratch)

    def without(self, removed) -> "Lines":
        """The lines of the scratches left after removing those where ``removed`` (S,) is True.

        Scratch indices are renumbered as ``ScratchSet.select(~removed)`` numbers them.
        """
        removed = np.asarray(removed, dtype=bool)
        keep = ~removed[self.scratch]
        renumber = np.cumsum(~removed) - 1
        return Lines(a=self.a[keep], b=self.b[keep], scratch=renumber[self.scratch[keep]],
                     width=self.width[keep], depth=self.depth[keep], unplaced=self.unplaced)

    def followed_by(self, other: "Lines", first_scratch: int) -> "Lines":
        """These lines, then ``other``'s, whose scratches are numbered from ``first_scratch``."""
        return Lines(a=np.vstack([self.a, other.a]), b=np.vstack([self.b, other.b]),
                     scratch=np.r_[self.scratch, other.scratch + first_scratch],
                     width=np.r_[self.width, other.width], depth=np.r_[self.depth, other.depth],
                     unplaced=self.unplaced + other.unplaced)


def scratch_lines(scratches: ScratchSet, locator: UVLocator, corners, normals=None, *,
                  offset: float = 0.0, max_uv_length: float | None = None) -> Lines:
    """Map ``scratches`` onto a mesh.

    Parameters
    ----------
    locator : UVLocator
        Built from the same mesh's triangle UVs.
    corners : (T, 3, 3) float
        Triangle corners (object or world coordinates: the result uses the same).
    normals : (T, 3) float, optional
        Unit triangle normals; with ``offset``, points are lifted along them so
        lines are not hidden in the surface.
    max_uv_length : float, optional
        Longest piece in UV units (default: the locator's cell size, about a triangle).
    """
    corners = np.asarray(corners, dtype=np.float64)
    if scratches.count == 0:
        empty = np.zeros((0, 3))
        return Lines(empty, empty, np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), 0)
    limit = locator.cell_size if max_uv_length is None else max_uv_length
    segments = subdivide(scratches, max_length=limit)
    triangle_a, bary_a = locator.locate(segments.a)
    triangle_b, bary_b = locator.locate(segments.b)
    placed = (triangle_a >= 0) & (triangle_b >= 0)
    bad_scratches = np.unique(segments.scratch[~placed])

    a = _point(corners, triangle_a[placed], bary_a[placed])
    b = _point(corners, triangle_b[placed], bary_b[placed])
    if offset and normals is not None:
        normals = np.asarray(normals, dtype=np.float64)
        a += offset * normals[triangle_a[placed]]
        b += offset * normals[triangle_b[placed]]
    return Lines(a=a, b=b, scratch=segments.scratch[placed], width=segments.width[placed],
                 depth=segments.depth[placed], unplaced=len(bad_scratches))


def _point(corners, triangle, bary):
    return np.einsum("nk,nki->ni", bary, corners[triangle])


def line_colours(values, low: float | None = None, high: float | None = None) -> np.ndarray:
    """RGBA (M, 4) float32 colours of ``values`` on :data:`COLOUR_MAP` between ``low`` and ``high``.

    Defaults are the smallest and largest value; a constant set gets the middle colour.
    """
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return np.zeros((0, 4), dtype=np.float32)
    low = float(values.min()) if low is None else low
    high = float(values.max()) if high is None else high
    if high > low:
        x = np.clip((values - low) / (high - low), 0.0, 1.0)
    else:
        x = np.full(values.shape, 0.5)
    position = x * (len(COLOUR_MAP) - 1)
    index = np.minimum(position.astype(np.int64), len(COLOUR_MAP) - 2)
    f = (position - index)[:, None]
    rgb = (1.0 - f) * COLOUR_MAP[index] + f * COLOUR_MAP[index + 1]
    return np.column_stack([rgb, np.ones(len(values))]).astype(np.float32)


def overlay_arrays(lines: Lines, colour_by: str, value_range=None):
    """Vertex positions (2M, 3) and colours (2M, 4), float32, for a ``LINES`` batch.

    ``colour_by`` is ``"DEPTH"`` or ``"WIDTH"``; ``value_range`` (low, high) in
    metres fixes the colour scale (default: the range of the drawn values).
    Returns (positions, colours, (low, high)).
    """
    values = lines.depth if colour_by == "DEPTH" else lines.width
    if value_range is None:
        value_range = (float(values.min()), float(values.max())) if len(values) else (0.0, 0.0)
    colours = line_colours(values, *value_range)
    positions = np.empty((2 * len(lines), 3), dtype=np.float32)
    positions[0::2] = lines.a
    positions[1::2] = lines.b
    return positions, np.repeat(colours, 2, axis=0), value_range
