"""The eraser: which scratches a stroke touches, and cutting away what lies under it (no ``bpy``).

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

from ...mitsuba_bridge.scratch import ScratchSet
from .scatter import piece_seeds

__all__ = ["densify", "touched_scratches", "near_stroke", "cut_scratches", "stroke_segments"]

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


def stroke_segments(runs):
    """The stroke as segments (a, b); a run of one point (a dab) is a zero-length segment."""
    starts, ends = [], []
    for run in runs:
        run = np.asarray(run, dtype=np.float64).reshape(-1, 3)
        if len(run) == 1:
            starts.append(run)
            ends.append(run)
        elif len(run) > 1:
            starts.append(run[:-1])
            ends.append(run[1:])
    if not starts:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.vstack(starts), np.vstack(ends)


def near_stroke(points, runs, radius: float) -> np.ndarray:
    """Boolean mask: which ``points`` (N, 3) lie within ``radius`` of the stroke (exact distances)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    near = np.zeros(len(points), dtype=bool)
    a, b = stroke_segments(runs)
    if not len(a) or not len(points):
        return near
    low, high = np.minimum(a, b), np.maximum(a, b)
    # Visit the points in spatial order (cells of 16 radii), so each chunk is compact and
    # its bounding box keeps only the nearby stroke segments.
    cell = np.floor((points - points.min(axis=0)) / (16.0 * radius)).astype(np.int64)
    order = np.lexsort(cell.T[::-1])
    chunk = 1024
    for start in range(0, len(points), chunk):
        index = order[start:start + chunk]
        block = points[index]
        candidate = np.flatnonzero(np.all((high >= block.min(axis=0) - radius)
                                          & (low <= block.max(axis=0) + radius), axis=1))
        batch = max(1, _PAIR_BUDGET // len(block))
        for first in range(0, len(candidate), batch):
            c = candidate[first:first + batch]
            near[index] |= _min_distance2_to_points(block, a[c], b[c]) <= radius * radius
    return near


def _min_distance2_to_points(points, a, b) -> np.ndarray:
    """Smallest squared distance from each of ``points`` (K,) to any segment (a, b)."""
    ab = b - a
    length2 = np.einsum("mi,mi->m", ab, ab)
    ap = points[:, None, :] - a[None, :, :]
    t = np.einsum("kmi,mi->km", ap, ab) / np.where(length2 > 0, length2, 1.0)
    np.clip(t, 0.0, 1.0, out=t)
    closest = ap - t[:, :, None] * ab[None, :, :]
    return np.einsum("kmi,kmi->km", closest, closest).min(axis=1)


def cut_scratches(scratches, to_surface, runs, radius: float):
    """The scratches with every part within ``radius`` of the stroke removed.

    Parameters
    ----------
    scratches : ScratchSet
    to_surface : callable
        ``to_surface(uv (N, 2)) -> (points (N, 3), found (N,) bool)``: UV to the
        stroke's 3D coordinates.
    runs : list of (n_i, 3) arrays
        The stroke.

    Each scratch is resampled every ``radius / 4`` along the surface; the
    samples under the brush are dropped and every remaining run of two or more
    samples becomes a scratch (keeping the original vertices and the run's end
    points), with the original's width, depth and profile, its variation
    frequency scaled by the run's share of the length, and its own seed.  A cut
    end lies within ``radius / 4`` of the brush's edge.  Scratches the brush
    does not touch are returned unchanged, first, in their order.
    """

    spacing = radius / 4.0
    uv, offsets = scratches.uv, scratches.offsets
    points, found = to_surface(uv)
    counts = np.diff(offsets)
    # Resample every edge at no more than `spacing` along the surface.
    first = np.flatnonzero(np.r_[np.diff(np.repeat(np.arange(scratches.count), counts)) == 0, False])
    edge_length = np.linalg.norm(points[first + 1] - points[first], axis=1)
    pieces = np.maximum(1, np.ceil(edge_length / spacing)).astype(np.int64)
    pieces[~(found[first] & found[first + 1])] = 1
    vertex_pieces = np.ones(len(uv), dtype=np.int64)  # a scratch's last vertex contributes itself
    vertex_pieces[first] = pieces
    owner = np.repeat(np.arange(len(uv)), vertex_pieces)
    k = np.arange(len(owner)) - np.repeat(np.cumsum(vertex_pieces) - vertex_pieces, vertex_pieces)
    fraction = (k / vertex_pieces[owner])[:, None]
    is_edge = np.zeros(len(uv), dtype=bool)
    is_edge[first] = True
    target = np.where(is_edge[owner], owner + 1, owner)
    sample_uv = uv[owner] + fraction * (uv[target] - uv[owner])
    original = k == 0
    sample_points, sample_found = to_surface(sample_uv)
    under = sample_found & near_stroke(sample_points, runs, radius)

    sample_scratch = np.repeat(np.arange(scratches.count), np.add.reduceat(vertex_pieces, offsets[:-1])
                               if scratches.count else np.zeros(0, dtype=np.int64))
    touched = np.zeros(scratches.count, dtype=bool)
    touched[sample_scratch[under]] = True
    if not touched.any():
        return scratches, touched
    # Runs of kept samples of the touched scratches.
    keep = ~under & touched[sample_scratch]
    new_run = keep & ~np.r_[False, keep[:-1] & (sample_scratch[1:] == sample_scratch[:-1])]
    run_id = np.cumsum(new_run) - 1
    run_of = np.where(keep, run_id, -1)
    kept = np.flatnonzero(keep)
    run_length = np.bincount(run_of[kept], minlength=int(new_run.sum()))
    is_end = np.zeros(len(keep), dtype=bool)
    run_first = np.flatnonzero(new_run)
    is_end[run_first] = True
    is_end[run_first + run_length - 1] = True
    vertex = kept[(original[kept] | is_end[kept]) & (run_length[run_of[kept]] >= 2)]
    runs_used = run_of[vertex]
    new_counts = np.bincount(runs_used, minlength=len(run_length))
    good = new_counts >= 2
    vertex = vertex[good[runs_used]]
    runs_used = run_of[vertex]
    source = sample_scratch[run_first[good]]
    new_offsets = np.zeros(int(good.sum()) + 1, dtype=np.int64)
    np.cumsum(new_counts[good], out=new_offsets[1:])

    # Each piece's share of its scratch's length along the surface.
    step = np.zeros(len(sample_points))
    step[1:] = np.linalg.norm(np.diff(sample_points, axis=0), axis=1)
    step[~np.r_[False, keep[1:] & keep[:-1] & (run_of[1:] == run_of[:-1])]] = 0.0
    piece_length = np.bincount(run_of[kept], weights=step[kept], minlength=len(run_length))[good]
    all_step = np.zeros(len(sample_points))
    all_step[1:] = np.linalg.norm(np.diff(sample_points, axis=0), axis=1)
    all_step[np.r_[True, sample_scratch[1:] != sample_scratch[:-1]]] = 0.0
    total = np.bincount(sample_scratch, weights=all_step, minlength=scratches.count)[source]
    share = np.where(total > 0, piece_length / np.where(total > 0, total, 1.0), 1.0)

    fields = {name: getattr(scratches, name)[source] for name in
              ("width", "depth", "profile", "width_variation", "depth_variation", "seed")}
    for name in ("width_variation", "depth_variation"):
        fields[name] = fields[name].copy()
        fields[name][:, 1] *= share
    fields["seed"] = piece_seeds(fields["seed"], np.arange(len(source)) - np.searchsorted(source, source))
    pieces_set = ScratchSet(uv=sample_uv[vertex], offsets=new_offsets, **fields)
    return ScratchSet.concatenate([scratches.select(~touched), pieces_set]), touched
