"""What a brush stroke puts on a surface: the pen's scratch and the spray's centres (no ``bpy``).

The pen joins consecutive stroke points by paths traced on the surface
(:mod:`.trace`), re-aimed until they arrive, so a stroke over a fold follows the
surface; the spray scatters scratch centres around the stroke, which the
caller snaps onto the surface and traces like generated scratches
(:func:`.scatter.scratches_from_centres`).
"""
from __future__ import annotations

import numpy as np

from .scatter import Placed, build_set, empty_placed
from .surface import SEAM_TOLERANCE_UV, Surface
from .trace import BOUNDARY, END, SEAM_IN, START, assemble, enter_towards, trace_paths

__all__ = ["pen_scratches", "spray_centres", "spray_centres_with_pressure", "pressure_factor", "stroke_pressure",
           "MIN_PRESSURE"]

#: Lowest pressure factor: a scratch keeps a width and depth > 0 at the lightest touch.
MIN_PRESSURE = 0.05


def pen_scratches(surface: Surface, runs, params: dict) -> Placed:
    """One scratch following a stroke: ``runs`` is a list of (triangle, bary) hit sequences.

    Consecutive hits of a run are joined by paths traced on the surface (so the
    scratch follows the surface between them, over folds too); runs are
    separate (the stroke left the surface in between).  The scratch is cut at
    UV seams.  ``params`` holds arrays of length 1 (the stroke's single
    scratch, as ``Looks.sample(rng, 1)``).
    """
    starts_t, starts_b, group, segment = [], [], [], []
    for run_index, (triangle, bary) in enumerate(runs):
        triangle = np.asarray(triangle, dtype=np.int64)
        if len(triangle) < 2:
            continue
        starts_t.append(triangle)
        starts_b.append(np.asarray(bary, dtype=np.float64))
        group.append(np.full(len(triangle) - 1, run_index))
        segment.append(np.arange(len(triangle) - 1))
    if not starts_t:
        return empty_placed()
    hit_t = np.concatenate([t[:-1] for t in starts_t])
    hit_b = np.concatenate([b[:-1] for b in starts_b])
    target = np.concatenate([surface.point(t[1:], b[1:]) for t, b in zip(starts_t, starts_b)])
    group = np.concatenate(group)
    segment = np.concatenate(segment)
    records, last_end, arrived = _trace_to_targets(surface, hit_t, hit_b, target)

    path, order, kind, triangle, uv, point = records
    n_segments = len(hit_t)
    # A segment's end joins the next segment's start (the next hit) when it arrived there
    # and both sides give that point the same UV; then the next start replaces it.  Where they
    # differ (the hit lies on a UV seam: one side ended on it, the other starts across it)
    # the scratch is cut there, as a seam crossed inside a segment cuts it.
    last_of_run = np.r_[group[1:] != group[:-1], True]
    next_start = np.full(n_segments, -1)
    starts = np.flatnonzero((kind == START) & (path > 0))
    next_start[path[starts] - 1] = starts  # the START record of segment i + 1, at index i
    next_start[last_of_run] = -1
    joins = ~last_of_run & arrived & (next_start >= 0)
    if joins.any():
        end_triangle = triangle[last_end[joins]]
        next_point = point[next_start[joins]]
        uv_here = surface.uv_at(end_triangle, surface.barycentric(end_triangle, next_point))
        jump = np.abs(uv_here - uv[next_start[joins]]).max(axis=1)
        joins[np.flatnonzero(joins)[jump > SEAM_TOLERANCE_UV]] = False
    drop = np.zeros(len(path), dtype=bool)
    drop[last_end[joins]] = True
    breaks = kind == SEAM_IN
    # A start that does not continue its predecessor begins a new piece.
    breaks |= (kind == START) & (segment[path] > 0) & ~np.r_[False, joins[:-1]][path]
    keep = ~drop
    span = int(order.max()) + 2
    tiny = 1e-9 * max(surface.size, 1e-300)
    pieces = assemble(group[path][keep], (segment[path] * span + order)[keep], uv[keep], point[keep],
                      breaks[keep], min_length=tiny, merge_distance=tiny)
    source = np.zeros(pieces.count, dtype=np.int64)
    scratches = build_set(pieces, source, params)
    return Placed(scratches=scratches, source=source, point=pieces.point, piece_length=pieces.length,
                  requested=1)


#: Re-aimed traces per pen segment (a fold or a curved surface needs more than one).
_PEN_STEPS = 6


def _trace_to_targets(surface: Surface, triangle, bary, target):
    """Trace from each start towards its target point, re-aiming until it arrives.

    Returns (records, last_end, arrived): the records (path = start index,
    order, kind, triangle, uv, point), the index of each path's final end
    record, and whether the path reached its target.
    """
    n = len(triangle)
    triangle, bary = triangle.copy(), bary.copy()
    tolerance = 1e-7 * max(surface.size, 1e-300)
    active = np.arange(n)
    parts = []
    span = 0
    blocked = np.zeros(n, dtype=bool)
    for step in range(_PEN_STEPS):
        gap = target[active] - surface.point(triangle[active], bary[active])
        distance = np.linalg.norm(gap, axis=1)
        if step:
            moving = distance > tolerance
            active, gap, distance = active[moving], gap[moving], distance[moving]
        if not active.size:
            break
        # A point on an edge or a vertex (a stroke sample there, or a trace that stopped there)
        # starts in the triangle the gap leads into: on a fold, not every side can go on.
        triangle[active], bary[active] = enter_towards(surface, triangle[active], bary[active], gap)
        trace = trace_paths(surface, triangle[active], bary[active], gap, distance)
        keep = (trace.kind != START) | (step == 0)  # later starts repeat the previous end
        parts.append((active[trace.path[keep]], trace.order[keep] + span, trace.kind[keep],
                      trace.triangle[keep], trace.uv[keep], trace.point[keep]))
        span += int(trace.order.max()) + 2
        triangle[active], bary[active] = trace.end_triangle, trace.end_bary
        stopped = np.zeros(len(active), dtype=bool)
        stopped[trace.path[trace.kind == BOUNDARY]] = True
        blocked[active[stopped]] = True
        active = active[~stopped]
    records = tuple(np.concatenate(column) for column in zip(*parts))
    path, order, kind = records[0], records[1], records[2]
    ends = np.flatnonzero(np.isin(kind, (END, BOUNDARY)))
    last_end = np.full(n, -1)
    by_order = ends[np.argsort(order[ends], kind="stable")]
    last_end[path[by_order]] = by_order  # the latest end of each path wins
    final_gap = np.linalg.norm(target - surface.point(triangle, bary), axis=1)
    arrived = ~blocked & (final_gap <= tolerance * 10)
    return records, last_end, arrived


def pressure_factor(pressure, enabled: bool) -> np.ndarray:
    """What a setting is multiplied by at ``pressure`` (0–1): the pressure itself (at least
    ``MIN_PRESSURE``) where the setting's pressure toggle is on, else 1 (as Blender's brushes do)."""
    pressure = np.asarray(pressure, dtype=np.float64)
    return np.clip(pressure, MIN_PRESSURE, 1.0) if enabled else np.ones_like(pressure)


def stroke_pressure(runs_points, runs_pressure) -> float:
    """The pen's pressure: the mean along the stroke, weighted by length (a scratch has one width and
    depth; a dab of one point counts as its own pressure)."""
    total, weight = 0.0, 0.0
    for points, pressure in zip(runs_points, runs_pressure):
        points, pressure = np.asarray(points, dtype=np.float64), np.asarray(pressure, dtype=np.float64)
        if len(points) < 2:
            total, weight = total + float(pressure.sum()), weight + len(pressure)
            continue
        step = np.linalg.norm(np.diff(points, axis=0), axis=1)
        total += float((0.5 * (pressure[1:] + pressure[:-1]) * step).sum())
        weight += float(step.sum())
    return total / weight if weight > 0 else 1.0


def spray_centres(rng: np.random.Generator, runs_points, normals, radius: float, density: float,
                  jitter: float):
    """Where a spray stroke puts scratches, before they are snapped to the surface.

    Parameters
    ----------
    runs_points : list of (n_i, 3) arrays
        The stroke's on-surface points, run by run.
    normals : list of (n_i, 3) arrays
        Surface normals at those points.
    radius : float
        Brush radius: centres are spread uniformly over a disc of this radius
        (in the tangent plane) around points drawn uniformly along the stroke.
    density : float
        Expected scratches per brush radius of stroke length; a single dab
        (a click) sprays ``density`` scratches on average.
    jitter : float
        Directions follow the stroke within ± ``jitter`` radians.

    Returns
    -------
    centres (N, 3), directions (N, 3) — directions are zero where the stroke has
    no direction (a click); the caller then draws them at random.
    """
    centres, directions, _ = _spray(rng, runs_points, normals, [None] * len(runs_points), radius, density,
                                    jitter, False)
    return centres, directions


def spray_centres_with_pressure(rng: np.random.Generator, runs_points, normals, runs_pressure, radius: float,
                                density: float, jitter: float, density_follows: bool):
    """:func:`spray_centres` with the stroke's pressure (one array per run, 0–1).

    Returns ``(centres, directions, pressure)``: the pressure at each centre's
    base point on the stroke (linear between stroke points).  With
    ``density_follows`` the scratches are thinned to ``pressure_factor`` of the
    run's highest pressure at their base point, so the expected count along
    the stroke follows the pressure; without it the centres are exactly those
    of :func:`spray_centres` with the same ``rng``.
    """
    return _spray(rng, runs_points, normals, runs_pressure, radius, density, jitter, density_follows)


def _spray(rng, runs_points, normals, runs_pressure, radius, density, jitter, thin):
    lengths = [np.linalg.norm(np.diff(p, axis=0), axis=1).sum() if len(p) > 1 else 0.0 for p in runs_points]
    weights = np.array([length / radius + 1.0 for length in lengths])
    peaks = np.array([1.0 if p is None or not thin else float(pressure_factor(p, True).max()) for p in runs_pressure])
    counts = rng.poisson(density * weights * peaks)
    centres, directions, pressures = [], [], []
    for points, nrm, n, pressure, peak in zip(runs_points, normals, counts, runs_pressure, peaks):
        if n == 0:
            continue
        pressure = np.ones(len(points)) if pressure is None else np.asarray(pressure, dtype=np.float64)
        points = np.asarray(points, dtype=np.float64)
        nrm = np.asarray(nrm, dtype=np.float64)
        if len(points) > 1:
            step = np.linalg.norm(np.diff(points, axis=0), axis=1)
            arc = np.r_[0.0, np.cumsum(step)]
            s = rng.uniform(0.0, arc[-1], n)
            segment = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, len(step) - 1)
            f = ((s - arc[segment]) / np.where(step[segment] > 0, step[segment], 1.0))[:, None]
            base = points[segment] + f * (points[segment + 1] - points[segment])
            at = pressure[segment] + f[:, 0] * (pressure[segment + 1] - pressure[segment])
            along = points[segment + 1] - points[segment]
            normal = nrm[segment]
        else:
            base = np.repeat(points, n, axis=0)
            at = np.repeat(pressure, n)
            along = np.zeros((n, 3))
            normal = np.repeat(nrm, n, axis=0)
        along = along - np.einsum("ni,ni->n", along, normal)[:, None] * normal
        norm = np.linalg.norm(along, axis=1)
        has_direction = norm > 0
        along = np.where(has_direction[:, None], along / np.where(has_direction, norm, 1.0)[:, None], 0.0)
        # A tangent basis for the disc even where the stroke has no direction.
        helper = np.where(np.abs(normal[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        e1 = np.where(has_direction[:, None], along, np.cross(normal, helper))
        e1 /= np.maximum(np.linalg.norm(e1, axis=1), 1e-300)[:, None]
        e2 = np.cross(normal, e1)
        rho = radius * np.sqrt(rng.uniform(0.0, 1.0, n))
        phi = rng.uniform(0.0, 2.0 * np.pi, n)
        centres.append(base + (rho * np.cos(phi))[:, None] * e1 + (rho * np.sin(phi))[:, None] * e2)
        turn = rng.uniform(-jitter, jitter, n)[:, None]
        directions.append(np.where(has_direction[:, None],
                                   np.cos(turn) * along + np.sin(turn) * np.cross(normal, along), 0.0))
        pressures.append(at)
        if thin:  # keep each with probability factor / peak: the expected count follows the pressure
            keep = rng.uniform(0.0, 1.0, n) * peak < pressure_factor(at, True)
            centres[-1], directions[-1], pressures[-1] = centres[-1][keep], directions[-1][keep], at[keep]
    if not centres:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    return np.concatenate(centres), np.concatenate(directions), np.concatenate(pressures)
