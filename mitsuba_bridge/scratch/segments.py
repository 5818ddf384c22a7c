"""Subdivision of a scratch set into straight segments with constant width and depth.

The diffraction model (docs/model.md §3) treats one straight segment of constant
cross-section at a time.  :func:`subdivide` splits every polyline edge so that

* no piece is longer than ``max_length`` (UV units), and
* the noise of a varying scratch is followed: at least ``pieces_per_cell``
  pieces per noise lattice cell (``1 / (255 f)`` of the scratch's length),

and evaluates width and depth at each piece's midpoint with
:func:`noise.width_depth_at` (the same function the editor uses).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .noise import GRADIENT_COUNT, width_depth_at
from .polyline import arc_parameter, edge_start_vertices
from .scratchset import ScratchSet

__all__ = ["Segments", "subdivide"]


@dataclass(frozen=True, eq=False)
class Segments:
    """Straight scratch segments, structure of arrays (N segments).

    Attributes
    ----------
    a, b : (N, 2) float64
        End points in UV space.
    scratch : (N,) int64
        Index of the scratch each segment belongs to.
    t0, t1 : (N,) float64
        Arc-length parameter of the end points along their scratch.
    width, depth : (N,) float64
        Width and depth in metres at the segment's midpoint (noise applied;
        may be 0 where a variation amplitude above 1 pinches the scratch shut).
    profile : (N,) uint8
        Cross-section (:class:`Profile` codes).
    """

    a: np.ndarray
    b: np.ndarray
    scratch: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    width: np.ndarray
    depth: np.ndarray
    profile: np.ndarray

    def __len__(self) -> int:
        return len(self.scratch)

    @property
    def length(self) -> np.ndarray:
        """UV length of each segment."""
        return np.hypot(*(self.b - self.a).T)


def subdivide(scratches: ScratchSet, *, max_length: float = np.inf,
              pieces_per_cell: int = 4) -> Segments:
    """Straight segments of ``scratches`` (see the module docstring).

    Parameters
    ----------
    max_length:
        Longest allowed segment in UV units (``inf``: only the noise splits edges).
    pieces_per_cell:
        Segments per noise lattice cell on scratches whose width or depth varies.
    """
    uv, offsets = scratches.uv, scratches.offsets
    t_vertex = arc_parameter(uv, offsets)
    first = edge_start_vertices(uv, offsets)  # (E,)
    edge_scratch = np.searchsorted(offsets, first, side="right") - 1

    start, end = uv[first], uv[first + 1]
    t_start, t_end = t_vertex[first], t_vertex[first + 1]
    length = np.hypot(*(end - start).T)

    # Noise cells crossed by each edge, for scratches that actually vary.
    varying = np.maximum(
        np.where(scratches.width_variation[:, 0] > 0, scratches.width_variation[:, 1], 0.0),
        np.where(scratches.depth_variation[:, 0] > 0, scratches.depth_variation[:, 1], 0.0))
    cells = GRADIENT_COUNT * varying[edge_scratch] * (t_end - t_start)
    pieces = np.maximum(1, np.ceil(cells * pieces_per_cell))
    if np.isfinite(max_length):
        if max_length <= 0:
            raise ValueError("max_length must be > 0")
        pieces = np.maximum(pieces, np.ceil(length / max_length))
    pieces = pieces.astype(np.int64)

    if np.all(pieces == 1):  # no edge is split (the CD's chords): the same arithmetic, without the gathers
        a = start + 0.0 * (end - start)
        b = end
        t0 = t_start + 0.0 * (t_end - t_start)
        t1 = t_start + 1.0 * (t_end - t_start)
        scratch = edge_scratch
    else:
        edge = np.repeat(np.arange(len(first)), pieces)
        piece_start = np.cumsum(pieces) - pieces
        k = np.arange(len(edge)) - np.repeat(piece_start, pieces)
        f0 = (k / pieces[edge])[:, None]
        f1 = ((k + 1) / pieces[edge])[:, None]
        direction = (end - start)[edge]
        a = start[edge] + f0 * direction
        b = np.where(f1 == 1.0, end[edge], start[edge] + f1 * direction)  # exact far ends
        dt = (t_end - t_start)[edge]
        t0 = t_start[edge] + f0[:, 0] * dt
        t1 = t_start[edge] + f1[:, 0] * dt
        scratch = edge_scratch[edge]

    width, depth = width_depth_at(scratches, scratch, 0.5 * (t0 + t1))
    return Segments(a=a, b=b, scratch=scratch, t0=t0, t1=t1, width=width, depth=depth,
                    profile=scratches.profile[scratch])
