"""Polyline geometry on CSR arrays (``uv`` + ``offsets``), vectorised over all scratches.

Lengths here are in UV units: the scratch set does not know the surface, so
arc length along a scratch, and the arc-length parameter ``t`` of the noise,
are measured in UV space (the editor and the renderer both use these functions).
"""
from __future__ import annotations

import numpy as np

__all__ = ["edge_lengths", "scratch_lengths", "vertex_arc_length", "arc_parameter", "resample"]


def _is_edge_start(offsets: np.ndarray, vertex_count: int) -> np.ndarray:
    """Boolean mask over vertices 0..P-2: vertex j starts an edge (j and j+1 are one scratch)."""
    mask = np.ones(max(vertex_count - 1, 0), dtype=bool)
    last = offsets[1:-1] - 1  # last vertex of every scratch but the final one
    mask[last] = False
    return mask


def edge_lengths(uv: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Length of every polyline edge, scratch by scratch; shape (P - S,)."""
    starts = np.flatnonzero(_is_edge_start(offsets, len(uv)))
    return np.hypot(*(uv[starts + 1] - uv[starts]).T)


def edge_start_vertices(uv: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Index of the first vertex of every edge; shape (P - S,)."""
    return np.flatnonzero(_is_edge_start(offsets, len(uv)))


def vertex_arc_length(uv: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Arc length from the scratch's first vertex to every vertex; shape (P,)."""
    step = np.zeros(len(uv))
    if len(uv) > 1:
        step[1:] = np.hypot(*(uv[1:] - uv[:-1]).T)
        step[offsets[:-1]] = 0.0  # first vertex of each scratch starts at 0
    cumulative = np.cumsum(step)
    # Subtract the running total at each scratch's first vertex.
    counts = np.diff(offsets)
    return cumulative - np.repeat(cumulative[offsets[:-1]], counts)


def scratch_lengths(uv: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Total arc length of each scratch; shape (S,)."""
    if len(offsets) < 2:
        return np.zeros(0)
    return vertex_arc_length(uv, offsets)[offsets[1:] - 1]


def arc_parameter(uv: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Arc-length parameter t in [0, 1] of every vertex (0 at the first, 1 at the last).

    A scratch of zero length (all vertices equal) gets evenly spaced parameters.
    """
    s = vertex_arc_length(uv, offsets)
    counts = np.diff(offsets)
    total = np.repeat(scratch_lengths(uv, offsets), counts)
    index_in_scratch = np.arange(len(uv)) - np.repeat(offsets[:-1], counts)
    even = index_in_scratch / np.maximum(np.repeat(counts, counts) - 1, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, s / np.where(total > 0, total, 1.0), even)


def resample(uv: np.ndarray, offsets: np.ndarray, counts) -> tuple[np.ndarray, np.ndarray]:
    """Resample every scratch to ``counts[i]`` vertices evenly spaced by arc length.

    ``counts`` is an int or an (S,) array, each >= 2.  Returns new ``(uv, offsets)``;
    the end points are kept exactly.
    """
    scratch_count = len(offsets) - 1
    counts = np.broadcast_to(np.asarray(counts, dtype=np.int64), (scratch_count,))
    if np.any(counts < 2):
        raise ValueError("every scratch needs at least 2 vertices")
    new_offsets = np.zeros(scratch_count + 1, dtype=np.int64)
    np.cumsum(counts, out=new_offsets[1:])
    if scratch_count == 0:
        return np.zeros((0, 2)), new_offsets

    t_old = arc_parameter(uv, offsets)
    scratch_new = np.repeat(np.arange(scratch_count), counts)
    index_new = np.arange(new_offsets[-1]) - np.repeat(new_offsets[:-1], counts)
    t_new = index_new / (counts[scratch_new] - 1)

    # Interpolate on one global monotone coordinate: scratch i lives in [2i, 2i + 1].
    old_counts = np.diff(offsets)
    x_old = t_old + 2.0 * np.repeat(np.arange(scratch_count), old_counts)
    x_new = t_new + 2.0 * scratch_new
    result = np.column_stack([np.interp(x_new, x_old, uv[:, 0]), np.interp(x_new, x_old, uv[:, 1])])
    # Exact end points (interpolation could round them).
    result[new_offsets[:-1]] = uv[offsets[:-1]]
    result[new_offsets[1:] - 1] = uv[offsets[1:] - 1]
    return result, new_offsets
