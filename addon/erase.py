"""Which scratches an eraser stroke touches (no ``bpy``).

The stroke is a polyline on the surface; the eraser covers every point within
``radius`` of it (a tube around the stroke, in 3D).  A scratch is erased when
any of its straight pieces (as drawn by the overlay, :mod:`.lines`) comes within
``radius`` of the stroke.  The stroke is resampled every ``radius / 4``; the
union of balls around those samples misses the exact tube by at most
``radius / 128``.  Work is done stroke chunk by stroke chunk, each tested only
against the pieces inside its bounding box.
"""
from __future__ import annotations

import numpy as np

__all__ = ["densify", "touched_scratches"]

_CHUNK_POINTS = 64
_PAIR_BUDGET = 4_000_000  # point-segment pairs evaluated at once


def densify(points, spacing: float) -> np.ndarray:
    """Insert points along a polyline so that consecutive points are at most ``spacing`` apart."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) < 2 or spacing <= 0:
        return points
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    pieces = np.maximum(1, np.ceil(step / spacing)).astype(np.int64)
    segment = np.repeat(np.arange(len(step)), pieces)
    f = (np.arange(pieces.sum()) - np.repeat(np.cumsum(pieces) - pieces, pieces)) / pieces[segment]
    inner = points[segment] + f[:, None] * (points[segment + 1] - points[segment])
    return np.vstack([inner, points[-1:]])


def touched_scratches(a, b, scratch, runs, radius: float, scratch_count: int) -> np.ndarray:
    """Boolean mask (scratch_count,) of scratches with a piece within ``radius`` of the stroke.

    Parameters
    ----------
    a, b : (M, 3) float
        Piece end points (same coordinates as the stroke).
    scratch : (M,) int
        Scratch of each piece.
    runs : list of (n_i, 3) float
        The stroke, as runs of points on the surface.
    """
    hit = np.zeros(scratch_count, dtype=bool)
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    scratch = np.asarray(scratch, dtype=np.int64)
    if len(a) == 0 or radius <= 0:
        return hit
    samples = [densify(run, radius / 4.0) for run in runs if len(run)]
    if not samples:
        return hit
    points = np.vstack(samples)
    low = np.minimum(a, b)
    high = np.maximum(a, b)
    r2 = radius * radius
    for start in range(0, len(points), _CHUNK_POINTS):
        chunk = points[start:start + _CHUNK_POINTS]
        box_low = chunk.min(axis=0) - radius
        box_high = chunk.max(axis=0) + radius
        candidate = np.flatnonzero(np.all((high >= box_low) & (low <= box_high), axis=1) & ~hit[scratch])
        if not candidate.size:
            continue
        batch = max(1, _PAIR_BUDGET // len(chunk))
        for first in range(0, len(candidate), batch):
            c = candidate[first:first + batch]
            near = _min_distance2(chunk, a[c], b[c]) <= r2
            hit[scratch[c[near]]] = True
    return hit


def _min_distance2(points, a, b) -> np.ndarray:
    """Smallest squared distance from any of ``points`` (K, 3) to each segment (M,)."""
    ab = b - a  # (M, 3)
    length2 = np.einsum("mi,mi->m", ab, ab)
    ap = points[:, None, :] - a[None, :, :]  # (K, M, 3)
    t = np.einsum("kmi,mi->km", ap, ab) / np.where(length2 > 0, length2, 1.0)
    np.clip(t, 0.0, 1.0, out=t)
    closest = ap - t[:, :, None] * ab[None, :, :]
    return np.einsum("kmi,kmi->km", closest, closest).min(axis=0)
